"""A drifting stage: the holder's shift read from the region around the base,
and the base following it."""

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from pipeline import drift, pipette
from pipeline.centreline import fit_to_polyline
from pipeline.render import default_scene, render_scene
from pipeline.tracks import track_video
from tests.pipeline.synthetic import arc_axis, tube_image

SHAPE, BASE, ANGLE, LENGTH, HW = (360, 480), 380 - 180j, np.pi, 260.0, 7.0


def _frame(shift: complex, kappa: float, *, seed: int = 0, pipette_hw: float = 2.0 * HW,
           pipette_look: float = 0.5) -> np.ndarray:
    """A tube bending ``kappa`` (1/px) from a wider holder, the whole scene
    moved by ``shift`` (px, y up)."""
    return tube_image(SHAPE, BASE + shift, ANGLE, LENGTH, kappa + 1e-12, HW, noise=0.01,
                      seed=seed, pipette_half_width=pipette_hw, pipette_contrast=pipette_look)


def _curve(shift: complex = 0j, kappa: float = 1e-12):
    z, _ = arc_axis(BASE + shift, ANGLE, LENGTH, kappa, n=400)
    return fit_to_polyline(z, ANGLE, n_coef=12)


def test_the_holder_s_shift_is_read_while_the_tube_bends():
    first = _frame(0j, 0.0)
    region = drift.StageDrift.start(first, _curve(), HW)
    assert region is not None
    for k in range(1, 7):
        # a drift of up to ~4 px, a frame apart by up to 1.3 px, while the tube
        # curls to 240 deg past its first stretch
        shift = complex(0.6 * k, -0.35 * k + 0.1 * k**2 / 6)
        kappa = -4.2 * k / 6 / LENGTH
        kept = region.inside.copy()
        got = region.measure(_frame(shift, kappa, seed=k), _curve(shift, kappa))
        assert abs(got - shift) < 0.1
        # (each frame's tube is left out of that frame's registration only)
        assert np.array_equal(region.inside, kept)
    assert region.followed == region.shift


def test_a_still_stage_is_not_followed():
    region = drift.StageDrift.start(_frame(0j, 0.0), _curve(), HW)
    for k in range(1, 6):
        kappa = -4.2 * k / 5 / LENGTH
        region.measure(_frame(0j, kappa, seed=k), _curve(0j, kappa))
    # (noise alone: a few hundredths of a pixel)
    assert region.largest < 0.1


def test_a_direction_the_region_does_not_tell_stays_put():
    # a band of the tube's own look and width all through the region: nothing
    # marks a place along it, so a shift along it is not measured; across it is
    def band(shift):
        return _frame(shift, 0.0, pipette_hw=HW, pipette_look=1.0)

    region = drift.StageDrift.start(band(0j), _curve(), HW)
    got = region.measure(band(2.0 + 1.0j), _curve(2.0 + 1.0j))
    assert got.imag == pytest.approx(1.0, abs=0.05)
    assert abs(got.real) < 0.15


def test_a_region_that_cannot_tell_gain_from_offset_is_not_measured():
    # a first frame's region all at one level (a clipped glow, a camera's
    # few counts alike): its values cannot tell the light's gain from its
    # offset, and the fit's normal equations are singular; the frame is not
    # measured, and the run goes on (an independent renderer's dim
    # fluorescent holder stopped the whole run with "Singular matrix")
    rows, cols = np.mgrid[0:40, 0:40].astype(np.float32)

    def blob(dx, dy):
        return (0.5 + 0.3 * np.exp(-((cols - 20 - dx) ** 2 + (rows - 20 - dy) ** 2) / 50.0)
                ).astype(np.float32)

    image = blob(0.0, 0.0)
    gy, gx = np.gradient(image)
    xs, ys = cols[5:35, 5:35].ravel(), rows[5:35, 5:35].ravel()
    assert drift._register(image, gx, gy, np.full(xs.size, 0.5), xs, ys, (0.0, 0.0)) is None
    # (a region whose values vary is registered as ever: the frame moved by
    # 0.3 px right and 0.2 px down from the first)
    first = blob(-0.3, -0.2)[5:35, 5:35].ravel()
    got = drift._register(image, gx, gy, first, xs, ys, (0.0, 0.0))
    assert got is not None
    np.testing.assert_allclose(got[0], [0.3, 0.2], atol=0.02)


def test_a_base_at_the_border_is_not_followed():
    curve = replace(_curve(), base=complex(SHAPE[1] - 3, BASE.imag))
    assert drift.StageDrift.start(_frame(0j, 0.0), curve, HW) is None


def test_a_drifting_stage_carries_the_base(tmp_path, monkeypatch):
    scene = default_scene(2, n_frames=14, seed=27, base_angle_deg=200.0, width=480,
                          height=360, drift_px=5.0)
    render_scene(scene, tmp_path / "scene", fmt="png")
    truth = pd.read_csv(tmp_path / "scene" / "truth_tracks.csv")
    scale = json.loads((tmp_path / "scene" / "scene.json").read_text())["layout"]["um_per_px"]

    def base_error(out):
        t = pd.read_csv(out / "tracks.csv")
        assert (t.status == "ok").all()
        return (np.hypot(t.base_x_um - truth.base_x_um, t.base_y_um - truth.base_y_um) / scale,
                np.abs(t.length_um / truth.length_um - 1),
                json.loads((out / "run.json").read_text())["left_out_and_why"])

    track_video(tmp_path / "scene" / "frames", tmp_path / "a", um_per_px=scale)
    moved, stretch, notes = base_error(tmp_path / "a")
    assert moved.max() < 1.0 and stretch.max() < 0.005
    assert any(n.startswith("stage drift followed") for n in notes)
    # a base given (on the first frame) is carried alike
    col, row = truth.base_x_um[0] / scale, -truth.base_y_um[0] / scale
    track_video(tmp_path / "scene" / "frames", tmp_path / "given", um_per_px=scale,
                base=f"{col:.2f},{row:.2f}")
    given, stretch, _ = base_error(tmp_path / "given")
    # (no frames held back for a vote there: those before the drift is told
    # keep the base where it was given)
    told = drift.FOLLOW_FRAMES * drift.STILL_EVERY
    assert given[told:].max() < 1.0 and stretch[told:].max() < 0.005
    # held where the first frames show it, the base is px off and the length too
    monkeypatch.setattr(drift.StageDrift, "start", classmethod(lambda cls, *a: None))
    track_video(tmp_path / "scene" / "frames", tmp_path / "b", um_per_px=scale)
    held, stretch, notes = base_error(tmp_path / "b")
    assert held.max() > 3.0 and stretch.max() > 0.01
    assert any(n.startswith("stage drift: none followed") for n in notes)


def test_the_renderer_s_drift_moves_tube_and_truth_alike():
    from pipeline.render import Renderer, truth_tables

    scene = default_scene(1, n_frames=10, seed=3, width=320, height=240, drift_px=4.0)
    path = scene.drift()
    assert path[0] == 0 and np.abs(path).max() == pytest.approx(4.0)
    still, _, _ = truth_tables(scene.replace(drift_px=0.0))
    moved, _, _ = truth_tables(scene)
    shift_um = (moved.base_x_um - still.base_x_um) + 1j * (moved.base_y_um - still.base_y_um)
    um_per_px = abs(shift_um.iloc[-1]) / abs(path[-1])
    assert np.allclose(shift_um.to_numpy(), path * um_per_px, atol=1e-9)
    # the drawn tube and pipette move by the path (y up: rows run down)
    import cv2

    a, b = Renderer(scene.replace(drift_px=0.0)), Renderer(scene)
    for k in (3, 9):
        (dx, dy), _ = cv2.phaseCorrelate(a.tube_layers(k), b.tube_layers(k))
        assert abs(complex(dx, -dy) - path[k]) < 0.25   # (a sign slip: 2|path|)
    with pytest.raises(ValueError, match="drift_px"):
        scene.replace(drift_px=50.0)


def test_a_still_scene_tracks_as_without_the_drift_watched(tmp_path, monkeypatch):
    # the registration's scatter on a still stage stays under the bar: every
    # frame's measurements are those of a run that never looks at the drift
    scene = default_scene(3, n_frames=12, seed=8, base_angle_deg=135.0, width=400,
                          height=300, look="opaque")
    render_scene(scene, tmp_path / "scene", fmt="png")
    scale = json.loads((tmp_path / "scene" / "scene.json").read_text())["layout"]["um_per_px"]
    track_video(tmp_path / "scene" / "frames", tmp_path / "a", um_per_px=scale)
    monkeypatch.setattr(drift.StageDrift, "start", classmethod(lambda cls, *a: None))
    track_video(tmp_path / "scene" / "frames", tmp_path / "b", um_per_px=scale)
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "tracks.csv"),
                                  pd.read_csv(tmp_path / "b" / "tracks.csv"))


def test_held_back_frames_take_the_stage_s_path_since_this_start():
    from pipeline.centreline import Curve
    from pipeline.track import FrameTrack, _stage_path, _staged

    class Following:
        following = True

    curve = Curve(10 - 10j, 0.0, 50.0, np.zeros(6))
    pending = [(FrameTrack(k, "ok", curve, "fast", stage_shift=0j), None) for k in range(8)]
    # this start's region taken on frame 3 (the stage 1 px away then, carried
    # from an earlier start), measured on frames 5 and 7
    path = _stage_path(pending, Following(), {3: 1.0 + 0j, 5: 2.0 + 0j, 7: 2.0 + 1j})
    assert sorted(path) == [3, 4, 5, 6, 7]          # an earlier start's keep their own
    assert path[4] == pytest.approx(1.5) and path[6] == pytest.approx(2.0 + 0.5j)
    staged, moved = _staged(pending, path)
    assert sorted(moved) == [3, 4, 5, 6, 7]
    assert staged[6][0].curve.base == pytest.approx(curve.base + 2.0 + 0.5j)
    assert staged[6][0].stage_shift == pytest.approx(2.0 + 0.5j)
    assert moved[6] is pending[6][0]               # as it was, should its refit fail
    # not yet followed: nothing moves
    Following.following = False
    assert _stage_path(pending, Following(), {3: 1.0 + 0j, 5: 2.0 + 0j}) == {}


def test_a_holder_keeps_its_place_once_the_drift_is_taken_off():
    # a tube clamped 60 px from the tracked base, bending past it, the stage
    # drifting under it: compared as they lie, the frames' first stretch moves;
    # brought back to where the stage stood, it is the holder it was
    from tests.pipeline.test_pipette import _clamped_tracks

    still = _clamped_tracks(60.0, [0.0, 0.5, 1.0, 2.0, 3.0], noise=1e-3)
    shifts = [0j, 1.5 - 0.5j, 3.0 + 1.0j, 2.0 + 2.5j, -1.0 + 3.0j]
    moved = [replace(r, curve=replace(r.curve, base=r.curve.base + d), stage_shift=d)
             for r, d in zip(still, shifts, strict=True)]
    assert pipette.static_stretch(moved, 5.0) < 10.0
    assert pipette.static_stretch(pipette.on_first_stage(moved), 5.0) == pytest.approx(
        pipette.static_stretch(still, 5.0))
    at, gain, _ = pipette.motion_hinge(pipette.on_first_stage(moved), 5.0, 100.0)
    assert at == pytest.approx(60.0, abs=2.0) and gain > pipette.MIN_HINGE_GAIN


def test_a_stage_drifting_under_an_over_curl_is_followed_past_the_coil(tmp_path, monkeypatch):
    # sample 3 curling to 440 deg over its holder while the stage drifts 4 px:
    # where the coil lies over part of the holder's region, the rest still
    # tells the shift
    from models import get_sample
    from pipeline.accuracy import score_folder
    from pipeline.render import strain_for_angle

    scene = default_scene(3, n_frames=40, seed=14, width=800, height=600, base_angle_deg=180.0,
                          eps_max=strain_for_angle(get_sample(3), 440.0, p_max=0.17),
                          drift_px=4.0)
    folder = render_scene(scene, tmp_path / "scene", fmt="avi")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    track_video(folder / "frames.avi", tmp_path / "a", um_per_px=scale)
    _, acc = score_folder(folder, tmp_path / "a")
    assert acc.frames_lost == 0 and acc.angle_max < 2.0
    assert acc.centreline_rms_px < 0.5 and acc.length_error_max_pct < 1.0
    # not measured once the coil covers any of it, the base stays behind the
    # stage from 280 deg on
    monkeypatch.setattr(drift, "COVERED", 0.02)
    track_video(folder / "frames.avi", tmp_path / "b", um_per_px=scale)
    _, held = score_folder(folder, tmp_path / "b")
    assert held.length_error_max_pct > 1.0 and held.base_error_max_px > acc.base_error_max_px + 2
