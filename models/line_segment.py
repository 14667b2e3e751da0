"""Line-segment model of a shape-engineered microtube (paper §2.4, Eqs. 9–12).

The tube is cut into N straight segments, of equal initial length ``L_o`` within
each section; each section receives its share of N by length (at least one,
:func:`segment_counts`). Under pressure p every segment of section i is turned
from the previous one by the tilt (Eqs. 10–12)::

    L_top = L_o ε_top t_t/t_b,   L_bot = L_o ε_bot t_t/t_b
    θ_i   = atan((L_bot − L_top) / r_in) · (p / p_max) · (1 + k |d_e,i|)

and stretched to ``L_o (1 + (λ − 1) p/p_max)``. The wall strain falls linearly
with wall thickness, from ε_max at the thinnest wall of the sample to ε_min at
its thickest (or over a fixed reference range ``t_ref_um``, so that several
samples can share one set of parameters). Hence
``ε_bot − ε_top = (ε_max − ε_min)(t_t − t_b)/(t_hi − t_lo)``: the strains enter
the shape only through their difference, computed without subtracting two
nearly equal strains.

Readings of the paper's under-specified parts (documented choices):

* Eq. 9 as printed rotates points about the origin; a chain needs *accumulated
  headings*: segment m of section i points along ``Φ_i + m θ_i`` with
  ``Φ_i = Σ_{k<i} n_k θ_k`` and the base tangent along +x. Headings are built
  from these sums, never from repeated rotation-matrix products, so they stay
  exact to rounding even for N = 10⁶.
* ``L_o`` in Eqs. 10–11 is the initial length of one *segment* (the paper says
  "section"; with the section length the bend would grow without bound in N).
  With it, the bend converges as N grows: N·atan(c/N) → c, with an error ∝ N⁻²;
  below about 128 segments the atan saturates and the angle depends strongly on
  N, so always report N with fitted strains.
* ``p_o`` is the current pressure (the paper's symbol list says so).
* The unit of d_e in ``(1 + d_e)`` is not stated, so the scaling is
  ``(1 + k·|d_e|)`` with d_e in µm and k in 1/µm; k = 0 is no scaling and the
  paper's literal form is k = 1 µm⁻¹ (or 1e-3 µm⁻¹ if d_e was in mm). |d_e| is
  used so that the factor scales the magnitude of the tilt whichever wall is
  the thicker one; the sign of the bend comes from ``t_t − t_b``.
* As N → ∞, ``N·atan(c/N) → c`` and the chain becomes a chain of circular arcs
  whose curvature no longer depends on N (:func:`ls_limit_shape`):
  ``κ_i = (ε_max − ε_min)/(t_hi − t_lo) · (t_t − t_b)(t_t/t_b)/r_in · (p/p_max)(1 + k|d_e|)``
  per unit initial length. This is the reading we recommend for fitting
  (parameters then mean the same at any resolution); the finite-N form is kept
  because it is the paper's.
* The elongation factor λ (default 1, no elongation) stretches every segment by
  ``1 + (λ − 1) p/p_max``: the paper "simply multiplies the elongation factor".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import _validate
from .euler_bernoulli import arc_points
from .samples import Sample, cached_on
from .shape import Shape, segment_chain
from .tables import Runs, progression_runs, segment_chain_vertices

#: The paper's strain range (Liu et al., via §2.4).
DEFAULT_EPS_MIN = 0.5
DEFAULT_EPS_MAX = 1.2
DEFAULT_SEGMENTS = 1000


@dataclass(frozen=True)
class LSParams:
    """Parameters of the line-segment model.

    Every float field may also be an array; arrays broadcast with each other and
    with the pressure, so one call evaluates many parameter sets at once.

    Parameters
    ----------
    eps_min, eps_max : float or ndarray
        Strain at the thickest and at the thinnest wall (default 0.5, 1.2).
    k_de_per_um : float or ndarray
        d_e scaling k, 1/µm (default 0: no scaling).
    elongation : float or ndarray
        Elongation factor λ at p_max (default 1: segments keep their length).
    n_segments : int
        Total number of line segments N (default 1000).
    p_max_mpa : float or None
        Pressure of full tilt, MPa; None takes the sample's ``p_max_mpa``.
    t_ref_um : (float, float) or None
        Thickness range (thinnest, thickest), µm, over which ε falls from
        ε_max to ε_min; None uses the sample's own thinnest and thickest wall.
    """

    eps_min: float | np.ndarray = DEFAULT_EPS_MIN
    eps_max: float | np.ndarray = DEFAULT_EPS_MAX
    k_de_per_um: float | np.ndarray = 0.0
    elongation: float | np.ndarray = 1.0
    n_segments: int = DEFAULT_SEGMENTS
    p_max_mpa: float | None = None
    t_ref_um: tuple[float, float] | None = None

    def __post_init__(self):
        # Store validated float arrays so that evaluation never re-checks them.
        object.__setattr__(self, "eps_min", _validate.positive("eps_min", self.eps_min))
        object.__setattr__(self, "eps_max", _validate.positive("eps_max", self.eps_max))
        object.__setattr__(self, "k_de_per_um", _validate.finite("k_de_per_um", self.k_de_per_um))
        object.__setattr__(self, "elongation", _validate.positive("elongation", self.elongation))
        object.__setattr__(self, "n_segments",
                           _validate.positive_int("n_segments", self.n_segments))
        if self.p_max_mpa is not None:
            object.__setattr__(self, "p_max_mpa",
                               float(_validate.positive("p_max_mpa", self.p_max_mpa)))
        if self.t_ref_um is not None:
            lo, hi = (float(v) for v in _validate.positive("t_ref_um", self.t_ref_um))
            if not hi > lo:
                raise ValueError(f"t_ref_um must be (thinnest, thickest) with thinnest < "
                                 f"thickest, got {self.t_ref_um!r}")
            object.__setattr__(self, "t_ref_um", (lo, hi))

    def replace(self, **changes) -> LSParams:
        """A copy with some fields changed."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        fields.update(changes)
        return LSParams(**fields)


def segment_counts(fractions, n_segments: int) -> np.ndarray:
    """Share N segments among sections by length, each section getting at least one.

    Largest-remainder apportionment of the quotas ``N·f_i``, after giving each
    section one segment; deterministic (ties go to the earlier section).

    Raises
    ------
    ValueError
        If N is smaller than the number of sections.
    """
    f = np.asarray(fractions, dtype=float)
    n = _validate.positive_int("n_segments", n_segments)
    if n < f.size:
        raise ValueError(f"n_segments must be >= the number of sections ({f.size}), got {n}")
    quota = n * f / f.sum()
    counts = np.maximum(1, np.floor(quota)).astype(np.int64)
    while counts.sum() > n:  # minimums overshot: take from the most over-served
        over = np.where(counts > 1, counts - quota, -np.inf)
        counts[np.argmax(over)] -= 1
    short = n - counts.sum()
    if short:
        order = np.argsort(-(quota - counts), kind="stable")
        counts[order[:short]] += 1
    return counts


class _Layout(NamedTuple):
    """Per-sample constants of the chain for N segments (see :func:`_layout`)."""

    counts: np.ndarray  # (n,) int, segments per section
    seg0: np.ndarray  # (n,) initial segment length L_o per section, µm
    lever: np.ndarray  # (n,) (t_t − t_b)(t_t/t_b) L_o / r_in, µm
    abs_de: np.ndarray  # (n,) |d_e|, µm
    wall_range: tuple[float, float]  # thinnest and thickest wall of the sample, µm
    abs_de_max: float  # max |d_e|, µm
    counts_float: np.ndarray  # counts as floats (for θ @ n)
    runs: Runs  # table layout of the segments, for all-vertex shapes


def _layout(sample: Sample, n_segments: int) -> _Layout:
    """Per-sample constants of the chain for N segments (cached on the sample).

    The first five fields (counts, seg0, lever, abs_de, wall_range) are those
    of earlier versions; callers may index them by position.
    """
    return cached_on(sample, ("ls_layout", n_segments), lambda: _build_layout(sample, n_segments))


def _build_layout(sample: Sample, n_segments: int) -> _Layout:
    counts = segment_counts(sample.fractions, n_segments)
    seg0 = sample.section_lengths_um / counts  # initial segment length L_o per section
    tt, tb = sample.t_top_um, sample.t_bot_um
    # L_bot − L_top = L_o (ε_bot − ε_top) t_t/t_b with ε_bot − ε_top = slope·(t_t − t_b):
    # the lever is everything but the slope, divided by r_in as in Eq. 12
    lever = (tt - tb) * (tt / tb) * seg0 / sample.r_in_um
    abs_de = np.abs(sample.geometry.d_e_um)
    counts_float = counts.astype(float)
    for arr in (counts, seg0, lever, abs_de, counts_float):
        arr.flags.writeable = False
    walls = np.concatenate([tt, tb])
    return _Layout(counts, seg0, lever, abs_de, (float(walls.min()), float(walls.max())),
                   float(abs_de.max()), counts_float, progression_runs(counts))


def _strain_slope(wall_range, params: LSParams) -> np.ndarray:
    """−dε/dt, 1/µm, after checking that every wall strain is > 0."""
    t_min, t_max = wall_range
    lo, hi = params.t_ref_um if params.t_ref_um is not None else wall_range
    d_eps = params.eps_max - params.eps_min
    slope = d_eps / (hi - lo) if hi > lo else np.zeros_like(d_eps)
    if params.t_ref_um is not None:
        # ε is linear in t, so its extremes over the walls are at the thinnest/thickest
        # wall; over the sample's own range they are eps_max and eps_min, both > 0
        worst = np.minimum(params.eps_max - slope * (t_min - lo),
                           params.eps_max - slope * (t_max - lo))
        if (worst <= 0).any():
            raise ValueError(f"wall strain must be > 0, got {float(worst.min())!r} "
                             "(eps_min/eps_max/t_ref_um extrapolate below zero for this sample)")
    return slope


def _gain(layout: _Layout, params: LSParams):
    """The d_e scaling ``1 + k|d_e|`` per section, or None when k = 0 (no scaling)."""
    k = params.k_de_per_um
    if k.ndim == 0 and k == 0:
        return None
    # the smallest factor of each k is at the largest |d_e| (k < 0) or is ≥ 1 (k ≥ 0)
    worst = 1.0 + np.minimum(k, 0.0) * layout.abs_de_max
    if (worst <= 0).any():
        raise ValueError(f"1 + k_de_per_um*d_e must be > 0 in every section, got "
                         f"{float(np.min(worst))!r} (k_de_per_um too negative)")
    return 1.0 + k[..., None] * layout.abs_de


def _pressure_ratio(sample: Sample, pressure_mpa, params: LSParams):
    """p / p_max: a float for one plain number, else an array."""
    p = _validate.nonnegative_float("pressure_mpa", pressure_mpa)
    if p is None:
        p = _validate.nonnegative("pressure_mpa", pressure_mpa)
    p_max = params.p_max_mpa if params.p_max_mpa is not None else sample.p_max_mpa
    if p_max is None:
        raise ValueError(f"p_max_mpa is not set and sample {sample.name} has none")
    return p / p_max


def _tilts(sample: Sample, pressure_mpa, params: LSParams):
    """θ (..., n), the layout, and the stretch (a float, or an array of batch shape).

    The work of :func:`ls_tilts`, without broadcasting the stretch: for one
    plain pressure and scalar parameters everything but θ stays a Python float.
    """
    ratio = _pressure_ratio(sample, pressure_mpa, params)
    layout = _layout(sample, params.n_segments)
    slope = _strain_slope(layout.wall_range, params)
    gain = _gain(layout, params)
    theta = np.arctan(slope[..., None] * layout.lever)
    theta = theta * (ratio if isinstance(ratio, float) else ratio[..., None])
    if gain is not None:
        theta = theta * gain
    lam = params.elongation
    if lam.ndim == 0 and isinstance(ratio, float):
        stretch = 1.0 + (float(lam) - 1.0) * ratio
        bad = not stretch > 0
    else:
        stretch = 1.0 + (lam - 1.0) * ratio
        bad = (stretch <= 0).any()
    if bad:
        raise ValueError(f"segment stretch 1 + (elongation-1)*p/p_max must be > 0, got "
                         f"{float(np.min(stretch))!r}")
    if not isinstance(stretch, float) and stretch.shape != theta.shape[:-1]:
        # an elongation array may add batch axes (or lengths) that the tilt does not have
        batch = np.broadcast_shapes(theta.shape[:-1], stretch.shape)
        if batch != theta.shape[:-1]:
            theta = np.broadcast_to(theta, batch + theta.shape[-1:])
    return theta, layout, stretch


def _per_section(stretch):
    """``stretch`` ready to multiply a (..., n_sections) or (..., M) array."""
    return stretch if isinstance(stretch, float) else stretch[..., None]


def ls_tilts(sample: Sample, pressure_mpa, params: LSParams = LSParams()):
    """Tilt θ_i between neighbouring segments of each section, and their count.

    Returns
    -------
    theta : (..., n_sections) ndarray
        Tilt per segment in each section, rad (Eq. 12).
    counts : (n_sections,) int ndarray
        Segments per section.
    stretch : (...) ndarray
        Length factor of every segment, ``1 + (λ − 1) p/p_max``.
    """
    theta, layout, stretch = _tilts(sample, pressure_mpa, params)
    return theta, layout.counts, np.broadcast_to(stretch, theta.shape[:-1])


def _vertex_queries(sample: Sample, n_segments: int):
    """(section, j, s0) of every vertex: the base, then the end of each segment."""
    def build():
        counts, seg0 = _layout(sample, n_segments)[:2]
        k = np.arange(n_segments + 1)
        cum = np.cumsum(counts)
        section = np.searchsorted(cum, np.maximum(k, 1), side="left")
        j = np.maximum(k, 1) - 1 - (cum[section] - counts[section])
        frac = (k > 0).astype(float)
        s0 = sample.section_starts_um[section] + (j + frac) * seg0[section]
        s0[-1] = sample.length_um
        for arr in (section, j, s0):
            arr.flags.writeable = False
        return section, j, s0
    return cached_on(sample, ("ls_vertices", n_segments), build)


def _queries(sample: Sample, n_segments: int, n_points: int):
    """(section, j, frac, s0) locating ``n_points`` uniformly spaced points on the chain."""
    def build():
        counts, seg0 = _layout(sample, n_segments)[:2]
        s0 = np.linspace(0.0, sample.length_um, n_points)
        starts = sample.section_starts_um
        section = np.clip(np.searchsorted(starts, s0, side="right") - 1, 0, counts.size - 1)
        q = (s0 - starts[section]) / seg0[section]
        j = np.clip(np.floor(q).astype(np.int64), 0, counts[section] - 1)
        frac = np.clip(q - j, 0.0, 1.0)
        for arr in (section, j, frac, s0):
            arr.flags.writeable = False
        return section, j, frac, s0
    return cached_on(sample, ("ls_points", n_segments, n_points), build)


def _shape(z, s, phi) -> Shape:
    if s.shape != z.shape:
        s = np.broadcast_to(s, z.shape)
    return Shape(z.real, z.imag, s, phi)


def ls_shape(sample: Sample, pressure_mpa, params: LSParams = LSParams(), *,
             n_points: int | None = None) -> Shape:
    """Shape(s) of the line-segment model, in closed form.

    Parameters
    ----------
    sample : Sample
    pressure_mpa : float or array_like
        Pressure(s), MPa; broadcast with the array fields of ``params``.
    params : LSParams
    n_points : int or None
        None returns every vertex of the chain (N + 1 points: the exact
        polyline, cost O(N), segment vectors from small per-section tables of
        complex exponentials, :func:`models.tables.cis_runs`). An integer
        returns that many points uniformly spaced in arc length, evaluated by
        closed-form Dirichlet sums at a cost independent of N.

    Returns
    -------
    Shape
        ``phi_rad`` is the heading of the segment each point lies on (the
        base point carries the first segment's heading); the bend angle is the
        last segment's heading, Σ n_i θ_i.
    """
    theta, layout, stretch = _tilts(sample, pressure_mpa, params)
    factor = _per_section(stretch)
    seg_len = layout.seg0 * factor
    if n_points is None:
        section, j, s0 = _vertex_queries(sample, params.n_segments)
        z, phi = segment_chain_vertices(theta, layout.counts, seg_len, section, j,
                                        runs=layout.runs)
    else:
        n_points = _validate.positive_int("n_points", n_points, minimum=2)
        section, j, frac, s0 = _queries(sample, params.n_segments, n_points)
        z, phi = segment_chain(theta, layout.counts, seg_len, section, j, frac)
    return _shape(z, s0 * factor, phi)


def ls_shape_cumsum(sample: Sample, pressure_mpa, params: LSParams = LSParams()) -> Shape:
    """Reference evaluation by explicit accumulation over all N segments.

    Headings are the cumulative sum of the per-segment tilts and vertices the
    cumulative sum of the segment vectors. O(N) per shape; used to check
    :func:`ls_shape`.
    """
    theta, counts, stretch = ls_tilts(sample, pressure_mpa, params)
    tilt = np.repeat(theta, counts, axis=-1)
    heading = np.cumsum(tilt, axis=-1)
    seg_len = np.repeat(sample.section_lengths_um / counts, counts) * stretch[..., None]
    steps = seg_len * np.exp(1j * heading)
    batch = steps.shape[:-1]
    z = np.concatenate([np.zeros(batch + (1,), complex), np.cumsum(steps, axis=-1)], axis=-1)
    phi = np.concatenate([heading[..., :1], heading], axis=-1)
    s = np.concatenate([np.zeros(batch + (1,)), np.cumsum(seg_len, axis=-1)], axis=-1)
    return Shape(z.real, z.imag, s, phi)


def ls_bend_angle(sample: Sample, pressure_mpa, params: LSParams = LSParams()) -> np.ndarray:
    """Tip angle Σ n_i θ_i, rad, without evaluating the shape."""
    theta, layout, _ = _tilts(sample, pressure_mpa, params)
    return theta @ layout.counts_float


def ls_limit_shape(sample: Sample, pressure_mpa, params: LSParams = LSParams(), *,
                   n_points: int = 201) -> Shape:
    """The line-segment model in the limit N → ∞: a chain of circular arcs.

    Each section bends with constant curvature (per unit initial length)
    ``lim n_i θ_i / L_i``, independent of ``params.n_segments``; the whole
    shape is then scaled by the stretch ``1 + (λ − 1) p/p_max``.
    """
    theta, layout, stretch = _tilts(sample, pressure_mpa, params)
    n = _validate.positive_int("n_points", n_points, minimum=2)
    ratio = _pressure_ratio(sample, pressure_mpa, params)
    slope = _strain_slope(layout.wall_range, params)
    gain = _gain(layout, params)
    # n_i atan(c_i / n_i) → c_i with c_i = slope·lever_i·n_i, i.e. per unit length:
    kappa0 = slope[..., None] * (layout.lever * layout.counts / sample.section_lengths_um)
    kappa0 = kappa0 * (ratio if isinstance(ratio, float) else ratio[..., None])
    if gain is not None:
        kappa0 = kappa0 * gain
    kappa0 = np.broadcast_to(kappa0, theta.shape)
    z, phi, s0 = arc_points(sample, kappa0, n)
    factor = _per_section(stretch)
    return _shape(z * factor, s0 * factor, phi)
