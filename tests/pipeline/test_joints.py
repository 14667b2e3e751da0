"""Finding section joints from measured edge midpoints and widths (no images needed)."""

import numpy as np
import pytest

from pipeline.centreline import basis_of, evaluate, fit_to_polyline
from pipeline.joints import (
    WidthRecord,
    find_joints,
    place_steps,
    record_resolves,
    recorded_steps,
    rewritten,
    same_joints,
    spacing_f,
    step_windows,
    width_steps,
)
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


def test_a_joint_stays_a_width_from_the_tip():
    """A kink within the last width (a tip hooking on a lumen's end, say) may
    be found at the last candidate, a width from the end, but is not polished
    past it: a last section 9 px long, held by too few edges, spun an
    independent renderer's tip by 430 deg."""
    width_u = 2 * HALF_WIDTH / 600.0
    z, _ = _two_arcs(split=1.0 - 0.3 * width_u, k2=1 / 10)
    smooth = fit_to_polyline(z, 0.0, n_coef=14)
    # (midpoints up to the end: the kink's pull reaches the last candidates)
    u = np.linspace(0.02, 0.999, 300)
    s = np.linspace(0.0, 600.0, z.size)
    pts = np.interp(u * 600.0, s, z.real) + 1j * np.interp(u * 600.0, s, z.imag)
    found = find_joints(smooth, u, pts, HALF_WIDTH)
    assert found, "the kink's pull shows at the last candidates"
    assert all(width_u - 1e-9 <= j <= 1.0 - width_u + 1e-9 for j in found), found


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


def test_rewriting_to_another_spacing_keeps_the_shape():
    z, _ = _two_arcs(split=0.7)
    curve = fit_to_polyline(z, 0.0, n_coef=24, joints=(0.7,))
    coarse = rewritten(curve, (0.7,), 12)
    assert coarse.coef.size == 12 and coarse.joints == (0.7,)
    assert (coarse.length, coarse.base, coarse.base_angle) == (curve.length, curve.base,
                                                               curve.base_angle)
    # the two arcs are in the coarse jointed spline's space: nothing is lost
    za = evaluate(curve, basis_of(curve)).z
    zb = evaluate(coarse, basis_of(coarse)).z
    assert np.abs(za - zb).max() < 0.05


def _widths(u, steps, levels, noise, seed):
    """A tube's outer width along u, stepping at ``steps`` between ``levels``, px."""
    rng = np.random.default_rng(seed)
    w = np.full(u.size, levels[0], float)
    for at, level in zip(steps, levels[1:], strict=True):
        w[u >= at] = level
    return w + rng.normal(0, noise, u.size)


LENGTH, HW = 800.0, 28.0


@pytest.mark.parametrize("seed", range(3))
def test_width_steps_are_found_and_placed_to_a_fraction_of_a_pixel(seed):
    true = (0.4317, 0.6702, 0.9004)
    levels = (56.0, 59.0, 62.5, 57.0)  # 3-10 % steps, like sample 1's
    # coarse: the tracker's profiles, a third of a half-width apart
    u = np.linspace(0.01, 0.997, int(LENGTH / (HW / 3)))
    coarse = width_steps(u, _widths(u, true, levels, 0.3, seed), HW, LENGTH)
    assert len(coarse) == 3
    # the candidates are a fifth of a width apart: up to 6 px off
    assert np.max(np.abs(np.array(coarse) - true)) * LENGTH < 0.6 * HW
    dense = step_windows(coarse, HW, LENGTH, spacing_px=0.25)
    placed = place_steps(dense, _widths(dense, true, levels, 0.3, seed + 10), coarse, HW,
                         LENGTH)
    assert np.max(np.abs(np.array(placed) - true)) * LENGTH < 0.5  # px


@pytest.mark.parametrize("seed", range(3))
def test_a_tube_of_even_width_shows_no_width_step(seed):
    u = np.linspace(0.01, 0.997, 100)
    assert width_steps(u, _widths(u, (), (56.0,), 0.5, seed), HW, LENGTH) == ()
    # nor does a step below the smallest relative one (1 %), however clean
    assert width_steps(u, _widths(u, (0.5,), (56.0, 56.5), 0.01, seed), HW, LENGTH) == ()


def test_a_step_seen_before_is_kept_down_to_the_lower_bar():
    """A 1.6 % step under 0.45 px of scatter stands about 4 standard errors
    out: between :data:`HELD_WIDTH_Z` and :data:`MIN_WIDTH_Z`. Not taken as
    new on most seeds; kept on most where it was seen before; and a joint
    seen before where the width does not step is still dropped."""
    u = np.linspace(0.01, 0.997, int(LENGTH / (HW / 3)))
    new = held = 0
    for seed in range(10):
        w = _widths(u, (0.5,), (56.0, 56.9), 0.45, seed)
        new += len(width_steps(u, w, HW, LENGTH))
        found = width_steps(u, w, HW, LENGTH, held=(0.5,))
        held += len(found) == 1 and abs(found[0] - 0.5) * LENGTH < 2 * HW
        even = _widths(u, (), (56.0,), 0.45, seed)
        assert width_steps(u, even, HW, LENGTH, held=(0.5,)) == ()
    assert new <= 3 and held >= 8, (new, held)


def test_width_steps_skip_profiles_without_a_width():
    u = np.linspace(0.01, 0.997, 100)
    w = _widths(u, (0.5,), (56.0, 62.0), 0.3, 0)
    w[::4] = np.nan
    (found,) = width_steps(u, w, HW, LENGTH)
    assert abs(found - 0.5) * LENGTH < 0.6 * HW
    assert width_steps(u[:10], w[:10], HW, LENGTH) == ()  # too few to tell


def test_a_rounded_end_s_narrowing_on_one_frame_is_no_step():
    """The widths one frame measures across a round cap, as measured on a 7 px
    tube 269 px long (its profiles 2 px apart): 2 % narrow 1.7 half-widths
    from the end, 10 % at 1.1, 15 % at 0.6. Read as a step, they put a joint
    1.3 widths from the tip of a one-section tube."""
    hw, length = 3.56, 269.0
    u = np.arange(0.9, length - 2.0, 2.0) / length
    rng = np.random.default_rng(0)
    w = 7.12 + rng.normal(0, 0.03, u.size)
    from_end = (1 - u) * length / hw
    w -= np.interp(from_end, [0.5, 1.1, 1.7, 2.0], [1.1, 0.71, 0.15, 0.0])
    assert width_steps(u, w, hw, length) == ()
    # a true 4 % step two widths from the end is still found
    stepped = np.where(from_end < 4.0, w - 0.3, w)
    (found,) = width_steps(u, stepped, hw, length)
    assert abs((1 - found) * length / hw - 4.0) < 1.0


def test_a_coarse_spline_missing_a_joint_is_told_by_the_finer_one():
    z, _ = _two_arcs(split=0.7)
    u, pts = _midpoints(z, 0.05, seed=4)
    # coarse with the joint: the finer spline gains nothing
    coarse = fit_to_polyline(z, 0.0, n_coef=10, joints=(0.7,))
    assert spacing_f(coarse, 24, u, pts) < 4.0
    # coarse without it: the finer spline follows the curvature step much better
    blind = fit_to_polyline(z, 0.0, n_coef=8)
    assert spacing_f(blind, 22, u, pts) > 20.0
    assert spacing_f(blind, 8, u, pts) == 0.0  # no finer spline to compare with


def test_a_kept_joint_beyond_the_last_midpoint_does_not_break_the_search():
    # no profile found the tube past 0.78 (a crossing, a faint tip): the
    # curvature after the kept joint at 0.88 is then fixed by nothing, neither
    # data nor roughness (a triple knot lets it step freely)
    z, _ = _two_arcs(split=0.7)
    smooth = fit_to_polyline(z, 0.0, n_coef=30)
    u, pts = _midpoints(z, 0.05, seed=4)
    pts[u > 0.78] = np.nan
    found = find_joints(smooth, u, pts, HALF_WIDTH, keep=(0.75, 0.88))
    assert found[-2:] == (0.75, 0.88)


# -- the width record: the mean width over frames ---------------------------------------------
REC_LENGTH, REC_HW = 343.0, 9.5  # a 19 px wide tube, as fluorescent sample 1 at 480x360
REC_SPACING = REC_HW / 3  # the tracker's profiles


def _record(frames, steps, levels, noise, seed, end=None):
    """A record of ``frames`` frames of a tube stepping at ``steps`` between
    ``levels`` (px), ``noise`` px of scatter per point; ``end``: (px, narrowing
    px) of the last stretch, alike on every frame."""
    record = WidthRecord()
    record.start(REC_LENGTH)
    for i in range(frames):
        w = _widths(record.u, steps, levels, noise, seed * 1000 + i)
        if end is not None:
            w[record.u > 1 - end[0] / REC_LENGTH] -= end[1]
        record.add(w)
    return record


def test_a_width_record_is_the_mean_where_most_frames_measured():
    record = WidthRecord()
    record.start(100.0)
    assert record.u.size == 100 and np.all(np.diff(record.u) > 0)
    a, b = np.full(100, 10.0), np.full(100, 12.0)
    a[:10] = np.nan            # measured on one frame of three: left out
    b[:10] = np.nan
    a[90:] = np.nan            # on two of three: kept
    record.add(a)
    record.add(b)
    record.add(np.full(100, 14.0))
    mean = record.mean()
    assert record.frames == 3
    assert np.all(np.isnan(mean[:10]))
    assert mean[50] == pytest.approx(12.0)
    assert mean[95] == pytest.approx(13.0)


@pytest.mark.parametrize("seed", range(3))
def test_a_width_step_too_faint_for_one_frame_shows_in_the_record(seed):
    """Steps of 0.5 and 1.5 px under 1 px of scatter per point: the faint one
    not told on one frame, both found on 16, each placed as well as it stands
    out (over 30 seeds: the faint one within 2.5 px on 25, at most 6.5 px;
    the clear one 0.3 px; one seed of 30 misses the faint one)."""
    true, levels = (0.43, 0.9), (19.0, 19.5, 18.0)
    one = recorded_steps(_record(1, true, levels, 1.0, seed), REC_HW, REC_LENGTH, REC_SPACING)
    assert not any(abs(j - 0.43) * REC_LENGTH < REC_HW for j in one), one
    many = recorded_steps(_record(16, true, levels, 1.0, seed), REC_HW, REC_LENGTH, REC_SPACING)
    assert len(many) == 2, many
    faint, clear = np.abs(np.array(many) - true) * REC_LENGTH  # px
    assert faint < 0.5 * REC_HW and clear < 0.5


@pytest.mark.parametrize("seed", range(3))
def test_an_even_tube_s_record_shows_no_step(seed):
    record = _record(32, (), (19.0,), 1.0, seed)
    assert recorded_steps(record, REC_HW, REC_LENGTH, REC_SPACING) == ()


def test_a_narrowing_end_is_no_step():
    """The end narrows the measured width alike on every frame (blur over the
    end face, a rounded cap): the mean of many frames would show it as a step
    a width from the tip."""
    record = _record(32, (), (19.0,), 1.0, 0, end=(4.0, 3.0))
    assert recorded_steps(record, REC_HW, REC_LENGTH, REC_SPACING) == ()


def test_a_record_resolves_once_every_step_worth_keeping_would_show():
    """A 1.5 % step (the smallest kept) under 0.05 px of scatter shows on two
    frames: more frames are not needed. Under 1 px of scatter it does not,
    nor on 4 frames, and the record goes on."""
    def resolves(frames, noise):
        return record_resolves(_record(frames, (), (19.0,), noise, 0), REC_HW, REC_LENGTH,
                               REC_SPACING)

    assert resolves(2, 0.05)
    assert not resolves(2, 1.0) and not resolves(4, 1.0)
