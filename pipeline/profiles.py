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
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

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
    """Sub-sample peak position by a parabola through the peak and its neighbours."""
    n = values.shape[1]
    i = np.clip(idx, 1, n - 2)
    rows = np.arange(values.shape[0])
    y0, y1, y2 = values[rows, i - 1], values[rows, i], values[rows, i + 1]
    denom = y0 - 2 * y1 + y2
    ok = np.isfinite(denom) & (denom < 0)
    shift = np.zeros(idx.shape)
    shift[ok] = 0.5 * (y0[ok] - y2[ok]) / denom[ok]
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


def edge_pairs(profiles: np.ndarray, step: float, half_width, *, polarity: int,
               window: float, width_tol: float = 0.2, smooth_px: float = 0.8,
               min_strength: float = 0.0) -> Edges:
    """Find the tube's outer edge pair on every profile.

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
        Edges are sought within ±width_tol·half_width of their expected place
        relative to a candidate centre, and a pair whose width is off by more
        than that fraction is invalid.
    smooth_px : float
        Gaussian smoothing along the profile before differentiating, px.
    min_strength : float
        Weakest acceptable inward step, intensity per px.

    Returns
    -------
    Edges
    """
    m, p = profiles.shape
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    inward_left = polarity * grad     # entering the tube from the −offset side
    if bad.any():
        inward_left[bad] = np.nan
    inward_right = -inward_left       # entering from the +offset side
    hw = np.broadcast_to(np.asarray(half_width, dtype=float), (m,))
    hw_s = np.round(hw / step).astype(int)
    tol_s = np.maximum(np.round(width_tol * hw / step).astype(int), 1)
    size = int(2 * tol_s.max() + 1)
    # NaN (outside the image) must never win a maximum: use −inf there
    left_f = np.nan_to_num(inward_left, nan=-np.inf)
    right_f = np.nan_to_num(inward_right, nan=-np.inf)
    max_left = maximum_filter1d(left_f, size, axis=1, mode="constant", cval=-np.inf)
    max_right = maximum_filter1d(right_f, size, axis=1, mode="constant", cval=-np.inf)
    mid = (p - 1) // 2
    w_s = int(round(window / step))
    cand = np.arange(mid - w_s, mid + w_s + 1)
    rows = np.arange(m)[:, None]
    li = np.clip(cand[None, :] - hw_s[:, None], 0, p - 1)
    ri = np.clip(cand[None, :] + hw_s[:, None], 0, p - 1)
    score = np.minimum(max_left[rows, li], max_right[rows, ri])
    # among strong candidates prefer the one nearest the prediction
    best = score.max(axis=1, keepdims=True)
    strong = score >= 0.7 * best
    dist = np.abs(cand - mid)[None, :]
    pick = np.argmin(np.where(strong, dist, p), axis=1)
    centre_s = cand[pick]
    # each edge at its strongest sample within the tolerance, then sub-sample
    r1 = np.arange(m)
    win = np.arange(-int(tol_s.max()), int(tol_s.max()) + 1)
    in_tol = np.abs(win)[None, :] <= tol_s[:, None]
    il = np.clip((centre_s - hw_s)[:, None] + win[None, :], 0, p - 1)
    ir = np.clip((centre_s + hw_s)[:, None] + win[None, :], 0, p - 1)
    vl = np.where(in_tol, left_f[r1[:, None], il], -np.inf)
    vr = np.where(in_tol, right_f[r1[:, None], ir], -np.inf)
    jl = np.argmax(vl, axis=1)
    jr = np.argmax(vr, axis=1)
    s_left = vl[r1, jl]
    s_right = vr[r1, jr]
    pos_l = (_parabolic(left_f, il[r1, jl]) - mid) * step
    pos_r = (_parabolic(right_f, ir[r1, jr]) - mid) * step
    width = pos_r - pos_l
    strength = np.minimum(s_left, s_right)
    valid = (np.isfinite(strength) & (strength > min_strength)
             & (np.abs(width - 2 * hw) <= width_tol * 2 * hw))
    return Edges(0.5 * (pos_l + pos_r), width, strength, valid)


def end_edge(profiles: np.ndarray, step: float, *, polarity: int, window: float,
             smooth_px: float = 0.8, strong: float = 0.6):
    """Position of the tube's end on profiles running along the tangent, tip outwards.

    The *outermost* strong tube → background step within ±window is taken, so
    that an inner edge (the end of the lumen inside a sealed tip) is not
    mistaken for the end of the tube.

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
    idx = p - 1 - np.argmax(ok[:, ::-1], axis=1)
    found = ok.any(axis=1)
    offset = np.where(found, (_parabolic(leaving, idx) - mid) * step, np.nan)
    return offset, np.where(found, masked[np.arange(m), idx], -np.inf)
