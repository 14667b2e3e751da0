"""The planar shape of a bent microtube, and closed-form chain evaluators.

A :class:`Shape` holds points along the tube in the tube's own frame: base at the
origin, initial (pipette) tangent along +x, y to the left of it, lengths in µm.
Arrays may carry leading *batch* axes (e.g. parameter sets × pressures); the last
axis runs along the tube, from base to tip.

Two evaluators are shared by the models:

* :func:`arc_chain` — a chain of circular arcs of constant curvature (the exact
  solution of the piecewise Euler–Bernoulli model, Eqs. 1–8). Each arc uses
  ``z = d · sinc(κd/2) · exp(i(φ0 + κd/2))``, exact for κ = 0 and free of the
  cancellation of ``(sin(φ0 + κd) − sin φ0)/κ`` at small κd.
* :func:`segment_chain` — a chain of equal straight segments with a constant tilt
  between neighbours inside each section (the line-segment model, Eq. 9). Within
  a section headings form an arithmetic progression, so the position after ``j``
  segments is a Dirichlet-kernel sum,
  ``ℓ Σ_{m=1..j} e^{i(Φ+mθ)} = ℓ e^{i(Φ+(j+1)θ/2)} sin(jθ/2)/sin(θ/2)``,
  evaluated at a cost independent of the number of segments. θ is first wrapped
  to (−π, π], where ``sin(θ/2)/(θ/2)`` stays ≥ 2/π, so the ratio never divides by
  a small number.

When *every* point of a run of equally spaced points is wanted, the
evaluators of :mod:`models.tables` do the same from small per-section tables
of complex exponentials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def sinc(x):
    """Unnormalised sinc, sin(x)/x, with sinc(0) = 1 exactly."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        return np.sinc(x / np.pi)
    out = np.sin(x)
    zero = x == 0
    np.divide(out, x, out=out, where=~zero)
    if zero.any():
        out[zero] = 1.0
    return out


@dataclass(frozen=True)
class Shape:
    """Points along one or many tube shapes.

    Attributes
    ----------
    x_um, y_um : (..., M) ndarray of float
        Positions, µm, base at the origin, initial tangent along +x, y up.
    s_um : (..., M) ndarray of float
        Arc length along the (deformed) tube from the base, µm.
    phi_rad : (..., M) ndarray of float
        Tangent heading, rad, counter-clockwise from +x, unwrapped (continuous
        along the tube; it can exceed 2π for a tube curling past a full turn).
    """

    x_um: np.ndarray
    y_um: np.ndarray
    s_um: np.ndarray
    phi_rad: np.ndarray

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return self.x_um.shape[:-1]

    @property
    def n_points(self) -> int:
        return self.x_um.shape[-1]

    @property
    def bend_angle_rad(self) -> np.ndarray:
        """Tip heading relative to the base tangent, rad (unwrapped)."""
        return self.phi_rad[..., -1]

    @property
    def bend_angle_deg(self) -> np.ndarray:
        return np.degrees(self.bend_angle_rad)

    @property
    def tip_um(self) -> np.ndarray:
        """(..., 2) tip position, µm."""
        return np.stack([self.x_um[..., -1], self.y_um[..., -1]], axis=-1)

    @property
    def length_um(self) -> np.ndarray:
        """Deformed arc length of the whole tube, µm."""
        return self.s_um[..., -1]

    @property
    def points_um(self) -> np.ndarray:
        """(..., M, 2) stacked (x, y) positions, µm."""
        return np.stack([self.x_um, self.y_um], axis=-1)

    def __getitem__(self, index) -> Shape:
        """Index the batch axes (never the point axis)."""
        if not self.batch_shape:
            raise IndexError("a single shape has no batch axes to index")
        if not isinstance(index, tuple):
            index = (index,)
        index = (*index, slice(None))
        return Shape(*(np.broadcast_to(a, self.x_um.shape)[index]
                       for a in (self.x_um, self.y_um, self.s_um, self.phi_rad)))

    def placed(self, origin_xy, angle_rad: float, scale: float = 1.0):
        """Positions rotated by ``angle_rad``, scaled and shifted to ``origin_xy``.

        Returns
        -------
        (..., M, 2) ndarray
            The points in the target frame (e.g. an image frame in µm or px).
        """
        z = (self.x_um + 1j * self.y_um) * (scale * np.exp(1j * angle_rad))
        z = z + complex(origin_xy[0], origin_xy[1])
        return np.stack([z.real, z.imag], axis=-1)


def _exclusive_cumsum(a, axis: int = -1):
    """Running sum along ``axis`` *before* each element (first element 0).

    A direct exclusive sum, not ``cumsum(a) − a``: the latter cancels, giving
    starts off by the rounding of a much larger running total.
    """
    out = np.empty(a.shape, dtype=a.dtype)
    if axis in (-1, a.ndim - 1):
        out[..., 0] = 0
        np.cumsum(a[..., :-1], axis=-1, out=out[..., 1:])
        return out
    head = [slice(None)] * a.ndim
    head[axis] = slice(0, 1)
    out[tuple(head)] = 0
    tail, body = list(head), list(head)
    tail[axis], body[axis] = slice(1, None), slice(0, -1)
    np.cumsum(a[tuple(body)], axis=axis, out=out[tuple(tail)])
    return out


def arc_starts(kappa, lengths, *, axis: int = -1):
    """Heading and position at the start of every arc of a chain.

    Parameters
    ----------
    kappa : (..., n) ndarray
        Curvature of each arc, 1/µm.
    lengths : (n,) ndarray
        Arc lengths, µm (broadcast against ``kappa``; with ``axis=0``, shape
        (n, 1) for a points-major (n, shapes) ``kappa``).
    axis : int
        The axis running along the chain.

    Returns
    -------
    phi_start : ndarray
        Heading at the start of each arc, rad, shaped as ``kappa``.
    z_start : complex ndarray
        Position at the start of each arc, µm, shaped as ``kappa``.
    """
    turn = kappa * lengths  # total turn of each arc
    phi_start = _exclusive_cumsum(turn, axis=axis)
    half = 0.5 * turn
    chord = (lengths * sinc(half)) * np.exp(1j * (phi_start + half))
    return phi_start, _exclusive_cumsum(chord, axis=axis)


def arc_chain(kappa, lengths, s_query):
    """Evaluate a chain of circular arcs at arc lengths ``s_query``.

    Parameters
    ----------
    kappa : (..., n) ndarray
        Curvature of each arc, 1/µm (positive bends counter-clockwise).
    lengths : (n,) ndarray
        Arc lengths, µm (> 0).
    s_query : (M,) ndarray
        Sorted arc lengths in [0, sum(lengths)] at which to evaluate, µm.

    Returns
    -------
    z : (..., M) complex ndarray
        Positions x + iy, µm.
    phi : (..., M) ndarray
        Headings, rad.
    """
    kappa = np.asarray(kappa, dtype=float)
    phi_start, z_start = arc_starts(kappa, lengths)
    starts = _exclusive_cumsum(np.asarray(lengths, dtype=float))
    idx = np.clip(np.searchsorted(starts, s_query, side="right") - 1, 0, len(lengths) - 1)
    d = s_query - starts[idx]
    k = kappa.take(idx, axis=-1)
    phi0 = phi_start.take(idx, axis=-1)
    half = 0.5 * k * d
    z = z_start.take(idx, axis=-1) + (d * sinc(half)) * np.exp(1j * (phi0 + half))
    return z, phi0 + k * d


def _wrap(theta):
    """Wrap angles to [−π, π]."""
    if np.abs(theta).max() < np.pi:  # round(θ/2π) = 0: nothing to wrap (the usual case)
        return theta
    return theta - 2.0 * np.pi * np.round(theta / (2.0 * np.pi))


#: Below this |sin(θ/2)| the Dirichlet ratio sin(jθ/2)/sin(θ/2) is j to within
#: (jθ)²/24 ≈ 1e-290 relative; dividing by a subnormal would lose bits instead.
_TINY = 1e-150


def _dirichlet_parts(theta_w):
    """Per-section pieces of the ratio sin(jθ/2)/sin(θ/2): (θ/2, 1/sin(θ/2) or 0, flag).

    The flag marks |sin(θ/2)| < 1e-150, where the ratio is taken as j; it is
    None when no section is flagged (then the caller can skip that term).
    """
    half = 0.5 * theta_w
    sin_half = np.sin(half)
    small = np.abs(sin_half) < _TINY
    if not small.any():
        return half, 1.0 / sin_half, None
    inv = np.where(small, 0.0, 1.0 / np.where(small, 1.0, sin_half))
    return half, inv, small


def segment_chain(theta, counts, seg_length, section, j, frac):
    """Evaluate a chain of straight segments at given (section, segment, fraction).

    Segment ``m`` (1-based) of section ``i`` has heading
    ``Φ_i + m·θ_i`` with ``Φ_i = Σ_{k<i} n_k θ_k`` (base tangent along +x).

    Parameters
    ----------
    theta : (..., n) ndarray
        Tilt of every segment of each section relative to the previous segment, rad.
    counts : (n,) int ndarray
        Number of segments n_i in each section.
    seg_length : (..., n) ndarray
        Deformed length of one segment in each section, µm.
    section, j : (M,) int ndarray
        For each query, its section and the number of complete segments of that
        section before it (0 ≤ j ≤ n_i − 1).
    frac : (M,) ndarray
        Fraction in [0, 1] of segment ``j + 1`` travelled.

    Returns
    -------
    z : (..., M) complex ndarray
        Positions x + iy, µm.
    phi : (..., M) ndarray
        Heading of the segment each query lies on, rad.
    """
    theta = np.asarray(theta, dtype=float)
    phi_start = _exclusive_cumsum(counts * theta)
    half, inv, small = _dirichlet_parts(_wrap(theta))
    # whole section: ℓ e^{i(Φ + (n+1)θ/2)} sin(nθ/2)/sin(θ/2), θ wrapped in both factors
    ratio_full = np.sin(counts * half) * inv
    if small is not None:
        ratio_full += counts * small
    lead = seg_length * np.exp(1j * phi_start)  # ℓ e^{iΦ}
    z_start = _exclusive_cumsum(lead * (ratio_full * np.exp(1j * ((counts + 1) * half))))
    # j segments and a fraction of the next: with v = e^{i(j+1)θ/2},
    # ℓ e^{iΦ} v (sin(jθ/2)/sin(θ/2) + frac·v)   (the partial one points along e^{iΦ} v²)
    jf = np.asarray(j, dtype=float)  # exact: j < 2⁵³
    jp1 = jf + 1.0
    h = half.take(section, axis=-1)
    v = np.exp(1j * (jp1 * h))
    ratio = np.sin(jf * h) * inv.take(section, axis=-1)
    if small is not None:
        ratio += jf * small.take(section, axis=-1)
    z = v * (ratio + frac * v)
    z *= lead.take(section, axis=-1)
    z += z_start.take(section, axis=-1)
    phi = phi_start.take(section, axis=-1) + jp1 * theta.take(section, axis=-1)
    return z, phi
