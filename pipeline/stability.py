"""The numerical-stability matrix of the models (issue "Models" §7).

Every stiff or extreme case is a small function that evaluates the float64
models and compares them with an independent 50-digit reference computed with
mpmath from the textbook formulas (so the cancellation-free float forms of
:mod:`models.section` and :mod:`models.shape` are checked against the plain
forms, evaluated where cancellation cannot hurt):

* cross-section: ``A = π(R² − r²)``, ``y_c = πR²e/A``,
  ``I = πR⁴/4 + πR²(e − y_c)² − πr⁴/4 − πr²y_c²``;
* Euler–Bernoulli arcs (Eqs. 1–8): ``z += (e^{i(φ0+κd)} − e^{iφ0})/(iκ)``;
* line segments (Eqs. 9–12): strains, L_top, L_bot and the atan of Eq. 12
  as printed, positions by the geometric series
  ``ℓ e^{i(Φ+θ)} (e^{ijθ} − 1)/(e^{iθ} − 1)``.

Each case checks several quantities, each with its own tolerance; a case
passes when every check does, and its row reports the check closest to (or
furthest past) its tolerance. :func:`stability_cases` runs the whole matrix
(a few seconds) and :func:`write_stability` writes it as ``stability.csv``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import mpmath
import numpy as np
import pandas as pd

from models import (
    PAPER_SAMPLES,
    LSParams,
    Sample,
    Section,
    cross_section,
    eb_bend_angle,
    eb_shape,
    eb_shape_trapezoid,
    ls_bend_angle,
    ls_limit_shape,
    ls_shape,
    ls_shape_cumsum,
    segment_counts,
)

from .atomic import write_csv

#: Working precision of the references, decimal digits.
DPS = 50
STABILITY_FILE = "stability.csv"
COLUMNS = ["case", "passed", "worst_deviation", "tolerance", "worst_check", "n_checks",
           "detail", "seconds"]


# -- checks ---------------------------------------------------------------------------

@dataclass
class _Checks:
    """Named deviations with their tolerances, collected by one case."""

    items: list[tuple[str, float, float]] = field(default_factory=list)

    def add(self, name: str, deviation, tolerance: float):
        dev = float(deviation)
        # a NaN deviation must fail, so it is turned into +inf here
        self.items.append((name, dev if np.isfinite(dev) else np.inf, float(tolerance)))

    def finite(self, name: str, *arrays):
        """Count non-finite values (tolerance 0): no NaN or inf may leave a model."""
        self.add(f"{name} non-finite values",
                 sum(int(np.size(a) - np.isfinite(a).sum()) for a in arrays), 0.0)

    def worst(self) -> tuple[str, float, float]:
        def ratio(item):
            _, dev, tol = item
            if tol > 0:
                return dev / tol
            return np.inf if dev > 0 else 0.0
        return max(self.items, key=ratio)


@dataclass(frozen=True)
class CaseResult:
    """One row of the stability matrix."""

    case: str
    passed: bool
    worst_deviation: float
    tolerance: float
    worst_check: str
    n_checks: int
    detail: str
    seconds: float


def _run(name: str, func: Callable[[_Checks], str]) -> CaseResult:
    checks = _Checks()
    start = time.perf_counter()
    try:
        note = func(checks)
    except Exception as exc:  # a case that crashes is a failed row, not a crashed matrix
        checks.add(f"raised {type(exc).__name__}: {exc}", np.inf, 0.0)
        note = "case raised"
    seconds = time.perf_counter() - start
    check, dev, tol = checks.worst()
    passed = all(d <= t for _, d, t in checks.items)
    listed = "; ".join(f"{n} {d:.3g} (<= {t:.3g})" for n, d, t in checks.items)
    return CaseResult(name, passed, dev, tol, check, len(checks.items),
                      f"{note}. {listed}" if note else listed, seconds)


# -- 50-digit references ------------------------------------------------------------------

def _mp_section(r, tt, tb):
    """(d_e, I) of an eccentric annulus by the textbook formulas, at working precision."""
    r, tt, tb = (mpmath.mpf(float(v)) for v in (r, tt, tb))
    big_r = r + (tt + tb) / 2
    e = (tt - tb) / 2
    area = mpmath.pi * (big_r**2 - r**2)
    y_c = mpmath.pi * big_r**2 * e / area
    inertia = (mpmath.pi * big_r**4 / 4 + mpmath.pi * big_r**2 * (e - y_c) ** 2
               - mpmath.pi * r**4 / 4 - mpmath.pi * r**2 * y_c**2)
    return y_c, inertia


def _mp_lengths(sample: Sample):
    fracs = [mpmath.mpf(sec.fraction) for sec in sample.sections]
    total = mpmath.fsum(fracs)
    return [f / total * mpmath.mpf(sample.length_um) for f in fracs]


def mp_eb_points(sample: Sample, p: float, E: float, s_query) -> tuple[list, list]:
    """50-digit reference of the EB shape (textbook arcs).

    Parameters
    ----------
    sample : Sample
    p, E : float
        Pressure and Young's modulus, MPa.
    s_query : (M,) array_like
        Sorted arc lengths, µm.

    Returns
    -------
    z : list of mpmath.mpc
        Positions x + iy, µm.
    phi : list of mpmath.mpf
        Headings, rad.
    """
    with mpmath.workdps(DPS):
        r = mpmath.mpf(sample.r_in_um)
        kappas = []
        for sec in sample.sections:
            d_e, inertia = _mp_section(sample.r_in_um, sec.t_top_um, sec.t_bot_um)
            kappas.append(mpmath.pi * r**2 * d_e * mpmath.mpf(p) / (mpmath.mpf(E) * inertia))
        lengths = _mp_lengths(sample)
        starts, phis, zs = [mpmath.mpf(0)], [mpmath.mpf(0)], [mpmath.mpc(0)]
        for kap, length in zip(kappas, lengths, strict=True):
            zs.append(zs[-1] + _mp_arc(phis[-1], kap, length))
            phis.append(phis[-1] + kap * length)
            starts.append(starts[-1] + length)
        z_out, phi_out = [], []
        for s in s_query:
            s = mpmath.mpf(float(s))
            i = max(k for k in range(len(kappas)) if starts[k] <= s or k == 0)
            d = s - starts[i]
            z_out.append(zs[i] + _mp_arc(phis[i], kappas[i], d))
            phi_out.append(phis[i] + kappas[i] * d)
        return z_out, phi_out


def _mp_arc(phi0, kappa, d):
    if kappa == 0:
        return d * mpmath.expj(phi0)
    return (mpmath.expj(phi0 + kappa * d) - mpmath.expj(phi0)) / (1j * kappa)


def mp_ls_vertices(sample: Sample, p: float, params: LSParams, vertices) -> tuple[list, list]:
    """Vertices (mpc) and headings (mpf) of the LS chain at vertex indices ``vertices``.

    Vertex 0 is the base (carrying the first segment's heading); vertex k ≥ 1 is
    the end of segment k. Segment counts are the model's apportionment (an
    integer choice, not a numerical one).
    """
    counts = [int(c) for c in segment_counts(sample.fractions, params.n_segments)]
    with mpmath.workdps(DPS):
        mpf = mpmath.mpf
        walls = [sec.t_top_um for sec in sample.sections] + [sec.t_bot_um for sec in
                                                            sample.sections]
        lo, hi = params.t_ref_um if params.t_ref_um is not None else (min(walls), max(walls))
        e_min, e_max = mpf(float(params.eps_min)), mpf(float(params.eps_max))
        slope = (e_max - e_min) / (mpf(hi) - mpf(lo)) if hi > lo else mpf(0)

        def strain(t):
            return e_max - slope * (mpf(t) - mpf(lo))

        p_max = params.p_max_mpa if params.p_max_mpa is not None else sample.p_max_mpa
        ratio = mpf(p) / mpf(p_max)
        stretch = 1 + (mpf(float(params.elongation)) - 1) * ratio
        thetas, ells = [], []
        for sec, length, n in zip(sample.sections, _mp_lengths(sample), counts, strict=True):
            l_o = length / n
            tt, tb = mpf(sec.t_top_um), mpf(sec.t_bot_um)
            l_top = l_o * strain(tt) * tt / tb  # Eq. 10
            l_bot = l_o * strain(tb) * tt / tb  # Eq. 11
            d_e, _ = _mp_section(sample.r_in_um, tt, tb)
            gain = 1 + mpf(float(params.k_de_per_um)) * abs(d_e)
            thetas.append(mpmath.atan((l_bot - l_top) / mpf(sample.r_in_um)) * ratio * gain)
            ells.append(l_o * stretch)
        first = [0]
        heads, zs = [mpf(0)], [mpmath.mpc(0)]
        for theta, ell, n in zip(thetas, ells, counts, strict=True):
            zs.append(zs[-1] + _mp_run(heads[-1], theta, ell, n))
            heads.append(heads[-1] + n * theta)
            first.append(first[-1] + n)
        z_out, phi_out = [], []
        for k in vertices:
            k = int(k)
            if k == 0:
                z_out.append(mpmath.mpc(0))
                phi_out.append(thetas[0])
                continue
            i = max(m for m in range(len(counts)) if first[m] < k)
            j = k - first[i]
            z_out.append(zs[i] + _mp_run(heads[i], thetas[i], ells[i], j))
            phi_out.append(heads[i] + j * thetas[i])
        return z_out, phi_out


def _mp_run(phi0, theta, ell, j):
    """ℓ Σ_{m=1..j} e^{i(φ0 + mθ)} by the geometric series."""
    if theta == 0:
        return ell * j * mpmath.expj(phi0)
    return (ell * mpmath.expj(phi0 + theta) * (mpmath.expj(j * theta) - 1)
            / (mpmath.expj(theta) - 1))


def _dev_z(z_float, z_ref) -> float:
    """Largest |z − z_ref| over points, µm (differences taken at working precision)."""
    z_float = np.ravel(z_float)
    with mpmath.workdps(DPS):
        return float(max(abs(mpmath.mpc(complex(a)) - b) for a, b in zip(z_float, z_ref,
                                                                       strict=True)))


def _dev_phi(phi_float, phi_ref) -> float:
    with mpmath.workdps(DPS):
        return float(max(abs(mpmath.mpf(float(a)) - b) for a, b in zip(np.ravel(phi_float),
                                                                       phi_ref, strict=True)))


def _rel(value: float, ref) -> float:
    """|value − ref| / |ref| at working precision (absolute when ref is 0)."""
    with mpmath.workdps(DPS):
        diff = abs(mpmath.mpf(float(value)) - ref)
        return float(diff / abs(ref)) if ref != 0 else float(diff)


def _z(shape) -> np.ndarray:
    return shape.x_um + 1j * shape.y_um


def _eb_vs_reference(checks: _Checks, label: str, sample: Sample, p: float, E: float | None,
                     *, n_points: int = 101, angle_rtol: float = 1e-12,
                     pos_rtol: float = 1e-12) -> float:
    """Compare the EB closed form with the 50-digit arcs; return the reference angle, rad."""
    E = sample.E_mpa if E is None else E
    shape = eb_shape(sample, p, E_mpa=E, n_points=n_points)
    z_ref, phi_ref = mp_eb_points(sample, p, E, shape.s_um)
    checks.finite(f"{label} EB", shape.x_um, shape.y_um, shape.phi_rad)
    checks.add(f"{label} EB angle rel. err", _rel(float(eb_bend_angle(sample, p, E_mpa=E)),
                                                  phi_ref[-1]), angle_rtol)
    checks.add(f"{label} EB heading err/|angle|",
               _dev_phi(shape.phi_rad, phi_ref) / max(abs(float(phi_ref[-1])), 1e-300),
               angle_rtol)
    checks.add(f"{label} EB position err/L", _dev_z(_z(shape), z_ref) / sample.length_um,
               pos_rtol)
    return float(phi_ref[-1])


def _ls_vs_reference(checks: _Checks, label: str, sample: Sample, p: float, params: LSParams,
                     *, angle_rtol: float = 1e-12, pos_rtol: float = 1e-11) -> float:
    """Compare LS closed form (vertices and resampled tip) with the 50-digit chain."""
    n = params.n_segments
    verts = ls_shape(sample, p, params)
    picks = np.unique(np.r_[np.linspace(0, n, 41).round().astype(int),
                            np.cumsum(segment_counts(sample.fractions, n))])
    z_ref, phi_ref = mp_ls_vertices(sample, p, params, picks)
    checks.finite(f"{label} LS", verts.x_um, verts.y_um, verts.phi_rad)
    scale = max(abs(float(phi_ref[-1])), 1e-300)
    checks.add(f"{label} LS angle rel. err",
               _rel(float(ls_bend_angle(sample, p, params)), phi_ref[-1]), angle_rtol)
    checks.add(f"{label} LS heading err/|angle|", _dev_phi(verts.phi_rad[picks], phi_ref) / scale,
               angle_rtol)
    length = float(verts.length_um)  # deformed length (λ may stretch the tube)
    checks.add(f"{label} LS vertex err/L", _dev_z(_z(verts)[picks], z_ref) / length, pos_rtol)
    tip = ls_shape(sample, p, params, n_points=2)
    checks.add(f"{label} LS closed-form tip err/L",
               _dev_z(_z(tip)[..., -1:], z_ref[-1:]) / length, pos_rtol)
    return float(phi_ref[-1])


def _uniform(tt: float, tb: float, *, length=9000.0, r_in=235.0, E=1.4, p_max=0.14) -> Sample:
    return Sample("uniform", length, r_in, (Section(1.0, tt, tb),), E_mpa=E, p_max_mpa=p_max)


S1 = PAPER_SAMPLES[1]
P1 = 0.14


# -- the cases ----------------------------------------------------------------------------

def case_equal_walls(checks: _Checks) -> str:
    """t_t = t_b exactly: d_e = 0, straight, no division by zero."""
    sample = Sample("equal", 9000.0, 235.0, (Section(0.5, 100.0, 100.0),
                                            Section(0.5, 80.0, 80.0)), p_max_mpa=0.14)
    geo = sample.geometry
    checks.add("|d_e| µm", np.abs(geo.d_e_um).max(), 0.0)
    shapes = {"EB": eb_shape(sample, 0.3), "EB trapezoid": eb_shape_trapezoid(sample, 0.3,
                                                                              n_points=101),
              "LS": ls_shape(sample, 0.3, LSParams(k_de_per_um=1.0)),
              "LS resampled": ls_shape(sample, 0.3, LSParams(k_de_per_um=1.0), n_points=64),
              "LS limit": ls_limit_shape(sample, 0.3)}
    for name, sh in shapes.items():
        checks.finite(name, sh.x_um, sh.y_um, sh.phi_rad)
        checks.add(f"{name} max|y| µm", np.abs(sh.y_um).max(), 0.0)
        checks.add(f"{name} max|phi| rad", np.abs(sh.phi_rad).max(), 0.0)
    return "two sections with equal walls at p = 0.3 MPa (> p_max), k = 1/µm"


def case_near_equal_walls(checks: _Checks) -> str:
    """t_t/t_b within 1e-12 of 1: a tiny, correctly signed bend, relative accuracy kept."""
    tb = 100.0
    for sign, tt in (("+", tb * (1 + 1e-12)), ("-", tb * (1 - 1e-12))):
        sample = _uniform(tt, tb)
        d_e, inertia = _mp_section(sample.r_in_um, tt, tb)
        geo = cross_section(sample.r_in_um, tt, tb)
        checks.add(f"t_t/t_b=1{sign}1e-12 d_e rel. err", _rel(float(geo.d_e_um), d_e), 1e-12)
        checks.add(f"t_t/t_b=1{sign}1e-12 I rel. err", _rel(float(geo.inertia_um4), inertia),
                   1e-13)
        angle = _eb_vs_reference(checks, f"1{sign}1e-12", sample, 0.14, None)
        checks.add(f"1{sign}1e-12 EB angle sign wrong", float(np.sign(angle) != float(f"{sign}1")),
                   0.0)
        _ls_vs_reference(checks, f"1{sign}1e-12", sample, 0.14, LSParams(n_segments=1000,
                                                                       k_de_per_um=0.01))
    return "uniform tube, t_b = 100 µm, t_t = t_b(1 ± 1e-12), p = 0.14 MPa"


def case_very_stiff(checks: _Checks) -> str:
    """E = 1 GPa at a small pressure: bend ~1e-5°, relative accuracy ≤ 1e-10."""
    p = 1e-5
    angle = _eb_vs_reference(checks, "E=1 GPa", S1, p, 1000.0, angle_rtol=1e-10,
                             pos_rtol=1e-12)
    shape = eb_shape(S1, p, E_mpa=1000.0, n_points=101)
    z_ref, _ = mp_eb_points(S1, p, 1000.0, shape.s_um)
    # the deflection itself (y ~ 1e-3 µm) must keep its relative accuracy, not just |z|/L
    y_ref = np.array([float(z.imag) for z in z_ref])
    checks.add("E=1 GPa EB deflection rel. err",
               np.abs(shape.y_um - y_ref).max() / np.abs(y_ref).max(), 1e-10)
    return f"sample #1, p = 1e-5 MPa, E = 1000 MPa: bend {np.degrees(angle):.3g}°"


def case_very_soft(checks: _Checks) -> str:
    """Very soft tube at high pressure: ten full turns, angle and tip against the reference."""
    turns = 10.0
    E = S1.E_mpa * float(eb_bend_angle(S1, P1)) / (2 * np.pi * turns)
    angle = _eb_vs_reference(checks, "10 turns", S1, P1, E, n_points=401)
    checks.add("10 turns EB angle off 20π rad", abs(angle - 2 * np.pi * turns), 1e-9)
    p_max = P1 * float(ls_bend_angle(S1, P1, LSParams(p_max_mpa=P1))) / (2 * np.pi * turns)
    ls_angle = _ls_vs_reference(checks, "10 turns", S1, P1, LSParams(p_max_mpa=p_max))
    return (f"sample #1, p = 0.14 MPa: EB at E = {E:.4g} MPa ({np.degrees(angle):.1f}°), "
            f"LS N = 1000 with p_max = {p_max:.4g} MPa ({np.degrees(ls_angle):.1f}°)")


def case_segment_counts(checks: _Checks) -> str:
    """N from 1 to 10^6: closed-form headings vs the cumsum reference and the 50-digit chain."""
    one = _uniform(134.0, 67.0)
    runs = [(one, n) for n in (1, 2, 3, 10, 100, 10**3, 10**4, 10**5, 10**6)]
    runs += [(S1, n) for n in (4, 10, 10**3, 10**6)]
    for sample, n in runs:
        params = LSParams(n_segments=n, k_de_per_um=0.002, elongation=1.1)
        label = f"{sample.name} N={n}"
        closed = ls_shape(sample, P1, params)
        ref = ls_shape_cumsum(sample, P1, params)
        # The cumsum reference itself carries the a-priori error of recursive
        # summation, ≤ N·u·Σ|θ| (u = 2⁻⁵³): 1e-9 rad would be its own noise at
        # N = 10⁶ and 11 turns, so the bound (at least 1e-9) is its tolerance.
        # The closed form is held to 1e-12 rad against 50 digits instead.
        bound = max(1e-9, n * 2.0**-53 * abs(float(closed.bend_angle_rad)))
        checks.add(f"{label} heading |closed − cumsum| rad",
                   np.abs(closed.phi_rad - ref.phi_rad).max(), bound)
        picks = np.array([0, n // 3, n // 2, n])
        z_ref, phi_ref = mp_ls_vertices(sample, P1, params, picks)
        length = float(closed.length_um)
        checks.finite(label, closed.x_um, closed.y_um, closed.phi_rad)
        checks.add(f"{label} heading err vs 50 digits rad", _dev_phi(closed.phi_rad[picks],
                                                                     phi_ref), 1e-12)
        checks.add(f"{label} cumsum heading err vs 50 digits rad",
                   _dev_phi(ref.phi_rad[picks], phi_ref), bound)
        checks.add(f"{label} vertex err/L", _dev_z(_z(closed)[picks], z_ref) / length, 1e-11)
        tip = ls_shape(sample, P1, params, n_points=2)
        checks.add(f"{label} closed-form tip err/L", _dev_z(_z(tip)[-1:], z_ref[-1:]) / length,
                   1e-12)
    return ("uniform tube N = 1…10^6 and sample #1 N = 4…10^6 (about 11 turns), p = p_max, "
            "k = 0.002/µm, λ = 1.1; closed-form headings within 1e-12 rad of 50 digits, the "
            "cumsum reference within its summation bound N·u·|Φ|")


def case_tiny_section(checks: _Checks) -> str:
    """A section of fractional length 1e-6 between two ordinary ones."""
    sample = Sample("tiny", 9000.0, 235.0, (Section(0.5, 134.0, 67.0),
                                            Section(1e-6, 30.0, 200.0),
                                            Section(0.5 - 1e-6, 166.0, 72.0)), p_max_mpa=0.14)
    s_cut = sample.section_starts_um[1:]
    s = np.unique(np.r_[np.linspace(0, sample.length_um, 101), s_cut, s_cut + 1e-9])
    shape = eb_shape(sample, P1, s_um=s)
    z_ref, phi_ref = mp_eb_points(sample, P1, sample.E_mpa, s)
    checks.finite("EB", shape.x_um, shape.y_um, shape.phi_rad)
    checks.add("EB heading err rad", _dev_phi(shape.phi_rad, phi_ref), 1e-12)
    checks.add("EB position err/L", _dev_z(_z(shape), z_ref) / sample.length_um, 1e-12)
    for n in (3, 1000, 10**5):
        _ls_vs_reference(checks, f"N={n}", sample, P1, LSParams(n_segments=n))
    return "fractions (0.5, 1e-6, 0.5 − 1e-6), the tiny section bending the other way"


def case_zero_pressure(checks: _Checks) -> str:
    """p = 0 exactly: x = s and y = 0 bit for bit, angle 0."""
    params = LSParams(k_de_per_um=0.01, elongation=1.3)
    exact = {"EB": eb_shape(S1, 0.0), "EB trapezoid": eb_shape_trapezoid(S1, 0.0, n_points=101),
             "LS cumsum": ls_shape_cumsum(S1, 0.0, params),
             "LS limit": ls_limit_shape(S1, 0.0, params)}
    summed = {"LS vertices": ls_shape(S1, 0.0, params),
              "LS resampled": ls_shape(S1, 0.0, params, n_points=101)}
    for name, sh in {**exact, **summed}.items():
        checks.add(f"{name} max|y| µm", np.abs(sh.y_um).max(), 0.0)
        checks.add(f"{name} max|phi| rad", np.abs(sh.phi_rad).max(), 0.0)
    for name, sh in exact.items():
        checks.add(f"{name} max|x − s| µm", np.abs(sh.x_um - sh.s_um).max(), 0.0)
    for name, sh in summed.items():
        # x is a running sum of segment lengths, s a product: equal to rounding only
        checks.add(f"{name} max|x − s|/L", np.abs(sh.x_um - sh.s_um).max() / S1.length_um,
                   1e-13)
    checks.add("EB angle", abs(float(eb_bend_angle(S1, 0.0))), 0.0)
    checks.add("LS angle", abs(float(ls_bend_angle(S1, 0.0, params))), 0.0)
    return ("sample #1; y = 0 and angle = 0 bit-exact everywhere; x = s bit-exact for EB, EB "
            "trapezoid, LS cumsum and LS limit; the LS closed form sums segment lengths, so "
            "its x equals s to rounding (< 1e-13 L)")


def case_extreme_ratios(checks: _Checks) -> str:
    """Thickness ratios t_t/t_b = 1e-3 and 1e3."""
    notes = []
    for label, tt, tb in (("t_t/t_b=1e-3", 0.1, 100.0), ("t_t/t_b=1e3", 100.0, 0.1)):
        sample = _uniform(tt, tb)
        d_e, inertia = _mp_section(sample.r_in_um, tt, tb)
        geo = sample.geometry
        checks.add(f"{label} d_e rel. err", _rel(float(geo.d_e_um[0]), d_e), 1e-13)
        checks.add(f"{label} I rel. err", _rel(float(geo.inertia_um4[0]), inertia), 1e-13)
        eb = _eb_vs_reference(checks, label, sample, 0.14, None)
        ls = _ls_vs_reference(checks, label, sample, 0.14, LSParams(n_segments=1000))
        notes.append(f"{label}: EB {np.degrees(eb):.4g}°, LS {np.degrees(ls):.4g}°")
    return "uniform tube at 0.14 MPa; " + "; ".join(notes)


def case_over_curl(checks: _Checks) -> str:
    """Several turns: EB (both evaluators) and LS finite, unwrapped, and accurate."""
    p = 1.0
    eb = _eb_vs_reference(checks, "p=1 MPa", S1, p, None, n_points=401)
    trap = eb_shape_trapezoid(S1, p, n_points=10**4)
    checks.finite("EB trapezoid", trap.x_um, trap.y_um, trap.phi_rad)
    checks.add("EB trapezoid tip err/L",
               abs(complex(*trap.tip_um) - complex(*eb_shape(S1, p, n_points=2).tip_um))
               / S1.length_um, 1e-6)
    ls = _ls_vs_reference(checks, "p=1 MPa", S1, p, LSParams(n_segments=1000))
    limit = ls_limit_shape(S1, p, n_points=401)
    checks.finite("LS limit", limit.x_um, limit.y_um, limit.phi_rad)
    for name, sh in (("EB", eb_shape(S1, p, n_points=401)), ("LS", ls_shape(S1, p)),
                     ("LS limit", limit)):
        # unwrapped: headings never jump back by ~2π between neighbouring points
        checks.add(f"{name} largest heading decrease rad", max(0.0, -np.diff(sh.phi_rad).min()),
                   0.0)
    checks.add("EB turns < 2", max(0.0, 4 * np.pi - eb), 0.0)
    checks.add("LS turns < 2", max(0.0, 4 * np.pi - ls), 0.0)
    return (f"sample #1 at 1.0 MPa (7× p_max): EB {np.degrees(eb):.1f}°, "
            f"LS N = 1000 {np.degrees(ls):.1f}°")


def _bad_inputs() -> list[tuple[str, Callable[[], object]]]:
    nan, inf = float("nan"), float("inf")
    sec = (Section(1.0, 134.0, 67.0),)
    return [
        ("pressure_mpa", lambda: eb_shape(S1, nan)),
        ("pressure_mpa", lambda: eb_shape(S1, [0.1, inf])),
        ("pressure_mpa", lambda: eb_shape_trapezoid(S1, -inf, n_points=11)),
        ("pressure_mpa", lambda: ls_shape(S1, nan)),
        ("pressure_mpa", lambda: ls_bend_angle(S1, inf)),
        ("pressure_mpa", lambda: ls_limit_shape(S1, nan)),
        ("E_mpa", lambda: eb_shape(S1, 0.1, E_mpa=nan)),
        ("E_mpa", lambda: eb_bend_angle(S1, 0.1, E_mpa=inf)),
        ("s_um", lambda: eb_shape(S1, 0.1, s_um=[0.0, nan])),
        ("fraction", lambda: Section(nan, 134.0, 67.0)),
        ("t_top_um", lambda: Section(1.0, inf, 67.0)),
        ("t_bot_um", lambda: Section(1.0, 134.0, nan)),
        ("length_um", lambda: Sample("x", nan, 235.0, sec)),
        ("r_in_um", lambda: Sample("x", 9000.0, inf, sec)),
        ("E_mpa", lambda: Sample("x", 9000.0, 235.0, sec, E_mpa=nan)),
        ("p_max_mpa", lambda: Sample("x", 9000.0, 235.0, sec, p_max_mpa=inf)),
        ("r_in_um", lambda: cross_section(nan, 100.0, 50.0)),
        ("t_bot_um", lambda: cross_section(235.0, 100.0, [50.0, inf])),
        ("eps_min", lambda: LSParams(eps_min=nan)),
        ("eps_max", lambda: LSParams(eps_max=inf)),
        ("k_de_per_um", lambda: LSParams(k_de_per_um=nan)),
        ("elongation", lambda: LSParams(elongation=inf)),
        ("p_max_mpa", lambda: LSParams(p_max_mpa=nan)),
        ("t_ref_um", lambda: LSParams(t_ref_um=(nan, 200.0))),
        ("n_segments", lambda: LSParams(n_segments=inf)),
    ]


def case_rejects_nan_inf(checks: _Checks) -> str:
    """NaN or inf in any input raises ValueError naming the field."""
    cases = _bad_inputs()
    missed = []
    for fieldname, call in cases:
        try:
            call()
        except ValueError as exc:
            if fieldname not in str(exc):
                missed.append(f"{fieldname}: message {str(exc)!r}")
        except Exception as exc:  # noqa: BLE001 - any other exception is a miss too
            missed.append(f"{fieldname}: {type(exc).__name__}")
        else:
            missed.append(f"{fieldname}: accepted")
    checks.add("inputs not rejected with a ValueError naming the field", len(missed), 0.0)
    return f"{len(cases)} NaN/inf inputs" + (f"; missed: {', '.join(missed)}" if missed else "")


#: The matrix: case name → function filling its checks and returning a note.
CASES: dict[str, Callable[[_Checks], str]] = {
    "equal_walls": case_equal_walls,
    "near_equal_walls_1e-12": case_near_equal_walls,
    "very_stiff_E_1GPa": case_very_stiff,
    "very_soft_10_turns": case_very_soft,
    "segments_N_1_to_1e6": case_segment_counts,
    "tiny_section_1e-6": case_tiny_section,
    "zero_pressure": case_zero_pressure,
    "extreme_ratio_1e-3_1e3": case_extreme_ratios,
    "over_curl": case_over_curl,
    "rejects_nan_inf": case_rejects_nan_inf,
}


def run_case(name: str) -> CaseResult:
    """Run one case of the matrix by name."""
    if name not in CASES:
        raise ValueError(f"unknown stability case {name!r}; known: {', '.join(CASES)}")
    return _run(name, CASES[name])


def stability_cases() -> pd.DataFrame:
    """Run the whole stability matrix.

    Returns
    -------
    DataFrame
        One row per case, columns :data:`COLUMNS`: ``passed``, the
        ``worst_deviation`` and ``tolerance`` of the check nearest to failing
        (``worst_check`` names it; units in the name), ``detail`` listing every
        check, and ``seconds`` of run time.
    """
    rows = [run_case(name).__dict__ for name in CASES]
    return pd.DataFrame(rows, columns=COLUMNS)


def write_stability(out_dir, table: pd.DataFrame | None = None) -> Path:
    """Write ``stability.csv`` into ``out_dir`` (created if needed), atomically.

    Parameters
    ----------
    out_dir : str or Path
    table : DataFrame, optional
        A matrix already computed by :func:`stability_cases` (run afresh if None).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return write_csv(stability_cases() if table is None else table, out / STABILITY_FILE)
