#!/usr/bin/env python
"""Mirrored and rotated copies of another set's scenes, their truth carried
along: does the tracker measure a scene the same whichever way it faces?

    python evals/flip/make.py evals/alien4 [--only NAME ...]

Writes ``scenes/<name>_mx`` (mirrored left-right: every bend's sign flips)
and ``scenes/<name>_r90`` (turned a quarter clockwise: bends unchanged), each
a folder of lossless PNG frames (8 or 16 bit, as decoded), with
``scene.json``, ``truth_tracks.csv`` and ``truth_centrelines.csv``
transformed. Score with ``python evals/flip/score.py``.
"""
import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))
from pipeline.frames import open_frames  # noqa: E402


def transform(src: Path, dst: Path, kind: str) -> None:
    meta = json.loads((src / "scene.json").read_text())
    um = meta["um_per_px"]
    frames_dir = dst / "frames"
    frames_dir.mkdir(parents=True, exist_ok=True)
    shape = None
    with open_frames(src / meta["input"]) as reader:
        for i, frame in enumerate(reader):
            f = np.asarray(frame)
            shape = f.shape[:2]
            f = cv2.flip(f, 1) if kind == "mx" else cv2.rotate(f, cv2.ROTATE_90_CLOCKWISE)
            if f.dtype not in (np.uint8, np.uint16):
                f = np.clip(np.round(f * 65535 if f.max() <= 1.0 else f), 0, 65535).astype(
                    np.uint16)
            if f.ndim == 3:
                f = cv2.cvtColor(f, cv2.COLOR_RGB2BGR)
            cv2.imwrite(str(frames_dir / f"f{i:04d}.png"), f)
    rows, cols = shape

    def xy(x, y):
        if kind == "mx":
            return (cols - 1) * um - x, y
        # (col, row) -> (rows - 1 - row, col)
        return (rows - 1) * um + y, -x

    tr = pd.read_csv(src / "truth_tracks.csv")
    for a in ("tip", "base"):
        tr[f"{a}_x_um"], tr[f"{a}_y_um"] = xy(tr[f"{a}_x_um"], tr[f"{a}_y_um"])
    if kind == "mx":
        tr["bend_angle_deg"] = -tr["bend_angle_deg"]
    tr.to_csv(dst / "truth_tracks.csv", index=False)
    cl = pd.read_csv(src / "truth_centrelines.csv")
    cl["x_um"], cl["y_um"] = xy(cl["x_um"], cl["y_um"])
    cl.to_csv(dst / "truth_centrelines.csv", index=False)
    meta["input"] = "frames"
    meta["name"] = dst.name
    (dst / "scene.json").write_text(json.dumps(meta, indent=1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set_dir", type=Path)
    ap.add_argument("--only", nargs="+")
    args = ap.parse_args(argv)
    names = args.only or sorted(p.name for p in (args.set_dir / "scenes").iterdir() if p.is_dir())
    for n in names:
        for kind in ("mx", "r90"):
            transform(args.set_dir / "scenes" / n, HERE / "scenes" / f"{n}_{kind}", kind)
            print(n, kind, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
