"""A holder taken for the tube's base stretch is cut off, told by the video."""

import json
from dataclasses import replace

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline import pipette
from pipeline.centreline import Curve, resample, tip_point
from pipeline.tracks import track_video
from tests.pipeline.synthetic import tube_image

BASE, ANGLE, LENGTH, HW = 420 - 240j, np.pi, 300.0, 8.0
#: Bend of the last frame, rad (clockwise)
TURN = -3.5


def _video(tmp_path, holder: float | None, n: int = 8, base=BASE, turn=TURN, hw=HW,
           holder_look: float = 0.5, capillary: tuple | None = None, size=(480, 640),
           holder_offset: float = 0.0):
    """A dark tube bending clockwise from straight to 200 deg, held (``holder``:
    that many of its half-widths wide, ``holder_look`` times as dark, running to
    the border, its axis ``holder_offset`` of its half-widths to the left of
    the tube's) or starting at the border itself, or held by a tapered glass
    capillary (``capillary``: its radius at the tube and far from it, and the
    taper's length, in half-widths, and its walls' depth; see
    :func:`_capillary`); frames (``size``: rows, cols) as PNGs, and the true
    bends (deg)."""
    folder = tmp_path / "frames"
    folder.mkdir()
    bends = []
    for k in range(n):
        kappa = turn * k / (n - 1) / LENGTH
        img = tube_image(size, base, ANGLE, LENGTH, kappa + 1e-12, hw, noise=0.01,
                         seed=k, pipette_half_width=None if holder is None else holder * hw,
                         pipette_contrast=holder_look, pipette_offset=holder_offset * hw)
        if capillary is not None:
            r_tip, r_far, taper, line = capillary
            img = _capillary(img, r_tip * hw, r_far * hw, taper * hw, base=base, line=line)
        cv2.imwrite(str(folder / f"f{k:02d}.png"), (img * 255).round().astype(np.uint8))
        bends.append(np.degrees(kappa * LENGTH))
    return folder, np.array(bends)


def _cut_and_measured(folder, out, bends, base=BASE) -> dict:
    """Track ``folder`` into ``out``; assert every frame measured, its base
    where the tube leaves the holder (1.5 px), its length (1 %) and bend
    (0.5 deg) the tube's; the run's record."""
    track_video(folder, out, um_per_px=1.0)
    t = pd.read_csv(out / "tracks.csv")
    assert (t.status == "ok").all()
    assert np.hypot(t.base_x_um - base.real, t.base_y_um - base.imag).max() < 1.5
    assert np.abs(t.length_um / LENGTH - 1).max() < 0.01
    assert np.abs(t.bend_angle_deg - bends).max() < 0.5
    return json.loads((out / "run.json").read_text())


def test_a_holder_as_wide_as_the_tube_is_cut_off_every_frame(tmp_path, monkeypatch):
    # a band as wide as the tube, half as dark, running from the base to the
    # border: no width step, so the detector runs the tube on into it
    folder, bends = _video(tmp_path, holder=1.0)
    run = _cut_and_measured(folder, tmp_path / "out", bends)
    assert "holder" in run["base_source"]
    assert any("holder (pipette) taken for the tube" in n for n in run["left_out_and_why"])
    assert any("profile stepped there" in n for n in run["left_out_and_why"])
    # without the test the tube runs on to the border, 218 px too long
    monkeypatch.setattr(pipette, "MIN_CHANGE", np.inf)
    monkeypatch.setattr(pipette, "MIN_HINGE_GAIN", np.inf)
    track_video(folder, tmp_path / "kept", um_per_px=1.0)
    kept = pd.read_csv(tmp_path / "kept" / "tracks.csv")
    assert kept.length_um.min() > LENGTH + 150


def test_a_holder_showing_for_under_three_tube_widths_is_cut_off(tmp_path):
    # 40 px of holder between the base and the border: 2.5 of the tube's widths,
    # but under 2 of the first frame's rough widths (its mask, blurred edges and
    # all, came out 1.4x as wide), by which a holder's shortest stretch is judged
    base = 600 - 240j
    folder, bends = _video(tmp_path, holder=1.0, base=base)
    run = _cut_and_measured(folder, tmp_path / "out", bends, base=base)
    assert any("holder (pipette) taken for the tube" in n for n in run["left_out_and_why"])


def test_a_holder_far_longer_than_the_tube_is_cut_off(tmp_path):
    # a holder crossing most of a wide frame: 980 px of it before a 300 px
    # tube, which is under a quarter of the structure tracked (an independent
    # renderer's pipette across half a 1280 px frame before a 90 px tube: its
    # base had been put at the border, 595 px away)
    base = 620 - 240j
    folder, bends = _video(tmp_path, holder=1.0, base=base, size=(480, 1600))
    run = _cut_and_measured(folder, tmp_path / "out", bends, base=base)
    assert any("holder (pipette) taken for the tube" in n for n in run["left_out_and_why"])


@pytest.mark.parametrize("holder, offset", [(1.6, 0.5), (1.5, 0.3)])
def test_a_holder_off_the_tube_s_axis_is_cut_at_its_end_face(tmp_path, holder, offset):
    # a holder 1.5-1.6x the tube's width, its axis 2.4-4 px beside the tube's
    # (a tube lying to one side of its holder's bore): the fit through both
    # hooks over from the holder's axis to the tube's past the end face, and
    # the profiles across it become the tube's only past the face, where the
    # base had been put: 19 px past it (length 6 % over; the frames cut anew
    # where they cross the face), or 1.3 px before it and 1.7 px aside (each
    # frame's tube carried on along the axis); looked for again along the
    # tube's own axis, the face is found
    folder, bends = _video(tmp_path, holder=holder, holder_look=1.0, holder_offset=offset)
    run = _cut_and_measured(folder, tmp_path / "out", bends)
    assert any("along the tube's own axis" in n for n in run["left_out_and_why"])


def test_a_holder_of_the_tube_s_own_look_is_cut_where_the_bending_starts(tmp_path,
                                                                       monkeypatch):
    # a holder exactly as wide and as dark as the tube: one frame cannot tell
    # where the tube starts (the profiles do not step), but the frames bending
    # from there on do
    folder, bends = _video(tmp_path, holder=1.0, holder_look=1.0)
    run = _cut_and_measured(folder, tmp_path / "out", bends)
    assert any("leave its line there as a tube clamped there would" in n
               for n in run["left_out_and_why"])
    # the profiles alone do not tell it: without the hinge it runs on to the border
    monkeypatch.setattr(pipette, "MIN_HINGE_GAIN", np.inf)
    track_video(folder, tmp_path / "kept", um_per_px=1.0)
    kept = pd.read_csv(tmp_path / "kept" / "tracks.csv")
    assert kept.length_um.min() > LENGTH + 150


def _clamped_tracks(s0: float, turns, noise: float = 0.0, stiff: float = 0.0,
                    tube: float = 300.0):
    """Frames of a tube lying straight along +x for ``s0`` px from the origin
    (or bending there at ``stiff`` times the rest's curvature), then bending at
    steady curvature over ``tube`` px (its end turned ``turns``, rad), with
    ``noise`` rad on its tangent angle: FrameTracks."""
    from pipeline.centreline import basis_of, make_basis
    from pipeline.track import FrameTrack

    length = s0 + tube
    n = 40
    basis = make_basis(n, basis_of(Curve(0j, 0.0, length, np.zeros(n))).n_grid)
    s = basis.u * length
    rng = np.random.default_rng(1)
    out = []
    for turn in turns:
        phi = (turn / tube * (np.clip(s - s0, 0.0, None) + stiff * np.minimum(s, s0))
               + noise * rng.normal(size=s.size))
        coef, *_ = np.linalg.lstsq(basis.values, phi, rcond=None)
        curve = Curve(0j, 0.0, length, coef)
        out.append(FrameTrack(frame=len(out), status="ok", curve=curve, stage="fast"))
    return out


@pytest.mark.parametrize("s0", [0.0, 60.0, 150.0])
def test_the_hinge_is_where_a_clamped_tube_starts_to_bend(s0):
    results = _clamped_tracks(s0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)
    at, gain, spread = pipette.motion_hinge(results, 5.0, s0 + 40.0)
    assert at == pytest.approx(s0, abs=2.0)
    assert spread <= pipette.HINGE_SPREAD_PX
    if s0 > 0:
        assert gain > pipette.MIN_HINGE_GAIN
    else:
        assert gain == pytest.approx(0.0, abs=1e-6)
    # frames bent less than MIN_BEND_DEG tell nothing; two bent ones no spread
    assert pipette.motion_hinge(results[:2], 5.0, s0 + 40.0) == (0.0, 0.0, np.inf)
    assert pipette.motion_hinge(results[:4], 5.0, s0 + 40.0)[2] == np.inf


def test_a_hinge_in_noisy_frames_is_not_spread_by_their_noise():
    """Sixteen bent frames whose tangents scatter: each frame's own hinge
    lies anywhere in a few px (their range 4 px, over HINGE_SPREAD_PX: the
    holder was not cut, on an independent renderer's dim fluorescent tube
    whose holder then passed for 91 px of it), but does not move with the
    bend."""
    results = _clamped_tracks(60.0, [0.0, *np.linspace(0.5, 3.0, 16)], noise=5e-3)
    at, gain, spread = pipette.motion_hinge(results, 5.0, 100.0)
    assert at == pytest.approx(60.0, abs=2.0) and gain > pipette.MIN_HINGE_GAIN
    assert spread <= pipette.HINGE_SPREAD_PX


def test_the_stretch_that_stood_still_does_not_wear_down_over_many_frames():
    """A holder of 100 px that stands still on 120 bent frames: every frame
    keeps all of it, and so does their stretch (each frame's last point
    within it lay up to a resampling step short, and the stretch came down
    by that on every frame: an independent 150-frame video's 102 px to 53,
    its holder then not cut, its base 93 px off)."""
    # (each frame's length a little off the others', as tracked lengths are:
    # its points along the stretch then lie off theirs)
    many = [frame for k, turn in enumerate([0.0, *np.linspace(1.0, 3.0, 120)])
            for frame in _clamped_tracks(100.0, [turn], tube=300.0 + 0.37 * (k % 7))]
    many = pipette.static_stretch(many, 5.0)
    # (the most bent frame sets how far past the holder the tube keeps its
    # line: the same on three frames bent as far)
    few = pipette.static_stretch(_clamped_tracks(100.0, [0.0, 1.0, 3.0]), 5.0)
    assert many == pytest.approx(few, abs=0.5)
    assert many >= 100.0


def test_a_stiff_first_section_is_no_hinge():
    # the tube's own first 60 px, bending at 1/25 of the rest's curvature: it
    # seems to end earlier the more the tube bends
    results = _clamped_tracks(60.0, [0.0, 0.5, 1.0, 2.0, 3.0], stiff=0.04)
    _, _, spread = pipette.motion_hinge(results, 5.0, 100.0)
    assert spread > 2 * pipette.HINGE_SPREAD_PX


def test_a_tube_starting_at_the_border_is_not_cut(tmp_path):
    # no holder: the tube itself runs from the border, and its base stretch
    # moves off the first frame's line once it bends
    base = 639 - 240j
    folder, bends = _video(tmp_path, holder=None, base=base)
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    ok = t[t.status == "ok"]
    assert len(ok) >= 6 and abs(ok.bend_angle_deg.iloc[-1]) > 150
    assert np.abs(ok.length_um / LENGTH - 1).max() < 0.01
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert "holder" not in run["base_source"]


def test_a_thin_tube_little_bent_from_the_border_is_not_cut(tmp_path, monkeypatch):
    # its base stretch stays within a pixel of the first frame's line for over
    # two widths (a thin tube bent 49 deg), so its profiles are looked at: one
    # look all along, no step, not cut
    looked = []

    def spy(*args, **kwargs):
        looked.append(change := pipette.profile_change.__wrapped__(*args, **kwargs))
        return change

    spy.__wrapped__ = pipette.profile_change
    monkeypatch.setattr(pipette, "profile_change", spy)
    folder, _ = _video(tmp_path, holder=None, base=639 - 240j, turn=-0.85, hw=4.0)
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    assert looked and looked[0][1] < pipette.MIN_CHANGE
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all()
    assert np.abs(t.length_um / LENGTH - 1).max() < 0.01


def test_a_given_base_is_not_cut(tmp_path):
    # the user says the tube starts at the border: the band stays part of it
    folder, _ = _video(tmp_path, holder=1.0)
    track_video(folder, tmp_path / "out", um_per_px=1.0, base="639,240")
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert t.length_um.min() > LENGTH + 150
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert not any("taken for the tube, cut off" in n for n in run["left_out_and_why"])


def test_a_shading_along_the_tube_is_no_step():
    # a tube darkening steadily along its length (uneven light) changes its
    # profiles as much as a step would, but a straight trend explains them
    img = tube_image((480, 640), BASE, ANGLE, LENGTH, 1e-12, HW, noise=0.01)
    img *= np.linspace(1.0, 0.85, 640)[None, ::-1].astype(np.float32)
    _, change = pipette.profile_change(img, Curve(BASE, ANGLE, LENGTH, np.zeros(8)), HW, 280.0)
    assert change < pipette.MIN_CHANGE


@pytest.mark.parametrize("fade, seed", [(0.5, 1), (0.7, 0)])
def test_a_glow_fading_along_the_tube_does_not_move_the_holder_s_end(fade, seed):
    # a bright tube running on into a holder that does not show (a dyed tube in
    # clear glass), its light fading steadily from the border: searched along
    # its axis, the holder's end moved 15-37 px into the tube (an independent
    # renderer's fluorescent tube: its base 27 px off, length 7 %); a straight
    # trend explains those profiles, so the end stays where the motion put it
    start = 639 - 240j
    img = tube_image((480, 640), start, ANGLE, LENGTH + abs(start - BASE), 1e-12, HW,
                     noise=0.01, seed=seed, polarity=1, background=0.1, contrast=6.0)
    x = np.arange(640)[None, :]
    img = (img * (1 + fade * np.clip((x - 300) / 340, 0, 1))).astype(np.float32)
    cut = Curve(BASE, ANGLE, LENGTH, np.zeros(8))
    assert pipette._end_on_axis(img, cut, abs(start - BASE) - 10, HW) == 0.0


def _arc(kappa=1 / 150):
    """A circular arc as a Curve (its spline fitted to the exact tangent angle)."""
    from pipeline.centreline import basis_of, make_basis

    n = 24
    basis = make_basis(n, basis_of(Curve(0j, 0.3, LENGTH, np.zeros(n))).n_grid)
    coef, *_ = np.linalg.lstsq(basis.values, kappa * basis.u * LENGTH, rcond=None)
    return Curve(10 - 5j, 0.3, LENGTH, coef)


def test_a_cut_curve_keeps_the_shape_beyond_the_cut():
    curve = _arc()
    s_cut = 80.0
    cut = pipette.cut_base(curve, s_cut)
    arc, z = resample(curve, 0.25)
    assert cut.length == pytest.approx(LENGTH - s_cut)
    assert abs(cut.base - np.interp(s_cut, arc, z.real) - 1j * np.interp(s_cut, arc, z.imag)) \
        < 1e-3
    assert cut.base_angle == pytest.approx(0.3 + s_cut / 150, abs=1e-4)
    assert cut.coef[-1] == pytest.approx((LENGTH - s_cut) / 150, abs=1e-4)
    assert abs(tip_point(cut) - tip_point(curve)) < 0.01
    # given the holder's axis as the base tangent, the tip's angle is measured from it
    held = pipette.cut_base(curve, s_cut, base_angle=0.3)
    assert held.base_angle == 0.3
    assert held.coef[-1] == pytest.approx(LENGTH / 150, abs=1e-4)


@pytest.mark.parametrize("holder, changes", [(None, False), (1.0, True), (0.6, True)])
def test_the_profiles_change_where_the_holder_ends(holder, changes):
    # a straight structure: tube from BASE leftwards, and (or not) a holder to its right
    # (no holder: the tube alone, from its base)
    img = tube_image((480, 640), BASE, ANGLE, LENGTH, 1e-12, HW, noise=0.01,
                     pipette_half_width=None if holder is None else holder * HW)
    start = BASE if holder is None else 639 - 240j
    structure = Curve(start, ANGLE, LENGTH + abs(start - BASE), np.zeros(8))
    s, change = pipette.profile_change(img, structure, HW, 280.0)
    assert (change >= pipette.MIN_CHANGE) == changes
    if changes:
        assert s == pytest.approx(abs(start - BASE), abs=2.0)


def _capillary(img, r_tip, r_far, taper, *, base=BASE, angle=ANGLE, line=0.45):
    """``img`` with a tapered glass capillary behind the tube's base: two dark
    wall lines ``r_tip`` px off its axis at the base, widening to ``r_far``
    over ``taper`` px, and on to the border."""
    from scipy.special import erf

    rows, cols = img.shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    rel = ((cc - 1j * rr) - base) * np.exp(-1j * angle)
    back = np.clip(-rel.real, 0.0, None)
    radius = r_tip + (r_far - r_tip) * np.minimum(back / taper, 1.0)
    behind = 0.5 * (1 + erf(-rel.real / 0.7))
    wall = np.exp(-0.5 * ((np.abs(rel.imag) - radius) / 0.8) ** 2)
    return (img * (1 - line * wall * behind)).astype(np.float32)


@pytest.mark.parametrize("r_tip", [0.5, 1.0])
def test_a_tapered_capillary_ends_where_the_tube_begins(r_tip):
    # a glass capillary half as wide as the tube (or as wide) where the tube
    # leaves it, widening to twice the tube's width over four widths: its
    # profiles change steadily along the taper (a single step fitted to the
    # stretch split it mid-taper, 54 px short), and step where it ends
    img = tube_image((480, 640), BASE, ANGLE, LENGTH, 1e-12, HW, noise=0.01)
    img = _capillary(img, r_tip * HW, 2.2 * HW, 8 * HW)
    start = 639 - 240j
    structure = Curve(start, ANGLE, LENGTH + abs(start - BASE), np.zeros(8))
    s, change = pipette.profile_change(img, structure, HW, abs(start - BASE) + 2 * HW)
    assert change >= pipette.MIN_CHANGE
    assert s == pytest.approx(abs(start - BASE), abs=1.0)


@pytest.mark.parametrize("r_far", [2.0, 3.0])
def test_a_long_tapered_capillary_ends_where_the_tube_begins_near_the_search_s_end(r_far):
    # a glass capillary tapering all the way from the border, 500 px, to half
    # the tube's width, searched to a tube width past its end: along the whole
    # stretch its profiles change unlike any straight trend, and that misfit,
    # over the long holder, outweighed its end's step, taken for a shading
    # (an independent renderer's tapered pipette from a frame's corner: the
    # base 61 px inside it)
    base, start = 700 - 240j, 1199 - 240j
    img = tube_image((480, 1200), base, ANGLE, LENGTH, 1e-12, HW, noise=0.01)
    img = _capillary(img, 0.5 * HW, r_far * HW, abs(start - base), base=base)
    structure = Curve(start, ANGLE, LENGTH + abs(start - base), np.zeros(8))
    s, change = pipette.profile_change(img, structure, HW, abs(start - base) + 2 * HW)
    assert change >= pipette.MIN_CHANGE
    assert s == pytest.approx(abs(start - base), abs=1.0)


@pytest.mark.parametrize("capillary", [(0.7, 1.5, 6.0, 0.6), (0.6, 2.0, 20.0, 0.6)])
def test_a_tapered_capillary_is_cut_off_every_frame(tmp_path, capillary):
    # tracked from the border through the capillary (the first), or from
    # within its taper, the base end told by motion (the second, whose wide end
    # the detector does not take for a tube): the holder's end was put 25 and
    # 132 px off before
    folder, bends = _video(tmp_path, holder=None, base=BASE, capillary=capillary)
    run = _cut_and_measured(folder, tmp_path / "out", bends)
    assert any("holder (pipette) taken for the tube" in n for n in run["left_out_and_why"])


def test_a_holder_s_end_is_found_past_a_drift_along_the_tube():
    # a holder as wide as the tube, and the light fading along the tube past
    # it (the tube's profiles differ from the far tube's by several times their
    # scatter near the holder): the holder ends where the profiles change
    # sharply, not where the drift has faded
    img = tube_image((480, 640), BASE, ANGLE, LENGTH, 1e-12, HW, noise=0.005,
                     pipette_half_width=HW)
    img *= np.linspace(0.9, 1.0, 640)[None, :].astype(np.float32)
    start = 639 - 240j
    structure = Curve(start, ANGLE, LENGTH + abs(start - BASE), np.zeros(8))
    s, change = pipette.profile_change(img, structure, HW, abs(start - BASE) + 6 * HW)
    assert change >= pipette.MIN_CHANGE
    assert s == pytest.approx(abs(start - BASE), abs=1.0)


def test_a_frame_far_from_the_first_frame_s_length_beyond_the_holder_is_lost():
    # a frame restarted on the holder and part of the tube: it passes the
    # holder's end, but the tube beyond it is 45 % of the first frame's
    results = _clamped_tracks(60.0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)
    short = _clamped_tracks(60.0, [3.0], noise=1e-3, tube=135.0)[0]
    results.append(replace(short, frame=len(results)))
    out, note = pipette.drop_holder(results, lambda: np.full((400, 500), 0.5, np.float32), 5.0)
    assert note is not None and "clamped" in note
    assert [r.status for r in out] == ["ok"] * 5 + [pipette.OFF_LENGTH]
    assert all(abs(r.curve.length - 300.0) < 2.0 for r in out[:5])


def test_a_tube_in_a_glass_sleeve_is_cut_where_it_leaves_it_though_it_bends_little(
        tmp_path, monkeypatch):
    # the tube runs on to the border inside a glass capillary, seen through the
    # glass (0.7 of its contrast, between the capillary's wall lines); it bends
    # 34 deg, too little for the frames to tell a holder by its standing still
    # (a tube's own base stretch, free, stays near its line that long too)
    folder, bends = _video(tmp_path, holder=1.0, holder_look=0.7, turn=-0.6,
                           capillary=(1.5, 1.5, 1.0, 0.5))
    run = _cut_and_measured(folder, tmp_path / "out", bends)
    assert any("kept its shape on the frames" in n for n in run["left_out_and_why"])
    # without the profiles looked at along the tube (nor the capillary's edges
    # wider apart, which tell it too: test_wide_holder.py), it runs on to the border
    monkeypatch.setattr(pipette, "rigid_wobble", lambda *args: np.inf)
    monkeypatch.setattr(pipette, "wide_holder_end", lambda *args, **kwargs: None)
    track_video(folder, tmp_path / "kept", um_per_px=1.0)
    kept = pd.read_csv(tmp_path / "kept" / "tracks.csv")
    assert kept.length_um.min() > LENGTH + 150


def test_a_holder_s_axis_is_the_straight_tube_s_direction_past_it():
    # a fit that wobbles through the holder (by 4 deg where the glass ends)
    # and runs straight past it: the tube's own direction is the holder's
    # axis; bent, the holder's own stretch is all there is
    coef = np.r_[np.radians([0.0, 3.0, 4.0, -1.0]), np.zeros(8)]
    wobbly = Curve(0j, 0.3, 480.0, coef)
    s = 120.0
    arc, _, phi, _ = pipette._sampled(wobbly, 0.5)
    straight = phi[arc > s + pipette.AXIS_CLEAR_HW * HW].mean()
    assert np.ptp(phi[arc > s + pipette.AXIS_CLEAR_HW * HW]) < np.radians(0.5)
    assert pipette.holder_axis(wobbly, s, HW) == pytest.approx(straight, abs=1e-4)
    assert abs(pipette.axis_angle(wobbly, s) - straight) > np.radians(1.0)
    bent = Curve(0j, 0.3, 480.0, np.r_[np.radians([0.0, 3.0, 4.0, -1.0]),
                                        np.linspace(0.0, 1.0, 8)])
    assert pipette.holder_axis(bent, s, HW) == pipette.axis_angle(bent, s)
    # a fit's end that wanders (5 deg over its last coefficient: an independent
    # scene's first frame turned its last 30 px by 4.6 deg) does not make the
    # straight tube a bent one (the axis fell back on the wobbly holder's fit,
    # 8.8 deg off)
    wandering = Curve(0j, 0.3, 480.0, np.r_[coef[:-1], np.radians(-5.0)])
    assert pipette.holder_axis(wandering, s, HW) == pytest.approx(straight, abs=np.radians(0.1))


def test_a_holder_is_cut_where_frames_restarted_along_it_leave_its_line(monkeypatch):
    # the last bent frames restarted with their base 30 px further along the
    # holder: their first stretch, laid on the first frame's, reaches onto the
    # bending tube and does not keep its shape; the bent frames all leave the
    # holder's line at its end, as from a clamp, and the profiles step there
    from dataclasses import replace as swap

    origin = 40 - 240j
    img = tube_image((480, 640), origin + 60, 0.0, 300.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=HW)
    held = _clamped_tracks(60.0, [0.0, 0.5, 1.0], noise=1e-3)
    moved = _clamped_tracks(30.0, [2.0, 3.0], noise=1e-3)
    results = [swap(r, curve=swap(r.curve, base=origin)) for r in held]
    results += [swap(r, frame=3 + k, curve=swap(r.curve, base=origin + 30))
                for k, r in enumerate(moved)]
    assert pipette.rigid_wobble(results, 60.0) > max(pipette.STILL_PX, pipette.RIGID_HW * HW)
    # (the still stretch, measured from each frame's base, not told: as on an
    # independent scene, whose restarted frames' fits strayed inside the glass)
    monkeypatch.setattr(pipette, "static_stretch", lambda *args: 0.0)
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is not None and "as a tube clamped there would" in note, note
    assert all(r.ok for r in out)
    assert all(abs(r.curve.base - (origin + 60)) < 1.5 for r in out)
    # with the stretch's shape alone asked for, the holder stays
    monkeypatch.setattr(pipette, "MIN_HINGE_GAIN", np.inf)
    assert pipette.drop_holder(results, lambda: img, HW)[1] is None


def test_a_holder_s_end_is_its_steepest_fall_not_the_halo_s_tail():
    # the profiles' difference from the tube's along the first frame, 1 px
    # apart: the holder at 16, its end a sharp fall between 30 and 31 (to 10),
    # then a halo's slow tail down to the tube's 2 by 42 (phase contrast),
    # the first profile like the tube's at 44; and before it a feature along
    # the holder (the tube's end inside the glass: 25 -> 16)
    s = np.arange(60.0)
    amp = np.full(s.size, 16.0)
    amp[:17] = 25.0
    amp[17:19] = [21.0, 17.0]
    amp[31:] = np.interp(s[31:], [31, 42], [10.0, 2.0])
    # (the fall 16 -> 10 between its neighbours' 0 and 0.73: the parabola's
    # vertex 0.03 of a profile past its middle)
    assert pipette._end_edge(s, amp**2, 44, 14.0) == pytest.approx(30.53, abs=0.05)
    # a sharp end (no halo), the fall into the first profile like the tube's,
    # and a steeper feature 1.5 half-widths before it, whose fall does not
    # reach half-way to the tube's level within a half-width
    amp = np.r_[np.full(15, 25.0), np.full(16, 15.0), [8.0], np.full(28, 1.0)]
    assert pipette._end_edge(s, amp**2, 32, 10.0) == pytest.approx(31.0, abs=0.05)
    amp = np.r_[np.full(15, 25.0), np.full(17, 15.0), np.full(28, 1.0)]
    assert pipette._end_edge(s, amp**2, 32, 10.0) == pytest.approx(31.5, abs=0.05)


def test_a_bent_tube_s_holder_axis_is_its_line_of_symmetry():
    # a holder twice the tube's width, along 180 deg; the fit through it leans
    # 1.7 deg and wobbles (as through a capillary whose glass ends), and the
    # tube past it bends: its axis from the holder's mirror-symmetric profiles
    base = 400 - 240j
    img = tube_image((480, 640), base, np.pi, 300.0, -3.0 / 300.0, HW, noise=0.01,
                     pipette_half_width=2 * HW)
    coef = np.r_[np.radians([0.0, 2.0, -2.0, 1.5, -1.0]), np.linspace(-0.5, -3.0, 7)]
    through = Curve(base + 150 + 3j, np.pi + 0.03, 450.0, coef)
    axis = pipette.holder_axis(through, 150.0, HW, img)
    assert abs(np.angle(np.exp(1j * (axis - np.pi)))) < np.radians(0.2)
    # (the fit's own mean direction through the holder)
    assert abs(np.angle(np.exp(1j * (pipette.axis_angle(through, 150.0) - np.pi)))) > np.radians(1)
    # the other way round (0 deg: the holder on the left)
    flipped = tube_image((480, 640), 240 - 240j, 0.0, 300.0, 3.0 / 300.0, HW, noise=0.01,
                         pipette_half_width=2 * HW)
    back = Curve(240 - 240j - 150 - 3j, -0.03, 450.0, -coef)
    axis = pipette.holder_axis(back, 150.0, HW, flipped)
    assert abs(np.angle(np.exp(1j * axis))) < np.radians(0.2)
    # no holder there (noise): the centres make no line, and the fit's own
    # direction is kept
    noise = np.random.default_rng(0).normal(0.5, 0.05, img.shape)
    assert pipette.symmetric_axis(noise, through, 150.0, HW) is None
    assert pipette.holder_axis(through, 150.0, HW, noise) == pipette.axis_angle(through, 150.0)


def test_a_holder_s_end_nearer_the_tracked_base_than_two_widths_is_cut():
    # the tracked structure runs 20 px on into a holder (a glass 1.5 tube widths
    # wide), under the two tube widths a holder's stretch must have: its
    # profiles' first one like the tube's lies past those, and the holder's
    # blurred end before it (the fit ran 23 px on into an independent scene's
    # glass, the base kept there, 13 deg off)
    base = 100 - 240j
    img = tube_image((480, 640), base, 0.0, 300.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=1.5 * HW)
    from dataclasses import replace as swap

    results = [swap(r, curve=swap(r.curve, base=base - 20.0))
               for r in _clamped_tracks(20.0, [0.0, 0.5, 1.0, 2.0], noise=1e-3)]
    least = pipette.MIN_WIDTHS * 2 * HW
    assert pipette.static_stretch(results, HW, least) >= least
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is not None and "profile stepped there" in note, note
    assert all(r.ok and abs(r.curve.base - base) < 1.5 for r in out)
    assert all(r.curve.length == pytest.approx(300.0, abs=1.5) for r in out)


def test_a_holder_whose_lumen_is_the_tube_s_width_ends_where_its_walls_do():
    from pipeline.track import _holder_end

    # the tube runs on from the border inside a glass whose walls stand two of
    # its half-widths off the axis: its edge pair shows behind the base as past
    # it (so edge pairs cannot place the base); the base was put 12 px past the
    # glass's mouth, as the mask's width step put an independent scene's
    mouth = BASE
    img = tube_image((480, 640), 639 - 240j, ANGLE, LENGTH + 219, 1e-12, HW, noise=0.01)
    img = _capillary(img, 2 * HW, 2 * HW, HW, base=mouth, line=0.5)
    late = Curve(mouth + 12 * np.exp(1j * ANGLE), ANGLE, LENGTH - 12, np.zeros(8))
    found = _holder_end(img, late, HW)
    assert found is not None
    assert abs(found.base - mouth) < 1.0
    assert found.length == pytest.approx(LENGTH, abs=1.0)
    assert found.base_angle == pytest.approx(ANGLE)
    assert abs(tip_point(found) - tip_point(late)) < 0.5
    # a base at the mouth stays; a tube with no glass has nothing to move to
    assert _holder_end(img, Curve(mouth, ANGLE, LENGTH, np.zeros(8)), HW) is None
    bare = tube_image((480, 640), 639 - 240j, ANGLE, LENGTH + 219, 1e-12, HW, noise=0.01)
    assert _holder_end(bare, late, HW) is None
    # put 5 half-widths past the mouth (a mask twice the tube's width, a small
    # fluorescent tube's: its step 16 px into the tube): out of the tube's own
    # reach, found within the detection's
    later = Curve(mouth + 5 * HW * np.exp(1j * ANGLE), ANGLE, LENGTH - 5 * HW, np.zeros(8))
    missed = _holder_end(img, later, HW)
    assert missed is None or abs(missed.base - mouth) > 2.0
    found = _holder_end(img, later, HW, rough_half_width=2 * HW)
    assert found is not None and abs(found.base - mouth) < 1.0


def test_a_hinge_nearer_the_tracked_base_than_two_widths_is_cut():
    # a holder of the tube's own look showing for 1.5 tube widths (the
    # profiles do not step; a glass 1.99 widths long before a tube 85 px wide
    # was kept as the tube, 18 deg off): the stretch that stood still is over
    # two widths (the tube bends little near its holder), the hinge the bent
    # frames fit is where the holder ends
    s0 = 1.5 * 2 * HW
    base = 100 - 240j
    img = tube_image((480, 640), base, 0.0, 300.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=HW, pipette_contrast=1.0)
    from dataclasses import replace as swap

    results = [swap(r, curve=swap(r.curve, base=base - s0))
               for r in _clamped_tracks(s0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)]
    least = pipette.MIN_WIDTHS * 2 * HW
    assert pipette.static_stretch(results, HW, least) >= least
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is not None and "as a tube clamped there would" in note, note
    assert all(r.ok and abs(r.curve.base - base) < 1.5 for r in out)
    # under a tube width it is not: a tube's own base may stand still so long
    short = [swap(r, curve=swap(r.curve, base=base - 0.5 * 2 * HW))
             for r in _clamped_tracks(0.5 * 2 * HW, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)]
    assert pipette.drop_holder(short, lambda: img, HW)[1] is None



def test_a_holder_the_hinge_tells_is_ended_where_its_profiles_step(monkeypatch):
    """Where the first frame's profiles near the still stretch's end do not
    tell a holder (here made so: that look is left out) but the bent frames'
    hinge does (60 px from the tracked base), and the profiles along the
    structure step 3 px further on, the holder's end is put where they step.
    The hinge alone put a pipette's end 1.5 px short on an independent
    renderer's scene (vignetting: the first look saw no step there)."""
    rows, cols = 300, 600
    results = [r.moved(100 - 150j)
               for r in _clamped_tracks(60.0, [0.0, *np.linspace(0.5, 3.0, 8)])]
    rr, cc = np.mgrid[0:rows, 0:cols].astype(float)
    img = np.full((rows, cols), 0.8)
    # the holder, wider and darker than the tube, along the first frame's line
    img[(np.abs(rr - 150) <= 8) & (cc >= 100) & (cc <= 163)] = 0.3
    img[(np.abs(rr - 150) <= 5) & (cc > 163) & (cc <= 460)] = 0.55
    img = (img + np.random.default_rng(0).normal(0.0, 0.01, img.shape)).astype(np.float32)
    looks = []
    real = pipette.profile_change

    def first_look_blind(*args, **kwargs):
        looks.append(args[-1])
        s, change = real(*args, **kwargs)
        return (s, 0.0) if len(looks) == 1 else (s, change)

    monkeypatch.setattr(pipette, "profile_change", first_look_blind)
    cut, note = pipette.drop_holder(results, lambda: img, 5.0)
    assert "its end placed where the profiles along it stepped" in note, note
    assert abs(cut[0].curve.base - (163 - 150j)) < 1.0, cut[0].curve.base


def test_a_frame_passing_the_holder_s_end_within_a_half_width_is_cut_there(monkeypatch):
    # a frame little bent whose fit passes the holder's end 4 px aside (the
    # camera shook it; the base held at the border): within a half-width (5
    # px) it is cut there and measured; 7 px aside it is lost
    img = np.full((400, 500), 0.5, np.float32)
    results = _clamped_tracks(60.0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)
    shaken = [results[0], results[1].moved(4j), *results[2:]]
    out, note = pipette.drop_holder(shaken, lambda: img, 5.0)
    assert note is not None and "clamped" in note
    assert all(r.ok for r in out)
    assert abs(out[1].curve.length - 300.0) < 2.0
    astray = [results[0], results[1].moved(7j), *results[2:]]
    out, _ = pipette.drop_holder(astray, lambda: img, 5.0)
    assert [r.status for r in out] == ["ok", pipette.OFF_HOLDER, "ok", "ok", "ok"]
    # held to half a half-width, the shaken frame was lost
    monkeypatch.setattr(pipette, "OFF_HOLDER_HW", 0.5)
    out, _ = pipette.drop_holder(shaken, lambda: img, 5.0)
    assert out[1].status == pipette.OFF_HOLDER


def test_a_step_in_the_profiles_past_where_the_frames_hinge_is_no_holder():
    """The bent frames hinge 1 px from the tracked base, as a tube clamped
    there (at a clear pipette's mouth); the tube's first 16 px look darker,
    and bend too little to leave the first frame's line by more than a px.
    That stretch is tube: its end is no holder's, since the frames do not
    bend as clamped there (an independent scene: 21 px cut off the tube)."""
    results = [r.moved(100 - 150j)
               for r in _clamped_tracks(1.0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)]
    at, gain, _ = pipette.motion_hinge(results, HW, 32.0)
    assert at == pytest.approx(1.0, abs=0.5) and gain > pipette.MIN_HINGE_GAIN
    rr, cc = np.mgrid[0:300, 0:600].astype(float)
    img = np.full((300, 600), 0.8)
    img[(np.abs(rr - 150) <= HW) & (cc >= 100) & (cc <= 400)] = 0.4
    img[(np.abs(rr - 150) <= HW) & (cc >= 100) & (cc <= 116)] = 0.3
    img = (img + np.random.default_rng(0).normal(0.0, 0.01, img.shape)).astype(np.float32)
    assert pipette.profile_change(img, results[0].curve, HW, 40.0)[1] >= pipette.MIN_CHANGE
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is None
    assert all(r.curve.base == p.curve.base for r, p in zip(out, results, strict=True))


@pytest.mark.parametrize("found_at", [pipette.HOLDER_STEP, "image border (no pipette step seen)"])
def test_a_stiff_first_section_past_a_mouth_the_start_found_is_not_cut(found_at):
    # the start found the holder's width step: the tracked base is at its mouth,
    # and the tube's first 60 px (a stiff section) stand still while the rest
    # bends, as a clamped tube's would; its profiles do not step there (the
    # tube's own look). Only a start that did not see the holder cuts it
    # (an independent renderer's capillary: its tube's straight first 30 %
    # taken for a holder, the base 128 px into the tube)
    from dataclasses import replace as swap

    base = 100 - 240j
    img = tube_image((480, 640), base, 0.0, 360.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=2.0 * HW)
    results = [swap(r, curve=swap(r.curve, base=base), base_source=found_at)
               for r in _clamped_tracks(60.0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)]
    out, note = pipette.drop_holder(results, lambda: img, HW)
    if found_at == pipette.HOLDER_STEP:
        assert note is None
        assert all(r.curve.base == base and r.curve.length == 360.0 for r in out)
    else:
        assert note is not None and "as a tube clamped there would" in note, note
        assert all(abs(r.curve.base - (base + 60)) < 2.0 for r in out)


@pytest.mark.parametrize("found_at", [pipette.HOLDER_STEP, pipette.EDGES_BEGIN])
def test_a_holder_s_end_within_a_width_and_a_half_of_a_start_at_its_mouth_is_not_cut(
        found_at):
    # the profiles step 10 px past the tracked base (a dark band across the
    # tube: the glass's end face shading it), which a start at the holder's
    # width step (or where the tube's edges begin past a faint pipette)
    # already put at the mouth: nothing is cut (an independent renderer's
    # tapered pipette: 16 px cut, the base 27 px into the tube)
    from dataclasses import replace as swap

    base = 100 - 240j
    img = tube_image((480, 640), base, 0.0, 360.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=2.0 * HW)
    img[:, 100:110] *= 0.6
    results = [swap(r, curve=swap(r.curve, base=base), base_source=found_at)
               for r in _clamped_tracks(10.0, [0.0, 0.5, 1.0, 2.0], noise=1e-3)]
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is None
    assert all(r.curve.base == base for r in out)


def test_a_holder_whose_look_steps_a_width_past_a_start_at_its_step_is_cut():
    # a start at a pipette's width step that lay 20 px into a glass band as
    # wide as the tube (the mask's step: the tube's edges taken on along the
    # glass): the stretch stands still and its profiles step from the glass's
    # look to the tube's far beyond a section's change, more than a width on.
    # Within a width and a half of such a start a holder's end is otherwise
    # left alone (see the test above); a material's step is not.
    from dataclasses import replace as swap

    start, mouth = 100 - 240j, 120 - 240j
    img = tube_image((480, 640), mouth, 0.0, 340.0, 1e-12, HW, noise=0.005,
                     pipette_half_width=HW, pipette_contrast=0.3)
    results = [swap(r, curve=swap(r.curve, base=start), base_source=pipette.PIPETTE_STEP)
               for r in _clamped_tracks(20.0, [0.0, 0.5, 1.0, 2.0], noise=1e-3, tube=340.0)]
    out, note = pipette.drop_holder(results, lambda: img, HW)
    assert note is not None and "profile stepped" in note, note
    assert all(abs(r.curve.base - mouth) < 1.5 for r in out), [r.curve.base for r in out]
    # (the step is a material's: far over what a section's change gives)
    _, change = pipette.profile_change(img, results[0].curve, HW, 20.0 + 8 * HW)
    assert change >= pipette.SURE_CHANGE


def test_a_holder_taken_for_the_tube_is_followed_as_the_stage_carries_it_along(
        tmp_path, monkeypatch):
    # a holder as wide as the tube runs to the border, where the tracker put
    # the base (no holder in view there to watch); the stage carries the
    # whole scene 0.9 px a frame along the holder's axis (6.3 px over the
    # video). Cut where the first frame shows its end, every frame's base
    # stayed put and the length grew by the drift (an independent renderer's
    # drifting and shaking scenes: lengths 1.6-2.3 % long); the holder's
    # mouth registered on a second read of the frames follows it
    folder = tmp_path / "frames"
    folder.mkdir()
    n = 8
    bases = BASE - 0.9 * np.arange(n)
    for k in range(n):
        kappa = TURN * k / (n - 1) / LENGTH
        img = tube_image((480, 640), bases[k], ANGLE, LENGTH, kappa + 1e-12, HW, noise=0.01,
                         seed=k, pipette_half_width=HW, pipette_contrast=0.5)
        cv2.imwrite(str(folder / f"f{k:02d}.png"), (img * 255).round().astype(np.uint8))

    def errors(out):
        track_video(folder, out, um_per_px=1.0)
        t = pd.read_csv(out / "tracks.csv")
        assert (t.status == "ok").all()
        notes = json.loads((out / "run.json").read_text())["left_out_and_why"]
        return (np.abs(t.base_x_um + 1j * t.base_y_um - bases).max(),
                np.abs(t.length_um / LENGTH - 1).max(), notes)

    base_off, stretch, notes = errors(tmp_path / "out")
    assert base_off < 1.0 and stretch < 0.004
    assert any("registered on a second read of the frames" in n for n in notes), notes
    monkeypatch.setattr(pipette, "_mouth_drift", lambda *a, **k: None)
    base_off, stretch, _ = errors(tmp_path / "held")
    assert base_off > 5.0 and stretch > 0.015


@pytest.mark.parametrize("moved", [0.0, -3.5])
def test_a_start_at_a_holder_s_step_is_carried_to_its_mouth_though_edges_moved_it(
        monkeypatch, moved):
    # a thick-walled glass around the tube from the border to its mouth: the
    # mask's width step (the holder wider than the tube) lies 8 px inside the
    # mouth, and the search for where the tube's edges begin, which see the
    # tube inside the glass, moved it 3.5 px further in (as on an independent
    # renderer's capillary 3x the tube's width: the base 25 px inside it)
    from scipy.special import erf

    import pipeline.track as T
    from pipeline.centreline import cut_base

    img = tube_image((480, 640), 639 - 240j, ANGLE, LENGTH + 219, 1e-12, HW, noise=0.01)
    rr, cc = np.mgrid[0:480, 0:640]
    rel = ((cc - 1j * rr) - BASE) * np.exp(-1j * ANGLE)
    across = np.abs(rel.imag)
    wall = (0.5 * (1 + erf((across - 1.3 * HW) / 0.8)) * 0.5 * (1 + erf((3 * HW - across) / 0.8))
            * 0.5 * (1 + erf(-rel.real / 0.7)))
    img = (img * (1 - 0.5 * wall)).astype(np.float32)
    located = T.locate_base

    def further_in(image, curve, look, reach=None, **kwargs):
        out = located(image, curve, look, reach=reach, **kwargs)
        return out if reach is None else cut_base(out, moved, out.base_angle)

    monkeypatch.setattr(T, "locate_base", further_in)
    fit, _, source = T.initialise(img)
    assert source.startswith(T.HOLDER_STEP) and "become the tube's" in source, source
    assert abs(fit.curve.base - BASE) < 1.0
