"""Section joints: where a tracked tube's curvature steps.

A shape-engineered microtube is made of sections with different walls, and
under pressure each section bends at its own curvature: the tangent angle
φ(s) has a kink (the curvature steps) at every joint. A cubic spline with
uniform knots cannot follow a kink; it rounds it off and rings, and the tip
angle comes out biased by degrees on a tube that curls past a turn (and by
tens of degrees on a tight curl with a short, nearly straight tip section).
With a triple knot at the joint (:func:`pipeline.centreline.knot_vector`)
the spline follows it.

When the sections are not known (no ``--sample``), the joints are found from
the frames, in two ways. The sections differ in their walls and so, most
often, in their outer width: a step in the measured width along the tube is
a joint, seen already on the first, straight frame (:func:`width_steps`,
then placed to a fraction of a pixel by :func:`place_steps`), or, when it is
too faint for one frame, in the mean width over several
(:class:`WidthRecord`, :func:`recorded_steps`). And once the tube bends, its
curvature steps show as kinks (:func:`find_joints`): a kink at u_c adds the
ramp (u − u_c)₊ to φ, and the joint is where adding that ramp to the current
fit lowers the residual of the measured edge midpoints most. The test is
linearised about the current fit, so one scan over all candidate positions
costs a few milliseconds, and a joint is kept only when the drop is large
against the midpoints' scatter (an F ratio): a tube whose curvature does not
step, or a frame too noisy to tell, gets none.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .centreline import Curve, basis_of, evaluate, jacobian, make_basis
from .profiles import END_NARROWING_HW
from .robust import robust_sd
from .steps import two_level_fit

#: F ratio (drop of the midpoints' residual sum of squares on adding the kink,
#: over their scatter per degree of freedom) above which a joint is kept.
#: Measured on rendered scenes of the eight catalogue samples: true joints
#: 25–70 and more (63 for sample 1's 0.67 joint at 306°), no joint (or a
#: second one within a width of a true joint) 5–17.
MIN_F = 20.0
#: A step in the tube's outer width (relative, and in units of its standard
#: error) from which it is a section joint (:func:`width_steps`). The eight
#: catalogue samples' outer widths step by 4–20 % at their joints. At z ≥ 8
#: the 8 % step of fluorescent sample 5 at 0.9, 1.4 widths from the tip, went
#: unseen (z ≈ 5; tip 16° off); at 5, 64 rendered scenes found no joint on a
#: single-section tube and one misplaced one (0.94 for 0.88) on a 6 px tube.
MIN_WIDTH_STEP = 0.015
MIN_WIDTH_Z = 5.0
#: The same, for a step the width record has already shown (a joint kept):
#: it is dropped only once it falls below this. A faint step hovers about
#: :data:`MIN_WIDTH_Z` as frames are added (fluorescent sample 5's 0.6 joint,
#: a 0.7 px step: z 5.3, 4.0, 5.1, 6.3 on 2–6 frames), and dropping it for
#: a frame leaves a curvature step the coarse spline of known joints cannot
#: follow.
HELD_WIDTH_Z = 3.0
#: F ratio of the fine spline against the coarser one of known joints
#: (:func:`spacing_f`) from which the coarse one is taken to miss a joint.
#: Measured on rendered scenes: 0.4–2.5 with every joint known; 3–53 with a
#: joint left out (growing with the bend).
MAX_SPACING_F = 4.0
#: At most this many joints are looked for.
MAX_JOINTS = 4


def find_joints(curve: Curve, u: np.ndarray, midpoints: np.ndarray, half_width: float, *,
                keep=(), min_f: float = MIN_F,
                max_joints: int = MAX_JOINTS) -> tuple[float, ...]:
    """The section joints a tube's measured shape shows: positions (fractions
    of the length) where it kinks away from a smooth curve.

    The search starts afresh from a fit to the midpoints with only the joints
    in ``keep`` (those of ``curve`` are not assumed), and adds one kink at a
    time, the one that lowers the residual most, while its F ratio is at
    least ``min_f``.

    Parameters
    ----------
    curve : Curve
        The fitted centreline (with or without joints).
    u : (M,) ndarray
        Fractions of the length at which the midpoints were measured.
    midpoints : (M,) complex ndarray
        Measured centres of the tube on normal profiles, px (y up); NaN
        where a profile found no tube.
    half_width : float
        The tube's half-width, px: candidates are a fifth of a width apart
        and at least a width from the ends and from each other.
    min_f : float
        Smallest F ratio for a joint to be kept.
    keep : tuple of float
        Joints known otherwise (e.g. seen as width steps): kept as they are.
    max_joints : int
        Most joints in all.

    Returns
    -------
    tuple of float
        All joints, ``keep`` and the ones found, increasing.
    """
    ok = np.isfinite(midpoints)
    u, pts = np.asarray(u, float)[ok], np.asarray(midpoints)[ok]
    keep = tuple(sorted(float(j) for j in keep))
    smooth = rewritten(curve, keep)
    k = smooth.coef.size
    if u.size < k + 10:
        return keep
    basis = basis_of(smooth)
    idx = _grid_index(u, basis)
    smooth = _fit_midpoints(smooth, basis, idx, pts)
    smp = evaluate(smooth, basis)
    normal = smp.normal[idx]
    resid = np.real(np.conj(normal) * (pts - smp.z[idx]))
    dz_da, _ = jacobian(smooth, basis, smp)
    columns = np.real(np.conj(normal)[:, None] * dz_da[idx])
    width_u = 2.0 * half_width / smooth.length
    cand = np.arange(width_u, 1.0 - width_u, 0.2 * width_u)
    if cand.size == 0:
        return keep
    # position change from a ramp (u − u_c)₊ added to φ, at the profiles
    mid_u = 0.5 * (basis.u[1:] + basis.u[:-1])
    ramp = np.maximum(mid_u[:, None] - cand[None, :], 0.0)
    shift = np.zeros((basis.n_grid, cand.size), dtype=complex)
    np.cumsum(1j * smp.chords[:, None] * ramp, axis=0, out=shift[1:])
    ramps = np.real(np.conj(normal)[:, None] * shift[idx])
    found: list[float] = []
    while len(found) + len(keep) < max_joints:
        q, _ = np.linalg.qr(columns)
        r_perp = resid - q @ (q.T @ resid)
        g_perp = ramps - q @ (q.T @ ramps)
        gg = np.einsum("ij,ij->j", g_perp, g_perp)
        drop = (g_perp.T @ r_perp) ** 2 / np.maximum(gg, 1e-300)
        dof = u.size - columns.shape[1] - 1
        rss = np.maximum(r_perp @ r_perp - drop, 1e-300)
        f_ratio = drop / (rss / dof)
        near = gg < 1e-12
        for j in found + list(keep):
            near |= np.abs(cand - j) < width_u
        f_ratio[near] = 0.0
        best = int(np.argmax(f_ratio))
        if f_ratio[best] < min_f:
            break
        found.append(float(cand[best]))
        columns = np.concatenate([columns, ramps[:, best:best + 1]], axis=1)
    return _polish(smooth, idx, pts, keep, sorted(found), width_u)


def _polish(smooth: Curve, idx, pts, keep, found: list[float],
            width_u: float) -> tuple[float, ...]:
    """Each found joint moved, within ±0.6 widths, to where the spline with
    triple knots fits the midpoints best: the ramp of the linear scan is not
    the spline's kink, and its best position strays by up to a width."""
    joints = list(found)
    for i in range(len(joints)):
        best = (np.inf, joints[i])
        for c in joints[i] + width_u * np.arange(-0.6, 0.61, 0.2):
            trial = sorted(joints[:i] + [float(c)] + joints[i + 1:] + list(keep))
            # (a width from either end, as the candidates are: polished up to
            # half a width from the tip, a 9 px last section of an independent
            # renderer's tube spun its end by 430 deg, the edges too few to hold it)
            if (not width_u <= c < 1.0 - width_u
                    or np.any(np.diff([0.0, *trial, 1.0]) < 0.5 * width_u)):
                continue
            rss = _midpoint_rss(rewritten(smooth, trial), idx, pts, iterations=2)
            best = min(best, (rss, float(c)))
        joints[i] = best[1]
    return tuple(sorted(joints + list(keep)))


def _grid_index(u: np.ndarray, basis) -> np.ndarray:
    """The grid nodes of ``basis`` nearest the fractions ``u``."""
    return np.clip(np.round(u * (basis.n_grid - 1)).astype(int), 0, basis.n_grid - 1)


def _midpoint_rss(curve: Curve, idx: np.ndarray, pts: np.ndarray, iterations: int = 4) -> float:
    """Residual sum of squares of the midpoints' normal offsets from ``curve``
    once fitted to them (:func:`_fit_midpoints`; ``idx`` on ``curve``'s grid)."""
    basis = basis_of(curve)
    curve = _fit_midpoints(curve, basis, idx, pts, iterations)
    smp = evaluate(curve, basis)
    return float(np.sum(np.real(np.conj(smp.normal[idx]) * (pts - smp.z[idx])) ** 2))


def _fit_midpoints(curve: Curve, basis, idx: np.ndarray, pts: np.ndarray,
                   iterations: int = 4) -> Curve:
    """Gauss–Newton fit of the spline to the midpoints' normal offsets (length
    kept; a light roughness penalty for spans no midpoint constrains)."""
    for _ in range(iterations):
        smp = evaluate(curve, basis)
        normal = smp.normal[idx]
        dz_da, _ = jacobian(curve, basis, smp)
        a = np.real(np.conj(normal)[:, None] * dz_da[idx])
        d = np.real(np.conj(normal) * (pts - smp.z[idx]))
        lhs = a.T @ a
        pen = 1e-4 * np.trace(lhs) / basis.roughness_trace
        # (a tiny ridge: a joint's knot between two profile-less stretches leaves
        # a direction that neither the data nor the roughness fixes)
        lhs = lhs + pen * basis.roughness + 1e-9 * np.trace(lhs) / lhs.shape[0] * np.eye(
            lhs.shape[0])
        rhs = a.T @ d - pen * basis.roughness @ curve.coef
        curve = curve.with_params(curve.coef + np.linalg.solve(lhs, rhs), curve.length)
    return curve


def same_joints(a, b, tolerance: float) -> bool:
    """Whether two joint sets are the same, each joint within ``tolerance``."""
    return len(a) == len(b) and all(abs(x - y) <= tolerance for x, y in zip(a, b, strict=True))


def rewritten(curve: Curve, joints, n_coef: int | None = None) -> Curve:
    """``curve`` rewritten with a triple knot at each of ``joints`` (instead of
    its own) and ``n_coef`` coefficients (default: its knot spacing kept, two
    coefficients per joint).

    The tangent angle φ(u) is projected onto the new spline by least squares
    on the curve's grid; base, base angle and length are kept.
    """
    joints = tuple(sorted(float(j) for j in joints))
    if n_coef is None:
        n_coef = curve.coef.size + 2 * (len(joints) - len(curve.joints))
    if joints == curve.joints and n_coef == curve.coef.size:
        return curve
    old = basis_of(curve)
    new = make_basis(n_coef, old.n_grid, joints)
    coef, *_ = np.linalg.lstsq(new.values, old.values @ curve.coef, rcond=None)
    return Curve(curve.base, curve.base_angle, curve.length, coef, joints)


def _width_scatter(w: np.ndarray) -> float:
    """The scatter of widths measured along the tube, px: from their
    differences (a step is one outlier there), robustly; at least 1e-3 px,
    which keeps a noise-free render finite."""
    return max(float(robust_sd(np.diff(w))) / np.sqrt(2), 1e-3)


def width_steps(u: np.ndarray, width: np.ndarray, half_width: float, length: float, *,
                min_rel: float = MIN_WIDTH_STEP, min_z: float = MIN_WIDTH_Z,
                held=(), held_z: float = HELD_WIDTH_Z,
                max_joints: int = MAX_JOINTS) -> tuple[float, ...]:
    """Joints seen as steps in the tube's measured outer width along its length.

    The sections of a shape-engineered tube differ in their walls, and so, most
    often, in their outer diameter: where the width steps is a joint, visible
    already on a straight tube (the curvature steps show only once it bends).

    Parameters
    ----------
    u : (M,) ndarray
        Fractions of the length of the width profiles.
    width : (M,) ndarray
        Measured outer width, px (NaN where not measured).
    half_width : float
        The tube's half-width, px: the means compared lie within two widths
        on either side of a candidate, and joints are two widths apart at least.
    length : float
        The tube's length, px.
    min_rel : float
        Smallest step kept, relative to the width.
    min_z : float
        Smallest step kept, in units of its standard error (from the widths'
        profile-to-profile scatter).
    held : tuple of float
        Joints already seen (e.g. on fewer frames): a step within a width of
        one is kept from ``held_z`` on.
    held_z : float
        Smallest step kept there, in standard errors.

    Returns
    -------
    tuple of float
        The joints, increasing (empty if the width does not step).
    """
    u, w = np.asarray(u, float), np.asarray(width, float)
    # (read as a step, a rounded end put a joint 1.3 widths from the tip of a
    # one-section tube, whose last stretch then curled 4-25 deg off)
    ok = np.isfinite(w) & (u <= 1.0 - END_NARROWING_HW * half_width / length)
    u, w = u[ok], w[ok]
    if w.size < 20:
        return ()
    sigma = _width_scatter(w)
    width_u = 2.0 * half_width / length
    reach = 2.0 * width_u
    # up to a width from the ends, the windows cut short there
    cand = np.arange(width_u, 1.0 - width_u, 0.2 * width_u)
    z = np.zeros(cand.size)
    for i, c in enumerate(cand):
        left = w[(u >= c - reach) & (u < c)]
        right = w[(u > c) & (u <= c + reach)]
        if left.size < 4 or right.size < 4:
            continue
        # means, not medians: a median's step is flat over a window's width
        # about the joint, a mean's peaks at it
        step = abs(np.mean(right) - np.mean(left))
        if step < min_rel * np.median(w):
            continue
        # (1.25: neighbouring profiles' widths are not quite independent)
        z[i] = step / (1.25 * sigma * np.sqrt(1 / left.size + 1 / right.size))
    bar = np.full(cand.size, max(float(min_z), 1e-12))
    for j in held:
        bar[np.abs(cand - j) < width_u] = max(min(held_z, min_z), 1e-12)
    # (a held joint that still steps is taken before a new one that steps more)
    z = np.where(z >= bar, z, 0.0) / bar
    found: list[float] = []
    while len(found) < max_joints and z.size and z.max() > 0:
        best = int(np.argmax(z))
        found.append(float(cand[best]))
        z[np.abs(cand - cand[best]) < 2 * width_u] = 0.0
    return tuple(sorted(found))


@dataclass
class WidthRecord:
    """The tube's outer width along its length, averaged over frames.

    A section's width is the same on every frame while its shape changes, so
    the mean over n frames has √n less scatter than one frame's: a width step
    too small to tell on one frame (a 2 px step on a noisy fluorescent tube,
    1 px scatter per profile) stands out after a few, and is placed to a
    pixel or two where one frame's placement strays by five. The widths are
    measured at fixed fractions of the length, about a pixel apart, on every
    frame added (measuring every third point on each frame, in turn, cost a
    third as much but lost two of sample 1's three joints on a noisy
    fluorescent scene: neighbours a pixel apart do not share their noise).

    Attributes
    ----------
    u : (K,) ndarray
        Where the widths are measured, fractions of the length.
    total, count : (K,) ndarray
        Sum and number of the widths measured there, px.
    frames : int
        Frames added.
    joints : tuple of float
        The joints seen as width steps so far (kept by the tracker).
    resolved : bool
        The record already tells every step that would be kept
        (:func:`record_resolves`): the tracker measures no more frames.
    """

    u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    total: np.ndarray = field(default_factory=lambda: np.zeros(0))
    count: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frames: int = 0
    joints: tuple[float, ...] = ()
    resolved: bool = False

    def start(self, length_px: float, max_points: int = 1000) -> None:
        """Set the points 1 px apart on a tube ``length_px`` long (further
        apart on a tube longer than ``max_points`` px), with nothing added."""
        n = int(np.clip(length_px, 16, max_points))
        self.u = (np.arange(n) + 0.5) / n
        self.total, self.count, self.frames = np.zeros(n), np.zeros(n), 0

    def add(self, width: np.ndarray) -> None:
        """Add one frame's widths at :attr:`u` (px, NaN where not measured)."""
        ok = np.isfinite(width)
        self.total[ok] += width[ok]
        self.count += ok
        self.frames += 1

    def mean(self) -> np.ndarray:
        """The mean width at :attr:`u`, px; NaN where measured on fewer than
        half the frames (its mean is noisier than the others')."""
        enough = self.count >= max(0.5 * self.frames, 1.0)
        return np.where(enough, self.total / np.maximum(self.count, 1.0), np.nan)


def _record_blocks(record: WidthRecord, half_width: float, length: float, spacing_px: float):
    """The record's mean (NaN over the last :data:`END_NARROWING_HW`
    half-widths: a rounded or blurred end narrows the tube there on every
    frame alike, which the mean would show as a step), and its means over
    blocks ``spacing_px`` long (the tracker's profile spacing, the scale
    :data:`MIN_WIDTH_Z` was measured on) with their centres."""
    mean = record.mean()
    mean[record.u > 1.0 - END_NARROWING_HW * half_width / length] = np.nan
    k = max(int(round(spacing_px * record.u.size / length)), 1)
    n = (record.u.size // k) * k
    ok = np.isfinite(mean[:n]).reshape(-1, k)
    sums = np.where(ok, mean[:n].reshape(-1, k), 0.0).sum(axis=1)
    blocks = np.where(ok.any(axis=1), sums / np.maximum(ok.sum(axis=1), 1), np.nan)
    return mean, record.u[:n].reshape(-1, k).mean(axis=1), blocks


def recorded_steps(record: WidthRecord, half_width: float, length: float,
                   spacing_px: float) -> tuple[float, ...]:
    """The joints a width record shows: found as steps (:func:`width_steps`)
    in its means over blocks ``spacing_px`` long (the tracker's profile
    spacing), then placed on the mean itself (:func:`place_steps`). The
    record's :attr:`~WidthRecord.joints` are held (:data:`HELD_WIDTH_Z`)."""
    mean, u_blocks, blocks = _record_blocks(record, half_width, length, spacing_px)
    coarse = width_steps(u_blocks, blocks, half_width, length, held=record.joints)
    if not coarse:
        return ()
    return place_steps(record.u, mean, coarse, half_width, length)


def record_resolves(record: WidthRecord, half_width: float, length: float, spacing_px: float,
                    *, min_rel: float = MIN_WIDTH_STEP, min_z: float = MIN_WIDTH_Z) -> bool:
    """Whether the record already tells every width step that
    :func:`width_steps` would keep: a step of ``min_rel`` stands ``min_z``
    standard errors out of its scatter. More frames then show nothing new
    (a smaller step is not kept however clear), and need not be measured."""
    _, u_blocks, blocks = _record_blocks(record, half_width, length, spacing_px)
    w = blocks[np.isfinite(blocks)]
    if w.size < 20:
        return False
    # as width_steps: windows of two widths on either side
    per_side = max(int(4.0 * half_width / (length / u_blocks.size)), 1)
    se = 1.25 * _width_scatter(w) * np.sqrt(2.0 / per_side)
    return bool(min_rel * np.median(w) >= min_z * se)


def step_windows(coarse, half_width: float, length: float, spacing_px: float = 1.0):
    """Fractions of the length ``spacing_px`` apart about each coarse joint
    (within 1.5 widths, and not past half-way to a neighbouring joint or to
    a width from an end), where :func:`place_steps` wants the width measured."""
    width_u = 2.0 * half_width / length
    bounds = [0.0, *coarse, 1.0]
    parts = []
    for i, c in enumerate(coarse):
        lo = max(c - 1.5 * width_u, 0.5 * (bounds[i] + c), width_u)
        hi = min(c + 1.5 * width_u, 0.5 * (c + bounds[i + 2]), 1.0 - width_u)
        parts.append(np.arange(lo, hi, spacing_px / length))
    return np.concatenate(parts) if parts else np.zeros(0)


def place_steps(u: np.ndarray, width: np.ndarray, coarse, half_width: float,
                length: float) -> tuple[float, ...]:
    """Each coarse joint (:func:`width_steps`, whose candidates are a fifth of
    a width apart) moved to where a two-level fit to the widths measured
    densely about it (:func:`step_windows`) splits best, within 0.75 widths.

    The tip angle is sensitive to where a joint is: a joint 0.005 of the
    length off (4 px on a 830 px tube) biased it by 0.4° at 300°.
    """
    width_u = 2.0 * half_width / length
    u = np.asarray(u, float)
    width = np.asarray(width, float)
    bounds = [0.0, *coarse, 1.0]
    out = []
    for i, c in enumerate(coarse):
        mine = ((u > 0.5 * (bounds[i] + c)) & (u < 0.5 * (c + bounds[i + 2]))
                & (np.abs(u - c) <= 1.5 * width_u) & np.isfinite(width))
        uu, ww = u[mine], width[mine]
        n = ww.size
        if n < 8:
            out.append(float(c))
            continue
        # residual sum of squares of the best two-level fit, for each split
        k = np.arange(3, n - 2)
        sse = two_level_fit(ww)[0][k - 1]
        split = 0.5 * (uu[k - 1] + uu[k])
        sse[np.abs(split - c) > 0.75 * width_u] = np.inf
        out.append(float(split[int(np.argmin(sse))]) if np.isfinite(sse).any() else float(c))
    return tuple(out)


def spacing_f(curve: Curve, fine_n_coef: int, u: np.ndarray, midpoints: np.ndarray) -> float:
    """F ratio of a finer spline (``fine_n_coef`` coefficients, the same joints)
    against ``curve`` on the measured edge midpoints: large when the coarse
    spline misses something the finer one follows (a curvature step at a
    joint not known)."""
    ok = np.isfinite(midpoints)
    u, pts = np.asarray(u, float)[ok], np.asarray(midpoints)[ok]
    extra = fine_n_coef - curve.coef.size
    if extra <= 0 or u.size < fine_n_coef + 10:
        return 0.0

    # both on the same grid (the curve's length sets it)
    idx = _grid_index(u, basis_of(curve))
    coarse = _midpoint_rss(curve, idx, pts)
    fine = _midpoint_rss(rewritten(curve, curve.joints, fine_n_coef), idx, pts)
    dof = u.size - fine_n_coef - 1
    return float((coarse - fine) / extra / max(fine / dof, 1e-300))
