import numpy as np
import pytest

from pipeline.centreline import (
    Curve,
    evaluate,
    fit_to_polyline,
    jacobian,
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
