"""Moving a tracked curve's base to where the first frames vote it is."""

import numpy as np
import pytest

from pipeline.centreline import fit_to_polyline, resample, tip_point
from pipeline.track import moved_base


def _turning_start():
    """A tracked structure whose first 40 px turn from 65 to 35 deg (a skeleton
    that came in along a holder's wall), then a tube bent by -100 deg."""
    s = np.linspace(0.0, 420.0, 4201)
    phi = np.radians(np.where(s < 40, 65 - 30 * s / 40, 35 - 100 * (s - 40) / 380))
    z = 100 + 300j + np.concatenate([[0], np.cumsum(np.diff(s) * np.exp(1j * phi[1:]))])
    return fit_to_polyline(z, np.radians(65.0), n_coef=24)


def test_a_base_moved_towards_the_tip_keeps_the_tip_where_it_was():
    curve = _turning_start()
    axis = np.exp(1j * curve.base_angle)
    moved = moved_base(curve, curve.base + 29.0 * axis)
    # (sliding the whole curve 29 px along the base axis put the tip 25 px off;
    # kept to a px, the first span turning from the base tangent as voted to the
    # curve's there, 22 deg off it: well within a refit's reach)
    assert abs(tip_point(moved) - tip_point(curve)) < 1.0
    # its new base lies on the curve, as far along the axis as asked
    s, z = resample(curve, 0.25)
    assert np.abs(z - moved.base).min() < 0.3
    assert np.real((moved.base - curve.base) * np.conj(axis)) == pytest.approx(29.0, abs=0.3)
    # the base tangent is the one the votes measured against
    assert moved.base_angle == pytest.approx(curve.base_angle)


def test_a_base_moved_back_runs_straight_along_the_axis_and_turns_as_voted():
    curve = _turning_start()
    axis = np.exp(1j * curve.base_angle)
    moved = moved_base(curve, curve.base - 20.0 * axis, turn=np.radians(1.0))
    assert moved.length == pytest.approx(curve.length + 20.0)
    assert abs(moved.base - (curve.base - 20.0 * axis)) < 1e-9
    assert moved.base_angle == pytest.approx(curve.base_angle + np.radians(1.0))
    assert abs(tip_point(moved) - tip_point(curve)) < 0.5
    # only turned, the shape past the first span is the one it was
    turned = moved_base(curve, None, turn=np.radians(1.0))
    assert turned.length == curve.length and turned.base == curve.base
    assert turned.coef[-1] + turned.base_angle == pytest.approx(curve.coef[-1]
                                                                  + curve.base_angle)


def _held_back(curves):
    from pipeline.track import FrameTrack

    return [(FrameTrack(k, "ok", c, "fast"), None) for k, c in enumerate(curves)]


def test_a_base_settled_past_a_hooked_start_takes_the_tube_s_tangent_there():
    from pipeline.track import _turn_past_holder

    curve = _turning_start()
    axis = np.exp(1j * curve.base_angle)
    # the votes put the base 29 px along the axis, where the tube runs at about
    # 35 deg (its first 40 px turn from 65): the votes' own turn, measured on
    # fits from the old base, is not the tube's
    base = curve.base + 29.0 * axis
    turn, aside = _turn_past_holder(_held_back([curve, curve]), [curve], base,
                                    np.radians(0.2), half_width=8.0)
    assert aside == 0j  # (no frames kept to measure it again on)
    _, z = resample(curve, 0.25)
    at = int(np.argmax(np.real((z - curve.base) * np.conj(axis)) >= 29.0))
    there = np.angle(z[at + 1] - z[at])
    assert curve.base_angle + turn == pytest.approx(there, abs=np.radians(0.3))
    assert np.degrees(curve.base_angle + turn) < 50.0
    # a base moved by less than a half-width keeps the votes' turn
    near = curve.base + 5.0 * axis
    assert _turn_past_holder(_held_back([curve]), [curve], near, np.radians(0.2),
                             half_width=8.0) == (np.radians(0.2), 0j)
    # and so does one not moved at all
    assert _turn_past_holder(_held_back([curve]), [curve], None, np.radians(0.2),
                             half_width=8.0) == (np.radians(0.2), 0j)


def test_a_short_move_slides_the_curve_a_long_one_cuts_it():
    curve = _turning_start()
    axis = np.exp(1j * curve.base_angle)
    slid = moved_base(curve, curve.base + 3.0 * axis, slide_px=8.0)
    assert slid.coef.tolist() == curve.coef.tolist()
    assert slid.base == pytest.approx(curve.base + 3.0 * axis)
    assert slid.length == pytest.approx(curve.length - 3.0)
    cut = moved_base(curve, curve.base + 29.0 * axis, slide_px=8.0)
    assert abs(tip_point(cut) - tip_point(curve)) < 1.0


def base_on(curve, base):
    """The point of ``curve`` where it first gets as far along its base axis
    as ``base`` (where the base is cut)."""
    from pipeline.centreline import cut_base
    from pipeline.track import _cut_at

    return cut_base(curve, _cut_at(curve, base)[0]).base


def test_a_base_settled_past_a_hooked_start_is_measured_again_on_the_frames():
    from pipeline.refine import TubeLook
    from pipeline.track import FrameTrack, TrackSettings, _turn_past_holder
    from tests.pipeline.synthetic import tube_image

    # the tracked structure's first 40 px turn from 65 to 30 deg (the skeleton
    # hooked into a wide glass), then it runs straight; the votes put the base
    # 29 px along the axis, near the glass's mouth, where the tube in the frames
    # leaves along 30 deg: the curves' own tangent there (43 deg) still
    # carries the hook, the fit from there (its base tangent free) does not
    s = np.linspace(0.0, 420.0, 4201)
    phi = np.radians(np.where(s < 40, 65 - 35 * s / 40, 30.0))
    z = 100 - 380j + np.concatenate([[0], np.cumsum(np.diff(s) * np.exp(1j * phi[1:]))])
    curve = fit_to_polyline(z, np.radians(65.0), n_coef=24)
    axis = np.exp(1j * curve.base_angle)
    base = curve.base + 29.0 * axis
    _, pts = resample(curve, 0.25)
    # (the tube in the frames begins 6 px on from there and 2.5 px aside of
    # the hooked curve)
    ahead = np.exp(1j * np.radians(30.0))
    mouth = (pts[int(np.argmax(np.real((pts - curve.base) * np.conj(axis)) >= 29.0))]
             + (6.0 + 2.5j) * ahead)
    img = tube_image((480, 640), mouth, np.radians(30.0), 380.0, 1e-12, 8.0, noise=0.005)
    look = TubeLook(-1, np.full(9, 8.0), 0.05)
    held = [(FrameTrack(k, "ok", curve, "fast"), img.astype(np.float32)) for k in range(3)]
    old, _ = _turn_past_holder(held, [curve], base, 0.0, half_width=8.0)
    new, aside = _turn_past_holder(held, [curve], base, 0.0, 8.0, look, TrackSettings())
    assert abs(np.degrees(curve.base_angle + old) - 30.0) > 5.0
    assert np.degrees(curve.base_angle + new) == pytest.approx(30.0, abs=0.5)
    # and the base found again where the tube begins, on its axis
    assert abs(base_on(curve, base) - mouth) > 5.0
    assert abs(base_on(curve, base) + aside - mouth) < 1.0
    # a frame whose fit from there fails the checks keeps the curves' tangent
    blank = [(r, np.full_like(image, 0.5)) for r, image in held]
    assert _turn_past_holder(blank, [curve], base, 0.0, 8.0, look) == (pytest.approx(old), 0j)


def test_a_base_settled_past_a_holder_takes_the_holder_s_line_where_no_pipette_axis_shows(
        monkeypatch):
    import pipeline.track as T
    from pipeline.refine import TubeLook
    from pipeline.track import FrameTrack, TrackSettings, _turn_past_holder
    from tests.pipeline.synthetic import arc_axis, tube_image

    # the tracked structure runs 70 px up a pipette 1.6x the tube's width
    # before the tube, which leaves the mouth at 90 deg and bends at once; the
    # votes put the base at the mouth. A fit from there, its base tangent
    # free, leans into the bend; the pipette's own line does not (an
    # independent scene, mirrored: 0.6 deg off on every frame)
    hw, mouth = 8.0, 320 - 400j
    img = tube_image((480, 640), mouth, np.radians(90.0), 300.0, -4.5 / 300, hw, noise=0.005,
                     pipette_half_width=1.6 * hw).astype(np.float32)
    tube, _ = arc_axis(mouth, np.radians(90.0), 300.0, -4.5 / 300, n=600)
    curve = fit_to_polyline(np.concatenate([mouth - 1j * np.arange(70, 0, -1), tube]),
                            np.radians(90.0), n_coef=24)
    look = TubeLook(-1, np.full(9, hw), 0.05)
    held = [(FrameTrack(k, "ok", curve, "fast"), img) for k in range(3)]
    # (where the pipette's axis is not found past the base)
    monkeypatch.setattr(T, "pipette_axis", lambda *args, **kwargs: None)
    turn, _ = _turn_past_holder(held, [curve], mouth, 0.0, hw, look, TrackSettings())
    assert np.degrees(curve.base_angle + turn) == pytest.approx(90.0, abs=0.05)
    monkeypatch.setattr(T, "_holder_line", lambda *args: None)
    leaning, _ = _turn_past_holder(held, [curve], mouth, 0.0, hw, look, TrackSettings())
    assert abs(np.degrees(curve.base_angle + leaning) - 90.0) > 0.15
