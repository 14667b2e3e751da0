#!/usr/bin/env python
"""Where a scored run's errors come from, scene by scene.

    python evals/errors.py evals/alien7 evals/alien7/res_A [--only NAME ...] [--csv OUT]

For every scene of a set (``SET/scenes/<name>/``: ``scene.json``, ``truth_tracks.csv``,
``truth_centrelines.csv``, as the alien sets write them) that a run scored (``RUN/<name>/``:
``tracks.csv``, ``centrelines.csv``, as ``microtube track`` writes them), the medians over
the frames of:

- ``bend_signed``: the bend-angle error against the bend's own sign, deg (< 0: the bend
  under-measured, whichever way the tube turns);
- ``tip_along``: how far the tracked tip lies beyond the true one along the true tip
  tangent, px (< 0: short of the apex);
- ``bend_from_tip``: the bend error that offset alone brings, deg (the true curvature at the
  tip times it: a tip found short of a curling end reads the tangent from before it);
- ``bend_rest``: |bend error - bend_from_tip|, deg, what is left;
- ``base_along``, ``base_across``: the tracked base's offset from the true one along and
  across the true base tangent, px (< 0 along: inside the holder).

A tool for development: it tells a tip placed short from a shape under-curved, and those
from a base moved or turned.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

#: The tip's tangent and curvature are read off the truth's last this many px.
TIP_PX = 6.0


def _points(frame: pd.DataFrame, um: float):
    z = (frame.x_um.to_numpy() + 1j * frame.y_um.to_numpy()) / um
    return z, frame.s_um.to_numpy() / um


def _end_line(z: np.ndarray, s: np.ndarray, at_tip: bool):
    """Tangent angle (rad) and curvature (rad/px) at one end of a polyline,
    from a line fitted to its chord angles over the last :data:`TIP_PX`."""
    sel = s >= s[-1] - TIP_PX if at_tip else s <= s[0] + TIP_PX
    zz, ss = z[sel], s[sel]
    if zz.size < 3:
        return np.nan, np.nan
    ang = np.unwrap(np.angle(np.diff(zz)))
    mid = 0.5 * (ss[1:] + ss[:-1]) - (ss[-1] if at_tip else ss[0])
    slope, value = np.polyfit(mid, ang, 1)
    return float(value), float(slope)


def scene_errors(scene_dir: Path, run_dir: Path) -> dict | None:
    """The medians above for one scene, or None if the run has no tracks for it."""
    tracks = run_dir / "tracks.csv"
    if not tracks.is_file():
        return None
    um = json.loads((scene_dir / "scene.json").read_text())["um_per_px"]
    truth = pd.read_csv(scene_dir / "truth_tracks.csv").set_index("frame")
    meas = pd.read_csv(tracks).set_index("frame")
    lines = pd.read_csv(scene_dir / "truth_centrelines.csv")
    rows = []
    for frame, line in lines.groupby("frame"):
        if frame not in meas.index or frame not in truth.index:
            continue
        m, t = meas.loc[frame], truth.loc[frame]
        if not np.isfinite(m.bend_angle_deg):
            continue
        z, s = _points(line, um)
        tip_angle, tip_kappa = _end_line(z, s, at_tip=True)
        base_angle, _ = _end_line(z, s, at_tip=False)
        tip = complex(m.tip_x_um, m.tip_y_um) / um
        base = complex(m.base_x_um, m.base_y_um) / um
        along_tip = ((tip - z[-1]) * np.exp(-1j * tip_angle)).real
        off_base = (base - z[0]) * np.exp(-1j * base_angle)
        err = m.bend_angle_deg - t.bend_angle_deg
        from_tip = np.degrees(tip_kappa * along_tip)
        sign = np.sign(t.bend_angle_deg) or 1.0
        rows.append((err * sign, along_tip, from_tip * sign, abs(err - from_tip),
                     off_base.real, off_base.imag))
    if not rows:
        return None
    med = np.nanmedian(np.array(rows, float), axis=0)
    return dict(zip(("bend_signed", "tip_along", "bend_from_tip", "bend_rest",
                     "base_along", "base_across"), med, strict=True))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set_dir", type=Path, help="the set (its scenes/ holds the truth)")
    ap.add_argument("run_dir", type=Path, help="a score.py --out directory")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="these scenes only")
    ap.add_argument("--csv", type=Path, help="also write the table here")
    args = ap.parse_args(argv)
    scenes = args.set_dir / "scenes"
    if not scenes.is_dir() or not args.run_dir.is_dir():
        print(f"errors: no {scenes if not scenes.is_dir() else args.run_dir}", file=sys.stderr)
        return 2
    names = args.only or sorted(p.name for p in scenes.iterdir() if p.is_dir())
    table = {n: e for n in names
             if (e := scene_errors(scenes / n, args.run_dir / n)) is not None}
    if not table:
        print(f"errors: no scored scene of {scenes} in {args.run_dir}", file=sys.stderr)
        return 2
    df = pd.DataFrame.from_dict(table, orient="index").sort_values("bend_signed")
    df.index.name = "scene"
    print(df.to_string(float_format=lambda x: f"{x:+.2f}"))
    if args.csv:
        df.to_csv(args.csv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
