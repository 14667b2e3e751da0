"""Holding a jointed tube's last section in proportion to the rest of it
(:class:`pipeline.refine.LastSection`, :func:`pipeline.track.hold_section_ratio`)."""

import re
from dataclasses import replace

import numpy as np
import pytest

from pipeline.refine import _last_section
from pipeline.track import FrameTrack, hold_section_ratio
from tests.pipeline.synthetic import two_sections

JOINT = 0.85
LENGTH = 400.0
K_BODY = 1 / 100     # 1/px at full load: the rest turns 3.4 rad
SIGMA = 0.01         # noise of a frame's last-section curvature, rad per unit fraction


def _system(size, seed=0):
    """A well-conditioned symmetric positive definite stand-in for a fit's system."""
    m = np.random.default_rng(seed).normal(size=(size, size))
    return m @ m.T + size * np.eye(size)


def _ratio(curve):
    sec = _last_section(_system(curve.coef.size + 1), curve.coef, curve.joints, 1.0)
    return sec.last / sec.before


def _frames(loads, ratios, noise=None):
    """FrameTracks of a two-section tube at ``loads`` (fractions of full),
    whose last section bends ``ratios`` times the rest, plus ``noise`` on its
    mean curvature (rad per unit fraction), each knowing its fit's noise is
    SIGMA."""
    noise = np.zeros(len(loads)) if noise is None else noise
    out = []
    for i, (p, r, e) in enumerate(zip(loads, ratios, noise, strict=True)):
        k_tip = r * K_BODY * p + e / LENGTH
        curve = two_sections(K_BODY * p, k_tip, joint=JOINT, length=LENGTH)
        sec = _last_section(_system(curve.coef.size + 1, seed=i), curve.coef, curve.joints, 1.0)
        h = np.array([1.0, -r])
        sec = replace(sec, var=SIGMA**2 / float(h @ sec.cov @ h))
        out.append(FrameTrack(i, "ok", curve, "fast", last_section=sec))
    return out


def _held_ratio(note):
    return float(re.search(r"held at ([-\d.]+) times", note).group(1))


def test_a_held_last_section_takes_the_ratio_at_the_least_cost():
    curve = two_sections(1 / 100, 1 / 300, joint=JOINT)
    system = _system(curve.coef.size + 1)
    sec = _last_section(system, curve.coef, curve.joints, 0.5)
    assert sec.last / sec.before == pytest.approx(1 / 3, abs=0.01)
    assert sec.before_turn == pytest.approx(LENGTH * JOINT / 100, rel=1e-3)
    delta, rise = sec.held(0.5)
    moved = curve.coef + delta[:-1]
    again = _last_section(system, moved, curve.joints, 0.5)
    assert again.last / again.before == pytest.approx(0.5, rel=1e-9)
    # the least change in the fit's own metric: its cost is the rise reported
    assert rise == pytest.approx(delta @ system @ delta / 0.5, rel=1e-9)
    # a shape that already has the ratio is left alone
    delta, rise = sec.held(sec.last / sec.before)
    assert np.abs(delta).max() < 1e-12 and rise < 1e-20


def test_frames_that_agree_on_a_ratio_are_held_to_it():
    loads = np.linspace(0.0, 1.0, 12)
    noise = np.random.default_rng(1).normal(0.0, SIGMA, loads.size)
    frames = _frames(loads, np.full(loads.size, 0.4), noise)
    out, note = hold_section_ratio(frames)
    assert note.startswith("last section's mean curvature held at")
    ratio = _held_ratio(note)
    # what the noisy frames tell: closer to the truth than most single frames
    assert ratio == pytest.approx(0.4, abs=0.005)
    singles = [abs(_ratio(f.curve) - 0.4) for f in frames[3:]]
    assert abs(ratio - 0.4) < np.median(singles)
    held = [f for f, g in zip(frames, out, strict=True) if g.curve is not f.curve]
    assert len(held) >= 10
    for f, g in zip(frames, out, strict=True):
        if g.curve is not f.curve and f.last_section.before_turn > 0.1:
            assert _ratio(g.curve) == pytest.approx(ratio, abs=1e-3)
    # the straight first frame gets a straight last section too
    assert abs(out[0].curve.coef[-1]) < abs(frames[0].curve.coef[-1])


def test_a_frame_far_off_the_ratio_is_left_as_fitted():
    loads = np.linspace(0.1, 1.0, 10)
    ratios = np.full(loads.size, 0.4)
    ratios[6] = 1.0
    out, note = hold_section_ratio(_frames(loads, ratios))
    assert _held_ratio(note) == pytest.approx(0.4, abs=1e-3)
    assert out[6].curve.coef[-1] == _frames(loads, ratios)[6].curve.coef[-1]
    assert f"on {loads.size - 1} of {loads.size} frames" in note


def test_frames_that_disagree_are_left_as_fitted():
    loads = np.linspace(0.1, 1.0, 10)
    frames = _frames(loads, np.where(np.arange(loads.size) % 2, 0.2, 0.8))
    out, note = hold_section_ratio(frames)
    assert "do not agree" in note
    assert all(g is f for f, g in zip(frames, out, strict=True))


def test_too_few_bent_frames_tell_no_ratio():
    loads = np.r_[np.full(8, 0.01), 0.5, 1.0]   # the rest turns 2 deg on 8 of them
    frames = _frames(loads, np.full(loads.size, 0.4))
    out, note = hold_section_ratio(frames)
    assert "2 frames bend the rest" in note and "too few" in note
    assert all(g is f for f, g in zip(frames, out, strict=True))


def test_a_tube_without_joints_is_not_held():
    frames = [replace(f, last_section=None) for f in _frames([0.5, 1.0], [0.4, 0.4])]
    out, note = hold_section_ratio(frames)
    assert "no section joints" in note
    assert all(g is f for f, g in zip(frames, out, strict=True))

