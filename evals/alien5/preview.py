#!/usr/bin/env python
"""Contact sheets of the rendered scenes: first / middle / last frame with the truth drawn.

    python preview.py OUTDIR [--only NAME ...] [--truth]
"""
import argparse
import json
import os

import cv2
import numpy as np
import pandas as pd

from verify import read_back  # (the same reader verify.py checks the scenes with)

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = os.path.join(HERE, 'scenes')


def to8(img):
    img = np.asarray(img)
    if img.dtype != np.uint8:
        img = img.astype(np.float64)
        lo, hi = np.percentile(img, 0.5), np.percentile(img, 99.5)
        img = np.clip((img - lo) / max(hi - lo, 1) * 255, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return img


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('out')
    ap.add_argument('--only', nargs='*')
    ap.add_argument('--truth', action='store_true')
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for name in sorted(os.listdir(SCENES)):
        if a.only and name not in a.only:
            continue
        d = os.path.join(SCENES, name)
        meta = json.load(open(os.path.join(d, 'scene.json')))
        frames, _ = read_back(os.path.join(d, meta['input']))
        n = len(frames)
        idx = [0, n // 2, n - 1]
        tiles = []
        cl = pd.read_csv(os.path.join(d, 'truth_centrelines.csv')) if a.truth else None
        for i in idx:
            im = to8(frames[i]).copy()
            if cl is not None:
                g = cl[cl.frame == i]
                pts = np.stack([g.x_um / meta['um_per_px'], -g.y_um / meta['um_per_px']], 1)
                cv2.polylines(im, [np.round(pts * 4).astype(np.int32)], False, (0, 0, 255), 1,
                              cv2.LINE_AA, 2)
            s = 480 / max(im.shape[:2])
            tiles.append(cv2.resize(im, None, fx=s, fy=s, interpolation=cv2.INTER_AREA))
        h = max(t.shape[0] for t in tiles)
        tiles = [cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, 4, cv2.BORDER_CONSTANT) for t in tiles]
        cv2.imwrite(os.path.join(a.out, name + '.png'), np.hstack(tiles))
        print(name, n, 'frames')


if __name__ == '__main__':
    main()
