"""Find the tube in a frame without a prediction: the tracker's (re)start.

Slow but global; run on the first frame and on frames where the fast
refinement fails. Steps, at a working resolution of at most ~512 px:

1. background = a wide median of the frame (illumination, vignetting), and
   contrast = frame − background, in units of the noise (robust MAD);
2. foreground = hysteresis threshold of |contrast|, so dark tubes, bright
   tubes and transparent tubes whose only strong features are their rims all
   give a mask; and the tube's outline = hysteresis threshold of the contrast's
   gradient magnitude, taken instead where the first finds no tube or a much
   shorter one (a transparent tube on a mottled background);
3. a hollow or transparent tube gives two rim lines: they are joined by a
   closing whose radius is chosen where the mean width of the structure jumps
   (the smallest radius that fills the tube) — not by ``binary_fill_holes``,
   which would also fill the background enclosed by a curled tube;
4. skeleton → pixel graph → the longest path of the largest structure; its
   width profile (distance transform) separates the narrower pipette from the
   tube, which gives the base (where the tube leaves the pipette);
5. where that finds nothing, or only a line a few pixels wide (a faint tube
   under strong noise, or one rim of it), all of it again at 2x and 4x
   coarser resolution, which averages the noise down.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage as ndi
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path
from skimage.filters import apply_hysteresis_threshold
from skimage.morphology import skeletonize

from .centreline import from_image
from .robust import robust_sd
from .steps import trend_level_fit, two_level_fit

#: The tube found by its outline (:func:`outline_foreground`) is taken instead
#: of the one found by its contrast when it is this much longer: on a mottled
#: background the contrast's mask breaks up, or follows one rim and the darker
#: patches beside it. Measured (with the tracker's wider first width guess):
#: 12 scenes of samples 2 and 6 on a 5 % mottle (4 seeds, 480x360 and 640x480)
#: 6 -> 9 meet every target; 6 textured scenes at 3-8 %: 1 -> 3; the 153 scenes
#: without a mottle (two renderers): identical figures.
OUTLINE_LONGER = 1.25
#: ... and the contrast's tube narrower than this fraction of the outline's (a
#: rim): where the contrast finds the tube whole, an outline that runs on
#: further follows a pipette's walls or the noise (a blurred, noisy pipette:
#: the base 150 px off).
OUTLINE_WIDER = 0.5
#: ... or whatever its width, when the contrast found under 1/OUTLINE_SPAN of
#: what the outline follows: a fragment of the tube, not the tube whole (a
#: transparent tube on a mottled background, 104 px of its 790 found by its
#: contrast, then drawn 290 px straight to the base given it: its outline,
#: the whole tube, was refused for its width and the frame lost).
OUTLINE_SPAN = 2.5
#: The outline's thresholds are multiples of the background's median gradient,
#: but of at least this fraction of the strongest edges' (99.9th percentile).
#: A noise-free MJPG frame of a sharp, dim fluorescent tube has a median
#: gradient 360x below its edges': 6x that took in the pipette and the
#: compression's blocks (a 'tube' 3x too wide). Mottled backgrounds, where
#: the outline is needed, have edges only 4-6x their median, and are unchanged.
OUTLINE_FLOOR = 50.0
#: Where the working scale finds no tube, or one under THIN_HALF_WIDTH working
#: pixels in half-width, the frame is searched again at these multiples of
#: it, coarser (while that leaves at least COARSE_MIN_PX on its shorter side),
#: and what that finds is taken when it is over twice as wide
#: (:data:`OUTLINE_WIDER`) and at least COARSE_LENGTH as long as what the finer
#: scale found, or shorter but run along by it (its rims, :func:`_rims_of`).
COARSER = (2, 4)
THIN_HALF_WIDTH = 3.0
COARSE_MIN_PX = 64
COARSE_LENGTH = 0.8


@dataclass(frozen=True)
class Detection:
    """A tube found in one frame.

    Attributes
    ----------
    path : (M,) complex ndarray
        Ordered points from the base to the tip end of the skeleton, px, y up
        (full-frame coordinates).
    base : complex
        Base point, px, y up.
    base_angle : float
        Direction of the tube at its base, rad (CCW from +x, y up).
    half_width : float
        Rough outer half-width of the tube, px.
    base_source : str
        How the base was found (pipette width step, image border, given …).
    bridged_px : float
        How much of :attr:`path` was not found but drawn straight from a
        given base to the tube found off it, px (0 if none).
    held_at : tuple of complex, optional
        Where a narrower stretch at one end of :attr:`path` and a wider
        holder at its other end each step to the tube, in that order, px (y
        up), both ends at the image border: the base is at one of them, and
        the video tells which (set only then).
    """

    path: np.ndarray
    base: complex
    base_angle: float
    half_width: float
    base_source: str
    bridged_px: float = 0.0
    held_at: tuple[complex, complex] | None = None

    @property
    def found_length(self) -> float:
        """Length of :attr:`path` that was found in the frame, px."""
        return self.length - self.bridged_px

    @property
    def length(self) -> float:
        """Length of :attr:`path`, px."""
        return float(np.abs(np.diff(self.path)).sum())


def working_scale(shape, target: int = 512) -> int:
    """Integer downsampling factor bringing the larger side to ≤ ``target`` px."""
    return max(1, int(np.ceil(max(shape) / target)))


def contrast_image(image: np.ndarray, factor: int):
    """Background-subtracted frame at 1/``factor`` resolution, in noise units.

    Returns
    -------
    contrast : (r, c) float32 ndarray
        (frame − background) / noise σ.
    background : (r, c) float32 ndarray
    """
    rows, cols = image.shape
    small = cv2.resize(image, (max(cols // factor, 1), max(rows // factor, 1)),
                       interpolation=cv2.INTER_AREA) if factor > 1 else image.copy()
    # illumination (gradient, vignetting) is smooth: a robust low-order surface fitted
    # on a ≤128 px thumbnail follows it into the corners, where a median does not,
    # and ignores the tube (Tukey weights)
    t = max(1, int(np.ceil(max(small.shape) / 128)))
    thumb = cv2.resize(small, (max(small.shape[1] // t, 1), max(small.shape[0] // t, 1)),
                       interpolation=cv2.INTER_AREA).astype(np.float64)
    bg_small = _smooth_surface(thumb)
    background = cv2.resize(bg_small, (small.shape[1], small.shape[0]),
                            interpolation=cv2.INTER_LINEAR)
    diff = small - background
    hp = diff - cv2.GaussianBlur(diff, (0, 0), 2.0)
    # a noise-free frame (rendered, or heavily denoised) would make every smooth
    # residual of the background "significant": floor the noise at half a grey
    # level of 8-bit video
    noise = max(float(robust_sd(hp, axis=None)) * 1.6, 0.5 / 255)
    return (diff / noise).astype(np.float32), background


def _smooth_surface(thumb: np.ndarray, degree: int = 4, rounds: int = 6) -> np.ndarray:
    """Robust least-squares polynomial surface through an image (Tukey biweight)."""
    rows, cols = thumb.shape
    y, x = np.mgrid[0:rows, 0:cols]
    x = (x.ravel() / max(cols - 1, 1)) * 2 - 1
    y = (y.ravel() / max(rows - 1, 1)) * 2 - 1
    terms = [x**i * y**j for i in range(degree + 1) for j in range(degree + 1 - i)]
    design = np.stack(terms, axis=1)
    values = thumb.ravel()
    weights = np.ones_like(values)
    for _ in range(rounds):
        # the weighted normal equations (15 unknowns: well conditioned on [-1, 1]²),
        # a third of the time of an SVD least squares of the 12 000 rows
        weighted = design * weights[:, None]
        coef = np.linalg.solve(weighted.T @ design, weighted.T @ values)
        resid = values - design @ coef
        scale = 1.4826 * np.median(np.abs(resid[weights > 0])) + 1e-9
        u = resid / (4.685 * scale)
        weights = np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
    return (design @ coef).reshape(rows, cols).astype(np.float32)


def foreground(contrast: np.ndarray, *, high: float = 6.0, low: float = 3.0,
               min_area_frac: float = 2e-4) -> np.ndarray:
    """Hysteresis mask of |contrast| (both polarities), small specks removed."""
    smooth = cv2.GaussianBlur(contrast, (0, 0), 1.0)
    # (no lower than white noise of the contrast's unit would give after this
    # blur: a noise-free frame has none to measure)
    mag = _in_noise_units(smooth, 0.3)
    return _without_specks(apply_hysteresis_threshold(mag, low, high), min_area_frac)


def _in_noise_units(smooth: np.ndarray, floor: float) -> np.ndarray:
    """|``smooth``| (a smoothed contrast) in units of its own noise, at least ``floor``."""
    # the *smoothed* image's noise (≈ 0.3 of the raw noise for white noise after
    # a 1 px blur, but measured: compression and optics correlate the noise)
    hp = smooth - cv2.GaussianBlur(smooth, (0, 0), 4.0)
    # ... but no lower than what the background model leaves over the whole frame
    # (uneven illumination it did not follow), or that residue floods the mask
    noise = max(robust_sd(hp, axis=None), robust_sd(smooth, axis=None), floor)
    return np.abs(smooth) / noise


#: The line filters of :func:`line_foreground`: Gaussian, this many working px
#: (σ) along their line and 1 across it, in LINE_DIRECTIONS directions.
LINE_ALONG_PX = 4.0
LINE_DIRECTIONS = 8


def line_foreground(contrast: np.ndarray, *, high: float = 6.0, low: float = 3.0,
                    min_area_frac: float = 2e-4) -> np.ndarray:
    """Hysteresis mask of the contrast averaged along lines: thin rims in noise.

    A transparent tube whose rims are a pixel or two wide shows them at a few
    times the noise of a pixel; the isotropic blur of :func:`foreground`
    averages them with the background beside them, and nothing stands out at
    any scale. Averaged along their own direction (the strongest of
    :data:`LINE_DIRECTIONS` elongated Gaussians, each response in units of its
    own noise), they do, as they do to the eye.
    """
    half = int(np.ceil(3.0 * LINE_ALONG_PX))
    y, x = np.mgrid[-half:half + 1, -half:half + 1].astype(np.float64)
    mag = np.zeros(contrast.shape, np.float32)
    for theta in np.pi * np.arange(LINE_DIRECTIONS) / LINE_DIRECTIONS:
        along = x * np.cos(theta) + y * np.sin(theta)
        across = -x * np.sin(theta) + y * np.cos(theta)
        kernel = np.exp(-0.5 * ((along / LINE_ALONG_PX) ** 2 + across**2))
        kernel /= kernel.sum()
        smooth = cv2.filter2D(contrast, cv2.CV_32F, kernel.astype(np.float32),
                              borderType=cv2.BORDER_REFLECT)
        # in units of this direction's own noise; and no lower than white noise
        # of half the contrast's unit would give (a frame's own noise is about
        # 0.6 of it: :func:`contrast_image`), for a noise-free frame
        np.maximum(mag, _in_noise_units(smooth, 0.5 * float(np.sqrt((kernel**2).sum()))),
                   out=mag)
    return _without_specks(apply_hysteresis_threshold(mag, low, high), min_area_frac)


def outline_foreground(contrast: np.ndarray, *, high: float = 6.0, low: float = 3.0,
                       min_area_frac: float = 2e-4) -> np.ndarray:
    """Hysteresis mask of the contrast's gradient magnitude: the tube's outline.

    On a mottled background (a textured substrate, a dirty slide) a transparent
    tube is no darker than the darker patches around it, and :func:`foreground`
    finds nothing or blobs; its edges, sharp where the mottle is smooth, still
    stand out. The thresholds are multiples of the median gradient magnitude
    over the frame (the background's, noise and mottle alike).
    """
    smooth = cv2.GaussianBlur(contrast, (0, 0), 1.0)
    # (Sobel's unnormalised scale cancels: the thresholds are multiples of the median)
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.hypot(gx, gy)
    # (OUTLINE_FLOOR: on a nearly noise-free background the median is the
    # quantisation's, and faint shading stands as far out of it as the tube)
    typical = max(float(np.median(mag)), float(np.percentile(mag, 99.9)) / OUTLINE_FLOOR)
    if not typical > 0:
        return np.zeros(contrast.shape, bool)
    return _without_specks(apply_hysteresis_threshold(mag / typical, low, high), min_area_frac)


def _without_specks(mask: np.ndarray, min_area_frac: float) -> np.ndarray:
    labels, n = ndi.label(mask)
    if n == 0:
        return mask
    areas = np.bincount(labels.ravel())
    areas[0] = 0
    keep = areas >= max(min_area_frac * mask.size, 8)
    return keep[labels]


def _largest(mask: np.ndarray) -> np.ndarray:
    labels, n = ndi.label(mask)
    if n == 0:
        return mask
    areas = np.bincount(labels.ravel())
    areas[0] = 0
    return labels == np.argmax(areas)


def _skeleton(mask: np.ndarray) -> np.ndarray:
    """``skeletonize(mask)``, worked out over the mask's bounding box only.

    The thinning decides each pixel from its 3x3 neighbourhood and never sets a
    background pixel, so a box with a pixel of background around the mask (or
    the image border where the mask reaches it) gives the same skeleton; a tube
    across a frame fills a small part of it.
    """
    rows, cols = np.nonzero(np.any(mask, axis=1))[0], np.nonzero(np.any(mask, axis=0))[0]
    out = np.zeros(mask.shape, dtype=bool)
    if rows.size == 0:
        return out
    r0, r1 = max(rows[0] - 1, 0), min(rows[-1] + 2, mask.shape[0])
    c0, c1 = max(cols[0] - 1, 0), min(cols[-1] + 2, mask.shape[1])
    out[r0:r1, c0:c1] = skeletonize(mask[r0:r1, c0:c1])
    return out


def _mean_width(mask: np.ndarray) -> float:
    skel = _skeleton(mask)
    if skel.sum() < 3:
        return 0.0
    return float(mask.sum() / skel.sum())


#: A hole (or a closing's addition) whose area exceeds this many times that of
#: its largest inscribed disc is long and thin: a lumen, not the round
#: background a curled tube encloses.
LUMEN_ELONGATION = 4.0


def fill_lumen(mask: np.ndarray, *, elongation: float = LUMEN_ELONGATION) -> np.ndarray:
    """Fill the holes a visible lumen leaves in the mask, not the background a curl encloses.

    A lumen is a long thin hole (its area is many times that of its largest
    inscribed disc); the background enclosed by a curled tube is round.
    """
    holes = ~mask
    labels, n = ndi.label(holes)
    if n <= 1:
        return mask
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    index = np.arange(1, n + 1)
    # each hole's largest inscribed radius (ufunc.at: ndi.maximum sorts every
    # pixel by its label, 18x the time on a 512x384 mask)
    radius = np.zeros(n + 1)
    np.maximum.at(radius, labels.ravel(), ndi.distance_transform_edt(holes).ravel())
    radius = radius[1:]
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    fill = (area > elongation * np.pi * radius**2) | (radius <= 2)
    fill[np.isin(index, edge)] = False
    lut = np.concatenate([[False], fill])
    return mask | lut[labels]


#: A closing that changes the mask's area by at most this fraction from the last
#: one whose skeleton was drawn is taken to leave its mean width in proportion
#: (its skeleton is not redrawn).
SAME_AREA = 0.01


def fill_tube(mask: np.ndarray, max_radius: int | None = None, *, fill_ratio: float = 2.5,
              plateau_ratio: float = 1.12):
    """Join the rims of a hollow tube with the smallest closing that fills it.

    A closing of radius r counts as filling the tube when the mean width jumps
    (by 1.25x, from one radius to the next or over two) to over ``fill_ratio`` ·
    r, and then levels off (the next radius widens it by at most
    ``plateau_ratio``).

    Returns
    -------
    filled : bool ndarray
        The largest structure after closing.
    radius : int
        Closing radius used, px (0 = the mask was already solid).
    """
    if max_radius is None:
        max_radius = max(2, min(mask.shape) // 10)
    radii = [r for r in (0, 1, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 64) if r <= max_radius]
    cache = {}

    def closed(i):
        # closed lazily: the first radius that fills is usually small, and the
        # large closings (up to 129 px across) cost the most
        if i not in cache:
            r = radii[i]
            out = mask
            if r:
                se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
                out = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, se,
                                       borderType=cv2.BORDER_REPLICATE).astype(bool)
            comp = _largest(out)
            area = int(comp.sum())
            # the last closing whose skeleton was drawn
            ref = cache[i - 1][2] if i else None
            if ref is not None and abs(area - ref[0]) <= SAME_AREA * ref[0]:
                # (all but the same pixels: the skeleton, most of the cost, would
                # give all but the same width; a solid mask runs through every radius)
                width = ref[1] * area / max(ref[0], 1)
            else:
                width = _mean_width(comp)
                ref = (area, width)
            cache[i] = (comp, width, ref)
        return cache[i]

    # a hollow tube's width jumps (rim → whole tube) once the radius reaches
    # half the gap between its rims; take the first such jump
    # (the rims may merge gradually first, so ask for a clear step followed by a
    # plateau rather than one fixed ratio)
    stepped = False
    for i in range(1, len(radii)):
        before, (filled, width, _) = closed(i - 1)[1], closed(i)
        step = before > 0 and width >= 1.25 * before
        # a jump spread over two radii (rims that merge over a stretch first,
        # then all along) counts from before it began, and against the radius
        # that began it
        spread = stepped and width >= 1.25 * closed(i - 2)[1]
        stepped = step
        if not ((step and width > fill_ratio * radii[i])
                or (spread and width > fill_ratio * radii[i - 1])):
            continue
        if ((i == len(radii) - 1 or closed(i + 1)[1] <= plateau_ratio * width)
                and not _filled_a_curl(closed(i - 2 if spread else i - 1)[0], filled)):
            return filled, radii[i]
    return closed(0)[0], radii[0]


def _filled_a_curl(before: np.ndarray, after: np.ndarray,
                   elongation: float = LUMEN_ELONGATION) -> bool:
    """Whether most of what a closing added to ``before`` is one round piece:
    the background a curled tube encloses, its tip closed onto its body. A
    lumen is long and thin (as in :func:`fill_lumen`), or, where the rims
    already meet here and there, many pieces (a faint tube: 18, the largest a
    fifth of the whole)."""
    added = after & ~before
    labels, n = ndi.label(added)
    if n == 0:
        return False
    area = np.bincount(labels.ravel())[1:]
    if area.max() < 0.5 * area.sum():
        return False
    biggest = labels == 1 + int(np.argmax(area))
    radius = float(ndi.distance_transform_edt(biggest).max())
    return bool(area.max() <= elongation * np.pi * radius**2)


def _skeleton_graph(skel: np.ndarray):
    rr, cc = np.nonzero(skel)
    index = -np.ones(skel.shape, dtype=np.int64)
    index[rr, cc] = np.arange(rr.size)
    rows, cols, w = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = rr + dr, cc + dc
        ok = (r2 >= 0) & (r2 < skel.shape[0]) & (c2 >= 0) & (c2 < skel.shape[1])
        j = np.full(rr.size, -1)
        j[ok] = index[r2[ok], c2[ok]]
        has = j >= 0
        rows.append(np.nonzero(has)[0])
        cols.append(j[has])
        w.append(np.full(has.sum(), np.hypot(dr, dc)))
    rows, cols, w = map(np.concatenate, (rows, cols, w))
    n = rr.size
    graph = coo_matrix((np.r_[w, w], (np.r_[rows, cols], np.r_[cols, rows])), shape=(n, n))
    return graph.tocsr(), rr, cc


def longest_path(skel: np.ndarray, *, border_bonus: float = 0.0, margin: float = 0.0,
                 radius: np.ndarray | None = None):
    """The longest shortest path between two end points of a skeleton.

    Parameters
    ----------
    skel : (rows, cols) bool ndarray
    border_bonus : float
        Length (px) added for each end within ``margin`` of the image border:
        a branch that runs out of the frame (the pipette, or the tube leaving
        it) then wins over a spur of about the same length into a speck of
        dust stuck to it.
    margin : float
        px.
    radius : (rows, cols) float ndarray, optional
        The structure's half-width about each skeleton pixel (its distance
        transform), px. Given, each step counts its length times the
        radius there, and the path with the most of the structure's area
        along it wins (``border_bonus`` then counts times the radius at that
        end): a thin line the tube touches (a burned-in reticle, a fibre, a
        scratch) runs longer than the tube but holds less of it.

    Returns
    -------
    (M, 2) int ndarray
        (row, col) of the path's pixels, in order.
    """
    graph, rr, cc = _skeleton_graph(skel)
    if radius is not None and rr.size:
        r = np.maximum(radius[rr, cc], 0.5)
        coo = graph.tocoo()
        graph = coo_matrix((coo.data * (r[coo.row] + r[coo.col]) / 2, (coo.row, coo.col)),
                           shape=coo.shape).tocsr()
    if rr.size < 2:
        return np.stack([rr, cc], axis=1)
    degree = np.diff(graph.indptr)
    ends = np.nonzero(degree == 1)[0]
    if ends.size < 2:
        ends = np.arange(rr.size)[:: max(1, rr.size // 64)]
    dist, pred = shortest_path(graph, indices=ends, return_predecessors=True)
    dist[~np.isfinite(dist)] = -1
    length = dist[:, ends]
    if border_bonus > 0:
        bonus = np.array([border_bonus if _touches_border((rr[e], cc[e]), skel.shape, margin)
                          else 0.0 for e in ends])
        if radius is not None:
            bonus = bonus * np.maximum(radius[rr[ends], cc[ends]], 0.5)
        length = np.where(length >= 0, length + bonus[:, None] + bonus[None, :], length)
    i, j = np.unravel_index(np.argmax(length), (ends.size, ends.size))
    src, dst = ends[i], ends[j]
    path = [dst]
    while path[-1] != src:
        path.append(pred[i, path[-1]])
    path = np.array(path[::-1])
    return np.stack([rr[path], cc[path]], axis=1)


#: Largest turn (deg) between the tube's start and the straight run back to a
#: given base that lies beyond it, for that run to be bridged (a missed stretch
#: curving no more than this); and its largest length, over the tube found.
BRIDGE_MAX_TURN_DEG = 45.0
BRIDGE_MAX_SHARE = 0.5


def _bridges_to(gap: complex, lead: complex, length_px: float) -> bool:
    """Whether a given base ``gap`` px behind the start of the tube found
    (``gap`` = start − base; ``lead`` the tube's direction from its start)
    carries the tube on back: along its line, and nearer than half its length."""
    if abs(lead) == 0:
        return False
    turn = abs(np.degrees(np.angle(gap / lead)))
    return turn <= BRIDGE_MAX_TURN_DEG and abs(gap) <= BRIDGE_MAX_SHARE * length_px


def _touches_border(point_rc, shape, margin: float) -> bool:
    return border_distance(point_rc, shape) < margin


def border_distance(point_rc, shape) -> float:
    """How far the point (row, col) lies from the nearest border of an image
    of ``shape`` (rows, cols), px (negative outside)."""
    r, c = point_rc
    return float(min(r, c, shape[0] - 1 - r, shape[1] - 1 - c))


#: A narrower stretch at the tube's end is a pipette only where it runs on
#: within this of the tube's line (deg): a fibre or a scratch that the tube's
#: end touches turns away (a dust fibre from a tube's tip: 74-78 deg, taken for
#: a pipette and the ends swapped), a pipette holds the tube along its axis (a
#: tube curled 300 deg from its base: 15-20 deg). (Not asked of a wider
#: holder: where a capillary's walls meet the tube the skeleton kinks.)
PIPETTE_IN_LINE_DEG = 45.0


def _in_line(path_rc: np.ndarray, split: int, ratio: float, half_width: float) -> bool:
    """Whether the narrower stretch of ``path_rc`` beyond ``split`` (before
    it where ``ratio`` > 1) runs on along the tube's line there
    (:data:`PIPETTE_IN_LINE_DEG`): chords over up to four half-widths of the
    narrow stretch and two of the tube (which may bend)."""
    narrow, tube = int(max(3, round(4 * half_width))), int(max(3, round(2 * half_width)))
    if ratio > 1.0:
        lo, hi = max(split - narrow, 0), min(split + tube, len(path_rc) - 1)
    else:
        lo, hi = max(split - tube, 0), min(split + narrow, len(path_rc) - 1)
    if split - lo < 2 or hi - split < 2:
        return True
    before = path_rc[split] - path_rc[lo]
    after = path_rc[hi] - path_rc[split]
    cos = float(before @ after) / max(float(np.hypot(*before) * np.hypot(*after)), 1e-12)
    return cos >= np.cos(np.radians(PIPETTE_IN_LINE_DEG))


#: A tube entering the frame at an angle to the border's normal is cut
#: obliquely by it: its mask narrows over ``half_width * tan(angle)`` on its
#: way to the border, as onto a narrower pipette. The angle counts up to
#: this (deg): a tube along the border is not cut across.
BORDER_CUT_MAX_DEG = 80.0


def _slanted_step(path_rc: np.ndarray, split: int, half_width: float, shape) -> bool:
    """Whether the narrowing of ``path_rc`` before ``split`` (towards its first
    point, at the border) is the border cutting the tube obliquely
    (:func:`slanted_cut`, the tube's line carried on from ``split``). A
    tube 15 px wide entering at 60 deg to the normal narrowed over 13 px on
    its way to the border, and that narrowing was taken for a pipette's
    step: the base put 18 px inside the frame."""
    reach = int(max(3, round(2 * half_width)))
    if split + reach >= len(path_rc):
        return False
    (row, col), (row_on, col_on) = path_rc[split], path_rc[split + reach]
    # (px, y up: the tangent runs from the step on along the tube)
    tangent = complex(col_on - col, row - row_on)
    if tangent == 0:
        return False
    return slanted_cut(complex(col, -row), float(np.angle(tangent)), half_width, shape)


#: A base this close to the frame's edge (in tube half-widths, back along its
#: tangent) that the tube enters from is at the edge
#: (:func:`base_at_edge`): a tube square to the edge has its first whole
#: profile there, but for the blur. (At 2: an independent scene's tube 40 px
#: wide, its base 50 px in past a capillary's stub, was carried back to the
#: border: base 53 px off, length 8 % long; at 1, 6 px and 0.9 %; of 157
#: other scenes one changed, its 95th percentile 2.01 -> 1.80 deg.) ...
BORDER_BASE_HW = 1.0
#: ... and as many more as the profiles across the tube reach beside it (up
#: to 3.5 half-widths) times the tangent of its slant to the edge's normal
#: (up to :data:`BORDER_CUT_MAX_DEG`): a tube entering at a slant has its
#: first whole profile that far in (at 60 deg, 26 px in for a tube 8 px in
#: half-width: left there, and the length 8 % short).
BORDER_SLANT_HW = 4.0


def edge_behind(base: complex, angle: float, shape) -> tuple[float, float]:
    """How far back from ``base`` (px, y up), against the tangent ``angle``
    (rad), the frame's edge lies, px (the nearest of the four edges it meets,
    half a pixel beyond the outer pixels' centres; inf if none); and the
    cosine of the tangent's angle to that edge's normal. ``shape``: the
    frame's (rows, cols)."""
    rows, cols = shape
    col, row = base.real, -base.imag
    back = -np.exp(1j * angle)
    dc, dr = back.real, -back.imag
    steps = []
    if dc < 0:
        steps.append(((col + 0.5) / -dc, -dc))
    if dc > 0:
        steps.append(((cols - 0.5 - col) / dc, dc))
    if dr < 0:
        steps.append(((row + 0.5) / -dr, -dr))
    if dr > 0:
        steps.append(((rows - 0.5 - row) / dr, dr))
    return tuple(float(v) for v in min(steps)) if steps else (np.inf, 1.0)


def base_at_edge(base: complex, angle: float, half_width: float, shape) -> float | None:
    """How far back along its tangent the frame's edge lies from a base that
    is at it (:data:`BORDER_BASE_HW`, :data:`BORDER_SLANT_HW`: the first
    whole profile across a tube entering there), px; None for a base farther
    in (or beyond the edge)."""
    d, cos = edge_behind(base, angle, shape)
    return (d if 0.0 < d <= (BORDER_BASE_HW + BORDER_SLANT_HW * _slant(cos)) * half_width
            else None)


def _slant(cos: float) -> float:
    """The tangent of the angle whose cosine is ``cos`` (a tube's to the
    frame edge's normal), the angle at most :data:`BORDER_CUT_MAX_DEG`."""
    return float(np.tan(min(np.arccos(min(cos, 1.0)), np.radians(BORDER_CUT_MAX_DEG))))


def slanted_cut(base: complex, angle: float, half_width: float, shape) -> bool:
    """Whether a tube whose full width starts at ``base`` (px, y up), its
    tangent there ``angle`` (rad), is cut obliquely by the frame's edge
    behind it: its line meets the edge (:func:`edge_behind`) within a
    half-width beyond where its far edge would (``half_width`` · tan of its
    angle to the edge's normal, up to :data:`BORDER_CUT_MAX_DEG`).
    ``shape``: the frame's (rows, cols); ``half_width`` in its px."""
    t, cos = edge_behind(base, angle, shape)
    return bool(np.isfinite(t) and t <= half_width * (_slant(cos) + 1.0))


def _narrow_and_holder(width: np.ndarray, split: int, ratio: float, trim: int,
                       min_pipette: float) -> tuple[int, int] | None:
    """Where a path whose ``width`` steps at ``split`` (``ratio`` after over
    before, :func:`_split_point`) runs from a narrower stretch at one end
    onto the tube, and from the tube onto a holder wider by
    :data:`HOLDER_BEYOND_RATIO` or more at the other: those two steps'
    indices, the narrower stretch's first; None where it does not.

    ``split`` is either step, whichever is the larger: the other is looked
    for on the tube's side of it.
    """
    n = width.size
    if 1 / 1.15 <= ratio <= 1.15 or not 0 < split < n:
        return None
    if ratio < 1.0:
        # (the same, read from the other end)
        found = _narrow_and_holder(width[::-1], n - split, 1.0 / ratio, trim, min_pipette)
        return None if found is None else (n - found[0], n - found[1])
    # narrower before the split: the narrow stretch there, a holder past the tube ...
    tube = width[split:]
    step, step_ratio = _split_point(tube, trim)
    if step and step_ratio >= HOLDER_BEYOND_RATIO and tube.size - step > min_pipette:
        return split, split + step
    # ... or the holder after it, the narrow stretch before the tube
    if ratio < HOLDER_BEYOND_RATIO or n - split <= min_pipette:
        return None
    tube = width[:split][::-1]
    step, step_ratio = _split_point(tube, trim)
    if step and step_ratio < 1 / 1.15 and tube.size - step > min_pipette:
        return split - step, split
    return None


#: ... its width over the tube's there, at least: past a tube's own sections'
#: 25 % (a capillary's width, 1.6x the tube's, measured with its thinner rims
#: at the border: 1.37x).
HOLDER_BEYOND_RATIO = 1.3


def held_between(det: Detection, base: complex) -> Detection:
    """``det`` (a detection with :attr:`Detection.held_at`) cut to the tube
    between its two steps, from the one at ``base`` (px, y up: where the
    video told the tube is held) to the other (where a thinner structure
    touches its tip)."""
    i, j = (int(np.argmin(np.abs(det.path - z))) for z in det.held_at)
    if abs(det.path[j] - base) < abs(det.path[i] - base):
        i, j = j, i
    pts = det.path[i:j + 1] if i < j else det.path[j:i + 1][::-1]
    if pts.size < 4:
        return det
    # (the path's points are a working pixel apart: three half-widths on)
    spacing = float(np.median(np.abs(np.diff(pts))))
    lead = pts[min(pts.size - 1, max(2, int(3 * det.half_width / max(spacing, 1e-9))))] - pts[0]
    return Detection(pts, complex(pts[0]), float(np.angle(lead)), det.half_width,
                     "where the tube leaves one of two structures at its ends (a narrower "
                     "one, a wider holder), the one the video told: the other end moved")


#: The longest path turning by more than this (deg) where it steps down by
#: :data:`HOLDER_RATIO` or more in width, from a stretch at least
#: :data:`CROSSING_WIDE_HW` of its own half-widths long, has turned off the
#: tube into a thinner structure crossing it (a dust fibre): the tube runs on
#: through a crossing, and a holder holds a tube along its own line. Directions
#: are chords over four half-widths each side, from 1.5 of the wider
#: structure's half-widths off the step: the skeleton kinks where a wall meets
#: the tube (an independent-renderer fibre, 4 px wide, across a transparent
#: tube 19 px wide: the path ran along the tube and turned 80 deg down the
#: fibre, which was then tracked as the tube, held by "a holder").
CROSSING_TURN_DEG = 60.0
#: The wider stretch's length at least, in its half-widths: a tube is 16-48
#: of them long (Table 1's, 8-12 mm by 0.25-0.5 mm), and the stretches before
#: the crossings seen ran 23-62, pipettes in. (A faint fluorescent tube's
#: outline, a blob of noise 13 of its half-widths long, was taken for the
#: tube once the path's turn off it was cut.)
CROSSING_WIDE_HW = 20.0
#: Thinner branches cut away at most, one after another.
CROSSINGS_MAX = 3


def _crossing_branch(path_rc: np.ndarray, width: np.ndarray) -> np.ndarray | None:
    """The pixels of ``path_rc`` (working px, (row, col)) to cut from the
    skeleton where the path turns off a wider structure into a thinner one
    crossing it (see :data:`CROSSING_TURN_DEG`), or None where it does not.

    Those are the thinner stretch's from a wider half-width and a pixel past
    the step on: the junction stays, for the path to run on through it."""
    split, ratio = _split_point(width, int(round(np.median(width) / 2)))
    if split == 0 or 1 / HOLDER_RATIO <= ratio <= HOLDER_RATIO:
        return None
    wide_first = ratio < 1.0
    wide = width[:split] if wide_first else width[split:]
    thin = width[split:] if wide_first else width[:split]
    hw_wide, hw_thin = float(np.median(wide)) / 2, float(np.median(thin)) / 2
    if wide.size < CROSSING_WIDE_HW * hw_wide:
        return None
    skip = int(round(1.5 * hw_wide))
    reach_wide, reach_thin = int(max(3, round(4 * hw_wide))), int(max(3, round(4 * hw_thin)))
    step = 1 if wide_first else -1
    # (index runs away from the step on each side)
    wide_ix = split - step * np.array([skip + reach_wide, skip]) - (0 if wide_first else 1)
    thin_ix = split + step * np.array([skip, skip + reach_thin]) - (0 if wide_first else 1)
    if (wide_ix.min() < 0 or wide_ix.max() >= len(path_rc) or thin_ix.min() < 0
            or thin_ix.max() >= len(path_rc)):
        return None
    before = path_rc[wide_ix[1]] - path_rc[wide_ix[0]]
    after = path_rc[thin_ix[1]] - path_rc[thin_ix[0]]
    cos = float(before @ after) / max(float(np.hypot(*before) * np.hypot(*after)), 1e-12)
    if cos >= np.cos(np.radians(CROSSING_TURN_DEG)):
        return None
    cut = int(round(hw_wide)) + 1
    return path_rc[split + cut:] if wide_first else path_rc[:max(split - cut, 0)]


def _pipette_step(path_rc: np.ndarray, split: int, ratio: float, half_width: float,
                  min_pipette: float, margin: float, shape) -> bool:
    """Whether ``path_rc``'s width, stepping up by ``ratio`` at ``split``,
    steps from a narrower pipette onto the tube: a step of over 15 %, the
    narrow stretch longer than ``min_pipette`` (working px), running from the
    border of a frame of ``shape`` (within ``margin``) in the tube's line,
    and no oblique cut of the tube by the border."""
    return (ratio > 1.15 and split > min_pipette
            and _touches_border(path_rc[0], shape, margin)
            and _in_line(path_rc, split, ratio, half_width)
            and not _slanted_step(path_rc, split, half_width, shape))


#: A pipette's taper narrows it by this share of the tube's width at least
#: over the stretch in view (:func:`_tapered_split`): a flatter trend is the
#: mask's own wobble, and a trend that widens the pipette towards the step is
#: no taper. (An independent scene's pulled pipette: from 1.35 to 0.75 of the
#: tube's width; a tube blurring towards its tip, its mask widening, gave a
#: trend of 3 %, with the mask's widening at the border.)
TAPER_MIN = 0.15


def _tapered_split(width: np.ndarray, trim: int = 0) -> tuple[int, float]:
    """Where ``width`` steps from a straight trend narrowing towards the
    step onto a level (:func:`~pipeline.steps.trend_level_fit`), and the
    level over the trend's end there: (index, ratio); (0, 1.0) where the
    trend narrows by less than :data:`TAPER_MIN` of the level (or widens)
    towards the step, or ``width`` is too short.

    A pulled glass pipette narrows towards its mouth: a tube wider than its
    mouth but narrower than the pipette at the frame's border gives a two-level
    fit no step (the pipette's mean width about the tube's), and its base was
    put at the border (an independent scene: length 50 % long). ``trim`` as
    :func:`_split_point`."""
    trim = int(max(0, min(trim, (width.size - 8) // 2)))
    inner = width[trim:width.size - trim]
    if inner.size < 8:
        return 0, 1.0
    sse, end, after = trend_level_fit(inner)
    # (a trend fitted to 3 points at least, a level to 3)
    k = int(np.argmin(sse[1:-2])) + 1
    slope = np.polyfit(np.arange(k + 2), inner[:k + 2], 1)[0]
    if -slope * (k + 1) < TAPER_MIN * after[k]:
        return 0, 1.0
    return k + 2 + trim, float(after[k] / max(end[k], 1e-9))


def _split_point(width: np.ndarray, trim: int = 0) -> tuple[int, float]:
    """Best single step of a piecewise-constant fit to ``width``: (index, ratio after/before).

    ``trim`` samples at each end are left out of the search: where the skeleton
    runs into an end (or into a spur at a compressed or blurred end), its width
    tapers to nothing, and that short, deep drop would outweigh the pipette's
    step.
    """
    trim = int(max(0, min(trim, (width.size - 6) // 2)))
    if trim:
        best, ratio = _split_point(width[trim:width.size - trim])
        return (best + trim, ratio) if best else (0, 1.0)
    n = width.size
    if n < 6:
        return 0, 1.0
    k = np.arange(2, n - 2)
    best = int(k[np.argmin(two_level_fit(width)[0][k - 1])])
    before = np.median(width[:best])
    after = np.median(width[best:])
    return best, float(after / max(before, 1e-9))


#: The base found where a narrower pipette's width steps up to the tube's.
PIPETTE_STEP = "pipette width step"
HOLDER_STEP = "holder width step (a holder wider than the tube)"
#: Base sources that a single frame cannot back up (see :mod:`pipeline.motion`).
AMBIGUOUS_BASE = "skeleton end nearest the border"
#: The base found where the structure meets the image border, no holder seen.
BORDER_BASE = "image border (no pipette step seen)"
#: The base found where the tube's edges begin, the structure's skeleton having
#: run on into a faint pipette before them (:func:`pipeline.track.initialise`).
EDGES_BEGIN = "where the tube's edges begin (the mask ran on into a pipette)"
#: Width of a holder (a clamp or a wide capillary the tube is pushed into)
#: over the tube's, at least. A tube's own sections differ by at most 25 % in
#: outer width (Table 1: 810 against 650 µm), so a step this large, with the
#: wide part running out of the frame, is no section joint.
HOLDER_RATIO = 1.5


def detect(image: np.ndarray, *, base_hint=None, base_end=None) -> Detection | None:
    """Find the tube, its base and a rough centreline in one frame.

    Parameters
    ----------
    image : (rows, cols) float32 ndarray
        The frame, values in [0, 1].
    base_hint : (col, row), optional
        Where the base is (e.g. from ``--base``), px.
    base_end : (col, row), optional
        A point near the base end (e.g. from the motion test): orients the
        tube, and the base is then found along it as without a hint.

    Returns
    -------
    Detection or None
        None when no elongated structure stands out from the background.
    """
    f = working_scale(image.shape)
    contrast = contrast_image(image, f)[0]
    det = _detect_at(image, f, base_hint, base_end, contrast)
    # a noisy frame: the tube, or one of a hollow tube's rims, stands out of the
    # noise only once more of it is averaged; each coarser scale averages 4x the
    # pixels. Tried only while what is found is nothing or a line a few pixels
    # wide, and kept where it finds a wider tube at least about as long
    for coarse in COARSER:
        if not ((det is None or det.half_width < THIN_HALF_WIDTH * f)
                and min(image.shape) / (coarse * f) >= COARSE_MIN_PX):
            break
        wide = _detect_at(image, coarse * f, base_hint, base_end)
        if wide is not None and (det is None or (
                det.half_width < OUTLINE_WIDER * wide.half_width
                and (wide.length >= COARSE_LENGTH * det.found_length or _rims_of(det, wide)))):
            det = wide
    if det is None:
        # nothing stands out at any scale: a faint tube's thin rims in noise may,
        # averaged along their own direction
        det = _detect_in(line_foreground(contrast), f, base_hint, base_end)
    return det


#: A thin structure is taken for the rims of a wider tube found coarser when at
#: least RIM_INSIDE of its points lie within RIM_REACH half-widths of that
#: tube's centreline, and half of them at least RIM_OFF half-widths off it.
RIM_INSIDE = 0.9
RIM_REACH = 1.25
RIM_OFF = 0.5


def _rims_of(thin: Detection, wide: Detection) -> bool:
    """Whether ``thin`` runs along the walls of ``wide``: a hollow tube's rims.

    A faint transparent tube shows only its rims at the working scale, and when
    no closing joins them (rims a few px thick, far apart) the skeleton runs up
    one rim, round the tip and back down the other: twice the tube's length, so
    the whole tube found coarser looks short beside it (a 28 px wide tube: 637
    px of rims for a 340 px tube).
    """
    # distance of each thin point to the wide centreline's nearest point
    # (paths of a few hundred points: the full distance matrix is small)
    off = np.abs(thin.path[:, None] - wide.path[None, :]).min(axis=1) / wide.half_width
    return bool(np.mean(off <= RIM_REACH) >= RIM_INSIDE and np.median(off) >= RIM_OFF)


def _detect_at(image: np.ndarray, f: int, base_hint, base_end,
               contrast: np.ndarray | None = None) -> Detection | None:
    """:func:`detect` at 1/``f`` resolution (``contrast``: the frame's
    :func:`contrast_image` there, if made already)."""
    if contrast is None:
        contrast, _ = contrast_image(image, f)
    # the tube by its own contrast, and by its outline: a transparent tube on a
    # mottled background, no darker than the darker patches, differs from them
    # mostly in its sharp edges
    det = _without_network(foreground, contrast, f, base_hint, base_end)
    outline = _without_network(outline_foreground, contrast, f, base_hint, base_end,
                               outline=True)
    return outline if _outline_wins(det, outline) else det


#: A foreground whose structures' skeletons (filled as a tube's) branch at
#: more than this many places is taken for a network of lines (printed grid
#: paper under the dish, a mesh) with the tube in it, not a tube with the odd
#: crossing and spur (12 at most on the 130 scenes of four renderers, but for
#: a reticle's crossed lines and scale bar, 15; grids: 21 and 82): its
#: thresholds are raised by each of NETWORK_RAISE in
#: turn until it is not, and the tube found there is kept where it is
#: tube-like (:data:`TUBE_MIN_HW`). Darker than the grid's lines, it stands out
#: of them; and the longest path through the network, which the tube joins,
#: runs along the lines. The thresholds are raised so too where no structure
#: of the plain mask is tube-like: the tube run into a wide region a little
#: darker or brighter than the background model (a meniscus's band across the
#: field, 110 px wide: the tube's 170 deg curl tracked along the band, median
#: error 64 deg; found at 4x, 0.3 deg), and the stubby structure kept where
#: nothing raised is tube-like either.
NETWORK_JUNCTIONS = 12
NETWORK_RAISE = (2.0, 4.0)


class _Network(Exception):
    """The foreground is a network of lines (:data:`NETWORK_JUNCTIONS`)."""


def _without_network(mask_of, contrast: np.ndarray, f: int, base_hint, base_end, *,
                     outline: bool = False) -> Detection | None:
    """:func:`_detect_in` on ``mask_of(contrast)`` (:func:`foreground` or
    :func:`outline_foreground`); where that is a network of lines, or holds
    nothing tube-like, on the mask at the first of :data:`NETWORK_RAISE`
    times its thresholds that is not a network, where the tube found there is
    tube-like."""
    plain = mask_of(contrast)
    stubby = None
    try:
        det = _detect_in(plain, f, base_hint, base_end, outline=outline, network_ok=False)
        if det is None or _tube_like(det):
            return det
        # no structure is tube-like: the tube may have merged into a wide
        # region the background model did not follow (the band either side of
        # a meniscus or a dish's edge, a brightness step across the field), of
        # less contrast than the tube
        stubby = det
    except _Network:
        pass
    for raised in NETWORK_RAISE:
        try:
            det = _detect_in(mask_of(contrast, high=6.0 * raised, low=3.0 * raised), f,
                             base_hint, base_end, outline=outline, network_ok=False)
        except _Network:
            continue
        if det is not None and _tube_like(det):
            return det
        break
    if stubby is not None:
        return stubby
    return _detect_in(plain, f, base_hint, base_end, outline=outline)


def _tube_like(det: Detection) -> bool:
    """Whether a structure found is tube-like: long for its width
    (:data:`TUBE_MIN_HW`)."""
    return det.found_length >= TUBE_MIN_HW * det.half_width


def _junctions(skel: np.ndarray) -> int:
    """The places where a skeleton branches (8-connected clusters of pixels
    with three or more neighbours)."""
    neighbours = ndi.convolve(skel.astype(np.uint8), np.ones((3, 3), np.uint8),
                              mode="constant") - 1
    return int(ndi.label(skel & (neighbours >= 3), structure=np.ones((3, 3)))[1])


def _outline_wins(det: Detection | None, outline: Detection | None) -> bool:
    """Whether the tube found by its outline is taken over the one found by
    its contrast (:data:`OUTLINE_LONGER`, :data:`OUTLINE_WIDER`,
    :data:`OUTLINE_SPAN`); lengths are what each found in the frame, not what
    was drawn to a given base."""
    if outline is None:
        return False
    if det is None:
        return True
    return (outline.found_length > OUTLINE_LONGER * det.found_length
            and (det.half_width < OUTLINE_WIDER * outline.half_width
                 or outline.found_length > OUTLINE_SPAN * det.found_length))


#: A structure found shorter than this many of its half-widths is stubby, not
#: tube-like: a tube is 32-96 of them long (Table 1: 8-12 mm by 0.25-0.5 mm;
#: 20 at least with a half-width a closing widened 1.6x), while a dark region
#: beyond a dish's wall, filling a corner of the frame, was 10 (its width as
#: large as its extent). The next structure is then looked at (as where a
#: given base lies off it: :func:`_off_the_base`), up to :data:`CANDIDATES`
#: in all, and the first one kept if none is better.
TUBE_MIN_HW = 12.0
CANDIDATES = 3


def _detect_in(mask: np.ndarray, f: int, base_hint, base_end, *,
               outline: bool = False, network_ok: bool = True) -> Detection | None:
    """:func:`detect` on a foreground ``mask`` at 1/``f`` resolution: the
    largest structure, or the next where that is stubby (:data:`TUBE_MIN_HW`)
    or lies off a given base (:func:`_off_the_base`). Raises :class:`_Network`
    where ``network_ok`` is False and the mask is a network of lines."""
    first = None
    for _ in range(CANDIDATES):
        det, filled = _detect_largest(mask, f, base_hint, base_end, outline=outline,
                                      network_ok=network_ok)
        network_ok = True
        if det is None:
            return first
        if _tube_like(det) and not _off_the_base(det, base_hint):
            return det
        first = first or det
        mask = mask & ~filled
    return first


def _off_the_base(det: Detection, base_hint) -> bool:
    """Whether the base given (``--base``, (col, row) px) lies over two of
    the structure's half-widths from it, off its line (:func:`_detect_largest`
    carries a structure on to a base near it or on its line): the user
    pointed at another structure, a fainter tube beside a larger one."""
    if base_hint is None:
        return False
    hint = complex(from_image(float(base_hint[0]), float(base_hint[1])))
    return float(np.min(np.abs(det.path - hint))) > 2.0 * det.half_width


def _detect_largest(mask: np.ndarray, f: int, base_hint, base_end, *, outline: bool = False,
                    network_ok: bool = True) -> tuple[Detection | None, np.ndarray | None]:
    """:func:`detect` on the largest structure of a foreground ``mask`` at
    1/``f`` resolution; and that structure, filled (None if there is none).
    Raises :class:`_Network` where ``network_ok`` is False and the filled
    mask's skeleton branches at more than :data:`NETWORK_JUNCTIONS` places."""
    if mask.sum() < 20:
        return None, None
    # an outline is the band of the edges' gradient: the closing that fills it
    # reaches its middle at a width under 2 radii (the discrete radii step past
    # half the gap), and the next radius still widens it as it rounds the ends'
    # corners; an outline no closing fills is a ring, not a tube
    filled, closing = fill_tube(fill_lumen(mask), **({"fill_ratio": 1.6, "plateau_ratio": 1.2}
                                                     if outline else {}))
    if outline and closing == 0:
        return None, None
    dist = ndi.distance_transform_edt(filled)
    skel = _skeleton(filled)
    if not network_ok and _junctions(skel) > NETWORK_JUNCTIONS:
        raise _Network
    radius = float(np.median(dist[skel])) if skel.any() else 0.0
    for cuts in range(CROSSINGS_MAX + 1):
        path_rc = longest_path(skel, border_bonus=2.0 * radius, margin=2.0 + radius, radius=dist)
        if path_rc.shape[0] < 5:
            return None, filled
        width = 2 * dist[path_rc[:, 0], path_rc[:, 1]]
        crossing = _crossing_branch(path_rc, width) if cuts < CROSSINGS_MAX else None
        if crossing is None:
            break
        # the path turned off the tube into a thinner structure crossing it:
        # that branch is cut away and the longest path looked for again
        skel = skel.copy()
        skel[crossing[:, 0], crossing[:, 1]] = False
    half_width = float(np.median(width)) / 2
    if path_rc.shape[0] * 1.0 < 3 * half_width:
        return None, filled  # a blob, not a tube
    # the skeleton stops about a radius short of each end: extend both ends
    path_rc = path_rc.astype(float)
    margin = 2.0 + half_width
    shape = filled.shape
    # a narrow stretch shorter than a tube width is the skeleton's taper into an
    # end, not a pipette
    min_pipette = max(3.0, 2.0 * half_width)
    trim = int(round(half_width))
    # orient base → tip
    orient = base_hint if base_hint is not None else base_end
    ambiguous = False
    held_rc = None
    if orient is not None:
        hint = np.array([orient[1], orient[0]], dtype=float) / f
        d_first = np.hypot(*(path_rc[0] - hint))
        d_last = np.hypot(*(path_rc[-1] - hint))
        reverse = d_last < d_first
        if base_hint is not None:
            # a base given inside the structure (the holder taken in on one
            # side of it): the holder's side is the one that runs to the
            # border, whichever end lies nearer (a tube curled past a turn
            # brings its tip back by the base: it was taken for the base end)
            k = int(np.argmin(np.hypot(*(path_rc - hint).T)))
            inside = min(k, path_rc.shape[0] - 1 - k) > 2 * half_width
            first_b = _touches_border(path_rc[0], shape, max(margin, 2.0 + width[0] / 2))
            last_b = _touches_border(path_rc[-1], shape, max(margin, 2.0 + width[-1] / 2))
            if inside and first_b != last_b:
                reverse = last_b
        if reverse:
            path_rc, width = path_rc[::-1], width[::-1]
    else:
        # (a wider holder's skeleton stops its own radius short of the border)
        first_b = _touches_border(path_rc[0], shape, max(margin, 2.0 + width[0] / 2))
        last_b = _touches_border(path_rc[-1], shape, max(margin, 2.0 + width[-1] / 2))
        if last_b and not first_b:
            path_rc, width = path_rc[::-1], width[::-1]
        elif first_b == last_b:
            # both ends at the border: a narrower pipette at one end says which is
            # held. Neither: the pipette does not show (it would come in from
            # outside the frame), and a narrower stretch is a section of the tube
            # (a thin-walled one is dimmer under fluorescence). Failing that, the
            # end nearer the border, for the motion test to confirm.
            split, ratio = _split_point(width, trim)
            in_line = _in_line(path_rc, split, ratio, half_width)
            # (a wider holder at the other end: the narrower stretch may be a
            # fibre or a scratch the tube's tip touches, in line with it)
            steps = _narrow_and_holder(width, split, ratio, trim, min_pipette) if first_b else None
            if steps is not None:
                held_rc = path_rc[np.minimum(steps, width.size - 1)]
            if (first_b and ratio < 1 / 1.15 and width.size - split > min_pipette
                    and in_line and held_rc is None):
                path_rc, width = path_rc[::-1], width[::-1]
            elif not (first_b and ratio > 1.15 and split > min_pipette and in_line
                      and held_rc is None):
                ambiguous = True
                if border_distance(path_rc[-1], shape) < border_distance(path_rc[0], shape):
                    path_rc, width = path_rc[::-1], width[::-1]
    # base: the pipette is narrower than the tube (a holder wider); find the width step
    split, ratio = _split_point(width, trim)
    if base_hint is not None:
        hint = np.array([base_hint[1], base_hint[0]], dtype=float) / f
        split = int(np.argmin(np.hypot(*(path_rc - hint).T)))
        source = "given (--base)"
    elif held_rc is not None:
        # a narrower stretch at one end, a wider holder at the other: the video tells
        split = 0
        source = AMBIGUOUS_BASE
    elif _pipette_step(path_rc, split, ratio, half_width, min_pipette, margin, shape):
        source = PIPETTE_STEP
    elif (ratio < 1 / HOLDER_RATIO and split > min_pipette
          and _touches_border(path_rc[0], shape, margin)):
        source = HOLDER_STEP
    elif _pipette_step(path_rc, *(tapered := _tapered_split(width, trim)), half_width,
                       min_pipette, margin, shape):
        split = tapered[0]
        source = PIPETTE_STEP
    elif ambiguous:
        split = 0
        source = AMBIGUOUS_BASE
    elif base_end is not None:
        split = 0
        source = "the static end over the video"
    else:
        split = 0
        source = BORDER_BASE
    tube = path_rc[split:]
    tube_width = width[split:]
    half_width = float(np.median(tube_width)) / 2
    pts = from_image(tube[:, 1] * f + (f - 1) / 2, tube[:, 0] * f + (f - 1) / 2)
    if pts.size < 4:
        return None, filled
    # smooth the pixel path a little: skeleton pixels zig-zag by ±0.5 px
    k = max(1, int(half_width / 2))
    if pts.size > 2 * k + 1:
        kern = np.ones(2 * k + 1) / (2 * k + 1)
        inner = np.convolve(pts, kern, mode="valid")
        pts = np.concatenate([pts[:1], inner, pts[-1:]])
    half_width_px = half_width * f
    lead = pts[min(len(pts) - 1, max(2, int(3 * half_width)))] - pts[0]
    base_angle = float(np.angle(lead))
    tip_dir = pts[-1] - pts[max(0, len(pts) - 1 - max(2, int(half_width)))]
    if abs(tip_dir) > 0:
        pts = np.append(pts, pts[-1] + 0.9 * half_width_px * tip_dir / abs(tip_dir))
    bridged = 0.0
    if base_hint is not None:
        # a tube that starts at the given base with no pipette in view: its
        # skeleton stops about a half-width short of that end, as of the tip's
        hint = complex(from_image(float(base_hint[0]), float(base_hint[1])))
        gap = pts[0] - hint
        if 1.0 < abs(gap) <= 2.0 * half_width_px:
            pts = np.concatenate([[hint], pts])
        elif abs(gap) > 1.0 and _bridges_to(gap, lead, float(np.abs(np.diff(pts)).sum())):
            # farther, but on the tube's line: a stretch of the tube the mask
            # missed (a relief fades where the tube runs along its shear; a
            # faint base section). The given base stands: the tube is carried
            # straight back to it, for the fit to bridge
            n = int(np.ceil(abs(gap)))
            pts = np.concatenate([hint + gap * np.arange(n) / n, pts])
            base_angle = float(np.angle(gap))
            bridged = abs(gap)
            source = (f"{source}; the tube's first {abs(gap):.0f} px did not stand out, "
                      "bridged straight to it")
        elif abs(gap) > 2.0 * half_width_px:
            source = (f"{source}; it lies {abs(gap):.0f} px from the tube found, off its line: "
                      "the base taken at the tube's nearest point")
    held_at = None if held_rc is None else tuple(
        complex(z) for z in from_image(held_rc[:, 1] * f + (f - 1) / 2,
                                       held_rc[:, 0] * f + (f - 1) / 2))
    return Detection(pts, complex(pts[0]), base_angle, half_width_px, source, bridged,
                     held_at), filled
