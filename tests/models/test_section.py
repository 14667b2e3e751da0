import numpy as np
import pytest

from models.section import cross_section


def _polygon_moments(r_in, t_top, t_bot, n=200_000):
    """Area, centroid and I of the annulus from fine polygons (Green's theorem)."""
    def moments(radius, cy):
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        x, y = radius * np.cos(a), cy + radius * np.sin(a)
        x1, y1 = np.roll(x, -1), np.roll(y, -1)
        cross = x * y1 - x1 * y
        area = cross.sum() / 2
        sy = ((y + y1) * cross).sum() / 6
        iyy = ((y * y + y * y1 + y1 * y1) * cross).sum() / 12  # ∫ y² dA
        return area, sy, iyy
    big = r_in + (t_top + t_bot) / 2
    e = (t_top - t_bot) / 2
    a_o, s_o, i_o = moments(big, e)
    a_v, s_v, i_v = moments(r_in, 0.0)
    area = a_o - a_v
    yc = (s_o - s_v) / area
    return area, yc, (i_o - i_v) - area * yc**2


@pytest.mark.parametrize("r,tt,tb", [(235, 134, 67), (125, 101, 38), (235, 67, 134),
                                     (50, 5, 400), (100, 30, 30)])
def test_closed_form_matches_polygon_integration(r, tt, tb):
    cs = cross_section(r, tt, tb)
    area, yc, inertia = _polygon_moments(r, tt, tb)
    assert cs.area_um2 == pytest.approx(area, rel=1e-8)
    assert cs.d_e_um == pytest.approx(yc, rel=1e-6, abs=1e-9)
    assert cs.inertia_um4 == pytest.approx(inertia, rel=1e-7)


def test_concentric_annulus_has_no_eccentricity():
    cs = cross_section(235.0, 80.0, 80.0)
    big = 315.0
    assert cs.d_e_um == 0.0
    assert cs.inertia_um4 == pytest.approx(np.pi / 4 * (big**4 - 235.0**4), rel=1e-14)


def test_eccentricity_points_to_the_thicker_wall_and_is_antisymmetric():
    a = cross_section(235.0, 134.0, 67.0)
    b = cross_section(235.0, 67.0, 134.0)
    assert a.d_e_um > 0 > b.d_e_um
    assert a.d_e_um == pytest.approx(-b.d_e_um, rel=1e-15)
    assert a.inertia_um4 == pytest.approx(b.inertia_um4, rel=1e-15)


def test_near_equal_walls_keep_relative_precision():
    # e = 5e-11 µm: a cancelling formula would lose most digits of d_e.
    tb = 100.0
    tt = np.nextafter(tb, 200.0)
    for _ in range(10):  # a handful of ulps above t_b
        tt = np.nextafter(tt, 200.0)
    cs = cross_section(235.0, tt, tb)
    big, e = 235.0 + (tt + tb) / 2, (tt - tb) / 2
    expected = big**2 * e / ((big - 235.0) * (big + 235.0))
    assert cs.d_e_um == pytest.approx(expected, rel=1e-14)
    assert cs.d_e_um > 0


def test_vectorised_over_broadcast_inputs():
    cs = cross_section(235.0, np.array([[100.0], [150.0]]), np.array([60.0, 70.0, 80.0]))
    assert cs.d_e_um.shape == (2, 3)
    single = cross_section(235.0, 150.0, 70.0)
    assert cs.d_e_um[1, 1] == single.d_e_um


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, np.inf])
@pytest.mark.parametrize("field", ["r_in_um", "t_top_um", "t_bot_um"])
def test_rejects_non_positive_or_non_finite(field, bad):
    args = {"r_in_um": 235.0, "t_top_um": 100.0, "t_bot_um": 50.0, field: bad}
    with pytest.raises(ValueError, match=field):
        cross_section(**args)
