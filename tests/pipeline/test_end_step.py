"""A dark tube's end whose edge midpoints step sideways off the rest's line
(a sealed tip past an off-centre lumen): measured, told over the frames, and
its side edges left out of the fits, or given an offset of their own."""
from dataclasses import replace

import numpy as np
import pytest

from pipeline.centreline import fit_to_polyline
from pipeline.refine import (
    END_PROFILE_HW,
    END_STEP_ZONES_HW,
    TubeLook,
    _own_offset,
    end_step_left_out,
    refine,
)
from pipeline.track import END_STEP_MAX_FRAMES, END_VOTE_FRAMES, FrameTrack, _EndStepVotes
from pipeline.tracks import _end_step_note
from tests.pipeline.synthetic import arc_axis, tube_image

SHAPE = (200, 480)
BASE = 40 - 100j
LENGTH = 400.0
HW = 8.0
STEP_PX = 12.0  # 1.5 half-widths


def _stepped_tube(shift: float, noise: float = 0.0, ramp_px: float = 0.0):
    """A dark straight tube along +x whose last ``STEP_PX`` sit ``shift`` px to
    its left, reached over ``ramp_px`` (a blurred lumen's end) or at once."""
    kw = dict(polarity=-1, noise=noise, seed=3)
    body = tube_image(SHAPE, BASE, 0.0, LENGTH, 0.0, HW, **kw)
    end = tube_image(SHAPE, BASE + 1j * shift, 0.0, LENGTH, 0.0, HW, **kw)
    past = np.arange(SHAPE[1])[None, :] - (BASE.real + LENGTH - STEP_PX)
    share = np.clip(past / ramp_px, 0.0, 1.0) if ramp_px else (past >= 0)
    return (share * end + (1.0 - share) * body).astype(np.float32)


def _truth():
    z, _ = arc_axis(BASE, 0.0, LENGTH, 0.0)
    return fit_to_polyline(z, 0.0, n_coef=12)


def _look(step_px):
    return TubeLook(-1, np.full(5, HW), 0.05, end_step_px=step_px)


@pytest.mark.parametrize("shift", [0.0, 0.3, -0.3])
def test_the_end_steps_are_how_far_the_ends_midpoints_sit_off_the_rests_line(shift):
    r = refine(_stepped_tube(shift), _truth(), _look(None), iterations=8, tol_px=0.005)
    assert r.end_steps.shape == (len(END_STEP_ZONES_HW), 3)
    offset, weight, se = r.end_steps.T
    # the full step is seen over a stretch a little longer than it (over a
    # shorter one the rest's line is pulled by the step's profiles left in)
    best = int(np.argmax(offset**2 * weight))
    assert offset[best] == pytest.approx(shift, abs=0.05)
    if shift:
        assert STEP_PX <= END_STEP_ZONES_HW[best] * HW <= STEP_PX + HW
    assert np.all(np.diff(weight) >= 0) and np.all((se >= 0) & (se < 0.05))
    # not measured once told; measured on a tube brighter than its
    # surroundings too (where only a plug is told from them)
    assert refine(_stepped_tube(shift), _truth(), _look(STEP_PX), iterations=2).end_steps is None
    bright = TubeLook(1, np.full(5, HW), 0.05, end_step_px=None)
    assert refine(1.0 - _stepped_tube(shift), _truth(), bright, iterations=2).end_steps is not None


@pytest.mark.parametrize("shift", [0.0, 0.3, -0.3])
@pytest.mark.parametrize("own", [False, True])
def test_once_told_the_stretch_s_offset_is_still_measured(shift, own):
    """Once told, the stretch's side edges are left out of the fit (or given
    an offset of their own, ``own``): how far their midpoints sit off the
    rest's line is still measured (``told_offset``), for the plug test to
    see every frame's, as :attr:`Refined.end_steps` measured it over the
    same stretch before (two thirds of the step: the rest's line is pulled
    by the profile straddling it); not before it is told, nor where it was
    told none."""
    look = replace(_look(STEP_PX), end_step_offset=1.0 if own else 0.0)
    assert end_step_left_out(_truth(), STEP_PX, look.end_step_offset) != own
    r = refine(_stepped_tube(shift), _truth(), look, iterations=8, tol_px=0.005)
    zone = int(np.argmin(np.abs(np.asarray(END_STEP_ZONES_HW) * HW - STEP_PX)))
    before = refine(_stepped_tube(shift), _truth(), _look(None), iterations=8, tol_px=0.005)
    assert r.told_offset == pytest.approx(before.end_steps[zone, 0], abs=0.01)
    assert r.told_offset == pytest.approx(0.67 * shift, abs=0.03)
    # and each profile's near the end, off the curve the farther ones fit:
    # the step's whole, nothing past it (the one straddling it between)
    d, off, _ = r.end_profile.T
    assert d.max() < END_PROFILE_HW * HW
    assert np.allclose(off[d < STEP_PX - 1], shift, atol=0.02)
    assert np.allclose(off[d > STEP_PX + 1], 0.0, atol=0.03)
    assert refine(_stepped_tube(shift), _truth(), _look(None), iterations=2).end_profile is None
    assert np.isnan(refine(_stepped_tube(shift), _truth(), _look(None), iterations=2).told_offset)
    assert np.isnan(refine(_stepped_tube(shift), _truth(), _look(0.0), iterations=2).told_offset)


@pytest.mark.parametrize(("polarity", "grows", "told"), [
    (-1, False, True), (1, False, False), (1, True, True), (-1, True, True)])
def test_a_bright_tube_s_end_is_told_only_where_it_grows_with_the_bend(polarity, grows, told):
    # a bright tube's shading makes steady "steps" of its own (7 of 182 own
    # fluorescent scenes): there only a straight plug's offsets, growing with
    # the bend, are told
    votes = _EndStepVotes()
    look = TubeLook(polarity, np.full(5, HW), 0.05, end_step_px=None)
    bends = np.radians(np.linspace(-20.0, -200.0, 8))
    zones = np.asarray(END_STEP_ZONES_HW) * HW
    for k, bend in enumerate(bends):
        offset = -0.2 * bend if grows else 0.3
        steps = np.zeros((zones.size, 3))
        steps[:, 0] = np.where(zones <= STEP_PX, offset, offset * STEP_PX / zones)
        steps[:, 1] = zones
        steps[:, 2] = 0.01
        steps[:, 0] += np.random.default_rng(k).normal(0.0, 0.01, zones.size)
        look = votes.add(steps, look, bend)
        if look.end_step_px is not None:
            break
    assert (bool(look.end_step_px) if look.end_step_px is not None else False) == told


def _told(shift: float, ramp_px: float = 0.0) -> TubeLook:
    """The look the first frames' votes give, on noisy frames of the stepped tube."""
    votes, look = _EndStepVotes(), _look(None)
    for k in range(END_VOTE_FRAMES):
        img = _stepped_tube(shift, noise=0.01, ramp_px=ramp_px)
        img = img + np.random.default_rng(k).normal(0.0, 0.01, img.shape).astype(np.float32)
        look = votes.add(refine(img, _truth(), look, iterations=8).end_steps, look)
    return look


@pytest.mark.parametrize("ramp_px", [0.0, 0.5 * STEP_PX])
def test_a_told_step_keeps_the_tip_tangent_on_the_rests_line(ramp_px):
    look = _told(0.4, ramp_px)
    assert STEP_PX - ramp_px <= look.end_step_px <= STEP_PX + HW
    img = _stepped_tube(0.4, noise=0.01, ramp_px=ramp_px)
    followed = refine(img, _truth(), _look(0.0), iterations=8, tol_px=0.005)
    told = refine(img, _truth(), look, iterations=8, tol_px=0.005)
    # the truth's tip tangent is the rest's: 0 (the end is shifted, not turned)
    tip_followed = abs(np.degrees(followed.curve.coef[-1]))
    assert tip_followed > 0.8
    assert abs(np.degrees(told.curve.coef[-1])) < 0.25 * tip_followed
    # a tube without a step is told none
    assert _told(0.0).end_step_px is None


def test_the_own_offset_is_the_least_squares_with_an_extra_unknown():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(30, 4)), rng.normal(size=30)
    weights = rng.uniform(0.2, 1.0, 30)
    zone = np.arange(30) >= 22
    a_w, b_w = a * weights[:, None], b * weights
    extra = np.column_stack([a_w, np.where(zone, weights, 0.0)])
    x_extra = np.linalg.lstsq(extra, b_w, rcond=None)[0][:4]
    a_o, b_o = _own_offset(a_w, b_w, weights, zone)
    np.testing.assert_allclose(np.linalg.lstsq(a_o, b_o, rcond=None)[0], x_extra, atol=1e-10)
    # the rows outside the zone are untouched; an empty zone changes nothing
    np.testing.assert_array_equal(a_o[~zone], a_w[~zone])
    a_n, b_n = _own_offset(a_w, b_w, weights, np.zeros(30, bool))
    np.testing.assert_array_equal(a_n, a_w)


def test_a_stretch_is_left_out_only_where_short_and_small_against_the_last_section():
    curve = _truth()  # 400 px, no joints
    assert end_step_left_out(curve, 12.0, 0.3)
    assert end_step_left_out(curve, 100.0, -0.5)
    assert not end_step_left_out(curve, 101.0, 0.3)  # over a quarter of the tube
    assert not end_step_left_out(curve, 12.0, 0.6)  # a bend the fit misses
    assert not end_step_left_out(curve, 0.0, 0.0)  # none told
    # with a joint at 0.9 the last section is 40 px
    jointed = fit_to_polyline(arc_axis(BASE, 0.0, LENGTH, 0.0)[0], 0.0, n_coef=12,
                              joints=(0.9,))
    assert end_step_left_out(jointed, 9.0, 0.3) and not end_step_left_out(jointed, 11.0, 0.3)


def _steps(offsets, weight=6.0, se=0.02):
    """An ``end_steps`` row set: ``offsets`` per stretch."""
    offsets = np.asarray(offsets, float)
    return np.column_stack([offsets, np.full(offsets.size, weight), np.full(offsets.size, se)])


def test_a_steady_step_is_told_and_scatter_or_a_growing_misfit_is_not():
    z = np.array(END_STEP_ZONES_HW)
    # a step over 1.5 half-widths: full there, diluted beyond, partial before
    step = np.where(z <= 1.5, 0.25 * z / 1.5, 0.25 * 1.5 / z)
    votes, look = _EndStepVotes(), _look(None)
    for k in range(END_VOTE_FRAMES):
        assert look.end_step_px is None, k  # not before enough frames
        look = votes.add(_steps(step + 0.01 * (-1) ** k), look)
    assert look.end_step_px == pytest.approx(1.5 * HW)
    assert look.end_step_offset == pytest.approx(0.25, abs=0.02)
    # zero-mean scatter: never told, and no longer looked for after a while
    rng = np.random.default_rng(2)
    votes, look = _EndStepVotes(), _look(None)
    for _ in range(END_STEP_MAX_FRAMES):
        look = votes.add(_steps(rng.normal(0.0, 0.2, z.size)), look)
    assert look.end_step_px == 0.0 and look.end_step_offset == 0.0
    # an offset still growing at the longest stretch is a bend the fit misses
    votes, look = _EndStepVotes(), _look(None)
    for _ in range(END_VOTE_FRAMES + 2):
        look = votes.add(_steps(0.3 * z / z[-1]), look)
    assert not look.end_step_px
    # steady but within the edges' noise: not told
    votes, look = _EndStepVotes(), _look(None)
    for _ in range(END_VOTE_FRAMES + 2):
        look = votes.add(_steps(step, se=0.2), look)
    assert not look.end_step_px


def test_the_run_notes_say_whether_the_ends_side_edges_were_left_out():
    curve = _truth()
    told = [FrameTrack(k, "ok", curve, "fast", end_step=(12.0, 0.31) if k >= 4 else None,
                       end_steps=_steps(np.zeros(3)) if k < 4 else None) for k in range(6)]
    note = _end_step_note(told)
    assert note.startswith("the last 12.0 px of the tube stepped sideways") and (
        "from frame 4 on" in note and "+0.31 px" in note
        and "left out of the fits on 2 of 2 frames" in note and "the other" not in note)
    big = [replace(r, end_step=(12.0, 0.8)) if r.end_step else r for r in told]
    note = _end_step_note(big)
    assert "left out of the fits on 0 of 2 frames" in note and "a bend the fits miss" in note
    assert "offset of their own on the other 2 (the offset over 0.5 px" in note
    # a stretch too long against the last section: a lumen's, but kept in
    short = replace(curve, length=40.0)
    long_ = [replace(r, curve=short) for r in told]
    note = _end_step_note(long_)
    assert "off-centre lumen" in note and "on the other 2 (the stretch over 25%" in note
    looked = [FrameTrack(k, "ok", curve, "fast", end_steps=_steps(np.zeros(3))) for k in range(3)]
    assert _end_step_note(looked).startswith("the tube's end did not step sideways")
    # a bright tube's end is not looked at this way: no note
    assert _end_step_note([FrameTrack(0, "ok", curve, "fast")]) is None
