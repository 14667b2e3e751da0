"""Blank margins of a frame: bars and lines along its borders that are no part of the scene.

A video exported to a wider or taller format carries black bars (letterbox,
pillarbox); a resampled or badly grabbed frame can carry a dark line along an
edge. Neither is scene: a background model cannot follow their sharp step, and
a line along the border joins everything that touches it into one skeleton.
They are found once, on the first frame, and cropped away before tracking.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robust import robust_sd
from .track import as_float

#: At most this share of each dimension is taken for a margin.
MAX_FRACTION = 0.25
#: A drawn bar's level differs from the scene's next to it by at least this many
#: noise σ (a line's median over hundreds of pixels is known to about 0.1 σ, and
#: the bar's flatness already sets it apart from any scene) ...
BAR_JUMP_SIGMA = 2.0
#: ... and lines at the border that are not flat, by at least this many: they
#: are told from the scene by their level alone.
LINE_JUMP_SIGMA = 6.0
#: ... and by at least this much of full scale either way: a compressed frame
#: flattens a dark or smooth background into runs of one grey level, which
#: step by a level or three (fluorescent MP4, JPEG at quality 30: 2-3 levels).
MIN_JUMP = 6 / 255
#: A bar's lines vary along themselves by at most this many noise σ: it is
#: drawn, not imaged (the scene's own lines carry at least its noise).
FLAT_SIGMA = 0.3
#: Lines past a bar (or at the very border, with no bar) that still differ from
#: the scene may be taken with it: a compressed bar's edge rings over up to a
#: JPEG block, and a resampled frame's last line mixes in the blank beyond it.
EDGE_LINES = 8
#: Lines of scene beside a margin that set the level the margin differs from.
REFERENCE_LINES = 6


@dataclass(frozen=True)
class Margins:
    """Blank lines along each border of a frame, px."""

    top: int = 0
    bottom: int = 0
    left: int = 0
    right: int = 0

    def __bool__(self) -> bool:
        return bool(self.top or self.bottom or self.left or self.right)

    def crop(self, frame: np.ndarray) -> np.ndarray:
        """The frame without its margins (a view)."""
        rows, cols = frame.shape[:2]
        return frame[self.top:rows - self.bottom, self.left:cols - self.right]

    @property
    def offset(self) -> complex:
        """Where the cropped frame's pixel (0, 0) lies in the whole frame, as
        col − 1j·row (the centrelines' y-up convention)."""
        return complex(self.left, -self.top)

    def sides(self) -> str:
        """The margins that are there, e.g. "60 top, 60 bottom px"."""
        return ", ".join(f"{n} {name}" for name, n in (
            ("top", self.top), ("bottom", self.bottom), ("left", self.left),
            ("right", self.right)) if n) + " px"

    def describe(self) -> str:
        return ("blank margins cropped away (bars or lines along the border, no part of the "
                "scene): " + self.sides())


def frame_noise(image: np.ndarray) -> float:
    """Robust pixel noise σ of a frame, from neighbouring pixels' differences
    (floored at half a grey level of 8-bit video: a noise-free frame has none)."""
    diff = np.diff(image[::4], axis=1)  # (every 4th row: a million pixels are not needed)
    mad = robust_sd(diff, axis=None)
    return max(float(mad / np.sqrt(2.0)), 0.5 / 255)


def blank_margins(image: np.ndarray) -> Margins:
    """The blank margins of a frame.

    A margin is a run of lines from a border whose level (median along the
    line) differs from the scene's beside it: flat lines (a drawn bar, varying
    by under :data:`FLAT_SIGMA` σ) by :data:`BAR_JUMP_SIGMA` noise σ or more,
    together with up to :data:`EDGE_LINES` lines past them that differ by
    :data:`LINE_JUMP_SIGMA`; or only such lines, at the border; and every
    margin ends in a step (a level that ramps into the border is
    illumination). Smooth illumination, a pipette or a tube crossing the
    border move a line's median little; a tube lying along the border could be
    taken for a line, but for at most :data:`EDGE_LINES` px.

    Parameters
    ----------
    image : (rows, cols) ndarray
        One frame, greyscale: uint8, uint16 or float in [0, 1].

    Returns
    -------
    Margins
        Zero on every side where there is none.
    """
    img = as_float(np.asarray(image))
    sigma = frame_noise(img)
    return Margins(top=_side(img, sigma), bottom=_side(img[::-1], sigma),
                   left=_side(img.T, sigma), right=_side(img.T[::-1], sigma))


def _side(lines: np.ndarray, sigma: float) -> int:
    """Blank lines at the start of ``lines`` (row i = the i-th line from the border)."""
    most = int(MAX_FRACTION * lines.shape[0])
    if most < 1 or lines.shape[0] < most + EDGE_LINES + 2 * REFERENCE_LINES:
        return 0
    # the border's lines first: a bar, if they are flat, is measured whole
    level, flat = _levels(lines[:EDGE_LINES + 2 * REFERENCE_LINES], sigma)
    run = 0
    if flat[0]:
        level, flat = _levels(lines[:most + EDGE_LINES + 2 * REFERENCE_LINES], sigma)
        run = min(int(np.argmin(flat)) if not flat.all() else flat.size, most)
    ref_at = run + EDGE_LINES
    near = float(np.median(level[ref_at:ref_at + REFERENCE_LINES]))
    far = float(np.median(level[ref_at + REFERENCE_LINES:ref_at + 2 * REFERENCE_LINES]))
    # (a steep illumination gradient moves the level too: a margin must differ
    # by more than three times the scene's own change over as many lines)
    slope = 3.0 * abs(near - far)
    apart = np.abs(level - near)
    if run and not np.all(apart[:run] >= max(BAR_JUMP_SIGMA * sigma, MIN_JUMP, slope)):
        return 0
    end = run
    while end < run + EDGE_LINES and apart[end] >= max(LINE_JUMP_SIGMA * sigma, MIN_JUMP, slope):
        end += 1
    # a margin ends in a step, where the scene begins; a level that ramps into
    # the border (vignetting, steepest at the edge) is scene
    while end > run and abs(level[end - 1] - level[end]) < 0.5 * apart[end - 1]:
        end -= 1
    return min(end, most)


def _levels(block: np.ndarray, sigma: float):
    """Each line's median, and whether it is flat (see :data:`FLAT_SIGMA`)."""
    level = np.median(block, axis=1)
    spread = robust_sd(block, axis=1)
    return level, spread <= FLAT_SIGMA * sigma
