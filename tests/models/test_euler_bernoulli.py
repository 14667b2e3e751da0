import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models import (
    PAPER_SAMPLES,
    Sample,
    Section,
    eb_bend_angle,
    eb_curvatures,
    eb_shape,
    eb_shape_trapezoid,
)

S1 = PAPER_SAMPLES[1]


def uniform(r=235.0, tt=134.0, tb=67.0, length=9000.0, E=1.4):
    return Sample("u", length, r, (Section(1.0, tt, tb),), E_mpa=E)


def test_curvature_formula():
    kappa = eb_curvatures(S1, 0.14)
    geo = S1.geometry
    expected = np.pi * 235.0**2 * geo.d_e_um * 0.14 / (1.4 * geo.inertia_um4)
    np.testing.assert_allclose(kappa, expected, rtol=1e-15)
    assert np.all(kappa > 0)  # thicker top walls: counter-clockwise


@settings(max_examples=60, deadline=None)
@given(r=st.floats(50, 400), tt=st.floats(5, 400), tb=st.floats(5, 400),
       p=st.floats(1e-4, 0.3), E=st.floats(0.05, 10.0))
def test_uniform_tube_is_an_exact_circular_arc(r, tt, tb, p, E):
    sample = uniform(r, tt, tb, E=E)
    shape = eb_shape(sample, p, n_points=64)
    (kappa,) = eb_curvatures(sample, p)
    if abs(kappa) * sample.length_um < 1e-6:
        return  # essentially straight: the circle's radius is beyond float range of test
    centre = 1j / kappa
    radius = np.abs(shape.x_um + 1j * shape.y_um - centre)
    np.testing.assert_allclose(radius, 1 / abs(kappa), rtol=1e-11)
    np.testing.assert_allclose(shape.phi_rad, kappa * shape.s_um, rtol=1e-13, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(p=st.floats(1e-4, 0.3), factor=st.floats(0.01, 100), E=st.floats(0.05, 50),
       sample_id=st.integers(1, 8))
def test_bend_angle_is_linear_in_pressure_and_compliance(p, factor, E, sample_id):
    sample = PAPER_SAMPLES[sample_id]
    base = eb_bend_angle(sample, p, E_mpa=E)
    assert eb_bend_angle(sample, p * factor, E_mpa=E) == pytest.approx(base * factor, rel=1e-13)
    assert eb_bend_angle(sample, p, E_mpa=E * factor) == pytest.approx(base / factor, rel=1e-13)
    assert eb_shape(sample, p, E_mpa=E).bend_angle_rad == pytest.approx(base, rel=1e-13)


def test_heading_and_position_are_continuous_across_sections():
    s = np.sort(np.concatenate([S1.section_starts_um[1:] + d for d in (-1e-7, 0.0, 1e-7)]))
    shape = eb_shape(S1, 0.3, s_um=s)
    jumps_phi = np.abs(np.diff(shape.phi_rad.reshape(-1, 3), axis=1))
    jumps_xy = np.abs(np.diff((shape.x_um + 1j * shape.y_um).reshape(-1, 3), axis=1))
    assert jumps_phi.max() < 1e-9 and jumps_xy.max() < 2e-7


def test_tangent_matches_derivative_of_position():
    shape = eb_shape(S1, 0.2, n_points=20001)
    z = shape.x_um + 1j * shape.y_um
    dz = np.gradient(z, shape.s_um)
    np.testing.assert_allclose(np.abs(dz), 1.0, atol=1e-6)
    interior = slice(1, -1)
    np.testing.assert_allclose(np.angle(dz[interior] * np.exp(-1j * shape.phi_rad[interior])),
                               0.0, atol=1e-5)


def test_trapezoid_converges_at_second_order():
    exact = eb_shape(S1, 0.14, n_points=2)
    errors = []
    ns = [101, 201, 401, 801]
    for n in ns:
        trap = eb_shape_trapezoid(S1, 0.14, n_points=n)
        errors.append(np.hypot(*(trap.tip_um - exact.tip_um)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.15), orders
    assert trap.bend_angle_rad == pytest.approx(exact.bend_angle_rad, rel=1e-14)


def test_batch_over_moduli_and_pressures_matches_single_calls():
    p = np.linspace(0, 0.2, 7)
    E = np.array([0.5, 1.4, 3.0])
    batch = eb_shape(S1, p[None, :], E_mpa=E[:, None], n_points=33)
    assert batch.x_um.shape == (3, 7, 33)
    one = eb_shape(S1, p[4], E_mpa=E[2], n_points=33)
    # positions to the last bit or two (NumPy's SIMD complex products may fuse
    # multiply-adds), headings exactly
    np.testing.assert_allclose(batch[2, 4].x_um, one.x_um, rtol=0, atol=4e-16 * S1.length_um)
    np.testing.assert_array_equal(batch[2, 4].phi_rad, one.phi_rad)
    np.testing.assert_array_equal(batch.bend_angle_rad[2, 4], one.bend_angle_rad)


def test_zero_pressure_is_exactly_straight():
    for shape in (eb_shape(S1, 0.0), eb_shape_trapezoid(S1, 0.0, n_points=101)):
        assert np.all(shape.y_um == 0) and np.all(shape.phi_rad == 0)
        np.testing.assert_array_equal(shape.x_um, shape.s_um)


def test_one_number_and_arrays_give_the_same_curvatures():
    for p in (0.14, 0, np.float64(0.14), np.array(0.14), [0.14], np.array([[0.14]])):
        for E in (None, 2.0, np.float64(2.0), np.array([2.0])):
            kappa = eb_curvatures(S1, p, E_mpa=E)
            ref = eb_curvatures(S1, np.array([float(np.ravel(p)[0])]),
                                E_mpa=np.array([S1.E_mpa if E is None else 2.0]))[0]
            np.testing.assert_array_equal(kappa.reshape(-1, 4)[0], ref)


@pytest.mark.parametrize("kwargs,match", [
    ({"pressure_mpa": 10**400}, "pressure_mpa"),
    ({"pressure_mpa": np.float64("nan")}, "pressure_mpa"),
    ({"pressure_mpa": -0.1, "E_mpa": 0.0}, "pressure_mpa"),
    ({"pressure_mpa": 0.1, "E_mpa": -1}, "E_mpa"),
    ({"pressure_mpa": 0.1, "E_mpa": np.float64("inf")}, "E_mpa"),
    ({"pressure_mpa": -0.1}, "pressure_mpa"),
    ({"pressure_mpa": np.nan}, "pressure_mpa"),
    ({"pressure_mpa": [0.1, np.inf]}, "pressure_mpa"),
    ({"pressure_mpa": 0.1, "E_mpa": 0.0}, "E_mpa"),
    ({"pressure_mpa": 0.1, "n_points": 1}, "n_points"),
    ({"pressure_mpa": 0.1, "s_um": [0.0, 1e9]}, "s_um"),
    ({"pressure_mpa": 0.1, "s_um": [10.0, 5.0]}, "sorted"),
])
def test_eb_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        eb_shape(S1, **kwargs)
