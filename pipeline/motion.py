"""Which end of the tube is its base, from how the scene moves over the video.

When the pipette cannot be seen (fluorescence, a glass pipette matched to the
medium, a base far from the image border) a single frame does not say which
end of the tube is held: both are free ends of the same bright or dark band.
The video does. The base is clamped in the pipette and stays put; the tip
sweeps away as the tube bends. So the end whose surroundings change least
from the first frame is the base.

The measure is the change from the first frame (smoothed by a quarter of the
tube's width, in units of that smoothed change's own spread over the image;
or its magnitude smoothed likewise, where that stands out more: in a relief
the tube's lit and shaded flanks change with opposite signs and cancel),
at its largest over the frames so far, along the tube's path within a
half-width of each end; the ends are compared on the first frame from which
one has clearly moved more (a tube curling past a turn later comes back over
its base). Not the temporal standard deviation: the tip leaves its first
place for good (a step, whose deviation is small when it goes early), and on
a bright fluorescent tube the shot noise alone makes the held end "vary"
more than the dark background the tip leaves (a 6 px tube: 3.8 against 2.1,
the wrong end).

The test needs one cheap pass over (at most) the first few hundred frames at
a working resolution of ≤ 256 px, stopped once the ends are told apart, and
is run only when the first frame leaves the base end ambiguous.

The same change tells a tube from a static structure taken for it
(:func:`moved_elsewhere`): run only when the tracked tube stood still.
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
#: The ends are compared on the first frame from which one has clearly moved
#: more than the other on this many frames running (or to the last frame):
#: a noise spike at one end, which the largest change holds on to, is matched
#: at the other within a few frames.
HELD_FRAMES = 5


@dataclass(frozen=True)
class EndMotion:
    """How much the scene changed around the two ends of a detected tube.

    Attributes
    ----------
    first, last : float
        Largest change from the first frame near the path's first and last
        point, in units of the smoothed change's noise.
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
        return hi > 5.0 and hi > 2.5 * max(lo, 1.0)

    @property
    def base_is_last(self) -> bool:
        return self.last < self.first


def _changes(frames: Iterable[np.ndarray], smooth_px: float, target: int, max_frames: int):
    """Each frame's change from the first, as :func:`change_map` measures it
    (before the maximum over frames): yields ``(change, factor)``, the first
    frame's change zero."""
    first = None
    for frame in islice(frames, max_frames):
        img = to_float(frame)
        if first is None:
            factor = max(1, int(np.ceil(max(img.shape) / target)))
            size = (max(img.shape[1] // factor, 1), max(img.shape[0] // factor, 1))
            sigma = max(smooth_px / factor, 1.0)
        small = (cv2.resize(img, size, interpolation=cv2.INTER_AREA) if factor > 1
                 else img).astype(np.float64)
        if first is None:
            first = small
            yield np.zeros_like(small), factor
            continue
        # a flickering lamp scales the whole frame: as the (static) median does
        gain = float(np.median(small)) / max(float(np.median(first)), 1e-9)
        raw = small - gain * first
        # smoothed as it is (noise averages out), and smoothed in magnitude: in
        # a relief the tube's lit and shaded flanks change with opposite signs
        # and cancel under the blur, on its centreline most of all
        out = np.zeros_like(small)
        for diff in (cv2.GaussianBlur(raw, (0, 0), sigma),
                     cv2.GaussianBlur(np.abs(raw), (0, 0), sigma)):
            dev = np.abs(diff - np.median(diff))
            spread = 1.4826 * float(np.median(dev))
            np.maximum(out, dev / max(spread, 1e-9), out=out)
        yield out, factor


def change_map(frames: Iterable[np.ndarray], smooth_px: float, *, target: int = 256,
               max_frames: int = MAX_FRAMES) -> tuple[np.ndarray, int, int]:
    """Largest change of each place from the first frame, downsampled.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
    smooth_px : float
        Gaussian smoothing of each frame's change, full-frame px (about the
        tube's half-width: it averages the noise and keeps a tube's worth of
        change).
    target : int
        Larger side of the working resolution, px.

    Returns
    -------
    change : (r, c) float64 ndarray
        max over frames of |smoothed (frame − gain · first frame)| and of
        smoothed |frame − gain · first frame| (each less its median), each
        in units of its robust spread over the image (most of which is
        static); the gain is the ratio of the frames' medians (flicker).
    factor : int
        Downsampling factor (full-frame px per working px).
    n : int
        Frames used.
    """
    out, factor, n = np.zeros((1, 1)), 1, 0
    for change, factor in _changes(frames, smooth_px, target, max_frames):  # noqa: B007 (returned)
        out = change if n == 0 else np.maximum(out, change, out=out)
        n += 1
    return out, factor, n


def _to_working(points_rc: np.ndarray, factor: int, shape) -> np.ndarray:
    """Full-frame (row, col) px to the change map's (``factor`` px each),
    as int indices clipped to its ``shape``."""
    rc = np.rint((np.asarray(points_rc, dtype=float) - (factor - 1) / 2) / factor).astype(int)
    return np.clip(rc, 0, np.array(shape) - 1)


def end_motion(frames: Iterable[np.ndarray], path_rc, radius_px: float, *,
               target: int = 256, max_frames: int = MAX_FRAMES) -> EndMotion:
    """Compare how much the scene changes at the two ends of a tube.

    The change near each end (its largest so far) is followed frame by frame,
    and the comparison made on the first frame from which one end has clearly
    moved more than the other (:attr:`EndMotion.decided`) on
    :data:`HELD_FRAMES` frames running, or on to the last frame read; else on
    the last frame. The tip sweeps away first; a tube that curls past a turn
    later passes over its own base, and the largest change over the whole
    video then saw both ends move alike (a 380 deg curl: 11 against 8.5).

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The video from its first frame (re-read; the tracker reads it again).
    path_rc : (M, 2) array
        The tube's centreline in the first frame, (row, col) full-frame px,
        from one end to the other.
    radius_px : float
        How far along the path from each end the change is looked at (its
        median), and twice the smoothing, full-frame px. The tracker uses the
        tube's half-width: further takes in the base section's own bending,
        which moved a 6 px tube's path 10 px from its base as much as its tip.
    """
    path = np.asarray(path_rc, dtype=float)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    first = last = 0.0
    n = 0
    told = None
    for change, factor in _changes(frames, 0.5 * radius_px, target, max_frames):
        if n == 0:
            # evenly along the path, a working pixel apart: a skeleton's path has
            # its ends carried on by a straight step, and a median over the one or
            # two points within reach of an end judged it by a single place (a
            # base end seen as moving as much as the tip: 114 against 186, from
            # one point a step past the base)
            even = np.linspace(0.0, arc[-1], max(2, int(np.ceil(arc[-1] / factor)) + 1))
            pts = np.c_[np.interp(even, arc, path[:, 0]), np.interp(even, arc, path[:, 1])]
            near = [tuple(_to_working(pts[d <= radius_px], factor, change.shape).T)
                    for d in (even, arc[-1] - even)]
        n += 1
        first = max(first, float(np.median(change[near[0]])))
        last = max(last, float(np.median(change[near[1]])))
        now = EndMotion(first, last, n)
        if not now.decided:
            told = None
        elif told is None or now.base_is_last != told.base_is_last:
            told = now
        if told is not None and n - told.frames >= HELD_FRAMES:
            return told
    return told if told is not None else EndMotion(first, last, n)


#: A place moved when its change (see :func:`change_map`) is at least this.
MOVED = 8.0


def moved_elsewhere(frames: Iterable[np.ndarray], path_rc, half_width_px: float,
                    **kwargs) -> float:
    """How much of the scene away from a structure moved over the video.

    The check behind a tracked tube that stood still: a tube being inflated
    bends, and sweeps an area about its own; a fibre, a scratch or a chamber's
    edge in the frame, which the detector may take for the tube, does not.

    Parameters
    ----------
    frames : iterable of (rows, cols) ndarray
        The video from its first frame.
    path_rc : (M, 2) array
        The structure's centreline, (row, col) full-frame px, ≤ 1 px apart.
    half_width_px : float
        Its half-width, px.

    Returns
    -------
    float
        The area that moved farther than three half-widths (and 2 working px)
        from the structure, over the structure's own area (2 half-widths times
        its length).
    """
    change, factor, n = change_map(frames, 0.5 * half_width_px, **kwargs)
    path = np.asarray(path_rc, dtype=float)
    if n < 2 or path.shape[0] < 2:
        return 0.0
    near = np.ones(change.shape, np.uint8)
    rc = _to_working(path, factor, change.shape)
    near[rc[:, 0], rc[:, 1]] = 0
    far = cv2.distanceTransform(near, cv2.DIST_L2, 5) > max(3.0 * half_width_px / factor, 2.0)
    length = float(np.hypot(*np.diff(path, axis=0).T).sum())
    return float(((change >= MOVED) & far).sum() * factor**2 / max(2.0 * half_width_px * length,
                                                                    1.0))
