"""``microtube demo``: the whole job on the committed scenes, checked against their truth.

For every scene folder (one with a ``scene.json``): track its frames at the
scene's known scale (as with a stage micrometer), score the tracking
against the truth, calibrate the line-segment model with the scene's pressure
log, and compare the fitted parameters with the ones the scene was rendered
with. Then write reports/.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from . import schema as S

REPO = Path(__file__).resolve().parents[1]


@dataclass
class SceneResult:
    """What the demo measured on one scene."""

    name: str
    sample: str
    frames: int
    track_s: float
    frames_per_s: float
    accuracy: object
    calibration: object | None
    truth: dict
    calibrate_s: float
    notes: list = field(default_factory=list)

    def row(self) -> dict:
        a = self.accuracy
        out = {"scene": self.name, "sample": self.sample, "frames": self.frames,
               "frames_lost": a.frames_lost, "angle_median_deg": a.angle_median,
               "angle_p95_deg": a.angle_p95, "angle_max_deg": a.angle_max,
               "centreline_rms_px": a.centreline_rms_px,
               "length_error_max_pct": a.length_error_max_pct,
               "base_error_max_px": a.base_error_max_px,
               "meets_targets": a.meets_targets(), "track_s": self.track_s,
               "frames_per_s": self.frames_per_s}
        return out

    def calibration_row(self) -> dict:
        c = self.calibration
        out = {"scene": self.name, "sample": self.sample,
               "true_delta_eps": self.truth["delta_eps"], "true_k_de": self.truth["k_de"]}
        if c is None:
            return out
        de = c.parameters["eps_max"]
        k = c.parameters["k_de"]
        lo, hi = de.ci95 if de.ci95 else (float("nan"), float("nan"))
        out.update({
            "fit_delta_eps": c.delta_eps,
            "delta_eps_ci95_lo": lo - c.value("eps_min"),
            "delta_eps_ci95_hi": hi - c.value("eps_min"),
            "delta_eps_error_pct": 100 * (c.delta_eps / self.truth["delta_eps"] - 1),
            "k_fitted": bool(k.fitted),
            "fit_k_de": k.value,
            "k_ci95_lo": k.ci95[0] if k.ci95 else float("nan"),
            "k_ci95_hi": k.ci95[1] if k.ci95 else float("nan"),
            "k_reason": "" if k.fitted else k.reason,
            "rms_um": c.rms_um, "angle_rms_deg": c.angle_rms_deg,
            "frames_used": c.frames_used, "calibrate_s": self.calibrate_s,
        })
        return out


def find_scenes(frames_dir) -> list[Path]:
    """Scene folders (holding a scene.json) under ``frames_dir``, by name."""
    frames_dir = Path(frames_dir)
    if not frames_dir.is_dir():
        raise ValueError(f"{frames_dir}: no such scenes folder (regenerate it with "
                         "'microtube render --sample-frames --out sample_frames')")
    scenes = sorted(p for p in frames_dir.iterdir() if (p / S.SCENE_FILE).is_file())
    if not scenes:
        raise ValueError(f"{frames_dir}: holds no scene folders (with {S.SCENE_FILE})")
    return scenes


def run_scene(scene_dir, out_dir, *, overlay: bool = True, progress=None) -> SceneResult:
    """Track, score and calibrate one rendered scene folder."""
    from .accuracy import score_folder
    from .calibrate import calibrate_folder
    from .tracks import track_video

    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    record = json.loads((scene_dir / S.SCENE_FILE).read_text(encoding="utf-8"))
    scene = record["scene"]
    frames = scene_dir / record["frames_file"]
    # the microscope's scale, as a lab knows it from a stage micrometer (tracking with
    # --sample instead ties every position to the length measured on frame 0)
    run = track_video(frames, out_dir, um_per_px=record["layout"]["um_per_px"],
                      overlay=overlay, progress=progress)
    _, acc = score_folder(scene_dir, out_dir)
    truth = {"delta_eps": scene["eps_max"] - scene["eps_min"], "k_de": scene["k_de_per_um"],
             "eps_min": scene["eps_min"], "eps_max": scene["eps_max"]}
    start = time.perf_counter()
    calib = None
    notes = list(run.notes)
    try:
        calib = calibrate_folder(scene["sample"], out_dir,
                                 pressure_csv=scene_dir / S.PRESSURE_FILE,
                                 n_segments=scene.get("n_segments"),
                                 out_json=out_dir / "fit.json")
    except ValueError as exc:
        notes.append(f"calibration failed: {exc}")
    return SceneResult(scene_dir.name, str(scene["sample"]), run.n_frames, run.runtime_s,
                       run.frames_per_s, acc, calib, truth, time.perf_counter() - start,
                       notes)


def format_table(results: list[SceneResult]) -> str:
    """The demo's printed table."""
    head = (f"{'scene':<10} {'frames':>6} {'fps':>5}  {'angle err med/p95/max (deg)':<27} "
            f"{'rms px':>6}  {'d_eps fit [95%] vs truth':<34} {'k fit (1/um) vs truth':<30}")
    lines = [head, "-" * len(head)]
    for r in results:
        a = r.accuracy
        ang = f"{a.angle_median:.2f}/{a.angle_p95:.2f}/{a.angle_max:.2f}"
        c = r.calibration_row()
        if r.calibration is None:
            de, k = "calibration failed", ""
        else:
            de = (f"{c['fit_delta_eps']:.4f} [{c['delta_eps_ci95_lo']:.4f},"
                  f"{c['delta_eps_ci95_hi']:.4f}] vs {c['true_delta_eps']:.4f}")
            k = (f"{c['fit_k_de']:+.5f} vs {c['true_k_de']:+.4f}" if c["k_fitted"]
                 else f"not fitted (truth {c['true_k_de']:+.4f})")
        lines.append(f"{r.name:<10} {r.frames:>6} {r.frames_per_s:>5.0f}  {ang:<27} "
                     f"{a.centreline_rms_px:>6.3f}  {de:<34} {k:<30}")
    return "\n".join(lines)


def run_demo(frames_dir=None, out_dir="demo_out", reports_dir="reports", *,
             quiet: bool = False, benchmarks: bool = False) -> list[SceneResult]:
    """Track and calibrate every scene, print the table, write reports/."""
    from .report import write_reports

    frames_dir = Path(frames_dir) if frames_dir else REPO / "sample_frames"
    scenes = find_scenes(frames_dir)
    out_dir = Path(out_dir)
    results = []
    for scene_dir in scenes:
        if not quiet:
            print(f"tracking and calibrating {scene_dir.name} ...", flush=True)
        results.append(run_scene(scene_dir, out_dir / scene_dir.name))
    if not quiet:
        print()
        print(format_table(results))
        print()
    paths = write_reports(reports_dir, benchmarks=benchmarks, quiet=quiet, demo=results,
                          demo_out=out_dir)
    if not quiet:
        print(f"wrote {len(paths)} report files into {reports_dir}/ "
              f"(start with {Path(reports_dir) / 'README.md'}); tracks and fits in {out_dir}/")
    return results


def demo_tables(results: list[SceneResult]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(tracking accuracy, calibration) tables of a demo run."""
    return (pd.DataFrame([r.row() for r in results]),
            pd.DataFrame([r.calibration_row() for r in results]))
