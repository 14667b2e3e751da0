"""Finding section joints from measured edge midpoints (no images needed)."""

import numpy as np
import pytest

from pipeline.centreline import basis_of, evaluate, fit_to_polyline
from pipeline.joints import find_joints, rewritten, same_joints
from tests.pipeline.test_centreline import _two_arcs

HALF_WIDTH = 10.0


def _midpoints(z_true, noise, seed=0, n=150, length=600.0):
    """Tube centres measured on n profiles (noise px along the normal), and their u."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.02, 0.99, n)
    s = np.linspace(0, length, z_true.size)
    pts = np.interp(u * length, s, z_true.real) + 1j * np.interp(u * length, s, z_true.imag)
    return u, pts + rng.normal(0, noise, n) * (1 + 1j) / np.sqrt(2)


@pytest.mark.parametrize("split", [0.45, 0.7, 0.9])
def test_a_curvature_step_is_found_where_it_is(split):
    z, _ = _two_arcs(split=split)
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    u, pts = _midpoints(z, 0.05)
    found = find_joints(smooth, u, pts, HALF_WIDTH)
    assert len(found) == 1
    assert found[0] == pytest.approx(split, abs=0.2 * 2 * HALF_WIDTH / 600.0)


@pytest.mark.parametrize("seed", range(5))
def test_a_smooth_tube_gets_no_joint(seed):
    z, _ = _two_arcs(k2=1 / 90)  # one arc: the curvature does not step
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    u, pts = _midpoints(z, 0.1, seed=seed)
    assert find_joints(smooth, u, pts, HALF_WIDTH) == ()


def test_a_step_hidden_in_noise_is_not_claimed():
    z, _ = _two_arcs(k2=1 / 95)  # a 5 % step under 0.3 px of scatter
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    u, pts = _midpoints(z, 0.3, seed=3)
    assert find_joints(smooth, u, pts, HALF_WIDTH) == ()


def test_kept_joints_stay_and_the_search_is_afresh():
    z, _ = _two_arcs(split=0.7)
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    u, pts = _midpoints(z, 0.05)
    # a wrong joint on the curve is not assumed; a kept one is
    wrong = rewritten(smooth, (0.4,))
    found = find_joints(wrong, u, pts, HALF_WIDTH)
    assert len(found) == 1 and found[0] == pytest.approx(0.7, abs=0.01)
    kept = find_joints(smooth, u, pts, HALF_WIDTH, keep=(0.3,))
    assert 0.3 in kept and len(kept) == 2


def test_rewriting_a_curve_with_joints_keeps_its_shape():
    z, _ = _two_arcs(split=0.7)
    curve = fit_to_polyline(z, 0.0, n_coef=16, joints=(0.7,))
    plain = rewritten(curve, ())
    back = rewritten(plain, (0.7,))
    assert plain.joints == () and plain.coef.size == 14
    assert back.joints == (0.7,) and back.coef.size == 16 and back.base == curve.base
    # the smooth curve, rewritten with a joint, keeps its shape (the jointed
    # spline has the freedom the smooth one used)
    za = evaluate(plain, basis_of(plain)).z
    zb = evaluate(back, basis_of(back)).z
    assert np.abs(za - zb).max() < 0.15  # px; the next refine takes it from there
    assert rewritten(curve, (0.7,)) is curve


def test_same_joints_compares_within_a_tolerance():
    assert same_joints((0.5, 0.9), (0.51, 0.89), 0.02)
    assert not same_joints((0.5,), (0.5, 0.9), 0.02)
    assert not same_joints((0.5,), (0.6,), 0.02)
