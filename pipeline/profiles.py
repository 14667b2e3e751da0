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

import functools
from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy import ndimage as ndi
from scipy.ndimage import correlate1d, gaussian_filter1d

from .robust import robust_sd

#: A tube's end narrows its measured width over this many half-widths: a
#: round cap over one, and the profiles' strips and edge filter carry that
#: half as far again (measured on a 7 px tube: 2 % narrower 1.7 half-widths
#: from the end, 10 % at 1.1): widths there are no section's.
END_NARROWING_HW = 1.5

#: A width tolerance this tight says the expected width is the tube's own
#: (learnt from it), not a guess (see :func:`_nearer_width`).
KNOWN_WIDTH_TOL = 0.2
#: ... and a pair sharing an edge with the one nearest the prediction is taken
#: instead where its width is nearer the tube's by this share of it, within
#: NEARER_WIDTH_OFF of it, over runs of NEARER_RUN profiles. (A dyed tube's
#: thick wall in colour: the pair of its lumen rim and the far outer edge,
#: 15 px for 18, held over its last 260 px once bent, the midline 1.5 px to
#: one side; a tube jumping 75 deg in a frame, found with that pair over its
#: last stretch: bend 20-34 deg off. Taken on single profiles too, it took
#: chance pairs among a glass capillary's lines under a tube's end.)
NEARER_WIDTH = 0.1
NEARER_WIDTH_OFF = 0.05
NEARER_RUN = 3


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
    starts = np.asarray(starts)
    directions = np.broadcast_to(directions, starts.shape)
    offsets = np.asarray(offsets, dtype=np.float64)
    # (col, row) = (x, −y), each formed straight into the float32 maps remap takes
    col = np.empty((starts.size, offsets.size), np.float32)
    row = np.empty_like(col)
    np.add(starts.real[:, None], offsets * directions.real[:, None], out=col, casting="unsafe")
    np.subtract(-starts.imag[:, None], offsets * directions.imag[:, None], out=row,
                casting="unsafe")
    return cv2.remap(image, col, row, interpolation=cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))


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


#: A relief's profile whose direction is this close to square with the shear
#: (|cos| under it) sees the tube's edges at under this share of their step.
FADED_COS = 0.3


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
    facing : (M,) ndarray, optional
        In a relief image, which way the chosen pair steps along the profile
        (±1); None for other looks.
    """

    centre: np.ndarray
    width: np.ndarray
    strength: np.ndarray
    valid: np.ndarray
    facing: np.ndarray | None = None


def _parabolic(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Sub-sample peak positions by a parabola through each peak and its neighbours.

    ``idx`` is (M,) or (M, K) indices into the rows of ``values``.
    """
    n = values.shape[1]
    # (np.minimum/np.maximum: np.clip costs more in its checks than the work
    # on these few hundred values, and this runs on every refinement round)
    i = np.minimum(np.maximum(idx, 1), n - 2)
    rows = np.arange(values.shape[0]).reshape((-1,) + (1,) * (idx.ndim - 1))
    y0, y1, y2 = values[rows, i - 1], values[rows, i], values[rows, i + 1]
    ok = np.isfinite(y0) & np.isfinite(y1) & np.isfinite(y2)
    y0, y1, y2 = (np.where(ok, y, 0.0) for y in (y0, y1, y2))
    denom = y0 - 2 * y1 + y2
    ok &= denom < 0
    shift = np.divide(0.5 * (y0 - y2), denom, out=np.zeros(denom.shape), where=ok)
    return i + np.minimum(np.maximum(shift, -0.5), 0.5)


def _inward_gradient(profiles: np.ndarray, step: float, smooth_px: float):
    """Derivative-of-Gaussian along the profiles, and where samples are missing."""
    bad = np.isnan(profiles)
    if bad.any():
        profiles = _held_across_gaps(profiles, bad)
    sigma = max(smooth_px / step, 0.5)
    grad = correlate1d(profiles, _gaussian_slope_weights(sigma), axis=1, mode="nearest") / step
    return grad, bad


def _held_across_gaps(profiles: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``profiles`` with each missing sample (off the image) set to the nearest
    valid one on its row before it (else after it); rows with none to 0.

    The slope filter then sees no step where a profile leaves the image. (Filled
    with one value for all rows, a profile whose last samples differ from it
    showed a step at the image's border as strong as the tube's end: on a
    blurred frame whose tip lay 40 px from the border, the end was put at the
    border, 12 % too long.)
    """
    p = profiles.shape[1]
    at = np.arange(p)
    before = np.maximum.accumulate(np.where(bad, -1, at), axis=1)
    after = np.minimum.accumulate(np.where(bad, p, at)[:, ::-1], axis=1)[:, ::-1]
    src = np.where(before >= 0, before, after)
    held = np.take_along_axis(profiles, np.clip(src, 0, p - 1), axis=1)
    return np.where(src < p, held, 0.0).astype(profiles.dtype, copy=False)


@functools.lru_cache(maxsize=64)
def _gaussian_slope_weights(sigma: float) -> np.ndarray:
    """The weights with which ``gaussian_filter1d(order=1)`` correlates: its
    response to a unit impulse, reversed. A tracking run filters profiles
    several times a frame with the same few widths, and building the kernel
    each time cost as much as the filtering itself."""
    radius = int(4.0 * sigma + 0.5)  # gaussian_filter1d's default truncate=4
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    weights = gaussian_filter1d(impulse, sigma, order=1, mode="constant")[::-1].copy()
    weights.flags.writeable = False
    return weights


def _local_maxima(values: np.ndarray) -> np.ndarray:
    """Where each row has a local maximum (on a plateau: its last point)."""
    is_max = np.zeros(values.shape, dtype=bool)
    is_max[:, 1:-1] = (values[:, 1:-1] >= values[:, :-2]) & (values[:, 1:-1] > values[:, 2:])
    return is_max


def _top_peaks(values: np.ndarray, k: int):
    """Indices and heights of the ``k`` highest local maxima of each row (−inf pads)."""
    # (the local maxima as _local_maxima finds them, written straight into -inf)
    heights = np.full(values.shape, -np.inf, dtype=np.result_type(values.dtype, -np.inf))
    inner = values[:, 1:-1]
    np.copyto(heights[:, 1:-1], inner, where=(inner >= values[:, :-2]) & (inner > values[:, 2:]))
    k = min(k, values.shape[1])
    # k passes of a row-wise argmax, each blanking what it took: for the few
    # peaks wanted, half the time of an argpartition over every row
    rows = np.arange(values.shape[0])
    idx = np.empty((values.shape[0], k), dtype=np.intp)
    top = np.empty((values.shape[0], k))
    for j in range(k):
        idx[:, j] = at = heights.argmax(axis=1)
        top[:, j] = heights[rows, at]
        heights[rows, at] = -np.inf
    return idx, top


def edge_pairs(profiles: np.ndarray, step: float, half_width, *, polarity: int,
               window: float, width_tol: float = 0.2, smooth_px: float = 0.8,
               min_strength: float = 0.0, n_peaks: int = 5,
               facing: np.ndarray | None = None,
               directions: np.ndarray | None = None) -> Edges:
    """Find the tube's outer edge pair on every profile.

    The inward steps on each side are reduced to their strongest local maxima
    (sub-sample by a parabola); every left/right pair whose width is within
    ``width_tol`` of the expected one and whose midpoint lies within
    ``window`` is a candidate; among the candidates at least 70% as strong as
    the best, the one nearest the profile's origin (the prediction) wins, so a
    neighbouring coil or a crossing tube is not taken for this one (in a
    relief, the widest: a lumen's walls are no weaker than the outer ones).
    Where the width is the tube's own (``width_tol`` at most
    :data:`KNOWN_WIDTH_TOL`), a pair sharing an edge with that one and
    nearer the width, along a stretch of profiles, is taken instead
    (:func:`_nearer_width`).

    Parameters
    ----------
    profiles : (M, P) ndarray
        Samples along the normals at offsets ``(j − (P−1)/2)·step`` px.
    step : float
        Sample spacing, px.
    half_width : float or (M,) ndarray
        Expected half-width of the tube at each profile, px.
    polarity : {+1, −1, 0}
        Sign of the intensity step entering the tube; 0 for a relief image
        (differential interference contrast, oblique light), in which the
        tube is lit on one flank and shaded on the other, so that its two
        edges step the same way along a profile.
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
    facing : (M,) ndarray of ±1, optional
        With ``polarity=0``: which way each profile's edges step (+1: up
        along the profile, where its direction faces the relief's shear);
        not given, both are tried and the stronger pair kept (but a pair
        within the other way's gives way to it if that is at least half as
        strong: a hollow tube's lumen, whose walls step the other way), or,
        given the profiles' ``directions``, every profile steps the way that
        one shear direction would make it, the one that finds the strongest
        pairs in all (a straight tube's profiles all step alike).
    directions : (M,) complex ndarray, optional
        The profiles' directions (unit, y up), for ``polarity=0``.

    Returns
    -------
    Edges
    """
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    if bad.any():
        # a sample outside the image, or next to one, never makes an edge
        near_bad = bad.copy()
        near_bad[:, 1:] |= bad[:, :-1]
        near_bad[:, :-1] |= bad[:, 1:]
        grad[near_bad] = np.nan
    kw = dict(step=step, half_width=half_width, window=window, width_tol=width_tol,
              min_strength=min_strength, n_peaks=n_peaks, gaps=bad.any())
    if polarity != 0:
        # entering the tube from the −offset side, and from the +offset side
        return _best_pairs(polarity * grad, -polarity * grad, **kw)
    # relief: both edges step the same way along the profile, the way the
    # profile faces the shear. A hollow tube also shows its lumen's walls: one
    # way, an outer wall paired with a lumen wall is as strong as the outer
    # pair and, where the walls are thin, within the width's tolerance, so of
    # the strong pairs the widest is taken (sample 2 in relief: the midline
    # 1.4 px off over its thin-walled section without this)
    kw["widest"] = True
    if facing is not None:
        facing = np.asarray(facing, dtype=float)
        pairs = _best_pairs(facing[:, None] * grad, facing[:, None] * grad, **kw)
        return replace(pairs, facing=facing)
    rising = _best_pairs(grad, grad, **kw)
    falling = _best_pairs(-grad, -grad, **kw)
    # the lumen's own pair steps the other way, and may step more strongly
    # (where a wall is thin its two lines cancel): a pair lying within the
    # other way's gives way to it, if that one is at least half as strong
    up = np.where(rising.valid, rising.strength, 0.0)
    down = np.where(falling.valid, falling.strength, 0.0)
    up = np.where(_encloses(falling, rising) & (down >= 0.5 * up), 0.0, up)
    down = np.where(_encloses(rising, falling) & (up >= 0.5 * down), 0.0, down)
    if directions is None:
        take = down > up
    else:
        theta = np.angle(np.asarray(directions))
        grid = np.radians(np.arange(0.0, 360.0, 2.0))
        c = np.cos(theta[:, None] - grid[None, :])
        # (a profile nearly square to the shear counts for neither way: else
        # a straight tube's nearly parallel profiles could be split in two)
        found = np.where(c >= 0, up[:, None], down[:, None]) * (np.abs(c) >= FADED_COS)
        shear = grid[np.argmax(found.sum(axis=0))]
        take = np.cos(theta - shear) < 0
    return Edges(*(np.where(take, f, r) for f, r in zip(
        (falling.centre, falling.width, falling.strength, falling.valid),
        (rising.centre, rising.width, rising.strength, rising.valid), strict=True)),
        facing=np.where(take, -1.0, 1.0))


#: :func:`side_edges` takes an edge only where no other step within its reach
#: is this share as strong.
SIDE_AMBIGUOUS = 0.5


def side_edges(profiles: np.ndarray, step: float, half_width, side: np.ndarray, *,
               polarity: int, reach: float, smooth_px: float = 0.8,
               min_strength: float = 0.0,
               max_strength: float = np.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tube's centre on every profile from one of its outer edges alone.

    Where another layer of the tube lies over one side of a profile (a coil
    running beside or over another), the pair cannot be trusted, but the edge
    on the side it leaves clear is still the tube's own: the strongest inward
    step of the tube's polarity within ``reach`` of where the expected
    half-width puts it, moved back in by that half-width.

    Parameters
    ----------
    profiles : (M, P) ndarray
        Samples along the normals at offsets ``(j − (P−1)/2)·step`` px.
    step : float
        Sample spacing, px.
    half_width : float or (M,) ndarray
        Expected half-width of the tube at each profile, px.
    side : (M,) ndarray of ±1
        Which edge to take: +1 the one at +half-width (entering the tube
        against the profile's direction), −1 the one at −half-width.
    polarity : {+1, −1}
        Sign of the intensity step entering the tube.
    reach : float
        The edge is looked for within ±reach px of ``side·half_width``.
    smooth_px : float
        Gaussian smoothing along the profile before differentiating, px.
    min_strength, max_strength : float
        Weakest and strongest acceptable inward step, intensity per px.

    Returns
    -------
    centre, strength : (M,) ndarray
        The centre's offset from the profile origin (px; NaN where no edge
        is valid) and the edge's step (−inf where no step lies within reach).
    valid : (M,) bool ndarray
        An edge was found there, the only one within reach (no other step
        :data:`SIDE_AMBIGUOUS` as strong).
    """
    m, p = profiles.shape
    side = np.asarray(side, dtype=float)
    hw = np.broadcast_to(np.asarray(half_width, dtype=float), (m,))
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    grad[bad] = np.nan
    # entering the tube from the −offset side steps by polarity·grad
    inward = -side[:, None] * polarity * grad
    pos = (np.arange(p) - (p - 1) / 2) * step
    near = np.abs(pos[None, :] - (side * hw)[:, None]) <= reach
    heights = np.where(near & _local_maxima(np.nan_to_num(inward, nan=-np.inf)),
                       inward, -np.inf)
    rows = np.arange(m)
    idx = np.argmax(heights, axis=1)
    strength = heights[rows, idx]
    heights[rows, idx] = -np.inf
    # (one step within reach: where two are, a line or an edge of something
    # else lies by the tube's, and either may be the tube's)
    valid = (np.isfinite(strength) & (strength > min_strength) & (strength <= max_strength)
             & (heights.max(axis=1) < SIDE_AMBIGUOUS * strength))
    at = (_parabolic(np.nan_to_num(inward, nan=-np.inf), idx[:, None])[:, 0]
          - (p - 1) / 2) * step
    return np.where(valid, at - side * hw, np.nan), strength, valid


def _encloses(outer: Edges, inner: Edges) -> np.ndarray:
    """Where both pairs were found and ``outer``'s edges lie outside ``inner``'s."""
    return (outer.valid & inner.valid
            & (outer.centre - 0.5 * outer.width < inner.centre - 0.5 * inner.width)
            & (outer.centre + 0.5 * outer.width > inner.centre + 0.5 * inner.width))


def _nearer_width(pick: np.ndarray, strong: np.ndarray, width: np.ndarray,
                  centre: np.ndarray, expected: np.ndarray, *, k: int) -> np.ndarray:
    """``pick`` (each profile's pair, a flat index into its K×K left/right
    peaks), or a ``strong`` pair sharing one of its edges whose ``width`` is
    within :data:`NEARER_WIDTH_OFF` of the ``expected`` one and nearer it by
    :data:`NEARER_WIDTH` of it: one outer edge and a thick wall's lumen edge
    taken for the tube, where the tube's outer pair shares that outer edge.
    Only over runs of :data:`NEARER_RUN` neighbouring profiles (in the order
    given) whose ``centre`` moves the same way: a pair taken along a stretch of
    the tube, not a chance pair of lines on one profile (the tube's end over a
    glass capillary's walls)."""
    rows = np.arange(pick.size)
    li, ri = np.divmod(np.arange(k * k), k)
    shares = strong & ((li[None, :] == (pick // k)[:, None]) | (ri[None, :] == (pick % k)[:, None]))
    off = np.where(shares, np.abs(width - expected[:, None]), np.inf)
    better = np.argmin(off, axis=1)
    gain = np.abs(width[rows, pick] - expected) - off[rows, better]
    take = (gain > NEARER_WIDTH * expected) & (off[rows, better] <= NEARER_WIDTH_OFF * expected)
    if not take.any():
        # (most calls, every round of every frame: the runs need no labelling)
        return pick
    way = np.sign(centre[rows, better] - centre[rows, pick])
    for sign in (-1.0, 1.0):
        runs, _ = ndi.label(take & (way == sign))
        size = np.bincount(runs)
        take[(runs > 0) & (size[runs] < NEARER_RUN)] = False
    return np.where(take, better, pick)


def _best_pairs(left, right, *, step, half_width, window, width_tol, min_strength,
                n_peaks, gaps, widest=False) -> Edges:
    """:func:`edge_pairs` given each side's inward steps (NaN: no edge there,
    only if ``gaps``)."""
    if gaps:
        left = np.where(np.isnan(left), -np.inf, left)
        right = np.where(np.isnan(right), -np.inf, right)
    m, p = left.shape
    mid = (p - 1) / 2
    # both sides in one pass (the arrays are small: numpy's per-call cost dominates)
    both = np.concatenate([left, right])
    idx, heights = _top_peaks(both, n_peaks)
    pos = (_parabolic(both, idx) - mid) * step     # (2M, K) offsets, px
    lpos, rpos, lh, rh = pos[:m], pos[m:], heights[:m], heights[m:]
    width = rpos[:, None, :] - lpos[:, :, None]    # (M, K, K)
    centre = 0.5 * (rpos[:, None, :] + lpos[:, :, None])
    strength = np.minimum(lh[:, :, None], rh[:, None, :])
    hw = np.broadcast_to(np.asarray(half_width, dtype=float), (m,))[:, None, None]
    ok = ((np.abs(width - 2 * hw) <= width_tol * 2 * hw) & (np.abs(centre) <= window)
          & np.isfinite(strength) & (strength > min_strength))
    score = np.where(ok, strength, -np.inf).reshape(m, -1)
    best = score.max(axis=1, keepdims=True)
    strong = score >= 0.7 * best
    if widest:
        pick = np.argmax(np.where(strong, width.reshape(m, -1), -np.inf), axis=1)
    else:
        pick = np.argmin(np.where(strong, np.abs(centre).reshape(m, -1), np.inf), axis=1)
        if width_tol <= KNOWN_WIDTH_TOL:
            pick = _nearer_width(pick, strong, width.reshape(m, -1), centre.reshape(m, -1),
                                 2 * hw[:, 0, 0], k=idx.shape[1])
    rows = np.arange(m)
    valid = np.isfinite(best[:, 0])
    def chosen(a):
        return a.reshape(m, -1)[rows, pick]

    return Edges(np.where(valid, chosen(centre), np.nan),
                 np.where(valid, chosen(width), np.nan),
                 np.where(valid, chosen(strength), -np.inf), valid)


def end_edge(profiles: np.ndarray, step: float, *, polarity: int, window: float,
             smooth_px: float = 0.8, strong: float = 0.6, nearest: bool = False,
             face_line: bool = True):
    """Position of the tube's end on profiles running along the tangent, tip outwards.

    The *outermost* strong tube → background step within ±window is taken, so
    that an inner edge (the end of the lumen inside a sealed tip) is not
    mistaken for the end of the tube; with ``nearest`` (crossings), the strong
    step nearest the window's centre. In a relief (``polarity`` 0) a cut end
    face shows as a line, placed midway between its flanks
    (:func:`_relief_line`); with ``face_line`` False (a round cap, whose
    path length falls to nothing at its apex: a lobe, not a line, and the
    strong step inside it the lumen's end) at its outer flank, a blur
    beyond the apex as the side edges lie a blur outside the walls. (On two
    independent sets' DIC tubes with round caps the middle lay 1.1-2.0 px
    inside the apex, the outer flank 0.4-1.0 px beyond it.)

    Returns
    -------
    offset : (M,) ndarray
        Offset of the end, px (NaN where the window holds no usable sample).
    strength : (M,) ndarray
        Its step, intensity per px.
    """
    m, p = profiles.shape
    grad, bad = _inward_gradient(profiles, step, smooth_px)
    # relief: the end face is lit or shaded as it faces the shear
    leaving = -polarity * grad if polarity != 0 else np.abs(grad)
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
    pos = _parabolic(leaving, idx)
    if polarity == 0 and face_line:
        pos = _relief_line(grad, idx, pos, ok_from=strong * peak[:, 0], bad=bad | ~inwin)
    offset = np.where(found, (pos - mid) * step, np.nan)
    return offset, np.where(found, masked[np.arange(m), idx], -np.inf)


def _relief_line(grad, idx, pos, *, ok_from, bad):
    """In a relief image a face across the profile (the tube's end) is a
    bright or dark *line*, not a step: its outer flank lies half the line's
    width beyond the face. Where the outer flank at ``idx`` has an inner one
    (the nearest strong opposite step inward), the face is midway between."""
    m, p = grad.shape
    rows = np.arange(m)
    opposite = -np.sign(grad[rows, idx])[:, None] * grad
    opposite[np.broadcast_to(bad, grad.shape)] = -np.inf
    inner = (_local_maxima(opposite) & (opposite >= ok_from[:, None])
             & (np.arange(p)[None, :] < idx[:, None]))
    has = inner.any(axis=1)
    j = p - 1 - np.argmax(inner[:, ::-1], axis=1)
    return np.where(has, 0.5 * (pos + _parabolic(opposite, j)), pos)


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
    return float(robust_sd(values))
