"""Hide a structure that stood still, so that the tube can be found past it.

An opaque holder, a fibre or a scratch can stand out more than a faint tube:
the detector then takes it for the tube, and the tracker follows it on every
frame (the check in :func:`pipeline.tracks.track_video` tells, from the
video's motion elsewhere, that it stood still). Such a structure does not
move, so one mask, made once from its tracked centreline and width, hides it
on every frame: its pixels are replaced by the background about it (a plane
fitted to a ring of pixels around the mask), and the tube is looked for
again in what is left.

The mask's ends are square, not round: a tube leaves a holder at its end
face, and a round cap a half-width deep would hide that much of the tube.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from scipy.spatial import cKDTree

from .centreline import Curve, resample
from .refine import MAD_TO_SD
from .segment import border_distance

#: Added to the structure's half-width, and beyond its ends, px: its edges'
#: blur (a holder's dark rim left at the mask's edge is itself a structure).
MARGIN_PX = 3.0
#: The ring of pixels about the mask the background is fitted to, px wide.
RING_PX = 6
#: Ring pixels this many robust standard deviations off the fitted plane (the
#: tube where it leaves the holder, dust) are left out of the refit.
RING_CLIP = 3.0


@dataclass(frozen=True)
class StaticMask:
    """Pixels of a structure that stood still, and how to hide them.

    Attributes
    ----------
    mask : (rows, cols) bool ndarray
        The structure's pixels, its margin included.
    ring : (rows, cols) bool ndarray
        The pixels about it that the background is fitted to.
    end : complex
        The structure's end away from the image border (its tip as tracked),
        px (y up): where a tube held by it leaves it.
    half_width : float
        The structure's half-width, px.
    """

    mask: np.ndarray
    ring: np.ndarray
    end: complex
    half_width: float

    def __bool__(self) -> bool:
        return bool(self.mask.any())

    # (the same pixels on every frame: found once)
    @cached_property
    def _ring_design(self):
        rows, cols = np.nonzero(self.ring)
        return rows, cols, np.c_[np.ones(rows.size), rows, cols].astype(np.float64)

    @cached_property
    def _mask_design(self):
        rows, cols = np.nonzero(self.mask)
        return rows, cols, np.c_[np.ones(rows.size), rows, cols].astype(np.float64)

    def fill(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` (greyscale, any dtype) with the structure's pixels replaced
        by the plane fitted to the ring about them (a copy)."""
        out = np.array(frame, copy=True)
        rows, cols, design = self._ring_design
        if rows.size < 3:
            # (a mask over the whole frame: nothing about it to fit)
            out[self.mask] = np.median(frame)
            return out
        values = frame[rows, cols].astype(np.float64)
        keep = np.ones(rows.size, bool)
        for _ in range(2):
            coef, *_ = np.linalg.lstsq(design[keep], values[keep], rcond=None)
            dev = values - design @ coef
            mad = np.median(np.abs(dev[keep] - np.median(dev[keep])))
            keep = np.abs(dev) <= RING_CLIP * max(MAD_TO_SD * mad, 1e-12)
            if keep.sum() < 3:
                break
        r, c, inside = self._mask_design
        level = inside @ coef
        if np.issubdtype(out.dtype, np.integer):
            info = np.iinfo(out.dtype)
            level = np.clip(np.rint(level), info.min, info.max)
        out[r, c] = level.astype(out.dtype)
        return out


def static_mask(curve: Curve, half_width: float, shape: tuple[int, int],
                margin: float = MARGIN_PX) -> StaticMask:
    """The mask of the structure along ``curve`` (px, y up), ``half_width`` px
    to either side plus ``margin``, square at both ends (``margin`` beyond
    them), in a frame of ``shape`` (rows, cols).

    The curve's end farther from the image border is taken as the
    structure's free end; the nearer one, within two reaches of the border, is
    carried on straight out of the frame (where the structure comes in).
    """
    rows, cols = shape
    _, z = resample(curve, 0.5)
    if z.size < 2:
        raise ValueError("the still structure's centreline is too short to mask")

    def border_dist(point: complex) -> float:
        return border_distance((-point.imag, point.real), shape)

    reach = half_width + margin
    # the end nearer the border is where the structure comes into view: its
    # centreline stops short of the border (a tracked end is a half-width or
    # so in), so it is carried on straight out of the frame
    if border_dist(z[0]) > border_dist(z[-1]):
        z = z[::-1]
    end = complex(z[-1])
    out = z[0] - z[1]
    out = out / max(abs(out), 1e-12)
    extra = border_dist(z[0]) + reach
    if border_dist(z[0]) <= 2.0 * reach:
        z = np.concatenate([z[0] + out * np.arange(np.ceil(extra / 0.5), 0, -1) * 0.5, z])
    tangent = np.gradient(z)
    tangent = tangent / np.maximum(np.abs(tangent), 1e-12)
    col, row = z.real, -z.imag
    r0 = max(int(np.floor(row.min() - reach - RING_PX - 1)), 0)
    r1 = min(int(np.ceil(row.max() + reach + RING_PX + 2)), rows)
    c0 = max(int(np.floor(col.min() - reach - RING_PX - 1)), 0)
    c1 = min(int(np.ceil(col.max() + reach + RING_PX + 2)), cols)
    rr, cc = np.mgrid[r0:r1, c0:c1]
    p = cc.ravel() - 1j * rr.ravel()
    dist, idx = cKDTree(np.c_[z.real, z.imag]).query(np.c_[p.real, p.imag])
    # past either end, a pixel's nearest point is that end: it is in only as
    # far along the end's tangent as the margin (a square end)
    along = np.real((p - z[idx]) * np.conj(tangent[idx]))
    beyond = ((idx == 0) & (along < -margin)) | ((idx == z.size - 1) & (along > margin))
    inside = (dist <= reach) & ~beyond
    mask = np.zeros(shape, bool)
    mask[r0:r1, c0:c1] = inside.reshape(rr.shape)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RING_PX + 1, 2 * RING_PX + 1))
    ring = cv2.dilate(mask.astype(np.uint8), kernel).astype(bool) & ~mask
    return StaticMask(mask, ring, end, float(half_width))
