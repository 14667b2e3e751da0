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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def sinc(x):
    """Unnormalised sinc, sin(x)/x, with sinc(0) = 1 exactly."""
    return np.sinc(np.asarray(x) / np.pi)


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
    turn = kappa * lengths  # total turn of each arc
    phi_start = np.cumsum(turn, axis=-1) - turn
    chord = lengths * sinc(0.5 * turn) * np.exp(1j * (phi_start + 0.5 * turn))
    z_start = np.cumsum(chord, axis=-1) - chord
    starts = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    idx = np.clip(np.searchsorted(starts, s_query, side="right") - 1, 0, len(lengths) - 1)
    d = s_query - starts[idx]
    k = kappa[..., idx]
    half = 0.5 * k * d
    phi0 = phi_start[..., idx]
    z = z_start[..., idx] + d * sinc(half) * np.exp(1j * (phi0 + half))
    return z, phi0 + k * d


def _wrap(theta):
    """Wrap angles to [−π, π]."""
    return theta - 2.0 * np.pi * np.round(theta / (2.0 * np.pi))


#: Below this |sin(θ/2)| the Dirichlet ratio sin(jθ/2)/sin(θ/2) is j to within
#: (jθ)²/24 ≈ 1e-290 relative; dividing by a subnormal would lose bits instead.
_TINY = 1e-150


def _dirichlet_parts(theta_w):
    """Per-section pieces of the ratio sin(jθ/2)/sin(θ/2): (θ/2, 1/sin(θ/2) or 0, flag)."""
    half = 0.5 * theta_w
    sin_half = np.sin(half)
    small = np.abs(sin_half) < _TINY
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
    turn = counts * theta
    phi_start = np.cumsum(turn, axis=-1) - turn
    half, inv, small = _dirichlet_parts(_wrap(theta))
    # whole section: ℓ e^{i(Φ + (n+1)θ/2)} sin(nθ/2)/sin(θ/2), θ wrapped in both factors
    ratio_full = np.sin(counts * half) * inv + counts * small
    chord = seg_length * ratio_full * np.exp(1j * (phi_start + (counts + 1) * half))
    z_start = np.cumsum(chord, axis=-1) - chord
    back = np.exp(-1j * phi_start)
    ph0 = phi_start[..., section]
    h = half[..., section]
    u = np.exp(1j * (ph0 + (j + 1) * h))  # e^{i(Φ + (j+1)θ/2)}
    ratio = np.sin(j * h) * inv[..., section] + j * small[..., section]
    # the partial segment points along e^{i(Φ + (j+1)θ)} = u² e^{−iΦ}
    z = z_start[..., section] + seg_length[..., section] * (
        ratio * u + frac * (u * u * back[..., section]))
    phi = ph0 + (j + 1) * theta[..., section]
    return z, phi


def segment_chain_vertices(theta, counts, seg_length, section, j):
    """Every vertex of a segment chain: exact headings, positions by summation.

    When all N + 1 vertices are wanted the output is O(N) anyway, and one
    complex exponential plus a running sum per vertex is the cheapest exact
    route. Headings are still the exact ``Φ_i + (j + 1)θ_i`` (never a running
    sum of tilts), so they carry no accumulated rounding; positions carry
    ~√N·ε relative rounding (1e-13 at N = 10⁶).

    Parameters are as for :func:`segment_chain`, with ``section`` and ``j``
    locating vertex k ≥ 1 at the end of segment k, and vertex 0 (the base) as
    (0, 0), carrying the first segment's heading.
    """
    theta = np.asarray(theta, dtype=float)
    turn = counts * theta
    phi_start = np.cumsum(turn, axis=-1) - turn
    phi = phi_start[..., section] + (j + 1) * theta[..., section]
    steps = seg_length[..., section[1:]] * np.exp(1j * phi[..., 1:])
    z = np.empty(phi.shape, dtype=complex)
    z[..., 0] = 0.0
    np.cumsum(steps, axis=-1, out=z[..., 1:])
    return z, phi
