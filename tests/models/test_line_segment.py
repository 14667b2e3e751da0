import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models import (
    PAPER_SAMPLES,
    LSParams,
    Sample,
    Section,
    ls_bend_angle,
    ls_limit_shape,
    ls_shape,
    ls_shape_cumsum,
    ls_tilts,
    segment_counts,
)

S1 = PAPER_SAMPLES[1]
P = 0.14


def test_segment_counts_share_by_length_with_a_minimum_of_one():
    counts = segment_counts([0.43, 0.24, 0.23, 0.10], 1000)
    assert counts.tolist() == [430, 240, 230, 100]
    tiny = segment_counts([1e-6, 0.5, 0.5 - 1e-6], 10)
    assert tiny.sum() == 10 and tiny.min() == 1
    assert segment_counts([0.5, 0.5], 2).tolist() == [1, 1]
    with pytest.raises(ValueError, match="n_segments"):
        segment_counts([0.5, 0.3, 0.2], 2)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(1e-6, 1.0), min_size=1, max_size=8), st.integers(0, 10_000))
def test_segment_counts_properties(raw, extra):
    f = np.array(raw) / sum(raw)
    n = f.size + extra
    counts = segment_counts(f, n)
    assert counts.sum() == n and counts.min() >= 1
    # never more than one segment (plus the enforced minimum) away from the quota
    assert np.all(np.abs(counts - n * f) < 1 + f.size)


@pytest.mark.parametrize("n", [4, 7, 100, 1000, 33_333])
def test_closed_form_vertices_match_the_cumsum_reference(n):
    params = LSParams(n_segments=n, k_de_per_um=-0.002, elongation=1.1)
    a = ls_shape(S1, P, params)
    b = ls_shape_cumsum(S1, P, params)
    assert a.n_points == n + 1
    scale = S1.length_um
    np.testing.assert_allclose(a.x_um, b.x_um, atol=1e-11 * scale)
    np.testing.assert_allclose(a.y_um, b.y_um, atol=1e-11 * scale)
    np.testing.assert_allclose(a.phi_rad, b.phi_rad, atol=1e-10)
    np.testing.assert_allclose(a.s_um, b.s_um, rtol=1e-12)


@pytest.mark.parametrize("n", [4, 9, 1000, 10**6])
def test_resampled_points_lie_on_the_vertex_polyline(n):
    params = LSParams(n_segments=n, eps_max=0.9)
    verts = ls_shape(S1, P, params) if n <= 10**5 else ls_shape_cumsum(S1, P, params)
    res = ls_shape(S1, P, params, n_points=257)
    np.testing.assert_allclose(res.x_um, np.interp(res.s_um, verts.s_um, verts.x_um),
                               atol=1e-8 * S1.length_um)
    np.testing.assert_allclose(res.y_um, np.interp(res.s_um, verts.s_um, verts.y_um),
                               atol=1e-8 * S1.length_um)
    # (the cumsum reference accumulates ~1e-11 rad over 10^6 additions; the sum is exact)
    assert res.bend_angle_rad == pytest.approx(ls_bend_angle(S1, P, params), rel=1e-14)
    assert res.tip_um == pytest.approx(verts.tip_um, abs=1e-8 * S1.length_um)


def test_bend_angle_is_sum_of_section_tilts():
    params = LSParams(n_segments=777)
    theta, counts, _ = ls_tilts(S1, P, params)
    assert ls_bend_angle(S1, P, params) == pytest.approx(float(theta @ counts), rel=1e-15)
    assert ls_shape(S1, P, params).bend_angle_rad == pytest.approx(float(theta @ counts))


def test_tilt_follows_eq12():
    params = LSParams(n_segments=1000, eps_min=0.5, eps_max=1.2, k_de_per_um=0.003)
    theta, counts, _ = ls_tilts(S1, 0.07, params)
    walls = np.concatenate([S1.t_top_um, S1.t_bot_um])
    eps = lambda t: 1.2 - 0.7 * (t - walls.min()) / (walls.max() - walls.min())  # noqa: E731
    seg0 = S1.section_lengths_um / counts
    tt, tb = S1.t_top_um, S1.t_bot_um
    l_top, l_bot = seg0 * eps(tt) * tt / tb, seg0 * eps(tb) * tt / tb
    expected = (np.arctan((l_bot - l_top) / 235.0) * (0.07 / 0.14)
                * (1 + 0.003 * S1.geometry.d_e_um))
    np.testing.assert_allclose(theta, expected, rtol=1e-12)


def test_strains_enter_only_through_their_difference():
    a = ls_shape(S1, P, LSParams(eps_min=0.5, eps_max=0.8))
    b = ls_shape(S1, P, LSParams(eps_min=0.9, eps_max=1.2))
    np.testing.assert_allclose(a.x_um, b.x_um, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(a.phi_rad, b.phi_rad, rtol=1e-13)


def test_reference_thickness_range_lets_samples_share_parameters():
    params = LSParams(t_ref_um=(60.0, 220.0), eps_min=0.5, eps_max=1.0)
    theta, _, _ = ls_tilts(S1, P, params)
    own, _, _ = ls_tilts(S1, P, params.replace(t_ref_um=None))
    walls = np.concatenate([S1.t_top_um, S1.t_bot_um])
    ratio = (220 - 60) / (walls.max() - walls.min())
    # the tilt's atan argument scales with 1/(t_hi − t_lo)
    np.testing.assert_allclose(np.tan(own) / np.tan(theta), ratio, rtol=1e-12)
    with pytest.raises(ValueError, match="strain"):
        ls_tilts(S1, P, LSParams(t_ref_um=(150.0, 160.0), eps_min=0.5, eps_max=1.2))


def test_elongation_scales_length_linearly_in_pressure():
    params = LSParams(elongation=1.2)
    for p, factor in ((0.0, 1.0), (0.07, 1.1), (0.14, 1.2)):
        assert ls_shape(S1, p, params).length_um == pytest.approx(S1.length_um * factor)


@settings(max_examples=25, deadline=None)
@given(eps_max=st.floats(0.55, 1.2), k=st.floats(-0.003, 0.01), sample_id=st.integers(1, 8),
       p=st.floats(0.01, 0.2), stretch=st.floats(0.9, 1.3))
def test_converges_to_the_arc_chain_limit_as_n_grows(eps_max, k, sample_id, p, stretch):
    sample = PAPER_SAMPLES[sample_id]
    params = LSParams(eps_max=eps_max, k_de_per_um=k, p_max_mpa=0.14, elongation=stretch)
    limit = ls_limit_shape(sample, p, params, n_points=2)
    ns = np.array([2**14, 2**16, 2**18, 2**20])
    shapes = [ls_shape(sample, p, params.replace(n_segments=int(n)), n_points=2) for n in ns]
    d_angle = np.abs([sh.bend_angle_rad - limit.bend_angle_rad for sh in shapes])
    d_tip = np.array([np.hypot(*(sh.tip_um - limit.tip_um)) for sh in shapes])
    # atan saturation: the angle converges as N^-2 (a factor 16 per quadrupling)
    assert np.all(d_angle[1:] <= d_angle[:-1] / 12 + 1e-12)
    # positions converge as N^-1: each segment's heading is off the arc's by at most
    # one tilt (Φ/N), so |Δtip| ≤ L·(|Φ|/N + |ΔΦ|); and in this asymptotic range
    # below N ~ 10^4 the N^-1 and N^-2 terms can cancel, and per-section rounding
    # of the segment counts makes the error jitter, so it need not fall at every step
    bound = limit.length_um * (abs(limit.bend_angle_rad) / ns + d_angle)
    assert np.all(d_tip <= bound + 1e-9)
    assert shapes[-1].length_um == pytest.approx(limit.length_um, rel=1e-14)


def test_batch_over_parameter_sets_and_pressures():
    p = np.linspace(0, 0.14, 5)
    eps = np.array([0.8, 1.0, 1.2])
    k = np.array([0.0, 0.004])
    params = LSParams(eps_max=eps[:, None, None], k_de_per_um=k[None, :, None])
    batch = ls_shape(S1, p[None, None, :], params, n_points=50)
    assert batch.x_um.shape == (3, 2, 5, 50)
    one = ls_shape(S1, p[3], LSParams(eps_max=eps[1], k_de_per_um=k[1]), n_points=50)
    np.testing.assert_allclose(batch[1, 1, 3].x_um, one.x_um, rtol=0, atol=1e-9)
    verts = ls_shape(S1, p[None, None, :], params)
    np.testing.assert_allclose(verts[1, 1, 3].y_um,
                               ls_shape(S1, p[3], LSParams(eps_max=eps[1],
                                                           k_de_per_um=k[1])).y_um, atol=1e-9)


def test_an_elongation_array_adds_its_own_batch_axes():
    p = np.array([0.07, 0.14])
    params = LSParams(elongation=np.array([1.0, 1.2])[:, None])
    for n_points in (None, 50):
        batch = ls_shape(S1, p, params, n_points=n_points)
        assert batch.x_um.shape == batch.phi_rad.shape == batch.s_um.shape
        assert batch.batch_shape == (2, 2)
        one = ls_shape(S1, p[1], LSParams(elongation=1.2), n_points=n_points)
        np.testing.assert_allclose(batch[1, 1].x_um, one.x_um, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(batch[1, 1].phi_rad, one.phi_rad)
    theta, _, stretch = ls_tilts(S1, p, params)
    assert theta.shape == (2, 2, S1.n_sections) and stretch.shape == (2, 2)
    assert ls_limit_shape(S1, p, params).batch_shape == (2, 2)
    # same number of axes, longer along one: (2, 1) elongations × (1, 2) pressures
    assert ls_shape(S1, p[None, :], params).batch_shape == (2, 2)
    assert ls_tilts(S1, p[None, :], params)[0].shape == (2, 2, S1.n_sections)


def test_zero_pressure_is_exactly_straight():
    for n_points in (None, 100):
        shape = ls_shape(S1, 0.0, LSParams(k_de_per_um=0.01, elongation=1.3), n_points=n_points)
        assert np.all(shape.y_um == 0) and np.all(shape.phi_rad == 0)
        np.testing.assert_allclose(shape.x_um, shape.s_um, rtol=1e-15, atol=1e-9)


def test_equal_walls_are_straight():
    sample = Sample("eq", 9000.0, 235.0, (Section(0.5, 100, 100), Section(0.5, 80, 80)),
                    p_max_mpa=0.1)
    shape = ls_shape(sample, 0.1, LSParams(k_de_per_um=1.0))
    assert np.all(shape.y_um == 0) and shape.bend_angle_rad == 0


@pytest.mark.parametrize("kwargs,match", [
    ({"eps_min": 0.0}, "eps_min"),
    ({"eps_max": -1.0}, "eps_max"),
    ({"eps_max": np.nan}, "eps_max"),
    ({"k_de_per_um": np.inf}, "k_de_per_um"),
    ({"k_de_per_um": -0.1}, "k_de_per_um"),
    ({"elongation": 0.0}, "elongation"),
    ({"n_segments": 3}, "n_segments"),
    ({"n_segments": 2.5}, "n_segments"),
    ({"p_max_mpa": 0.0}, "p_max_mpa"),
    ({"t_ref_um": (100.0, 50.0)}, "t_ref_um"),
])
def test_ls_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ls_shape(S1, P, LSParams(**kwargs))


def test_one_number_and_arrays_give_the_same_shape():
    params = LSParams(n_segments=1000, k_de_per_um=0.002, elongation=1.1)
    ref = ls_shape(S1, np.array([P]), params)
    for p in (P, np.float64(P), np.array(P)):
        for n_points in (None, 201):
            one = ls_shape(S1, p, params, n_points=n_points)
            many = ls_shape(S1, np.array([P]), params, n_points=n_points)[0]
            np.testing.assert_array_equal(one.phi_rad, many.phi_rad)
            np.testing.assert_allclose(one.x_um, many.x_um, rtol=0, atol=4e-16 * S1.length_um)
            np.testing.assert_allclose(one.y_um, many.y_um, rtol=0, atol=4e-16 * S1.length_um)
            np.testing.assert_array_equal(one.s_um, many.s_um)
    assert ls_bend_angle(S1, P, params) == ref.bend_angle_rad[0]
    scalar_params = LSParams(eps_max=np.array(1.0), k_de_per_um=np.float64(0.0))
    array_params = LSParams(eps_max=np.array([1.0]), k_de_per_um=np.array([0.0]))
    np.testing.assert_array_equal(ls_tilts(S1, P, scalar_params)[0],
                                  ls_tilts(S1, P, array_params)[0][0])


def test_layouts_are_cached_on_the_sample_and_bounded():
    sample = Sample("cache", 9000.0, 235.0, (Section(0.6, 134, 67), Section(0.4, 166, 72)),
                    p_max_mpa=0.1)
    twin = Sample("cache", 9000.0, 235.0, (Section(0.6, 134, 67), Section(0.4, 166, 72)),
                  p_max_mpa=0.1)
    first = ls_shape(sample, 0.05, LSParams(n_segments=100))
    assert sample.model_cache and not twin.model_cache
    assert sample == twin and hash(sample) == hash(twin)  # the cache is not a field
    again = ls_shape(sample, 0.05, LSParams(n_segments=100))
    np.testing.assert_array_equal(first.x_um, again.x_um)
    for n in range(2, 300):
        ls_shape(sample, 0.05, LSParams(n_segments=n), n_points=3)
    assert len(sample.model_cache) <= 64
    # the render module reads the initial segment lengths by position
    from models.line_segment import _layout
    np.testing.assert_allclose(_layout(sample, 100)[1], sample.section_lengths_um / [60, 40])


def test_ls_rejects_bad_pressure_and_missing_p_max():
    with pytest.raises(ValueError, match="pressure_mpa"):
        ls_shape(S1, -0.01)
    with pytest.raises(ValueError, match="pressure_mpa"):
        ls_shape(S1, [0.1, np.nan])
    for bad in (np.float64("nan"), float("inf"), -1, 10**400, "x", None):
        with pytest.raises(ValueError, match="pressure_mpa"):
            ls_shape(S1, bad)
        with pytest.raises(ValueError, match="pressure_mpa"):
            ls_bend_angle(S1, bad)
    with pytest.raises(ValueError, match="p_max_mpa"):
        ls_shape(PAPER_SAMPLES[5], 0.1)
    with pytest.raises(ValueError, match="stretch"):
        ls_shape(S1, 0.5, LSParams(elongation=0.5))
