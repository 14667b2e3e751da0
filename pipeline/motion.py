"""Which end of the tube is its base, from how the scene moves over the video.

When the pipette cannot be seen (fluorescence, a glass pipette matched to the
medium, a base far from the image border) a single frame does not say which
end of the tube is held: both are free ends of the same bright or dark band.
The video does. The base is clamped in the pipette and stays put; the tip
sweeps through the image as the tube bends. So the end whose surroundings
change least over the frames is the base.

The test needs one cheap pass over (at most) the first few hundred frames at
a working resolution of ≤ 256 px, and is run only when the first frame leaves
the base end ambiguous.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import islice

import cv2
import numpy as np

from .frames import to_float

#: Frames read at most by the motion pass (the bend is under way by then).
MAX_FRAMES = 300


@dataclass(frozen=True)
class EndMotion:
    """Temporal variation around the two ends of a detected tube.

    Attributes
    ----------
    first, last : float
        Upper quartile of the temporal standard deviation around the path's
        first and last point, in units of the frames' noise (the tube covers
        only part of the neighbourhood of its end).
    frames : int
        Frames looked at.
    """

    first: float
    last: float
    frames: int

    @property
    def decided(self) -> bool:
        """Whether one end is clearly more static than the other."""
        lo, hi = sorted((self.first, self.last))
        return hi > 3.0 and hi > 2.5 * max(lo, 1.0)

    @property
    def base_is_last(self) -> bool:
        return self.last < self.first


def motion_map(frames: Iterable[np.ndarray], *, target: int = 256,
               max_frames: int = MAX_FRAMES) -> tuple[np.ndarray, int, int]:
    """Per-pixel temporal standard deviation of the frames, downsampled.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
    target : int
        Larger side of the working resolution, px.

    Returns
    -------
    std : (r, c) float64 ndarray
        Temporal standard deviation in units of the spatial noise of one frame.
    factor : int
        Downsampling factor (full-frame px per working px).
    n : int
        Frames used.
    """
    total = total2 = None
    factor = 1
    n = 0
    noise = []
    for frame in islice(frames, max_frames):
        img = to_float(frame)
        if total is None:
            factor = max(1, int(np.ceil(max(img.shape) / target)))
            size = (max(img.shape[1] // factor, 1), max(img.shape[0] // factor, 1))
        small = (cv2.resize(img, size, interpolation=cv2.INTER_AREA) if factor > 1
                 else img).astype(np.float64)
        if total is None:
            total = np.zeros_like(small)
            total2 = np.zeros_like(small)
        total += small
        total2 += small * small
        if len(noise) < 5:
            hp = small - cv2.GaussianBlur(small, (0, 0), 1.5)
            noise.append(1.4826 * np.median(np.abs(hp - np.median(hp))))
        n += 1
    if n == 0:
        return np.zeros((1, 1)), 1, 0
    var = np.maximum(total2 / n - (total / n) ** 2, 0.0)
    sigma = max(float(np.median(noise)), 1e-6)
    return np.sqrt(var) / sigma, factor, n


def end_motion(frames: Iterable[np.ndarray], first_rc, last_rc, radius_px: float,
               **kwargs) -> EndMotion:
    """Compare how much the scene changes around the two ends of a tube.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The video from its first frame (re-read; the tracker reads it again).
    first_rc, last_rc : (row, col)
        The two ends of the tube in the first frame, full-frame px.
    radius_px : float
        Radius of the neighbourhood looked at, full-frame px (the tracker uses
        the tube's half-width: wider takes in the base section's own bending).
    """
    std, factor, n = motion_map(frames, **kwargs)
    rows, cols = np.indices(std.shape)

    def around(rc):
        r, c = (np.asarray(rc, dtype=float) - (factor - 1) / 2) / factor
        near = np.hypot(rows - r, cols - c) <= max(radius_px / factor, 1.5)
        return float(np.percentile(std[near], 75)) if near.any() else 0.0

    return EndMotion(around(first_rc), around(last_rc), n)
