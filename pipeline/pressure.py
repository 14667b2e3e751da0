"""Pressure of every tracked frame: from a pressure log or a linear ramp.

The calibration needs the pressure p of each frame (the models take p/p_max).
Two sources, and the result always says which one was used:

* a **pressure log**, a CSV with ``pressure_mpa`` and either ``frame`` (matched
  by frame index) or ``time_s`` (matched by the tracks' ``time_s``), linearly
  interpolated between logged rows. The log must cover every frame asked for:
  extrapolating a pressure is refused;
* a **linear ramp** from 0 at the first frame of the tracks to ``p_max`` at the
  last one (by frame index), for recordings made with a steady ramp and no log.

Column names are those of :mod:`pipeline.schema`. Bad input raises
``ValueError`` with a one-line message naming the file, column or value.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import schema as S

#: Relative slack on the ends of the logged range (rounding of times in a CSV).
_COVER_TOL = 1e-9


@dataclass(frozen=True)
class FramePressures:
    """The pressure of each requested frame and where it came from.

    Attributes
    ----------
    frame : (F,) ndarray of int
        Frame indices, as in ``tracks.csv``.
    pressure_mpa : (F,) ndarray of float
        Pressure of each frame, MPa (finite, ≥ 0).
    source : str
        One line saying where the pressures came from, e.g.
        ``"log pressure.csv, interpolated by frame"`` or
        ``"linear ramp 0 -> 0.14 MPa over frames 0..49 (--p-max)"``.
    kind : str
        ``"log:frame"``, ``"log:time"`` or ``"ramp"``.
    p_max_mpa : float or None
        The ramp's end pressure (the p_max given by the user), None for a log.
    """

    frame: np.ndarray
    pressure_mpa: np.ndarray
    source: str
    kind: str
    p_max_mpa: float | None = None


def read_pressure_log(path) -> pd.DataFrame:
    """Read and check a pressure log CSV.

    Parameters
    ----------
    path : str or Path
        CSV with ``pressure_mpa`` and ``frame`` and/or ``time_s``.

    Returns
    -------
    DataFrame
        The log's key column(s) and ``pressure_mpa``, as floats, sorted by the
        key that will be used (``frame`` if present, else ``time_s``).

    Raises
    ------
    ValueError
        Missing file or columns, fewer than two rows, non-finite or negative
        pressures, non-finite or repeated keys.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"pressure log not found: {path}")
    try:
        log = pd.read_csv(path)
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise ValueError(f"cannot read pressure log {path}: {_first_line(exc)}") from None
    if S.PRESSURE not in log.columns:
        raise ValueError(f"pressure log {path} has no '{S.PRESSURE}' column "
                         f"({_columns(log)})")
    key = S.FRAME if S.FRAME in log.columns else S.TIME if S.TIME in log.columns else None
    if key is None:
        raise ValueError(f"pressure log {path} needs a '{S.FRAME}' or '{S.TIME}' column "
                         f"({_columns(log)})")
    keep = [c for c in (S.FRAME, S.TIME) if c in log.columns] + [S.PRESSURE]
    log = log[keep].copy()
    for col in keep:
        log[col] = pd.to_numeric(log[col], errors="coerce").astype(float)
    if len(log) < 2:
        raise ValueError(f"pressure log {path} needs at least two rows, got {len(log)}")
    p = log[S.PRESSURE].to_numpy()
    bad = ~np.isfinite(p)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"pressure log {path}: {S.PRESSURE} must be finite, got "
                         f"{log[S.PRESSURE].iloc[row]!r} in data row {row + 1}")
    if (p < 0).any():
        row = int(np.flatnonzero(p < 0)[0])
        raise ValueError(f"pressure log {path}: {S.PRESSURE} must be >= 0, got {p[row]!r} "
                         f"in data row {row + 1}")
    k = log[key].to_numpy()
    if not np.isfinite(k).all():
        row = int(np.flatnonzero(~np.isfinite(k))[0])
        raise ValueError(f"pressure log {path}: {key} must be finite, got "
                         f"{log[key].iloc[row]!r} in data row {row + 1}")
    log = log.sort_values(key, kind="stable").reset_index(drop=True)
    if (np.diff(log[key].to_numpy()) == 0).any():
        raise ValueError(f"pressure log {path}: {key} values must be unique")
    return log


def pressures_from_log(tracks: pd.DataFrame, log: pd.DataFrame, frames, *,
                       name: str = "pressure log") -> FramePressures:
    """Interpolate a pressure log at the given frames.

    Matched by ``frame`` when the log has it, else by ``time_s`` (then the
    tracks must carry finite times for those frames).

    Parameters
    ----------
    tracks : DataFrame
        ``tracks.csv`` (needs ``frame``; ``time_s`` when matching by time).
    log : DataFrame
        From :func:`read_pressure_log`.
    frames : (F,) array_like of int
        Frames that need a pressure (usually the usable ones).
    name : str
        How to call the log in messages and in ``source``.

    Raises
    ------
    ValueError
        When the log does not cover every frame, or times are missing.
    """
    frames = np.asarray(frames, dtype=np.int64)
    if S.FRAME in log.columns:
        kind, key = "log:frame", S.FRAME
        at = frames.astype(float)
    else:
        kind, key = "log:time", S.TIME
        times = tracks.set_index(S.FRAME)[S.TIME] if S.TIME in tracks.columns else None
        if times is None:
            raise ValueError(f"{name} is by {S.TIME} but the tracks have no {S.TIME} column")
        at = pd.to_numeric(times.reindex(frames), errors="coerce").to_numpy(dtype=float)
        if not np.isfinite(at).all():
            bad = int(frames[~np.isfinite(at)][0])
            raise ValueError(f"{name} is by {S.TIME} but frame {bad} of the tracks has no "
                             f"time (give a log by frame, or track with --fps)")
    k = log[key].to_numpy(dtype=float)
    lo, hi = k[0], k[-1]
    slack = _COVER_TOL * max(1.0, abs(lo), abs(hi))
    outside = (at < lo - slack) | (at > hi + slack)
    if outside.any():
        unit = "" if key == S.FRAME else " s"
        raise ValueError(f"{name} does not cover the frames: it spans {key} {lo:g}..{hi:g}{unit}"
                         f" but the frames need {at.min():g}..{at.max():g}{unit}")
    p = np.interp(at, k, log[S.PRESSURE].to_numpy(dtype=float))
    return FramePressures(frame=frames, pressure_mpa=p,
                          source=f"{name}, interpolated by {key}", kind=kind)


def pressures_from_ramp(tracks: pd.DataFrame, frames, p_max_mpa: float, *,
                        origin: str = "--p-max") -> FramePressures:
    """A linear ramp from 0 at the first frame of ``tracks`` to ``p_max_mpa`` at its last.

    The ramp runs over all frames of the table (measured or not), by frame index.

    Raises
    ------
    ValueError
        If ``p_max_mpa`` is not a positive number or the tracks hold fewer than
        two distinct frames.
    """
    try:
        p_max = float(p_max_mpa)
    except (TypeError, ValueError):
        raise ValueError(f"p_max must be a positive number, got {p_max_mpa!r}") from None
    if not (np.isfinite(p_max) and p_max > 0):
        raise ValueError(f"p_max must be a positive number, got {p_max_mpa!r}")
    all_frames = tracks[S.FRAME].to_numpy(dtype=float)
    f0, f1 = float(np.min(all_frames)), float(np.max(all_frames))
    if not f1 > f0:
        raise ValueError("a pressure ramp needs at least two frames in the tracks")
    frames = np.asarray(frames, dtype=np.int64)
    p = p_max * (frames - f0) / (f1 - f0)
    return FramePressures(
        frame=frames, pressure_mpa=p, kind="ramp", p_max_mpa=p_max,
        source=f"linear ramp 0 -> {p_max:g} MPa over frames {f0:g}..{f1:g} ({origin})")


def frame_pressures(tracks: pd.DataFrame, frames, *, pressure_csv=None,
                    p_max=None) -> FramePressures:
    """The pressure of each frame, from a log (``pressure_csv``) or a ramp to ``p_max``.

    Exactly one of the two must be given.

    Raises
    ------
    ValueError
        If both or neither are given, or the chosen source is invalid.
    """
    if pressure_csv is not None and p_max is not None:
        raise ValueError("give either a pressure log or p_max, not both")
    if pressure_csv is not None:
        log = read_pressure_log(pressure_csv)
        return pressures_from_log(tracks, log, frames,
                                  name=f"pressure log {Path(pressure_csv).name}")
    if p_max is not None:
        return pressures_from_ramp(tracks, frames, p_max)
    raise ValueError("no pressures: give a pressure log (--pressure) or the ramp's end "
                     "pressure (--p-max)")


def _columns(log: pd.DataFrame) -> str:
    """The header of a table for a message, or a hint when it is not a CSV header."""
    text = ", ".join(map(str, log.columns))
    if len(text) > 120 or not text.isprintable():
        return "is it a CSV file with a header row?"
    return f"columns: {text}"


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
