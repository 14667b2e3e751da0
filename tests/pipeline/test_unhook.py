"""The hook a fit through a holder leaves where the tube comes out of it is
taken out of the cut curve (:func:`pipeline.pipette.unhooked`)."""

import numpy as np

from pipeline import pipette
from pipeline.centreline import fit_to_polyline, resample
from pipeline.pipette import unhooked


def _arc(base, angle, length, kappa, n=801):
    s = np.linspace(0.0, length, n)
    if kappa == 0:
        return base + s * np.exp(1j * angle)
    return base + (np.exp(1j * (angle + kappa * s)) - np.exp(1j * angle)) / (1j * kappa)


def _hooked(hook_px, reach):
    """A circular arc from a base set ``hook_px`` aside, its first ``reach`` px
    bending over to the arc (a fit pulled sideways at a holder's end)."""
    true = _arc(0j, 0.0, 300.0, 1 / 150)
    s = np.linspace(0.0, 300.0, true.size)
    normal = 1j * np.exp(1j * s / 150)
    points = true + normal * hook_px * np.clip(1 - s / reach, 0, 1) ** 2
    return true, fit_to_polyline(points, 0.0, n_coef=24, iterations=6)


def test_a_base_laid_aside_is_put_back_on_the_arc_it_leaves_along():
    true, curve = _hooked(3.5, 20.0)
    assert abs(curve.base - true[0]) > 3.0
    fixed = unhooked(curve, 24.0)
    # back on the arc's line (the base tangent is +x); along it, off by the
    # length the hook added to the fit (0.3 px)
    off = fixed.base - true[0]
    assert abs(off.imag) < 0.05 and abs(off.real) < 0.5
    assert fixed.base_angle == curve.base_angle and fixed.length == curve.length
    # past the reach, every point stays where the fit had it
    s, z = resample(curve, 1.0)
    _, zf = resample(fixed, 1.0)
    past = s > 30.0
    assert np.abs(zf[past] - z[past]).max() < 0.1


def test_a_curve_that_leaves_along_its_tangent_on_one_arc_is_unchanged():
    true = _arc(10 + 5j, 0.3, 300.0, 1 / 120)
    curve = fit_to_polyline(true, 0.3, n_coef=24, iterations=6)
    fixed = unhooked(curve, 24.0)
    _, z = resample(curve, 1.0)
    _, zf = resample(fixed, 1.0)
    assert abs(fixed.base - curve.base) < 0.05
    assert np.abs(zf - z).max() < 0.05


def test_the_hook_is_taken_out_only_where_it_moves_the_base_aside():
    # (cut at the base itself: s = 0, the holder's axis +x)
    _, hooked = _hooked(3.5, 20.0)
    assert pipette._hook(hooked, 0.0, 0.0, 8.0) == 24.0
    clean = fit_to_polyline(_arc(0j, 0.0, 300.0, 1 / 150), 0.0, n_coef=24, iterations=6)
    assert pipette._hook(clean, 0.0, 0.0, 8.0) == 0.0
    # a hook of half a pixel is left: the arc would move the base by as much
    _, slight = _hooked(0.5, 20.0)
    assert pipette._hook(slight, 0.0, 0.0, 8.0) == 0.0
