"""Frames whose tube runs out of the image (:mod:`pipeline.view`)."""

import json
from dataclasses import replace

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline.accuracy import score_folder
from pipeline.centreline import Curve
from pipeline.render import default_scene, render_scene
from pipeline.track import FrameTrack
from pipeline.tracks import track_video
from pipeline.view import OUT_OF_VIEW, cut_by_border


def _straight(frame: int, tip_col: float, length: float = 200.0) -> FrameTrack:
    """A straight tube along the row 50, its tip at ``tip_col`` (y up)."""
    curve = Curve(base=(tip_col - length) - 50.0j, base_angle=0.0, coef=np.zeros(6),
                  length=length)
    return FrameTrack(frame, "ok", curve, "fast", fit=curve)


def test_a_short_tube_reaching_the_border_is_cut_by_it_and_no_other():
    shape = (100, 300)  # rows, cols: the border on the right is at col 299
    results = [
        _straight(0, 200.0),                 # whole, well inside: the reference
        _straight(1, 298.0, length=180.0),   # 10 % short, ends at the border: out
        _straight(2, 297.0),                 # at the border, but whole: in view
        _straight(3, 200.0, length=180.0),   # short, but far from the border
        FrameTrack(4, "tube not found", None, ""),
        _straight(5, 210.0),
    ]
    marked, note = cut_by_border(results, shape)
    assert [r.status for r in marked] == [
        "ok", OUT_OF_VIEW, "ok", "ok", "tube not found", "ok"]
    assert marked[1].curve is None and marked[1].fit is None
    assert marked[3] is results[3]
    assert "1 of 6 frames" in note


def test_a_centreline_past_the_border_is_out_whatever_its_length():
    """A fit held at the tube's own length runs on past the frame's edge where
    the tip left it: not short, but out of view all the same."""
    results = [_straight(0, 200.0), _straight(1, 305.0), _straight(2, 299.5)]
    marked, _ = cut_by_border(results, (100, 300))
    assert [r.status for r in marked] == ["ok", OUT_OF_VIEW, "ok"]


def test_no_frame_shows_the_whole_tube_so_nothing_is_marked_but_the_note_says_so():
    results = [_straight(i, 298.0, length=200.0 - 10 * i) for i in range(3)]
    marked, note = cut_by_border(results, (100, 300))
    assert marked == results
    assert "could not be checked" in note


def test_every_tip_well_inside_leaves_everything_as_it_is():
    results = [_straight(i, 200.0 + i) for i in range(3)]
    assert cut_by_border(results, (100, 300)) == (results, None)


def test_a_tube_curling_out_of_the_image_and_back_is_not_measured_while_out(tmp_path):
    """Sample 1 curling to 306 deg, its frames cut 90 rows from the top: the
    tip passes up to 25 px above the cut on frames 3-4, and on frame 5 the
    outer wall runs 2 px past the border. Without the check frames 4-5 came
    out ok, the tube 12 % and 4 % short and the bend up to 4.2 deg off; every
    frame called ok is measured as well as ever (frame 5 now: 0.3 deg)."""
    scene = default_scene(1, n_frames=8, seed=5, width=480, height=360)
    whole = render_scene(scene, tmp_path / "whole", fmt="png")
    cut = tmp_path / "cut"
    (cut / "frames").mkdir(parents=True)
    top = 90
    for i, path in enumerate(sorted((whole / "frames").iterdir())):
        frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(cut / "frames" / f"{i:03d}.png"), frame[top:])
    record = json.loads((whole / "scene.json").read_text())
    um_per_px = record["layout"]["um_per_px"]
    for name, columns in (("truth_tracks.csv", ("base_y_um", "tip_y_um")),
                          ("truth_centrelines.csv", ("y_um",))):
        table = pd.read_csv(whole / name)
        for column in columns:  # y up: rows cut from the top raise every point
            table[column] += top * um_per_px
        table.to_csv(cut / name, index=False)
    (cut / "scene.json").write_text(json.dumps(record))
    run = track_video(cut / "frames", tmp_path / "out", um_per_px=um_per_px)

    truth = pd.read_csv(cut / "truth_centrelines.csv")
    above = (truth.y_um / um_per_px).groupby(truth.frame).max()  # px above the cut's top row
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv").set_index("frame")
    out = above[above >= 5].index
    inside = above[above <= -15].index  # the wall clear of the border by 5 px
    assert len(out) >= 2 and len(inside) >= 4
    # (the tracker may lose such a frame before: its tip not found)
    assert (tracks.loc[out, "status"] != "ok").all()
    assert (tracks.loc[inside, "status"] == "ok").all()
    # each either marked cut by the border or lost by the fit itself (since the
    # wide search runs an unsettled fit on, frames 3-4's tip is not found;
    # the marking itself: the tests above)
    assert all(s == OUT_OF_VIEW or s.startswith("lost:") for s in tracks.loc[out, "status"])
    assert not any("cut by the image's border" in note for note in run.notes) \
        or (tracks.status == OUT_OF_VIEW).any()
    # every frame still called ok is measured as well as ever: no silently
    # wrong number from a tube that the border cuts
    _, acc = score_folder(cut, tmp_path / "out")
    assert acc.angle_max <= 2.0
    assert acc.length_error_max_pct <= 1.0
    assert acc.centreline_rms_px <= 0.5


def test_a_base_near_the_edge_is_carried_back_to_it_along_its_tangent():
    from pipeline.centreline import tip_point
    from pipeline.view import base_to_border

    # entering from the left at -20 deg (y up: heading down-right), its base
    # 3 px in from the edge at col -0.5; another frame's base 40 px in
    angle = np.radians(-20.0)
    near = Curve(base=-0.5 - 100.0j + 3.0 * np.exp(1j * angle),
                 base_angle=angle, coef=np.linspace(0.0, 0.6, 8), length=200.0)
    far = Curve(base=40.0 - 100.0j, base_angle=angle, coef=np.zeros(8), length=200.0)
    results = [FrameTrack(0, "ok", near, "fast", fit=near),
               FrameTrack(1, "ok", far, "fast"), FrameTrack(2, "tube not found", None, "")]
    out, gap = base_to_border(results, (300, 400), half_width=8.0)
    assert gap == pytest.approx(3.0)
    moved = out[0].curve
    assert moved.base.real == pytest.approx(-0.5)
    assert moved.base.imag == pytest.approx(-100.0)
    assert moved.length == pytest.approx(203.0)
    assert moved.base_angle == pytest.approx(angle)
    assert abs(tip_point(moved) - tip_point(near)) < 0.1
    assert out[0].fit.length == pytest.approx(203.0)
    assert out[1] is results[1] and out[2] is results[2]


def test_a_wide_tube_s_base_a_holder_stub_s_length_in_is_not_carried_to_the_edge():
    from pipeline.view import base_to_border

    # a tube 40 px wide entering at -13 deg, its first whole profile 50 px (2.5
    # half-widths) in, past a capillary's stub 1.25 widths long that the frames
    # did not tell: a slant of 13 deg puts a first whole profile 4 x 0.23
    # half-widths in, and one more is allowed, so 1.9 in all (at 2.9, an
    # independent scene was carried 57 px back: its base 53 px off, 8 % long)
    angle = np.radians(-13.0)
    stub = Curve(base=-0.5 - 300.0j + 50.0 * np.exp(1j * angle), base_angle=angle,
                 coef=np.zeros(8), length=600.0)
    results = [FrameTrack(0, "ok", stub, "fast", fit=stub)]
    out, gap = base_to_border(results, (480, 640), half_width=20.0)
    assert gap == 0.0 and out[0] is results[0]
    # one a half-width in at that slant still starts at the edge
    near = replace(stub, base=-0.5 - 300.0j + 10.0 * np.exp(1j * angle))
    out, gap = base_to_border([FrameTrack(0, "ok", near, "fast")], (480, 640), 20.0)
    assert gap == pytest.approx(10.0)


def test_a_tube_entering_from_the_border_at_a_slant_starts_at_the_edge(tmp_path):
    from tests.pipeline.synthetic import tube_image

    # the tube enters at -25 deg from outside the left edge; no holder
    folder = tmp_path / "frames"
    folder.mkdir()
    angle, hw = np.radians(-25.0), 8.0
    start = -60.0 * np.exp(1j * angle) - 200j      # outside the frame
    for k in range(6):
        kappa = 1.2 * k / 5 / 420.0
        img = tube_image((480, 640), start, angle, 420.0, kappa + 1e-12, hw, noise=0.01, seed=k)
        cv2.imwrite(str(folder / f"f{k}.png"), (img * 255).round().astype(np.uint8))
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all()
    # where the straight start crosses col -0.5
    row = -(start.imag + np.tan(angle) * (-0.5 - start.real))
    assert np.abs(t.base_x_um + 0.5).max() < 0.3
    assert np.abs(-t.base_y_um - row).max() < 0.5
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert any("enters from the image's border" in n for n in run["left_out_and_why"])


def test_a_tube_entering_steeply_from_the_border_starts_at_the_edge(tmp_path):
    """A tube held outside the frame enters it at 60 deg to the border's
    normal, straight up to the edge and bent past it. The border cuts its
    mask over 14 px on its way out, as onto a narrower pipette: that
    narrowing was taken for a pipette's step, the base put 14-20 px inside
    the frame and the length 8 % short. Now the base is the edge's, the
    length the whole of what is in view, and the base tangent the edge's."""
    from tests.pipeline.synthetic import tube_image

    folder = tmp_path / "frames"
    folder.mkdir()
    angle, hw, inside = np.radians(-60.0), 8.0, 240.0
    edge = -0.5 - 100j                               # on the image's left edge (y up)
    rng = np.random.default_rng(0)

    def cover(img):
        # (tube_image's background 0.8, darkened by its contrast 0.35 where the tube is)
        return (1.0 - img / 0.8) / 0.35

    for k in range(6):
        kappa = 1.2 * k / 5 / inside + 1e-12
        held = tube_image((480, 640), edge - 60.0 * np.exp(1j * angle), angle, 60.0, 1e-12, hw)
        bent = tube_image((480, 640), edge, angle, inside, kappa, hw)
        img = 0.8 * (1.0 - 0.35 * np.clip(cover(held) + cover(bent), 0.0, 1.0))
        img += rng.normal(0.0, 0.01, img.shape)
        cv2.imwrite(str(folder / f"f{k}.png"), np.clip(img * 255, 0, 255).round().astype(np.uint8))
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all()
    assert np.abs(t.base_x_um - edge.real).max() < 0.3
    assert np.abs(t.base_y_um - edge.imag).max() < 0.5
    assert np.abs(t.length_um / inside - 1).max() < 0.01
    # (the base tangent was 0.7-0.9 deg off on every frame: the first frames
    # measured it at the first whole profile, 26 px in, where the tube held
    # at the edge had turned already as it bent. Now carried back to the edge)
    assert np.abs(t.bend_angle_deg - np.degrees(1.2 * np.arange(6) / 5)).max() < 0.5


@pytest.mark.parametrize("pipette", [True, False])
def test_a_narrowing_at_a_slanted_border_is_a_pipette_only_past_the_cut(pipette):
    """At 60 deg to the border's normal: a narrower pipette showing 60 px of
    itself in the frame is still told by its step (which lies past where
    the border's slanted cut could narrow the tube); a tube entering with
    none is not given one."""
    from pipeline.segment import PIPETTE_STEP, detect
    from tests.pipeline.synthetic import tube_image

    angle, hw = np.radians(-60.0), 8.0
    edge = -0.5 - 100j
    base = edge + (60.0 if pipette else 0.0) * np.exp(1j * angle)
    start = base if pipette else edge - 60.0 * np.exp(1j * angle)
    img = tube_image((480, 640), start, angle, 300.0, 1e-12, hw, noise=0.01,
                     pipette_half_width=5.0 if pipette else None, pipette_contrast=1.0)
    det = detect(img)
    assert (det.base_source == PIPETTE_STEP) == pipette, det.base_source
    if pipette:
        assert abs(det.base - base) < hw, det.base


def test_a_tangent_is_carried_back_to_the_edge_only_from_a_slanted_entry():
    """:func:`pipeline.track._lean_from_edge`: an arc bending 0.002 rad/px
    whose base lies 20 px (back along its tangent) from the left edge has
    turned 0.04 rad since it; one 4 px from it (under its half-width of 8)
    and one 200 px from it are left as they are."""
    from pipeline.centreline import fit_to_polyline
    from pipeline.track import _lean_from_edge

    kappa, angle = 0.002, np.radians(-60.0)

    def arc(edge_px):
        base = -0.5 + edge_px * np.exp(1j * angle) - 100j
        s = np.linspace(0.0, 300.0, 601)
        z = base + (np.exp(1j * (angle + kappa * s)) - np.exp(1j * angle)) / (1j * kappa)
        return fit_to_polyline(z, angle, n_coef=12)

    assert _lean_from_edge(arc(20.0), 8.0, (480, 640)) == pytest.approx(kappa * 20.0, rel=0.05)
    assert _lean_from_edge(arc(4.0), 8.0, (480, 640)) == 0.0
    assert _lean_from_edge(arc(200.0), 8.0, (480, 640)) == 0.0


@pytest.mark.parametrize("bend", [0.0, 0.001])
def test_a_slanted_entry_s_base_tangent_is_voted_on_from_past_the_edge_s_profiles(
        monkeypatch, bend):
    """A tube entering the left border at 55 deg (the first whole profile 11
    px in): the base tangent voted on is fitted from two half-widths past it
    and carried back to the edge; fitted from the first whole profile, the
    profiles beside the oblique edge pulled it 0.26 deg off (an independent
    renderer's tube near a corner: 0.5 deg, the median bend 0.66 deg off)."""
    from pipeline import track as T
    from tests.pipeline.synthetic import tube_image

    angle, hw = np.radians(55.0), 7.0
    at_edge = complex(-0.5, -400.0)
    start = at_edge - 40 * np.exp(1j * angle)
    # (the arc's tangent where it crosses the edge: 55 deg, whatever it bends)
    img = tube_image((480, 640), start, angle - 40 * bend, 440.0, bend + 1e-12, hw,
                     noise=0.01).astype(np.float32)
    # the tube's tangent where its axis crosses the edge (col -0.5)
    s = np.linspace(0.0, 80.0, 80001)
    x = start.real + np.cumsum(np.cos(angle - 40 * bend + bend * s)) * (s[1] - s[0])
    truth = np.degrees(angle - 40 * bend + bend * s[np.argmax(x >= -0.5)])
    r, look, source = T.initialise(img)
    assert source.startswith(T.BORDER_BASE)

    def voted():
        votes = T._BaseVotes(from_edge=True)
        votes.add(img, r.curve, look, T.TrackSettings())
        return np.degrees(r.curve.base_angle + votes.turns[0][1])

    assert voted() == pytest.approx(truth, abs=0.1)
    monkeypatch.setattr(T, "EDGE_SKIP_HW", 0.0)
    assert abs(voted() - truth) > 0.2
