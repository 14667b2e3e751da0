"""Once the frames tell that the tube's curvature changes along its end, the
reported tip stretch follows the trend of the curvature before it: a tube
whose curvature ramps toward its end (stiffer at its base), or away from it,
has its tip angle measured, not pulled toward that of a constant-curvature
end. Until they do (an arc), it is held to a constant curvature."""
import numpy as np
import pytest

from pipeline.centreline import angle_spline, fit_to_polyline
from pipeline.refine import TubeLook, _tip_trend, refine
from pipeline.track import TREND_VOTE_FRAMES, _reported, _TrendVotes
from tests.pipeline.synthetic import axis_image, ramp_axis

HW = 10.0
LENGTH = 420.0


@pytest.mark.parametrize("k_base, k_tip", [(0.002, 0.010), (0.010, 0.002), (0.006, 0.006)])
def test_a_ramping_curvature_s_tip_angle_is_measured(k_base, k_tip):
    z, s, phi = ramp_axis(80 - 420j, 0.0, LENGTH, k_base, k_tip)
    img = axis_image((480, 640), z, s, phi, HW)
    truth = fit_to_polyline(z[::20], 0.0, n_coef=28)
    start = truth.with_params(truth.coef * 0.98, truth.length * 0.99)
    look = TubeLook(-1, np.full(5, HW), 0.05, tip_trend=True)
    r = refine(img, start, look, iterations=12, tol_px=0.005)
    shown = _reported(r)
    assert r.tip_found and r.tip_hold == "trend"
    # (a tip held to a constant curvature: -0.21 deg on the ramp up, +0.15 deg
    # on the ramp down)
    assert abs(np.degrees(shown.coef[-1] + shown.base_angle - phi[-1])) < 0.1
    assert abs(shown.length - LENGTH) < 1.0


def test_no_trend_is_read_across_the_last_joint():
    span = 0.07  # the stretch before it begins at 0.86
    assert _tip_trend(20, (), span) is not None
    assert _tip_trend(20, (0.87,), span) is None
    assert _tip_trend(20, (0.8,), span) is not None


def test_the_trend_costs_nothing_on_a_ramp_and_something_on_a_hook_at_the_tip():
    u = np.linspace(0, 1, 2001)
    basis = angle_spline(20)(u)
    matrix = _tip_trend(20, (), 0.1)

    def cost(phi):
        coef = np.linalg.lstsq(basis, phi, rcond=None)[0]
        return coef[1:] @ matrix @ coef[1:]

    # a curvature ramping over the whole tube (φ'' = 1.6 everywhere)
    assert cost(1.5 * u + 0.8 * u**2) < 1e-9
    # one that steps up within the last 5 %: the trend before does not hold it
    assert cost(1.5 * u + 40 * np.clip(u - 0.95, 0, None) ** 2) > 1.0


def test_a_tip_whose_last_section_is_short_is_held_to_a_constant_curvature():
    # (a joint 40 px from the end: the stretch before the stiff 30 px would
    # reach past it, where the curvature steps)
    z, s, phi = ramp_axis(80 - 420j, 0.0, LENGTH, 0.004, 0.004)
    curve = fit_to_polyline(z[::20], 0.0, n_coef=16, joints=(1 - 40 / LENGTH,))
    img = axis_image((480, 640), z, s, phi, HW)
    r = refine(img, curve, TubeLook(-1, np.full(5, HW), 0.05, tip_trend=True), iterations=6)
    assert r.tip_found and r.tip_hold == "constant"


def test_untold_the_tip_is_held_to_a_constant_curvature():
    z, s, phi = ramp_axis(80 - 420j, 0.0, LENGTH, 0.002, 0.010)
    img = axis_image((480, 640), z, s, phi, HW)
    truth = fit_to_polyline(z[::20], 0.0, n_coef=28)
    r = refine(img, truth, TubeLook(-1, np.full(5, HW), 0.05), iterations=6)
    assert r.tip_hold == "constant"


def _votes(curves, half_width=HW):
    votes, look = _TrendVotes(), TubeLook(-1, np.full(5, half_width), 0.05)
    told = []
    for c in curves:
        look = votes.add(c, look)
        told.append(look.tip_trend)
    return told


def test_frames_that_ramp_alike_tell_the_trend_and_arcs_do_not():
    rng = np.random.default_rng(3)
    ramps, arcs = [], []
    for p in np.linspace(0.2, 1.0, 8):
        # (the fits' own scatter: 0.05 % of each coefficient)
        for k_base, k_tip, out in ((0.002, 0.010, ramps), (0.006, 0.006, arcs)):
            z = ramp_axis(80 - 420j, 0.0, LENGTH, p * k_base, p * k_tip)[0]
            c = fit_to_polyline(z[::20], 0.0, n_coef=28)
            out.append(c.with_params(c.coef * (1 + 5e-4 * rng.standard_normal(c.coef.size)),
                                     c.length))
    told = _votes(ramps)
    assert told[TREND_VOTE_FRAMES - 1] and told[-1]
    assert not any(_votes(arcs))
    # a fit whose last joint lies within the stretches looked at tells nothing
    z = ramp_axis(80 - 420j, 0.0, LENGTH, 0.002, 0.010)[0]
    jointed = fit_to_polyline(z[::20], 0.0, n_coef=16, joints=(0.9,))
    assert not any(_votes([jointed] * 8))
    # nor does the same arc on every frame (its ratio, numerical noise, fits
    # exactly), nor a fit gone NaN; the same ramp on every frame is a ramp
    assert not any(_votes([arcs[-1]] * 8))
    broken = ramps[-1].with_params(np.full(ramps[-1].coef.size, np.nan), LENGTH)
    assert not any(_votes([broken] * 8))
    assert _votes([ramps[-1]] * 8)[-1]


def test_frames_fitted_before_the_trend_was_told_are_held_to_it_afterwards():
    """Frames of a tube whose curvature ramps towards its tip, the first
    three fitted before the frames told the trend (tip held to a constant
    curvature), the last after: :func:`pipeline.track.hold_tip_trend` fits
    the two bent at least half as far as the last once more with the trend,
    and their tip angles come right; the one bent less, a frame at a
    crossing, and frames with no trend told at all are left alone."""
    from dataclasses import replace

    from pipeline.track import FrameTrack, hold_tip_trend

    frames, results, tips = [], [], []
    plain = TubeLook(-1, np.full(5, HW), 0.05)
    for k, scale in enumerate((0.4, 0.9, 0.95, 1.0)):
        z, s, phi = ramp_axis(80 - 420j, 0.0, LENGTH, 0.002 * scale, 0.010 * scale)
        img = axis_image((480, 640), z, s, phi, HW)
        truth = fit_to_polyline(z[::20], 0.0, n_coef=28)
        look = replace(plain, tip_trend=k == 3)
        r = refine(img, truth, look, iterations=12, tol_px=0.005)
        frames.append(img)
        tips.append(phi[-1])
        results.append(FrameTrack(k, "ok", _reported(r), "fast", r.residual_px, fit=r.curve,
                                  tip_hold=r.tip_hold, look=look))

    def tip_error(r, k):
        return abs(np.degrees(r.curve.coef[-1] + r.curve.base_angle - tips[k]))

    assert [r.tip_hold for r in results] == ["constant"] * 3 + ["trend"]
    before = [tip_error(r, k) for k, r in enumerate(results)]
    assert min(before[1:3]) > 0.12
    out, held = hold_tip_trend(frames, results)
    assert held == 2
    assert [r.tip_hold for r in out] == ["constant"] + ["trend"] * 3
    assert all(tip_error(out[k], k) < 0.1 for k in (1, 2)), before
    assert out[0] is results[0] and out[3] is results[3]
    # a frame at a crossing is not refitted; nor any without the trend told
    crossed = results[:1] + [replace(results[1], crossing=True)] + results[2:]
    assert hold_tip_trend(frames, crossed)[0][1] is crossed[1]
    untold = results[:3]
    assert hold_tip_trend(frames[:3], untold) == (untold, 0)
