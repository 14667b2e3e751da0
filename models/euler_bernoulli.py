"""Multi-segment Euler–Bernoulli beam model of a microtube (paper §2.3, Eqs. 1–8).

Each section i carries a constant bending moment from the pressure acting on the
void, offset by d_e,i from the neutral axis (Eq. 4), and so bends with constant
curvature::

    M_i = π r_in² d_e,i p,        κ_i = M_i / (E I_i)

With lengths in µm and p, E in MPa, κ comes out in 1/µm. The deviation angle
φ(s) = ∫ κ ds is piecewise linear in s (Eq. 1 summed over sections — the general
form of Eqs. 5–8 for any number of sections), and the shape is a chain of
circular arcs.

Two evaluators:

* :func:`eb_shape` — exact closed form (:func:`models.shape.arc_chain`; on a
  uniform grid of many points :func:`models.tables.arc_chain_grid`, the same
  sinc form with the complex exponentials from small per-section tables);
* :func:`eb_shape_trapezoid` — the paper's method, Eqs. 2–3 integrated by the
  cumulative trapezoidal rule on ``n`` points, so that its error can be measured
  against the exact form (it converges as n⁻²).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from . import _validate
from .samples import Sample, cached_on
from .shape import Shape, arc_chain
from .tables import arc_chain_grid, arc_grid

#: From this many uniformly spaced points on, shapes use the per-section
#: exponential tables of :func:`models.tables.arc_chain_grid` (fewer points:
#: the direct :func:`models.shape.arc_chain`, cheaper there). The choice
#: depends on the point count only, never on the batch size, so one pressure
#: alone and the same pressure inside a batch take the same formulas (equal
#: headings; positions equal to rounding).
_TABLE_MIN_POINTS = 16


def _unit_curvature(sample: Sample) -> np.ndarray:
    """κ_i per unit p/E, π r² d_e,i / I_i, 1/µm (cached on the sample)."""
    def build():
        geo = sample.geometry
        # κ = π r² d_e p / (E I): µm²·µm·MPa / (MPa·µm⁴) = 1/µm
        per_unit = np.pi * sample.r_in_um**2 * geo.d_e_um / geo.inertia_um4
        per_unit.flags.writeable = False
        return per_unit
    return cached_on(sample, "eb_unit_curvature", build)


def eb_curvatures(sample: Sample, pressure_mpa, *, E_mpa=None) -> np.ndarray:
    """Curvature of every section, 1/µm.

    Parameters
    ----------
    sample : Sample
    pressure_mpa : float or array_like
        Pressure(s), MPa (≥ 0).
    E_mpa : float or array_like, optional
        Young's modulus, MPa; defaults to ``sample.E_mpa``. Broadcasts with
        ``pressure_mpa`` (e.g. ``E[:, None]`` against ``p[None, :]``).

    Returns
    -------
    (..., n_sections) ndarray
        κ_i, 1/µm; positive bends counter-clockwise (towards the thicker top wall).
    """
    p = _validate.nonnegative_float("pressure_mpa", pressure_mpa)
    if p is None:
        p = _validate.nonnegative("pressure_mpa", pressure_mpa)
    E = sample.E_mpa if E_mpa is None else _validate.positive_float("E_mpa", E_mpa)
    if E is None:
        E = _validate.positive("E_mpa", E_mpa)
    compliance = p / E
    if isinstance(compliance, float):
        return compliance * _unit_curvature(sample)
    return compliance[..., None] * _unit_curvature(sample)


def eb_bend_angle(sample: Sample, pressure_mpa, *, E_mpa=None) -> np.ndarray:
    """Tip angle Σ κ_i L_i, rad, without evaluating the shape."""
    return eb_curvatures(sample, pressure_mpa, E_mpa=E_mpa) @ sample.section_lengths_um


def _grid(sample: Sample, n_points) -> np.ndarray:
    n = _validate.positive_int("n_points", n_points, minimum=2)
    return np.linspace(0.0, sample.length_um, n)


def arc_points(sample: Sample, kappa, n_points: int):
    """A chain of arcs along the sample's sections at ``n_points`` uniform points.

    Parameters
    ----------
    sample : Sample
    kappa : (..., n_sections) ndarray
        Curvature of each section, 1/µm.
    n_points : int
        Validated point count (≥ 2).

    Returns
    -------
    z : (..., n_points) complex ndarray
    phi : (..., n_points) ndarray
    s : (n_points,) ndarray
    """
    if n_points >= _TABLE_MIN_POINTS:
        grid = cached_on(sample, ("arc_grid", n_points),
                         lambda: arc_grid(sample.section_lengths_um, n_points))
        z, phi = arc_chain_grid(kappa, sample.section_lengths_um, grid)
        return z, phi, grid.s

    def build():
        s = _grid(sample, n_points)
        s.flags.writeable = False
        return s
    s = cached_on(sample, ("arc_s", n_points), build)
    z, phi = arc_chain(kappa, sample.section_lengths_um, s)
    return z, phi, s


def eb_shape(sample: Sample, pressure_mpa, *, E_mpa=None, n_points: int = 201,
             s_um=None) -> Shape:
    """Exact shape of the multi-segment Euler–Bernoulli model.

    Parameters
    ----------
    sample : Sample
    pressure_mpa : float or array_like
        Pressure(s), MPa; any shape, broadcast with ``E_mpa``.
    E_mpa : float or array_like, optional
        Young's modulus, MPa (default: the sample's).
    n_points : int, optional
        Number of points, uniformly spaced in arc length from base to tip.
    s_um : (M,) array_like, optional
        Explicit sorted arc lengths in [0, L_tot], µm, instead of ``n_points``.

    Returns
    -------
    Shape
        Batch shape = broadcast shape of the pressure and modulus.
    """
    kappa = eb_curvatures(sample, pressure_mpa, E_mpa=E_mpa)
    if s_um is None:
        n = _validate.positive_int("n_points", n_points, minimum=2)
        z, phi, s = arc_points(sample, kappa, n)
    else:
        s = _query(sample, s_um)
        z, phi = arc_chain(kappa, sample.section_lengths_um, s)
    return Shape(z.real, z.imag, s if s.shape == z.shape else np.broadcast_to(s, z.shape), phi)


def eb_shape_trapezoid(sample: Sample, pressure_mpa, *, E_mpa=None, n_points: int) -> Shape:
    """The paper's evaluation: Eqs. 2–3 by the cumulative trapezoidal rule.

    φ(s) is evaluated exactly on ``n_points`` uniformly spaced points and
    ``x = ∫cos φ ds``, ``y = ∫sin φ ds`` are integrated with the trapezoidal rule.
    """
    kappa = eb_curvatures(sample, pressure_mpa, E_mpa=E_mpa)
    s = _grid(sample, n_points)
    lengths = sample.section_lengths_um
    starts = sample.section_starts_um
    # φ(s) = Σ_i κ_i · clip(s − S_i, 0, L_i): exact, continuous, piecewise linear
    overlap = np.clip(s[:, None] - starts, 0.0, lengths)  # (M, n)
    phi = kappa @ overlap.T
    x = cumulative_trapezoid(np.cos(phi), s, axis=-1, initial=0.0)
    y = cumulative_trapezoid(np.sin(phi), s, axis=-1, initial=0.0)
    return Shape(x, y, np.broadcast_to(s, x.shape), phi)


def _query(sample: Sample, s_um) -> np.ndarray:
    s = _validate.finite("s_um", s_um)
    if s.ndim != 1 or s.size < 1:
        raise ValueError(f"s_um must be a 1-D array of arc lengths, got shape {s.shape}")
    tol = 1e-9 * sample.length_um
    if s.min() < -tol or s.max() > sample.length_um + tol:
        raise ValueError(f"s_um must lie in [0, {sample.length_um}] µm, got "
                         f"[{s.min()}, {s.max()}]")
    if np.any(np.diff(s) < 0):
        raise ValueError("s_um must be sorted from base to tip")
    return np.clip(s, 0.0, sample.length_um)
