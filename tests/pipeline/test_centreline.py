import numpy as np
import pytest

from pipeline.centreline import (
    Curve,
    evaluate,
    fit_to_polyline,
    jacobian,
    knot_vector,
    make_basis,
    n_grid_for,
    resample,
    tip_point,
)
from tests.pipeline.synthetic import arc_axis


@pytest.mark.parametrize("kappa", [0.0, 1 / 400, -1 / 150, 1 / 60])
def test_fit_to_polyline_reproduces_an_arc(kappa):
    z, phi = arc_axis(100 - 300j, 0.4, 700.0, kappa)
    curve = fit_to_polyline(z, 0.4, n_coef=12)
    basis = make_basis(12, n_grid_for(curve.length))
    smp = evaluate(curve, basis)
    # (the input polyline of 2001 chords is itself ~(hκ)²L/24 ≈ 2e-3 px short)
    assert curve.length == pytest.approx(700.0, abs=5e-3)
    z_true, phi_true = arc_axis(100 - 300j, 0.4, 700.0, kappa, n=basis.n_grid)
    assert np.abs(smp.z - z_true).max() < 2e-3
    assert smp.phi[-1] == pytest.approx(phi_true[-1], abs=1e-5)  # unwrapped, not mod 2π


def test_multi_turn_angle_is_unwrapped():
    kappa = 2.6 * 2 * np.pi / 900.0  # 2.6 turns
    z, phi = arc_axis(0j, 0.0, 900.0, kappa)
    curve = fit_to_polyline(z, 0.0, n_coef=20)
    assert curve.coef[-1] == pytest.approx(2.6 * 2 * np.pi, abs=1e-4)
    assert tip_point(curve) == pytest.approx(z[-1], abs=1e-3)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    curve = Curve(10 - 5j, 0.3, 500.0, rng.normal(0, 0.5, 10))
    basis = make_basis(10, n_grid_for(curve.length))
    smp = evaluate(curve, basis)
    dz_da, dz_dl = jacobian(curve, basis, smp)
    eps = 1e-6
    for k in (0, 4, 9):
        c2 = curve.with_params(curve.coef + eps * np.eye(10)[k], curve.length)
        fd = (evaluate(c2, basis).z - smp.z) / eps
        assert np.abs(fd - dz_da[:, k]).max() < 1e-3 * np.abs(fd).max() + 1e-6
    c3 = curve.with_params(curve.coef, curve.length + 1e-4)
    assert np.abs((evaluate(c3, basis).z - smp.z) / 1e-4 - dz_dl).max() < 1e-6


def test_roughness_vanishes_on_arcs_and_not_on_wiggles():
    basis = make_basis(12, 301)
    z, _ = arc_axis(0j, 0.0, 600.0, 1 / 200)
    arc = fit_to_polyline(z, 0.0, n_coef=12, n_grid=301)
    wiggle = arc.with_params(arc.coef + 0.1 * np.sin(np.arange(12)), arc.length)
    assert arc.coef @ basis.roughness @ arc.coef < 1e-6
    assert wiggle.coef @ basis.roughness @ wiggle.coef > 1.0


def test_first_basis_completes_a_partition_of_unity():
    basis = make_basis(9, 101)
    first = np.concatenate([[basis.first_mid[0]], basis.first_mid])  # interval means
    mids = np.concatenate([basis.mid[:1], basis.mid])
    assert np.allclose(first + mids.sum(axis=1), 1.0)
    assert np.all(basis.values[0] == 0)  # φ(0) is the base angle


def test_resample_spacing_and_ends():
    z, _ = arc_axis(5 - 5j, 1.0, 333.3, 1 / 120)
    curve = fit_to_polyline(z, 1.0, n_coef=10)
    s, pts = resample(curve, 1.0)
    assert np.diff(s).max() <= 1.0 + 1e-9 and s[0] == 0
    assert s[-1] == pytest.approx(curve.length)
    assert np.abs(np.diff(pts)).max() <= 1.0 + 1e-9
    assert pts[0] == pytest.approx(5 - 5j) and pts[-1] == pytest.approx(tip_point(curve))


def test_partial_roughness_leaves_arcs_alone_and_sums_to_the_whole():
    basis = make_basis(20, 301)
    q = basis.quad_second
    assert np.allclose(q.T @ q, basis.roughness, rtol=1e-12, atol=1e-9)
    # φ(u) = θu (an arc): its clamped cubic coefficients are θ × the Greville
    # abscissae; φ'' = 0 on every part of the curve, the tip's last width too
    n = basis.n_coef + 1
    knots = np.r_[np.zeros(4), np.linspace(0, 1, n - 2)[1:-1], np.ones(4)]
    greville = np.array([knots[j + 1:j + 4].mean() for j in range(n)])
    arc = 2.5 * greville[1:]
    assert np.allclose(basis.values @ arc, 2.5 * basis.u, atol=1e-12)
    tip = q[basis.quad_u > 0.93]
    assert np.abs(tip @ arc).max() < 1e-9
    # ... while a change of curvature near the tip is penalised there
    kink = np.where(greville[1:] > 0.9, (greville[1:] - 0.9) ** 2, 0.0)
    assert (tip @ kink) @ (tip @ kink) > 0.5 * kink @ basis.roughness @ kink


# -- section joints: triple knots where the curvature may step ----------------------------------
def _two_arcs(split=0.7, length=600.0, k1=1 / 90, k2=1 / 900, n=4001):
    """A polyline whose curvature steps from k1 to k2 at ``split`` of its length."""
    s = np.linspace(0, length, n)
    phi = np.where(s < split * length, k1 * s, k1 * split * length + k2 * (s - split * length))
    chords = np.diff(s) * np.exp(1j * 0.5 * (phi[1:] + phi[:-1]))
    return np.concatenate([[0j], np.cumsum(chords)]), phi


def test_knot_vector_puts_a_triple_knot_at_each_joint_and_keeps_the_count():
    knots = knot_vector(19, (0.6, 0.9))
    assert knots.size == 19 + 1 + 4  # n_coef free functions + B_0 + degree + 1
    for j in (0.6, 0.9):
        assert np.sum(np.isclose(knots, j)) == 3
    inner = np.unique(knots)
    assert np.ptp(np.diff(inner)) < 0.05  # the other knots keep an even spacing
    assert np.array_equal(knot_vector(12), make_basis_knots_uniform(12))


def make_basis_knots_uniform(n_coef):
    return np.concatenate([np.zeros(4), np.linspace(0, 1, n_coef - 1)[1:-1], np.ones(4)])


@pytest.mark.parametrize("joints", [(0.0, 0.5), (0.5, 0.5), (0.7, 0.3), (1.2,)])
def test_knot_vector_refuses_joints_outside_or_out_of_order(joints):
    with pytest.raises(ValueError, match="joints"):
        knot_vector(20, joints)


def test_a_joint_lets_the_spline_follow_a_curvature_step_exactly():
    z, phi = _two_arcs()
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    jointed = fit_to_polyline(z, 0.0, n_coef=16, joints=(0.7,))
    assert jointed.joints == (0.7,)
    # the tip angle: exact with the joint, ringing by a visible amount without
    assert jointed.coef[-1] == pytest.approx(phi[-1], abs=1e-4)
    assert abs(smooth.coef[-1] - phi[-1]) > 20 * abs(jointed.coef[-1] - phi[-1])
    _, zr = resample(jointed, 1.0)
    assert np.abs(zr[-1] - z[-1]) < 1e-2


def test_roughness_with_joints_is_exact_and_ignores_the_kink():
    basis = make_basis(16, 301, (0.7,))
    # φ piecewise linear with its kink at the joint: no roughness at all
    from scipy.interpolate import make_lsq_spline
    u = np.linspace(0, 1, 2001)
    phi = np.where(u < 0.7, 3 * u, 2.1 + 0.4 * (u - 0.7))
    spline = make_lsq_spline(u, phi, knot_vector(16, (0.7,)), k=3)
    coef = spline.c[1:] - spline.c[0]
    assert abs(coef @ basis.roughness @ coef) < 1e-9
    # a cubic's ∫φ''² du over [0, 1] is reproduced exactly (φ = u³: 12)
    cubic = make_lsq_spline(u, u**3, knot_vector(16, (0.7,)), k=3)
    c = cubic.c[1:] - cubic.c[0]
    assert c @ basis.roughness @ c == pytest.approx(12.0, rel=1e-9)
    # the penalty's scale is that of the same spacing without the joint
    assert basis.roughness_trace == pytest.approx(make_basis(14, 301).roughness_trace)


def test_a_curve_cut_back_before_its_base_runs_on_straight_there():
    z, _ = arc_axis(100 - 300j, 0.4, 500.0, 1 / 200)
    curve = fit_to_polyline(z, 0.4, n_coef=14)
    from pipeline.centreline import cut_base

    longer = cut_base(curve, -30.0)
    assert longer.length == pytest.approx(530.0)
    assert longer.base_angle == pytest.approx(0.4)
    assert abs(longer.base - (curve.base - 30.0 * np.exp(0.4j))) < 1e-9
    # (the spline rounds the curvature's step where the straight meets the arc)
    assert abs(tip_point(longer) - tip_point(curve)) < 0.1
    s, pts = resample(longer, 1.0)
    # straight along the base tangent for the first 30 px, then the arc as it was
    along = pts[s <= 30.0] - longer.base
    assert np.abs((along * np.exp(-0.4j)).imag).max() < 0.25
    s_old, old = resample(curve, 1.0)
    past = s >= 30.0
    was = np.interp(s[past] - 30.0, s_old, old.real) + 1j * np.interp(s[past] - 30.0, s_old,
                                                                       old.imag)
    assert np.abs(pts[past] - was).max() < 0.2
