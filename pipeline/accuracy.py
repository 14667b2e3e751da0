"""Tracking accuracy against a rendered scene's truth.

Both sides use the tracker's tables (:mod:`pipeline.schema`), so anything that
writes them — this tracker or another — can be scored the same way.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import schema as S


def _polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance from each point (n, 2) to the polyline ``line`` (m, 2)."""
    from scipy.spatial import cKDTree

    if len(line) < 2:
        return np.hypot(*(points - line[0]).T)
    _, idx = cKDTree(line).query(points)
    best = np.full(len(points), np.inf)
    for k in (idx - 1, idx):  # the two segments meeting at the nearest vertex
        k = np.clip(k, 0, len(line) - 2)
        a, b = line[k], line[k + 1]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", points - a, ab)
                    / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1)
        best = np.minimum(best, np.hypot(*(a + t[:, None] * ab - points).T))
    return best


def compare(tracks: pd.DataFrame, lines: pd.DataFrame, truth_tracks: pd.DataFrame,
            truth_lines: pd.DataFrame, um_per_px: float) -> pd.DataFrame:
    """Per-frame errors of a tracking run against the truth.

    Returns
    -------
    DataFrame
        ``frame``, ``status``, ``angle_error_deg`` (measured − true),
        ``centreline_rms_px`` and ``centreline_max_px`` (distance of the
        measured points to the true centreline), ``length_error_pct``,
        ``base_error_px``, ``tip_error_px``. Frames without a measurement have
        NaN errors.
    """
    truth = truth_tracks.set_index(S.FRAME)
    measured = tracks.set_index(S.FRAME).reindex(truth.index)
    status = measured[S.STATUS].fillna("missing")
    out = pd.DataFrame({S.FRAME: truth.index, S.STATUS: status.to_numpy()})
    out["angle_error_deg"] = (measured[S.BEND] - truth[S.BEND]).to_numpy()
    out["length_error_pct"] = (100 * (measured[S.LENGTH] / truth[S.LENGTH] - 1)).to_numpy()
    out["base_error_px"] = (np.hypot(measured[S.BASE_X] - truth[S.BASE_X],
                                     measured[S.BASE_Y] - truth[S.BASE_Y]) / um_per_px).to_numpy()
    out["tip_error_px"] = (np.hypot(measured[S.TIP_X] - truth[S.TIP_X],
                                    measured[S.TIP_Y] - truth[S.TIP_Y]) / um_per_px).to_numpy()
    rms = np.full(len(out), np.nan)
    worst = np.full(len(out), np.nan)
    groups = dict(tuple(lines.groupby(S.FRAME))) if len(lines) else {}
    true_groups = dict(tuple(truth_lines.groupby(S.FRAME)))
    for i, frame in enumerate(truth.index):
        if frame not in groups or frame not in true_groups:
            continue
        pts = groups[frame][[S.X, S.Y]].to_numpy() / um_per_px
        ref = true_groups[frame].sort_values(S.S)[[S.X, S.Y]].to_numpy() / um_per_px
        d = _polyline_distance(pts, ref)
        rms[i] = float(np.sqrt(np.mean(d**2)))
        worst[i] = float(d.max())
    out["centreline_rms_px"] = rms
    out["centreline_max_px"] = worst
    return out


@dataclass(frozen=True)
class Accuracy:
    """Summary of :func:`compare` over a scene (angles in degrees, distances in px)."""

    frames: int
    frames_lost: int
    angle_median: float
    angle_p95: float
    angle_max: float
    centreline_rms_px: float
    centreline_max_px: float
    length_error_max_pct: float
    base_error_max_px: float

    def meets_targets(self) -> bool:
        """The tracking issue's targets."""
        return (self.frames_lost == 0 and self.angle_median <= 0.5 and self.angle_p95 <= 2.0
                and self.angle_max <= 5.0 and self.centreline_rms_px <= 0.5
                and self.length_error_max_pct <= 1.0)

    def as_dict(self) -> dict:
        return asdict(self)


def summarise(errors: pd.DataFrame) -> Accuracy:
    """Median, 95th percentile and max of the absolute angle error, and the rest."""
    ok = errors[errors[S.STATUS] == S.STATUS_OK]
    ang = np.abs(ok["angle_error_deg"].to_numpy())

    def stat(fn, values):
        values = values[np.isfinite(values)]
        return float(fn(values)) if values.size else float("nan")

    return Accuracy(
        frames=len(errors), frames_lost=int(len(errors) - len(ok)),
        angle_median=stat(np.median, ang), angle_p95=stat(lambda a: np.percentile(a, 95), ang),
        angle_max=stat(np.max, ang),
        # pooled over frames: the RMS of all point distances
        centreline_rms_px=stat(lambda r: np.sqrt(np.mean(r**2)),
                               ok["centreline_rms_px"].to_numpy()),
        centreline_max_px=stat(np.max, ok["centreline_max_px"].to_numpy()),
        length_error_max_pct=stat(np.max, np.abs(ok["length_error_pct"].to_numpy())),
        base_error_max_px=stat(np.max, ok["base_error_px"].to_numpy()))


def score_folder(scene_dir, tracked_dir) -> tuple[pd.DataFrame, Accuracy]:
    """Compare ``tracked_dir`` (written by ``microtube track``) with ``scene_dir``'s truth."""
    import json

    scene_dir, tracked_dir = Path(scene_dir), Path(tracked_dir)
    record = json.loads((scene_dir / S.SCENE_FILE).read_text(encoding="utf-8"))
    scale = float(record["layout"]["um_per_px"])
    errors = compare(pd.read_csv(tracked_dir / S.TRACKS_FILE),
                     pd.read_csv(tracked_dir / S.CENTRELINES_FILE),
                     pd.read_csv(scene_dir / S.TRUTH_TRACKS_FILE),
                     pd.read_csv(scene_dir / S.TRUTH_CENTRELINES_FILE), scale)
    return errors, summarise(errors)
