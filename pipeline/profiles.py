"""Sub-pixel tube edges from intensity profiles along the centreline's normals.

For every profile point of a predicted centreline we sample the image along
the normal (one ``cv2.remap`` call for all profiles) and look for the tube's two
*outer* edges: the pair of edges, one on each side, whose inward intensity
steps have the tube's polarity and whose separation matches the expected
width. The midpoint of the pair is the measured centre and their distance the
measured width; a profile whose pair is missing or of the wrong width (a
crossing, dust, the tube's end) is marked invalid and does not pull the fit.

Polarity ``+1`` means the tube is brighter than its surroundings just inside
its edge (fluorescence), ``-1`` darker (transmitted light: dark refraction rims
or an opaque tube). Offsets are in pixels along the left normal.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.stats import median_abs_deviation

from .centreline import to_image


def sample_lines(image: np.ndarray, starts, directions, offsets) -> np.ndarray:
    """Bilinear samples of ``image`` along lines ``start + offset·direction``.

    Parameters
    ----------
    image : (rows, cols) float32 ndarray
    starts, directions : (M,) complex ndarray
        Line origins and unit directions, px, y up.
    offsets : (P,) ndarray
        Positions along each line, px.

    Returns
    -------
    (M, P) float32 ndarray
        Samples; NaN outside the image.
    """
    pts = starts[:, None] + offsets[None, :] * directions[:, None]
    col, row = to_image(pts)
    return cv2.remap(image, col.astype(np.float32), row.astype(np.float32),
                     interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=float("nan"))


def sample_strips(image: np.ndarray, starts, directions, offsets, shifts) -> np.ndarray:
    """Like :func:`sample_lines`, each line averaged with parallel copies of it.

    Parameters
    ----------
    image : (rows, cols) float32 ndarray
    starts, directions : (M,) complex ndarray
        Line origins and unit directions, px, y up.
    offsets : (P,) ndarray
        Positions along each line, px.
    shifts : (M, K) ndarray
        Where each line's K copies lie, px, measured along ``-1j·direction``
        (the tube's tangent when ``directions`` are its left normals).

    Returns
    -------
    (M, P) float32 ndarray
        The mean of the K copies' samples; NaN where any lies outside the image.
    """
    m, k = shifts.shape
    along = -1j * directions[:, None] * shifts
    lines = sample_lines(image, (starts[:, None] + along).ravel(),
                         np.repeat(directions, k), offsets)
    return lines.reshape(m, k, -1).mean(axis=1)


@dataclass(frozen=True)
class Edges:
    """Edge pairs found on a set of normal profiles.

    Attributes
    ----------
    centre : (M,) ndarray
        Offset of the pair's midpoint from the profile origin, px.
    width : (M,) ndarray
        Distance between the two edges, px.
    strength : (M,) ndarray
        The weaker of the two edges' inward steps (intensity per px).
    valid : (M,) bool ndarray
        Both edges found, strong enough and at a plausible width.
    """

    centre: np.ndarray
    width: np.ndarray
    strength: np.ndarray
    valid: np.ndarray


def _parabolic(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Sub-sample peak positions by a parabola through each peak and its neighbours.

    ``idx`` is (M,) or (M, K) indices into the rows of ``values``.
    """
    n = values.shape[1]
    i = np.clip(idx, 1, n - 2)
    rows = np.arange(values.shape[0]).reshape((-1,) + (1,) * (idx.ndim - 1))
    y0, y1, y2 = values[rows, i - 1], values[rows, i], values[rows, i + 1]
    ok = np.isfinite(y0) & np.isfinite(y1) & np.isfinite(y2)
    y0, y1, y2 = (np.where(ok, y, 0.0) for y in (y0, y1, y2))
    denom = y0 - 2 * y1 + y2
    ok &= denom < 0
    shift = np.divide(0.5 * (y0 - y2), denom, out=np.zeros(denom.shape), where=ok)
    return i + np.clip(shift, -0.5, 0.5)


def _inward_gradient(profiles: np.ndarray, step: float, smooth_px: float):
    """Derivative-of-Gaussian along the profiles, and where samples are missing."""
    bad = np.isnan(profiles)
    if bad.any():
        fill = np.nanmean(profiles) if not bad.all() else 0.0
        profiles = np.where(bad, fill, profiles)
    sigma = max(smooth_px / step, 0.5)
    grad = gaussian_filter1d(profiles, sigma, axis=1, order=1, mode="nearest") / step
    return grad, bad


def _top_peaks(values: np.ndarray, k: int):
    """Indices and heights of the ``k`` highest local maxima of each row (−inf pads)."""
    m, p = values.shape
    is_max = np.zeros((m, p), dtype=bool)
    is_max[:, 1:-1] = (values[:, 1:-1] >= values[:, :-2]) & (values[:, 1:-1] > values[:, 2:])
    heights = np.where(is_max, values, -np.inf)
    k = min(k, p)
    idx = np.argpartition(-heights, k - 1, axis=1)[:, :k]
    return idx, np.take_along_axis(heights, idx, axis=1)


def edge_pairs(profiles: np.ndarray, step: float, half_width, *, polarity: int,
               window: float, width_tol: float = 0.2, smooth_px: float = 0.8,
               min_strength: float = 0.0, n_peaks: int = 5) -> Edges:
    """Find the tube's outer edge pair on every profile.

    The inward steps on each side are reduced to their strongest local maxima
    (sub-sample by a parabola); every left/right pair whose width is within
    ``width_tol`` of the expected one and whose midpoint lies within
    ``window`` is a candidate; among the candidates at least 70% as strong as
    the best, the one nearest the profile's origin (the prediction) wins, so a
    neighbouring coil or a crossing tube is not taken for this one.

    Parameters
    ----------
    profiles : (M, P) ndarray
        Samples along the normals at offsets ``(j − (P−1)/2)·step`` px.
    step : float
        Sample spacing, px.
    half_width : float or (M,) ndarray
        Expected half-width of the tube at each profile, px.
    polarity : {+1, −1}
        Sign of the intensity step entering the tube.
    window : float
        The centre is searched within ±window px of the profile origin.
    width_tol : float
        Accepted relative deviation of the pair's width from 2·half_width.
    smooth_px : float
        Gaussian smoothing along the profile before differentiating, px.
    min_strength : float
        Weakest acceptable inward step, intensity per px.
    n_peaks : int
        Local maxima kept per side and profile.

    Returns
    -------
    Edges
    """
    m, p = profiles.shape
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    left = polarity * grad            # entering the tube from the −offset side
    right = -left                     # entering from the +offset side
    if bad.any():
        # a sample outside the image, or next to one, never makes an edge
        near_bad = bad.copy()
        near_bad[:, 1:] |= bad[:, :-1]
        near_bad[:, :-1] |= bad[:, 1:]
        left[near_bad] = -np.inf
        right[near_bad] = -np.inf
    mid = (p - 1) / 2
    li, lh = _top_peaks(left, n_peaks)
    ri, rh = _top_peaks(right, n_peaks)
    lpos = (_parabolic(left, li) - mid) * step     # (M, K) offsets, px
    rpos = (_parabolic(right, ri) - mid) * step
    width = rpos[:, None, :] - lpos[:, :, None]    # (M, K, K)
    centre = 0.5 * (rpos[:, None, :] + lpos[:, :, None])
    strength = np.minimum(lh[:, :, None], rh[:, None, :])
    hw = np.broadcast_to(np.asarray(half_width, dtype=float), (m,))[:, None, None]
    ok = ((np.abs(width - 2 * hw) <= width_tol * 2 * hw) & (np.abs(centre) <= window)
          & np.isfinite(strength) & (strength > min_strength))
    score = np.where(ok, strength, -np.inf).reshape(m, -1)
    best = score.max(axis=1, keepdims=True)
    near = np.where(score >= 0.7 * best, np.abs(centre).reshape(m, -1), np.inf)
    pick = np.argmin(near, axis=1)
    rows = np.arange(m)
    valid = np.isfinite(best[:, 0])
    def chosen(a):
        return a.reshape(m, -1)[rows, pick]

    return Edges(np.where(valid, chosen(centre), np.nan),
                 np.where(valid, chosen(width), np.nan),
                 np.where(valid, chosen(strength), -np.inf), valid)


def end_edge(profiles: np.ndarray, step: float, *, polarity: int, window: float,
             smooth_px: float = 0.8, strong: float = 0.6, nearest: bool = False):
    """Position of the tube's end on profiles running along the tangent, tip outwards.

    The *outermost* strong tube → background step within ±window is taken, so
    that an inner edge (the end of the lumen inside a sealed tip) is not
    mistaken for the end of the tube; with ``nearest`` (crossings), the strong
    step nearest the window's centre.

    Returns
    -------
    offset : (M,) ndarray
        Offset of the end, px (NaN where the window holds no usable sample).
    strength : (M,) ndarray
        Its step, intensity per px.
    """
    m, p = profiles.shape
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    leaving = -polarity * grad
    leaving[bad] = -np.inf
    mid = (p - 1) // 2
    w_s = int(round(window / step))
    offs = np.arange(p)
    inwin = np.abs(offs - mid) <= w_s
    masked = np.where(inwin[None, :], leaving, -np.inf)
    peak = masked.max(axis=1, keepdims=True)
    # local maxima that are strong: the last (outermost) one is the tube's end
    is_max = np.zeros_like(masked, dtype=bool)
    is_max[:, 1:-1] = (masked[:, 1:-1] >= masked[:, :-2]) & (masked[:, 1:-1] >= masked[:, 2:])
    ok = is_max & (masked >= strong * peak) & np.isfinite(masked)
    if nearest:
        # where the tip lies over another part of the tube, the outermost step may
        # be that part's edge: take the strong step nearest the prediction instead
        dist = np.where(ok, np.abs(offs - mid)[None, :], np.inf)
        idx = np.argmin(dist, axis=1)
    else:
        idx = p - 1 - np.argmax(ok[:, ::-1], axis=1)
    found = ok.any(axis=1)
    offset = np.where(found, (_parabolic(leaving, idx) - mid) * step, np.nan)
    return offset, np.where(found, masked[np.arange(m), idx], -np.inf)


def gradient_noise(image: np.ndarray, smooth_px: float) -> float:
    """Robust spread of the profiles' edge filter over ``image``, intensity per px.

    The derivative of a Gaussian of ``smooth_px`` along the rows (as along a
    profile): over a frame that is mostly background its median absolute
    deviation is the noise an edge must stand out of. Non-finite samples are
    left out.
    """
    grad = gaussian_filter1d(np.asarray(image, dtype=np.float32), max(smooth_px, 0.5),
                             axis=1, order=1, mode="nearest")
    values = grad[np.isfinite(grad)]
    if values.size == 0:
        return 0.0
    return float(median_abs_deviation(values, scale="normal"))
