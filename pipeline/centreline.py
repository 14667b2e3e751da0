"""The tracked centreline: tangent angle as a spline of normalised arc length.

A centreline is described, as in the best research trackers, by its tangent
angle along the arc length rather than by points::

    φ(u) = φ_base + Σ_k a_k B_k(u),      u = s / L ∈ [0, 1]
    z(u) = z_base + L ∫_0^u e^{iφ(v)} dv

with B_k clamped cubic B-splines whose first function is left out, so that
φ(0) = φ_base: the tube leaves the pipette along the pipette's axis. The tip
angle is then φ(1) − φ_base, unwrapped by construction, however many turns the
tube makes; and the shape has few, smooth parameters (10–24), which keeps a
fit stable where parts of the image are unusable (crossings, dust).

Positions are complex numbers ``z = x + iy`` in pixels with **y up**
(``x = col``, ``y = −row``): the one place where image (row, col) becomes
(x, y) is :func:`to_image` / :func:`from_image`.

The integral is a sum of chords on a fine grid: with φ linear between nodes,
each chord ``h·sinc(Δφ/2)·e^{i(φ_a+φ_b)/2}`` is exact, so a 2-px grid keeps
positions exact to ~1e-4 px on any smooth curve.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from scipy.interpolate import BSpline

from models.shape import sinc


def to_image(z):
    """Complex px (y up) → (col, row) float arrays."""
    return np.real(z), -np.imag(z)


def from_image(col, row):
    """(col, row) → complex px with y up."""
    return np.asarray(col, dtype=float) - 1j * np.asarray(row, dtype=float)


@dataclass(frozen=True)
class Basis:
    """Spline basis sampled on a uniform grid of u.

    Attributes
    ----------
    u : (Q,) ndarray
        Grid of normalised arc length, 0 … 1.
    values : (Q, K) ndarray
        B_k(u_q), without the first B-spline (so every column vanishes at u = 0).
    mid : (Q-1, K) ndarray
        Mean of the values at the two ends of every grid interval.
    roughness : (K, K) ndarray
        ∫₀¹ B_j''(u) B_k''(u) du: the quadratic form of ∫ φ''² du, which
        penalises changes of curvature and leaves circular arcs untouched.
    first_mid : (Q-1,) ndarray
        Interval means of the left-out first B-spline B_0 (the only one
        non-zero at u = 0), for fitting the base direction.
    roughness_first : (K+1,) ndarray
        ∫ B_0'' B_j'' du for j = 0 … K (B_0 first), to extend the roughness
        penalty when the base direction is fitted too.
    quad_u : (N,) ndarray
        Simpson nodes (three per knot span) on which the roughness is summed.
    quad_second : (N, K) ndarray
        B_k''(u) at those nodes, each row scaled by the square root of its
        Simpson weight: ``quad_second.T @ quad_second`` is ``roughness``, and
        a subset of the rows gives the roughness of part of the curve.
    roughness_trace : float
        Trace of ``roughness`` for the same knot spacing without joints: the
        scale the roughness penalty is weighed against (a triple knot's
        functions bend sharply and would inflate the trace, weakening the
        penalty everywhere else).
    """

    u: np.ndarray
    values: np.ndarray
    mid: np.ndarray
    roughness: np.ndarray
    first_mid: np.ndarray
    roughness_first: np.ndarray
    quad_u: np.ndarray
    quad_second: np.ndarray
    roughness_trace: float

    @property
    def n_coef(self) -> int:
        return self.values.shape[1]

    @property
    def n_grid(self) -> int:
        return self.u.size


def knot_vector(n_coef: int, joints: tuple[float, ...] = ()) -> np.ndarray:
    """Knots of a clamped cubic spline with ``n_coef`` free functions (B_0 left out).

    Without joints the interior knots are uniform. Each joint (a section
    joint, as a fraction of the length) gets a triple knot, so that φ stays
    continuous there but its slope, the curvature, may step, as it does
    where a tube's walls change; the other knots are spread uniformly within
    each section, at about the spacing they would have without joints. A
    joint costs two coefficients: ``n_coef`` must be ≥ 3 + 3·len(joints).
    """
    joints = tuple(float(j) for j in joints)
    if n_coef < 3 + 3 * len(joints):
        raise ValueError(f"n_coef must be >= {3 + 3 * len(joints)} with {len(joints)} "
                         f"joint(s), got {n_coef}")
    if any(not 0 < j < 1 for j in joints) or any(np.diff(joints) <= 0):
        raise ValueError(f"joints must be increasing fractions strictly inside (0, 1), "
                         f"got {joints}")
    n_spans = n_coef - 2 - 2 * len(joints)
    ends = np.array([0.0, *joints, 1.0])
    share = np.diff(ends) * n_spans
    spans = np.maximum(1, np.floor(share)).astype(int)
    while spans.sum() < n_spans:
        spans[np.argmax(share - spans)] += 1
    while spans.sum() > n_spans:
        spans[np.argmax(np.where(spans > 1, spans - share, -np.inf))] -= 1
    interior = []
    for i, (a, b) in enumerate(zip(ends[:-1], ends[1:], strict=True)):
        if i:
            interior += [a] * 3
        interior += list(np.linspace(a, b, spans[i] + 1)[1:-1])
    return np.concatenate([np.zeros(4), interior, np.ones(4)])


@lru_cache(maxsize=64)
def make_basis(n_coef: int, n_grid: int, joints: tuple[float, ...] = ()) -> Basis:
    """Clamped cubic B-spline basis with ``n_coef`` free functions on ``n_grid``
    nodes, with a triple knot at every joint (:func:`knot_vector`)."""
    if n_coef < 3:
        raise ValueError(f"n_coef must be >= 3, got {n_coef}")
    degree = 3
    knots = knot_vector(n_coef, joints)
    u = np.linspace(0.0, 1.0, n_grid)
    full = BSpline.design_matrix(u, knots, degree).toarray()
    values = np.ascontiguousarray(full[:, 1:])
    mid = 0.5 * (values[1:] + values[:-1])
    quad_u, quad_second = _second_derivatives(knots, n_coef)
    full_roughness = quad_second.T @ quad_second
    roughness = np.ascontiguousarray(full_roughness[1:, 1:])
    roughness_first = np.ascontiguousarray(full_roughness[0])
    quad_second = np.ascontiguousarray(quad_second[:, 1:])
    first_mid = 0.5 * (full[1:, 0] + full[:-1, 0])
    for arr in (u, values, mid, roughness, first_mid, roughness_first, quad_u, quad_second):
        arr.flags.writeable = False
    trace = (float(np.trace(roughness)) if not joints
             else make_basis(n_coef - 2 * len(joints), n_grid).roughness_trace)
    return Basis(u, values, mid, roughness, first_mid, roughness_first, quad_u, quad_second,
                 trace)


@lru_cache(maxsize=64)
def angle_spline(n_coef: int, joints: tuple[float, ...] = ()) -> BSpline:
    """The ``n_coef`` + 1 basis functions of :func:`make_basis` (B_0, which
    :class:`Basis` leaves out, first) as one vector-valued spline, for their
    values or derivatives anywhere: ``angle_spline(n, j)(u, nu=2)`` is
    (len(u), n + 1)."""
    return BSpline(knot_vector(n_coef, joints), np.eye(n_coef + 1), 3)


def basis_of(curve: Curve, n_grid: int | None = None) -> Basis:
    """The basis ``curve`` is written in, on ``n_grid`` nodes (default: ≤ 2 px apart)."""
    return make_basis(curve.coef.size, n_grid or n_grid_for(curve.length), curve.joints)


def _second_derivatives(knots: np.ndarray, n_coef: int):
    """Simpson nodes of every knot span and B_j''(u)·√weight at them, for all
    n_coef + 1 basis functions, B_0 first (second derivatives are piecewise
    linear, so Simpson's rule on each span is exact for ∫ B_j'' B_k'' du).

    B'' is evaluated inside each span, at its quarter points, and extended
    linearly to the span's ends: at a triple knot it jumps, and its value
    there belongs to neither side.
    """
    spans = np.unique(knots)
    a, b = spans[:-1], spans[1:]
    inner = np.concatenate([a + 0.25 * (b - a), a + 0.75 * (b - a)])
    at = BSpline(knots, np.eye(n_coef + 1), 3)(inner, nu=2)
    f1, f2 = at[:a.size], at[a.size:]
    # per span: the values at its start, middle and end
    second = np.stack([1.5 * f1 - 0.5 * f2, 0.5 * (f1 + f2), 1.5 * f2 - 0.5 * f1], axis=1)
    second = second.reshape(-1, n_coef + 1)
    nodes = np.stack([a, 0.5 * (a + b), b], axis=1).ravel()
    weights = ((b - a) / 6)[:, None] * np.array([1.0, 4.0, 1.0])
    return nodes, second * np.sqrt(weights.ravel())[:, None]


@dataclass(frozen=True)
class Curve:
    """A centreline: base point and direction, length and tangent-angle spline.

    Attributes
    ----------
    base : complex
        Base point (where the tube leaves the pipette), px, y up.
    base_angle : float
        Direction of the base tangent, rad, counter-clockwise from +x.
    length : float
        Arc length, px.
    coef : (K,) ndarray
        Spline coefficients of φ(u) − φ_base, rad.
    joints : tuple of float
        Section joints, as fractions of the length, where the curvature may
        step (:func:`knot_vector`); empty for a smooth tube.
    """

    base: complex
    base_angle: float
    length: float
    coef: np.ndarray
    joints: tuple[float, ...] = ()

    def with_params(self, coef, length) -> Curve:
        return replace(self, coef=np.asarray(coef, dtype=float), length=float(length))


@dataclass(frozen=True)
class CurveSample:
    """A curve evaluated on its basis grid.

    Attributes
    ----------
    z : (Q,) complex ndarray
        Points, px (y up), from base (q = 0) to tip.
    phi : (Q,) ndarray
        Tangent angle, rad (unwrapped).
    chords : (Q-1,) complex ndarray
        Chord vectors between consecutive points.
    """

    z: np.ndarray
    phi: np.ndarray
    chords: np.ndarray

    @property
    def tangent(self) -> np.ndarray:
        return np.exp(1j * self.phi)

    @property
    def normal(self) -> np.ndarray:
        """Left normal (counter-clockwise from the tangent)."""
        return 1j * np.exp(1j * self.phi)


def evaluate(curve: Curve, basis: Basis) -> CurveSample:
    """Points and tangent angles of ``curve`` on the grid of ``basis``."""
    phi = curve.base_angle + basis.values @ curve.coef
    h = curve.length / (basis.n_grid - 1)
    d_phi = np.diff(phi)
    chords = h * sinc(0.5 * d_phi) * np.exp(0.5j * (phi[1:] + phi[:-1]))
    z = np.empty(basis.n_grid, dtype=complex)
    z[0] = curve.base
    np.cumsum(chords, out=z[1:])
    z[1:] += curve.base
    return CurveSample(z, phi, chords)


def jacobian(curve: Curve, basis: Basis, sample: CurveSample):
    """Derivatives of the grid points with respect to the coefficients and the length.

    Returns
    -------
    dz_da : (Q, K) complex ndarray
        ∂z_q/∂a_k (the small derivative of sinc with respect to Δφ is left
        out: it changes the Gauss–Newton step direction by O(h²κ²) only).
    dz_dl : (Q,) complex ndarray
        ∂z_q/∂L.
    """
    d_chord = 1j * sample.chords[:, None] * basis.mid
    dz_da = np.zeros((basis.n_grid, basis.n_coef), dtype=complex)
    np.cumsum(d_chord, axis=0, out=dz_da[1:])
    dz_dl = (sample.z - curve.base) / curve.length
    return dz_da, dz_dl


def n_coef_for(length_px: float, width_px: float, *, widths_per_coef: float = 0.75) -> int:
    """Spline size: about one coefficient per ``widths_per_coef`` tube widths, 8 … 48.

    A tube made of sections of different walls has curvature steps at its
    section joints; knots closer than a width apart would only fit noise, much
    wider ones blur the steps and bias the tip angle (measured: 1.5 widths per
    knot gave +2° at a 306° bend, 0.75 widths +0.3°).
    """
    return int(np.clip(round(length_px / (widths_per_coef * max(width_px, 1.0))), 8, 48))


def n_grid_for(length_px: float) -> int:
    """Grid of ≤ 2 px spacing (chords are exact for linear φ within a step)."""
    return int(np.clip(np.ceil(length_px / 2.0), 64, 4096)) + 1


def fit_to_polyline(points, base_angle: float, *, n_coef: int, n_grid: int | None = None,
                    iterations: int = 4, joints: tuple[float, ...] = ()) -> Curve:
    """A curve through an ordered polyline (base first), e.g. a skeleton path.

    The base is the first point; the length is the polyline's; the spline is
    first fitted to the polyline's (unwrapped) chord angles, then refined by
    Gauss–Newton on the positions at matched arc-length fractions.

    Parameters
    ----------
    points : (M,) complex ndarray
        Ordered points, px (y up), M ≥ 2.
    base_angle : float
        Base tangent direction, rad.
    joints : tuple of float, optional
        Section joints, fractions of the length (:func:`knot_vector`).
    """
    joints = tuple(float(j) for j in joints)
    pts = np.asarray(points, dtype=complex)
    seg = np.abs(np.diff(pts))
    keep = np.concatenate([[True], seg > 1e-9])
    pts = pts[keep]
    seg = np.abs(np.diff(pts))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = float(s[-1])
    if length <= 0:
        raise ValueError("cannot fit a curve to a polyline of zero length")
    n_grid = n_grid or n_grid_for(length)
    basis = make_basis(n_coef, n_grid, joints)
    u_mid = 0.5 * (s[1:] + s[:-1]) / length
    ang = np.unwrap(np.angle(np.diff(pts)))
    # bring the unwrapped chord angles to the branch nearest the base angle
    ang += 2 * np.pi * np.round((base_angle - ang[0]) / (2 * np.pi))
    knots = knot_vector(n_coef, joints)
    design = BSpline.design_matrix(np.clip(u_mid, 0, 1), knots, 3).toarray()[:, 1:]
    # chord-length-weighted least squares, lightly regularised for empty knot spans
    weighted = design.T * (seg / seg.sum())
    coef = np.linalg.solve(weighted @ design + 1e-6 * np.eye(n_coef),
                           weighted @ (ang - base_angle))
    curve = Curve(complex(pts[0]), float(base_angle), length, coef, joints)
    target = np.interp(basis.u * length, s, pts.real) + 1j * np.interp(basis.u * length, s,
                                                                        pts.imag)
    for _ in range(iterations):
        smp = evaluate(curve, basis)
        dz_da, dz_dl = jacobian(curve, basis, smp)
        jac = np.concatenate([dz_da, dz_dl[:, None]], axis=1)
        jac_r = np.concatenate([jac.real, jac.imag])
        res = target - smp.z
        rhs = np.concatenate([res.real, res.imag])
        lhs = jac_r.T @ jac_r + 1e-6 * np.eye(n_coef + 1)
        step = np.linalg.solve(lhs, jac_r.T @ rhs)
        curve = curve.with_params(curve.coef + step[:-1], max(curve.length + step[-1], 1.0))
    return curve


def angle_coef(basis: Basis, turn: np.ndarray) -> np.ndarray:
    """Spline coefficients of the tangent's turn from the base, ``turn`` (rad,
    on ``basis``'s grid): least squares, the tip's angle exactly (only the
    last function reaches u = 1)."""
    coef, *_ = np.linalg.lstsq(basis.values, turn, rcond=None)
    coef[-1] = turn[-1]
    return coef


def cut_base(curve: Curve, s: float, base_angle: float | None = None,
             joints: tuple[float, ...] | None = None) -> Curve:
    """``curve`` from arc length ``s`` (px) on, with the same spline size and
    the joints beyond ``s`` (but those within 2 % of the new length of it;
    or ``joints``, fractions of the new length); for ``s < 0``, carried
    straight back by ``-s`` px along its base tangent first.

    Its base tangent is ``base_angle`` (rad; default: the curve's tangent at
    ``s``): a tube leaves its holder along the holder's axis, where a fit
    through both, whose curvature cannot step, has already turned a little.
    """
    n = int(np.ceil(curve.length / 0.25)) + 1
    basis = basis_of(curve, max(n, 2))
    smp = evaluate(curve, basis)
    arc, z, phi = basis.u * curve.length, smp.z, smp.phi
    length = curve.length - s
    if joints is None:
        joints = tuple(float((j * curve.length - s) / length) for j in curve.joints
                       if j * curve.length - s > 0.02 * length)
    basis = make_basis(curve.coef.size, basis_of(curve).n_grid, joints)
    if base_angle is None:
        base_angle = float(np.interp(s, arc, phi))   # (the base tangent's, for s < 0)
    coef = angle_coef(basis, np.interp(s + basis.u * length, arc, phi) - base_angle)
    base = (complex(np.interp(s, arc, z.real), np.interp(s, arc, z.imag)) if s >= 0
            else curve.base + s * np.exp(1j * curve.base_angle))
    return Curve(base, float(base_angle), length, coef, joints)


def resample(curve: Curve, spacing_px: float = 1.0):
    """Points at uniform arc-length spacing ≤ ``spacing_px``, base to tip.

    Returns
    -------
    s : (M,) ndarray
        Arc length, px.
    z : (M,) complex ndarray
        Points, px (y up).
    """
    n = int(np.ceil(curve.length / spacing_px)) + 1
    basis = basis_of(curve, max(n, 2))
    smp = evaluate(curve, basis)
    return basis.u * curve.length, smp.z


def tip_point(curve: Curve) -> complex:
    """The end of the centreline, px (y up), on the curve's exact grid."""
    return complex(evaluate(curve, basis_of(curve)).z[-1])
