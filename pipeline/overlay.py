"""Pictures of the tracked centreline on the frames, for a person to check by eye."""

from __future__ import annotations

import cv2
import numpy as np

from .atomic import atomic_path
from .centreline import resample
from .track import FrameTrack

_GREEN = (60, 200, 60)
_RED = (40, 40, 230)
_BLUE = (230, 120, 30)


def draw_frame(frame: np.ndarray, result: FrameTrack) -> np.ndarray:
    """A BGR uint8 copy of ``frame`` with the centreline, base and tip drawn."""
    img = frame
    if img.dtype != np.uint8:
        img = np.clip(img.astype(np.float32) / (65535.0 if img.dtype == np.uint16 else 1.0)
                      * 255, 0, 255).astype(np.uint8)
    bgr = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    thick = max(1, int(round(max(frame.shape) / 500)))
    if result.ok:
        _, z = resample(result.curve, 2.0)
        pts = np.stack([z.real, -z.imag], axis=1)
        shift = 4  # cv2 draws at sub-pixel precision with fixed-point coordinates
        poly = np.round(pts * (1 << shift)).astype(np.int32)
        cv2.polylines(bgr, [poly], False, _GREEN, thick, cv2.LINE_AA, shift)
        for point, colour in ((pts[0], _BLUE), (pts[-1], _RED)):
            centre = tuple(int(v) for v in np.round(point * (1 << shift)))
            cv2.circle(bgr, centre, (3 * thick) << shift, colour, thick, cv2.LINE_AA, shift)
        label = f"#{result.frame}  {np.degrees(result.bend_angle_rad):+.1f} deg  {result.stage}"
    else:
        label = f"#{result.frame}  {result.status}"
    scale = max(0.4, max(frame.shape) / 1600)
    cv2.putText(bgr, label, (8, int(24 * scale) + 4), cv2.FONT_HERSHEY_SIMPLEX, scale,
                (0, 0, 0), 3 * thick, cv2.LINE_AA)
    cv2.putText(bgr, label, (8, int(24 * scale) + 4), cv2.FONT_HERSHEY_SIMPLEX, scale,
                (255, 255, 255), thick, cv2.LINE_AA)
    return bgr


def pick_frames(results: list[FrameTrack], n: int = 6) -> list[int]:
    """Evenly spread frames, plus up to two that could not be measured."""
    idx = np.unique(np.linspace(0, len(results) - 1, min(n, len(results))).round().astype(int))
    lost = [r.frame for r in results if not r.ok][:2]
    return sorted(set(idx.tolist()) | set(lost))


def write_overlay(source, results: list[FrameTrack], path, *, n: int = 6,
                  tile_width: int = 480) -> None:
    """A montage PNG of a few frames with their tracked centrelines."""
    from .frames import open_frames
    from .levels import levels_of

    wanted = set(pick_frames(results, n))
    tiles = []
    with open_frames(source) as reader:
        # (shown as tracked: a few bits' counts in 16-bit files are black otherwise)
        levels = levels_of(reader.first)
        for i, frame in enumerate(reader):
            if i in wanted:
                tile = draw_frame(levels.frame(frame), results[i])
                h = int(round(tile.shape[0] * tile_width / tile.shape[1]))
                tiles.append(cv2.resize(tile, (tile_width, h), interpolation=cv2.INTER_AREA))
            if i >= max(wanted):
                break
    if not tiles:
        return
    cols = min(3, len(tiles))
    rows = -(-len(tiles) // cols)
    h, w = tiles[0].shape[:2]
    sheet = np.full((rows * h, cols * w, 3), 255, np.uint8)
    for k, tile in enumerate(tiles):
        r, c = divmod(k, cols)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = tile[:h, :w]
    with atomic_path(path, suffix=".png") as tmp:
        if not cv2.imwrite(str(tmp), sheet):
            raise ValueError(f"could not write {path}")
