"""A microscope's round field of view: the dark beyond it, filled from its edge.

Many microscope cameras image the round field stop: a lit disc, black beyond
it. That black is no part of the scene, but it is the frame's strongest
structure: a background model cannot follow its step, the dark corners are
taken for a tube, and a pipette crossing the field's edge ends there in the
middle of the image instead of at its border (rendered scenes inside a disc
of 0.8 of the half-diagonal: 6 of 7 tracked no frame at all).

The disc is found once, on the first frame, where the frame has a dark region
connected to its border whose edge is a circle. Every frame then has its
pixels beyond the disc's lit part replaced by the pixel where their ray from
the disc's centre enters that part (from a lightly smoothed copy): the
background carries on outwards, and a pipette crossing the edge runs on to
the image's border, as it does in a frame without a field stop. The disc's
edge also bounds the view where the tube may run out of it
(:mod:`pipeline.view`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage as ndi

from .track import as_float

#: The first frame is looked at this many px across (at most), for speed.
THUMB_PX = 256
#: The dark beyond a field stop is at most this fraction of the lit field's
#: level (above the black level); a frame whose darkest percent is brighter
#: has no field stop (a fluorescent frame's dark background counts too: its
#: field stop, if any, is as dark as the background and does no harm).
DARK_FRACTION = 0.3
#: Dark pixels are those below this share of the way from the black level to
#: the field's (a quarter: a dim field's own vignetting, towards its edge,
#: stays above it).
DARK_LEVEL = 0.25
#: The dark region connected to the border covers at least this share of the
#: frame (four corners cut off by a disc 0.92 of the half-diagonal wide: 1.5 %) ...
MIN_DARK_SHARE = 0.005
#: ... its edge is a circle within this RMS, thumbnail px ...
MAX_RMS_THUMB_PX = 1.0
#: ... and the frame beyond that circle (by 2 thumbnail px) is this dark; the
#: circle's radius is at least this share of the frame's smaller side (and
#: at most its diagonal: a straight dark edge fits a circle too, a huge one).
MIN_DARK_BEYOND = 0.9
MIN_RADIUS = 0.3
#: The lit part ends where the radial level's slope, going inwards from the
#: edge, has fallen to this share of its peak on the edge.
EDGE_SLOPE = 0.1
#: The edge's ramp is looked for within this far of the dark's edge, px.
EDGE_REACH_PX = 40.0
#: Margin kept inside the lit part's edge, px.
EDGE_MARGIN_PX = 1.0


@dataclass(frozen=True)
class Field:
    """A round field stop: the lit disc and how a frame is filled beyond it.

    Attributes
    ----------
    centre : complex
        The disc's centre, col + 1j·row, px.
    radius : float
        Where the level is a quarter of the way from the dark to the field, px.
    lit_radius : float
        Where the field's own level ends (the edge's soft ramp begins), px:
        pixels beyond it are filled.
    """

    centre: complex = 0j
    radius: float = 0.0
    lit_radius: float = 0.0
    _beyond: np.ndarray = field(default=None, repr=False, compare=False)
    _source: np.ndarray = field(default=None, repr=False, compare=False)

    def __bool__(self) -> bool:
        return self.radius > 0

    def fill(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` with its pixels beyond the lit disc replaced (a copy)."""
        if not self:
            return frame
        out = np.array(frame, copy=True)
        smooth = cv2.blur(frame, (5, 5))
        channels = frame.shape[2] if frame.ndim == 3 else 1
        out.reshape(-1, channels)[self._beyond] = smooth.reshape(-1, channels)[self._source]
        return out

    def describe(self, origin=(0, 0)) -> str:
        """A line for the run's notes; ``origin`` (col, row) is where the frame
        the field was found on lies in the whole frame (a crop's corner)."""
        col, row = self.centre.real + origin[0], self.centre.imag + origin[1]
        return (f"round field of view (a field stop): the lit disc of radius {self.radius:.0f} px "
                f"about ({col:.0f}, {row:.0f}); the frame beyond {self.lit_radius:.0f} px "
                "filled from the disc's edge, which bounds the view")


def field_stop(image: np.ndarray) -> Field:
    """The round field stop of a frame, or ``Field()`` where there is none.

    Parameters
    ----------
    image : (rows, cols) ndarray
        One frame, greyscale: uint8, uint16 or float in [0, 1].
    """
    img = as_float(np.asarray(image))
    rows, cols = img.shape[:2]
    f = max(1, int(np.ceil(max(rows, cols) / THUMB_PX)))
    if min(rows, cols) // f < 16:
        return Field()
    thumb = cv2.resize(img, (cols // f, rows // f), interpolation=cv2.INTER_AREA)
    # (smoothed: a dim field's noise would riddle the dark with holes)
    thumb = cv2.GaussianBlur(thumb, (0, 0), 1.0)
    black, level = np.percentile(thumb, [1, 75])
    if not level > 0 or black > DARK_FRACTION * level:
        return Field()
    dark = thumb < black + DARK_LEVEL * (level - black)
    labels, _ = ndi.label(dark)
    at_border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    outside = np.isin(labels, at_border[at_border > 0])
    if outside.mean() < MIN_DARK_SHARE:
        return Field()
    # the edge: dark pixels next to the lit field (the largest region left)
    lit, n = ndi.label(~outside)
    if n == 0:
        return Field()
    lit = lit == 1 + int(np.argmax(np.bincount(lit.ravel())[1:]))
    edge = outside & ndi.binary_dilation(lit)
    edge[[0, -1]] = False
    edge[:, [0, -1]] = False
    y, x = np.nonzero(edge)
    if x.size < 20:
        return Field()
    centre, radius = _circle(x.astype(float), y.astype(float))
    if centre is None:
        return Field()
    yy, xx = np.mgrid[0:thumb.shape[0], 0:thumb.shape[1]]
    beyond = np.abs(xx + 1j * yy - centre) > radius + 2
    if (not MIN_RADIUS * min(thumb.shape) <= radius <= np.hypot(*thumb.shape)
            or not beyond.any() or dark[beyond].mean() < MIN_DARK_BEYOND):
        return Field()
    # back to the frame's pixels: the thumbnail's pixel (c, r) is the block
    # whose centre is f·(c, r) + (f − 1)/2
    centre = f * centre + 0.5 * (f - 1) * (1 + 1j)
    return _with_fill(img, centre, f * radius)


def _circle(x: np.ndarray, y: np.ndarray):
    """Least-squares circle through points (algebraic fit, refitted without the
    points off it by over 3 px: a pipette's outline where it crosses the edge);
    (centre, radius), or (None, None) when the points are no circle."""
    keep = np.ones(x.size, bool)
    for _ in range(3):
        a = np.c_[x[keep], y[keep], np.ones(keep.sum())]
        c, *_ = np.linalg.lstsq(a, x[keep] ** 2 + y[keep] ** 2, rcond=None)
        centre = complex(c[0] / 2, c[1] / 2)
        radius = float(np.sqrt(max(c[2] + abs(centre) ** 2, 0.0)))
        off = np.abs(np.abs(x + 1j * y - centre) - radius)
        keep = off <= 3.0
        if keep.sum() < 20:
            return None, None
    rms = float(np.sqrt(np.mean(off[keep] ** 2)))
    if rms > MAX_RMS_THUMB_PX or keep.mean() < 0.8:
        return None, None
    return centre, radius


def _with_fill(img: np.ndarray, centre: complex, radius: float) -> Field:
    """The field of ``centre`` and ``radius`` (px) with its lit radius read
    from the frame's radial profile, and the pixels to fill."""
    rows, cols = img.shape[:2]
    yy, xx = np.mgrid[0:rows, 0:cols]
    ray = xx + 1j * yy - centre
    dist = np.abs(ray)
    # radial mean level in 1 px rings across the edge: its slope peaks on the
    # edge's ramp, many times steeper than the field's own vignetting; the lit
    # part ends where, going inwards, the slope falls to a tenth of that peak
    inner = radius - EDGE_REACH_PX
    ring = (dist >= inner) & (dist < radius + EDGE_REACH_PX)
    which = (dist[ring] - inner).astype(int)
    n = int(which.max()) + 1 if which.size else 0
    if n < 10:
        return Field()
    count = np.bincount(which, minlength=n)
    seen = count > 0
    mean = np.bincount(which, weights=img[ring], minlength=n)[seen] / count[seen]
    level = np.interp(np.arange(n), np.flatnonzero(seen), mean)
    slope = -np.gradient(np.convolve(level, np.ones(3) / 3, mode="same"))
    slope[[0, -1]] = 0.0  # (the smoothing's ends)
    peak = int(np.argmax(slope))
    flat = np.flatnonzero(slope[:peak] < EDGE_SLOPE * slope[peak])
    beyond_dark = float(np.median(img[dist > radius + 3])) if (dist > radius + 3).any() else 1.0
    # an edge: the slope peaks within the window, onto a dark at most a
    # fraction of the field's level (a vignetted corner fades, and not that far)
    if (not slope[peak] > 0 or flat.size == 0 or peak >= n - 3
            or beyond_dark > DARK_FRACTION * level[flat[-1]]):
        return Field()
    lit = inner + flat[-1] - EDGE_MARGIN_PX
    beyond = dist > lit
    # each pixel beyond takes the pixel where its ray enters the lit disc
    # (the segment to the centre stays in the frame when the centre does)
    src = centre + ray[beyond] * ((lit - 1.0) / dist[beyond])
    src_col = np.clip(np.rint(src.real), 0, cols - 1).astype(np.intp)
    src_row = np.clip(np.rint(src.imag), 0, rows - 1).astype(np.intp)
    return Field(centre, float(radius), float(lit), np.flatnonzero(beyond),
                 src_row * cols + src_col)
