"""End to end: render frames whose truth is known, track them, score them against the truth.

Every case renders a few frames (:func:`pipeline.render.default_scene`,
:func:`pipeline.render.render_scene`), tracks them at the scene's scale
(:func:`pipeline.tracks.track_video`) and scores the tracked folder with
:func:`pipeline.accuracy.score_folder`. The thresholds are the tracking spec
(``Accuracy.meets_targets``, reports/README.md): bend-angle error median
≤ 0.5°, p95 ≤ 2°, max ≤ 5°; centreline RMS ≤ 0.5 px; length within 1 %; no
frame lost. The committed scenes in ``sample_frames/`` are tracked as they are.

Every case is one fixed seed, so a run is deterministic; each scene setting
below was also checked on other seeds before it went in, and settings that
miss the spec on some seed are left out (the report says which and by how much).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from models import get_sample
from pipeline import schema as S
from pipeline.accuracy import score_folder
from pipeline.render import default_scene, render_scene, strain_for_angle
from pipeline.tracks import track_video

SAMPLE_FRAMES = Path(__file__).resolve().parents[2] / "sample_frames"

# the tracking spec (pipeline.accuracy.Accuracy.meets_targets)
ANGLE_MEDIAN_DEG = 0.5
ANGLE_P95_DEG = 2.0
ANGLE_MAX_DEG = 5.0
CENTRELINE_RMS_PX = 0.5
LENGTH_ERROR_PCT = 1.0

#: bends smaller than this are too small for their sign to be a test
SIGN_MIN_DEG = 5.0

SMALL = {"width": 640, "height": 480, "n_frames": 6}


def _track(scene_dir: Path, out_dir: Path, label: str | None = None):
    """Track ``scene_dir``'s frames at its scale; (per-frame errors, summary, tracks, truth)."""
    record = json.loads((scene_dir / S.SCENE_FILE).read_text(encoding="utf-8"))
    track_video(scene_dir / record["frames_file"], out_dir,
                um_per_px=record["layout"]["um_per_px"])
    errors, acc = score_folder(scene_dir, out_dir)
    tracks = pd.read_csv(out_dir / S.TRACKS_FILE)
    truth = pd.read_csv(scene_dir / S.TRUTH_TRACKS_FILE)
    print(f"{label or scene_dir.name}: {acc.frames} frames, {acc.frames_lost} lost; angle error "
          f"median {acc.angle_median:.3f}, p95 {acc.angle_p95:.3f}, max {acc.angle_max:.3f} deg; "
          f"centreline RMS {acc.centreline_rms_px:.3f} px; length {acc.length_error_max_pct:.3f} "
          f"%; base {acc.base_error_max_px:.2f} px")
    return errors, acc, tracks, truth


def _render_and_track(tmp_path: Path, sample, *, fmt="avi", bit_depth=8, **changes):
    scene = default_scene(sample, **changes)
    scene_dir = render_scene(scene, tmp_path / "scene", fmt=fmt, bit_depth=bit_depth)
    label = ", ".join(f"{k}={v}" for k, v in changes.items() if k not in SMALL)
    return _track(scene_dir, tmp_path / "tracked", f"sample {sample} {fmt}/{bit_depth} {label}")


def _assert_angles_and_shape(errors, acc):
    """Every frame measured; angle and centreline within the spec."""
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, f"frames not measured:\n{lost.to_string(index=False)}"
    figures = (f"median {acc.angle_median:.3f}, p95 {acc.angle_p95:.3f}, "
               f"max {acc.angle_max:.3f} deg")
    assert acc.angle_median <= ANGLE_MEDIAN_DEG, figures
    assert acc.angle_p95 <= ANGLE_P95_DEG, figures
    assert acc.angle_max <= ANGLE_MAX_DEG, figures
    assert acc.centreline_rms_px <= CENTRELINE_RMS_PX, f"RMS {acc.centreline_rms_px:.3f} px"


def _assert_meets_spec(errors, acc):
    _assert_angles_and_shape(errors, acc)
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT, f"{acc.length_error_max_pct:.3f} %"


def _assert_same_sign(tracks, truth):
    """The tracked bend turns the same way as the true one (CCW positive)."""
    bent = truth[S.BEND].abs() > SIGN_MIN_DEG
    assert bent.any()
    assert (np.sign(tracks[S.BEND][bent]) == np.sign(truth[S.BEND][bent])).all()


# -- looks: how the tube shows under the microscope ------------------------------------------
LOOK_CASES = {
    # a transparent tube whose lumen shows as a lighter band between dark refraction rims
    "transmitted": dict(sample=3, look="transmitted", **SMALL),
    "opaque": dict(sample=3, look="opaque", **SMALL),
    # bright tube on a dark background, strong vignetting
    "fluorescent": dict(sample=3, look="fluorescent", width=800, height=600, n_frames=6),
    # 0.3 contrast: the tracker needs the smaller steps between frames here (on 6
    # frames, or smaller, it loses frames on some seeds)
    "low_contrast": dict(sample=2, look="low_contrast", width=800, height=600, n_frames=12),
    "uneven_illumination": dict(sample=3, look={"gradient": 0.5, "vignetting": 0.5}, **SMALL),
    "noise": dict(sample=3, look={"photons": 1000.0, "read_noise": 0.012}, **SMALL),
    "dust": dict(sample=3, look={"dust": 80}, **SMALL),
    "blur": dict(sample=3, look={"blur_px": 1.0}, **SMALL),
    "flicker": dict(sample=3, look={"flicker": 0.05}, **SMALL),
    # differential interference contrast: lit on one flank, shaded on the other,
    # the lumen's walls as strong as the outer ones
    "dic": dict(sample=3, look="dic", **SMALL),
}


@pytest.mark.parametrize("case", LOOK_CASES)
def test_tracking_meets_the_spec_in_every_look(tmp_path, case):
    errors, acc, tracks, truth = _render_and_track(tmp_path, seed=1, **LOOK_CASES[case])
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


# -- where the base is and which way the tube curls ------------------------------------------
ORIENTATIONS = [  # (base_angle_deg: direction the tube leaves the pipette, CCW from +x; mirror)
    (180.0, False),   # base on the right, pointing left
    (-90.0, False),   # base above, pointing down
    (-30.0, False),   # diagonal
    (90.0, True),     # base below, curling clockwise
    (45.0, True),
    (135.0, True),
    (270.0, True),
]


@pytest.mark.parametrize(("base_angle_deg", "mirror"), ORIENTATIONS)
def test_tracking_meets_the_spec_in_any_orientation(tmp_path, base_angle_deg, mirror):
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 3, seed=2, fmt="png", base_angle_deg=base_angle_deg, mirror=mirror, **SMALL)
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)
    # counter-clockwise is positive, a clockwise (mirrored) curl negative
    bent = truth[S.BEND].abs() > SIGN_MIN_DEG
    assert (np.sign(tracks[S.BEND][bent]) == (-1 if mirror else 1)).all()


def test_a_mirrored_tube_gives_the_opposite_angles(tmp_path):
    kw = dict(seed=3, base_angle_deg=180.0, **SMALL)
    errors, acc, ccw, truth_ccw = _render_and_track(tmp_path / "ccw", 3, **kw)
    _assert_meets_spec(errors, acc)
    errors, acc, cw, truth_cw = _render_and_track(tmp_path / "cw", 3, mirror=True, **kw)
    _assert_meets_spec(errors, acc)
    assert np.allclose(truth_cw[S.BEND], -truth_ccw[S.BEND])
    bent = truth_ccw[S.BEND].abs() > SIGN_MIN_DEG
    assert (ccw[S.BEND][bent] > 0).all()
    assert (cw[S.BEND][bent] < 0).all()
    # the mirror image bends by the same amount, to within the spec on each side
    assert np.allclose(cw[S.BEND], -ccw[S.BEND], atol=2 * ANGLE_MAX_DEG)


# -- file formats ------------------------------------------------------------------------------
FORMATS = [("avi", 8), ("mp4", 8), ("png", 8), ("png", 16), ("tiff", 8), ("tiff", 16)]


@pytest.mark.parametrize(("fmt", "bit_depth"), FORMATS)
def test_tracking_meets_the_spec_in_every_file_format(tmp_path, fmt, bit_depth):
    errors, acc, tracks, truth = _render_and_track(tmp_path, 3, seed=0, fmt=fmt,
                                                   bit_depth=bit_depth, **SMALL)
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


@pytest.mark.parametrize("look", ["opaque", {"blur_px": 1.0}], ids=["opaque", "blur"])
def test_compressed_video_still_shows_the_pipette(tmp_path, look):
    """MJPG blocks and blur taper the skeleton into a spur at the tip; that taper
    must not be taken for the pipette's width step (it once put the base at the
    image border, 117 px behind the pipette, and the length 25 % too long)."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 2, seed=2, fmt="avi", look=look,
                                                   **SMALL)
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text(encoding="utf-8"))
    # (then perhaps moved or turned to what the first frames show)
    assert run["base_source"].startswith("pipette width step")
    assert acc.base_error_max_px < 1.0
    _assert_meets_spec(errors, acc)


def test_a_dim_section_is_not_taken_for_the_pipette(tmp_path):
    """Under fluorescence a thin-walled section is dimmer, so its mask is narrower;
    with the pipette unseen (it would come in from the border) that narrower
    stretch once became the "pipette" and only the last section was tracked
    (length 66 % short). The base end now comes from the motion."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 2, seed=1, look="fluorescent",
                                                   width=320, height=240, n_frames=8)
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text(encoding="utf-8"))
    assert run["base_source"] != "pipette width step"
    assert acc.frames_lost == 0
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT
    assert acc.base_error_max_px < 2.0
    _assert_same_sign(tracks, truth)


@pytest.mark.parametrize(("sample", "size", "n_frames"), [(3, (320, 240), 8), (1, (200, 160), 4)],
                         ids=["39deg-per-frame", "100deg-per-frame"])
def test_a_fast_bend_right_after_the_start_is_still_followed(tmp_path, sample, size, n_frames):
    """On the frame after a start only the last shape predicts the next. At 39°
    per frame the tube ran out of the crop, whose edge passed for the tip (8°
    short, marked ok). At 100° per frame, refining the last shape on the whole
    frame alone ended 110° short and lost the next two frames: the fresh
    detection on that frame is what follows it."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, sample, seed=1, width=size[0],
                                                   height=size[1], n_frames=n_frames)
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, lost.to_string(index=False)
    assert acc.angle_max <= ANGLE_MAX_DEG, errors["angle_error_deg"].round(2).to_list()
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT


def test_a_video_that_starts_bent_meets_the_spec(tmp_path):
    """Deflating from p_max: the first frames are bent, so the base tangent
    cannot be measured on a straight tube; a fit to the bent tube leans
    0.6-0.7° into the bend (median error 1.0° before the pipette's axis was
    used). Sample 3 (seeds 1-3 meet the spec; sample 2 misses on seed 3)."""
    scene = default_scene(3, seed=1, width=640, height=480, n_frames=8)
    scene = scene.replace(pressures_mpa=tuple(np.linspace(scene.p_max_mpa, 0.0, 8)))
    scene_dir = render_scene(scene, tmp_path / "scene", fmt="avi")
    errors, acc, tracks, truth = _track(scene_dir, tmp_path / "tracked", "deflating sample 3")
    assert truth[S.BEND].iloc[0] > 200  # it does start bent
    _assert_meets_spec(errors, acc)


def test_a_video_that_starts_curled_past_300_deg_meets_the_spec(tmp_path):
    """Sample 1 deflating from a 306 deg curl, its base pointing up and to
    the left. The curl's tip comes close to its body: closing the mask shut
    the curl and filled the background inside it, and the start took the blob
    for the tube; carrying its base back to the pipette moved the whole curl
    off the tube; the fit of the base tangent slid off it (the base tangent
    18 deg off in every frame before). Seeds 1-4 at this and at a 0 deg base:
    7 of 8 meet the spec (seed 2 here misses p95 by 1.1 deg)."""
    scene = default_scene(1, seed=1, width=640, height=480, n_frames=8, base_angle_deg=300.0)
    scene = scene.replace(pressures_mpa=tuple(np.linspace(scene.p_max_mpa, 0.0, 8)))
    scene_dir = render_scene(scene, tmp_path / "scene", fmt="avi")
    errors, acc, tracks, truth = _track(scene_dir, tmp_path / "tracked", "deflating sample 1")
    assert truth[S.BEND].iloc[0] > 300
    _assert_meets_spec(errors, acc)


def test_a_video_that_starts_curled_over_itself_finds_its_base_at_the_restart(tmp_path):
    """The committed over-curl scene played backwards: it starts curled 440 deg
    over itself. Its first frames were taken for a short tube (169 px of the
    578) and tracked "ok" until lost; the restart 20 frames on was given that
    start's base, and the base votes counted that start's frames: the base sat
    58 px into the pipette and every angle was 24 deg off. A restart finds the
    base afresh (at the end nearest the earlier one) and the votes are this
    start's own: every frame measured meets the spec, the base within 1 px.
    The frames before that restart, lost on the way forward (4 of 60), are
    tracked again backwards from it (:func:`pipeline.backtrack.track_back`):
    none is lost."""
    import tifffile

    from pipeline.frames import open_frames

    src = SAMPLE_FRAMES / "overcurl"
    record = json.loads((src / S.SCENE_FILE).read_text(encoding="utf-8"))
    with open_frames(src / record["frames_file"]) as reader:
        frames = np.stack(list(reader))[::-1]
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    tifffile.imwrite(scene_dir / "frames.tif", frames)
    last = len(frames) - 1
    for name in (S.TRUTH_TRACKS_FILE, S.TRUTH_CENTRELINES_FILE):
        truth = pd.read_csv(src / name)
        truth[S.FRAME] = last - truth[S.FRAME]
        truth.sort_values(S.FRAME, kind="stable").to_csv(scene_dir / name, index=False)
    record["frames_file"] = "frames.tif"
    (scene_dir / S.SCENE_FILE).write_text(json.dumps(record), encoding="utf-8")
    errors, acc, tracks, truth = _track(scene_dir, tmp_path / "tracked", "over-curl backwards")
    assert truth[S.BEND].iloc[0] > 400
    _assert_meets_spec(errors, acc)
    assert acc.base_error_max_px < 1.0
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())
    assert any("tracked again backwards" in n for n in run["left_out_and_why"])


@pytest.mark.parametrize("failed_starts", [1, 2])
def test_frames_before_the_tracker_could_start_are_tracked_backwards(tmp_path, monkeypatch,
                                                                     failed_starts):
    """The first frames, on which the tube could not be found (here: made to
    fail), are found from the shape of the first frame that started the
    tracker, backwards, and meet the spec like the rest."""
    import pipeline.track as track

    calls = []
    start = track.initialise

    def failing(image, **kw):
        calls.append(1)
        return None if len(calls) <= failed_starts else start(image, **kw)

    monkeypatch.setattr(track, "initialise", failing)
    errors, acc, tracks, truth = _render_and_track(tmp_path, 3, seed=1, **SMALL)
    assert list(tracks[S.STATUS]) == [S.STATUS_OK] * SMALL["n_frames"]
    _assert_meets_spec(errors, acc)
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())
    assert any(f"tracked backwards on {failed_starts} of" in n for n in run["left_out_and_why"])


# -- the committed scenes ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["sample1", "sample2", "sample3"])
def test_committed_scenes_meet_the_spec(tmp_path, name):
    errors, acc, tracks, truth = _track(SAMPLE_FRAMES / name, tmp_path / "tracked")
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


def test_over_curl_keeps_the_unwrapped_angle_and_every_frame(tmp_path):
    """The tube curls to 440° and crosses its own base; no frame may be lost or wrap,
    and the length holds where the tip ends against the tube's own body."""
    errors, acc, tracks, truth = _track(SAMPLE_FRAMES / "overcurl", tmp_path / "tracked")
    assert truth[S.BEND].max() > 360  # the scene really goes past a full turn
    _assert_meets_spec(errors, acc)
    # unwrapped: past a full turn the tracked angle keeps counting instead of
    # restarting near 0° (a wrap would be a 360° error in a single frame)
    assert tracks[S.BEND].max() > 360
    past_a_turn = truth[S.BEND] > 360
    assert (tracks[S.BEND][past_a_turn] > 360 - ANGLE_MAX_DEG).all()
    _assert_same_sign(tracks, truth)



def test_a_tip_section_hidden_over_the_base_keeps_its_curvature(tmp_path):
    """Sample 7 (a straighter last tenth) curling to ~450°: once its tip lies
    over the base, the tip section's profiles are all left out. Carried by the
    prediction alone, its curvature drifted (43° off, every frame "ok"); it
    is now held in its ratio to the section before, as last seen whole."""
    spec = get_sample("7")
    eps = strain_for_angle(spec, 450.0, p_max=spec.p_max_mpa or 0.15)
    errors, acc, tracks, truth = _render_and_track(tmp_path, 7, eps_max=eps, n_frames=24,
                                                   seed=11, look="opaque", width=640,
                                                   height=480, base_angle_deg=30.0)
    assert truth[S.BEND].max() > 400
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text(encoding="utf-8"))
    assert run["stages"].get("crossing", 0) >= 3  # the hidden-tip frames really occur
    _assert_meets_spec(errors, acc)

# -- section joints: the curvature steps where the walls change -----------------------------------
def test_a_tight_curl_with_a_straight_tip_section_is_followed(tmp_path):
    """Sample 5 curls tightly in its middle section and hardly at all in its
    last tenth. A spline with uniform knots rounded that curvature step off:
    37° short at 270°, every frame marked ok. The joints are now found from
    the kinks in the measured shape, without being told the sample."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 5, seed=7, width=640, height=480,
                                                   n_frames=16)
    _assert_meets_spec(errors, acc)
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text(encoding="utf-8"))
    assert any("joint" in note for note in run["left_out_and_why"])


def test_a_fluorescent_tight_curl_finds_its_joints_by_the_width_steps(tmp_path):
    """Sample 5, fluorescent, without --sample: the kinks in its shape stand
    out of the noise too late (found only past 270°, 40° off before), but its
    sections differ in outer width, which shows on the first, straight frame."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 5, seed=7, width=800, height=600,
                                                   n_frames=12, look="fluorescent")
    _assert_meets_spec(errors, acc)
    first = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["first_curve"]
    assert first["joints"] == pytest.approx([0.6, 0.9], abs=0.003)


def test_a_joint_whose_width_does_not_step_is_still_followed(tmp_path, monkeypatch):
    """Sample 5 with its tip joint's width step hidden (as if the walls changed
    but not the outer width): the spline coarsened for the joints seen cannot
    follow the hidden curvature step (42° off at 270°) until a finer spline
    is seen to fit the edges better; then the fine spacing comes back."""
    from pipeline import joints, track

    steps = joints.width_steps
    # hidden on the first frame and in the mean width over the frames
    for module in (track, joints):
        monkeypatch.setattr(module, "width_steps", lambda *a, **k: steps(*a, **k)[:-1])
    errors, acc, tracks, truth = _render_and_track(tmp_path, 5, seed=7, width=640, height=480,
                                                   n_frames=16)
    assert acc.frames_lost == 0
    assert acc.angle_max <= ANGLE_MAX_DEG


def test_a_frame_the_coarse_spline_cannot_follow_is_found_with_the_fine_one(tmp_path):
    """Sample 5 tracked with only its 0.9 joint known (its 0.6 joint's faint
    width step unseen): the coarse spline of known joints cannot follow the
    curvature step at 0.6 once the tube bends past 100 deg, and a fresh
    detection rewritten to it failed too, so 7 of 12 frames were lost. The
    fresh detection's fine spline follows the tube, and is now kept."""
    from pipeline.frames import open_frames
    from pipeline.track import track_frames

    scene = default_scene(5, n_frames=12, seed=1, width=800, height=600,
                          base_angle_deg=222.5)
    scene_dir = render_scene(scene, tmp_path / "scene", fmt="avi")
    truth = pd.read_csv(scene_dir / S.TRUTH_TRACKS_FILE)[S.BEND].to_numpy()
    with open_frames(scene_dir / "frames.avi") as reader:
        results = list(track_frames(reader, joints=(0.9,)))
    assert [r.status for r in results] == ["ok"] * len(results)
    errors = np.array([np.degrees(r.curve.coef[-1]) for r in results]) - truth
    assert np.median(np.abs(errors)) <= ANGLE_MEDIAN_DEG, errors.round(2)


def test_a_noise_free_sharp_fluorescent_tube_is_found_on_its_first_frame(tmp_path):
    """A noise-free MJPG video of a sharp, dim fluorescent tube: the median
    gradient over the background is the compression's, and the tube's outline
    (edges 6x that) took in the faint pipette and the background's blocks as
    well: a 'tube' 3x too wide and 1.7x too long, whose first frame came out
    22 deg off. The outline's thresholds now stand at least a fiftieth of the
    strongest edges high."""
    look = {"name": "fluorescent", "photons": 1e9, "blur_px": 0.8, "gradient": 0.0, "dust": 0}
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 5, seed=1, n_frames=12, width=800, height=600, base_angle_deg=222.5,
        look=look)
    assert abs(errors["angle_error_deg"].iloc[0]) <= ANGLE_MEDIAN_DEG
    _assert_meets_spec(errors, acc)


def test_the_samples_joints_are_used_when_it_is_given(tmp_path):
    """With --sample the joints come from its sections."""
    scene = default_scene(5, seed=7, width=1024, height=768, n_frames=12, look="fluorescent")
    scene_dir = render_scene(scene, tmp_path / "scene")
    track_video(scene_dir / json.loads((scene_dir / S.SCENE_FILE).read_text())["frames_file"],
                tmp_path / "tracked", sample="5")
    errors, acc = score_folder(scene_dir, tmp_path / "tracked")
    _assert_angles_and_shape(errors, acc)
    first = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["first_curve"]
    assert first["joints"] == pytest.approx([0.6, 0.9])


@pytest.mark.parametrize("seed", [1014, 2])
def test_given_joints_do_not_let_the_first_fit_kink_into_the_skeleton_s_hooks(tmp_path, seed):
    """A noisy fluorescent sample 1 (480x360, 940 photons) with --sample: the
    tube was first fitted to its rough skeleton with the joints' kinks already
    in, which followed a hook at the skeleton's end (seed 1014: a wrong end
    and curl, 52 deg off and 3 of 4 frames lost; seed 2: 6 % short, 19 deg
    off). The tube is now found without them, and they go in once it is."""
    scene = default_scene(1, seed=seed, width=480, height=360, n_frames=4, base_angle_deg=29.19,
                          look={"name": "fluorescent", "photons": 940.0, "blur_px": 1.66})
    scene_dir = render_scene(scene, tmp_path / "scene")
    track_video(scene_dir / json.loads((scene_dir / S.SCENE_FILE).read_text())["frames_file"],
                tmp_path / "tracked", sample="1")
    errors, acc = score_folder(scene_dir, tmp_path / "tracked")
    assert acc.frames_lost == 0
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT, f"{acc.length_error_max_pct:.2f} %"
    assert acc.angle_max <= ANGLE_MAX_DEG, f"max {acc.angle_max:.2f} deg"
    first = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["first_curve"]
    assert first["joints"] == pytest.approx([0.43, 0.67, 0.9])


def test_a_single_section_sample_is_not_searched_for_joints(tmp_path, monkeypatch):
    """--sample of one section says there are no joints: the frames are not
    searched for kinks, and the run says so (it once told the user to give
    --sample, which had been given)."""
    from pipeline import track

    searched = []
    monkeypatch.setattr(track, "find_joints", lambda *a, **k: searched.append(1) or ())
    scene = default_scene(8, seed=3, width=480, height=360, n_frames=8)
    scene_dir = render_scene(scene, tmp_path / "scene")
    track_video(scene_dir / json.loads((scene_dir / S.SCENE_FILE).read_text())["frames_file"],
                tmp_path / "tracked", sample="8")
    errors, acc = score_folder(scene_dir, tmp_path / "tracked")
    truth = pd.read_csv(scene_dir / S.TRUTH_TRACKS_FILE)
    assert acc.frames_lost == 0 and acc.angle_max <= ANGLE_MAX_DEG
    assert truth[S.BEND].abs().max() > 60  # bent far enough that the frames would be searched
    assert not searched
    notes = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["left_out_and_why"]
    assert any("single section" in n and "not looked for" in n for n in notes), notes
    # a clean scene: the sharpest edge filter
    assert any(n.startswith("edge profiles smoothed over 0.8 px, the narrowest") for n in notes)


def test_a_faint_pipette_short_of_the_border_is_not_taken_for_tube(tmp_path):
    """A fluorescent scene whose pipette glows faintly and fades before the
    border: the skeleton ran 72 px into it, and the base search did not reach
    the tube's start (length 12 % long)."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 7, seed=11, width=800, height=600,
                                                   n_frames=10, look="fluorescent")
    assert acc.frames_lost == 0
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT
    assert acc.base_error_max_px <= 1.0


def test_a_thin_dark_tube_is_measured_at_its_own_width(tmp_path):
    """Sample 8 (355 µm wide) opaque at 57 µm/px is a 6 px dark band. The
    detection mask of so strong a band spreads over its blurred skirts to
    twice the tube's width, and the edge pairs then sought (±40 % of that)
    missed the true pair on every frame: all 16 lost as "edges do not fit".
    The first fit now also tries narrower widths and keeps the strongest."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 8, seed=1016, look="opaque",
                                                   width=320, height=240, n_frames=8,
                                                   base_angle_deg=-60.0, mirror=True)
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, lost.to_string(index=False)
    assert acc.centreline_rms_px <= CENTRELINE_RMS_PX
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT
    assert acc.angle_max <= ANGLE_MAX_DEG
    _assert_same_sign(tracks, truth)


def test_a_skeleton_that_runs_on_into_dust_is_cut_back_to_the_tube(tmp_path):
    """On this 320x240 frame a dust speck lies just past the straight tube's
    tip: the skeleton ran on into it, the curve came out 16 px too long, its
    end was never found and the first frame was lost. The curve is now cut
    back to where the tube's edges stop before the end is searched for."""
    errors, acc, tracks, truth = _render_and_track(tmp_path, 6, seed=1031, width=320,
                                                   height=240, n_frames=16,
                                                   base_angle_deg=151.45222014086193)
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, lost.to_string(index=False)
    assert abs(errors["length_error_pct"].iloc[0]) <= LENGTH_ERROR_PCT
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT
    # (the angle median, 0.51 deg, is the base tangent measured on this one
    # 10 px wide frame: 0.5 deg off, and carried by every frame)
    assert acc.angle_max <= ANGLE_MAX_DEG


@pytest.mark.parametrize(("sample", "seed", "base_angle_deg"), [(3, 7, 120.0), (2, 6, 200.0)],
                         ids=["run-on", "redetect"])
def test_a_frame_scaled_up_twice_keeps_its_tube_s_end(tmp_path, sample, seed, base_angle_deg):
    """A 480x360 low-contrast video scaled up 2x (cubic, as a camera's or an
    export's resampling does): its noise comes in blobs, and beyond the tip
    they form an edge pair now and then.

    run-on: the first fit, carried on past the end to see whether the tube runs
    on, took 3 such profiles of 5 for the tube: the tip went 2.5 half-widths
    past its end and 7 of 8 frames were lost. A tube now runs on only where most
    profiles past the end find its edges.

    redetect: on the frame after the start (25 deg more bend, no velocity yet)
    the tube was found afresh with its end too far out (the skeleton ran on
    past the tip), and the frame was lost. A fresh find longer than the last
    frame's tube by more than a length step now looks for the end again where
    that length puts it.
    """
    import cv2

    from pipeline.frames import open_frames

    scene = default_scene(sample, seed=seed, width=480, height=360, n_frames=8,
                          base_angle_deg=base_angle_deg,
                          look={"photons": 1300.0, "contrast": 0.3})
    small = render_scene(scene, tmp_path / "small", fmt="png")
    record = json.loads((small / S.SCENE_FILE).read_text(encoding="utf-8"))
    big = tmp_path / "big"
    (big / "frames").mkdir(parents=True)
    with open_frames(small / record["frames_file"]) as reader:
        for i, frame in enumerate(reader):
            # pixel centre (c, r) to (2c, 2r): the truth scales with the frame
            up = cv2.warpAffine(frame, np.float32([[2, 0, 0], [0, 2, 0]]), (960, 720),
                                flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
            cv2.imwrite(str(big / "frames" / f"{i:03d}.png"), up)
    for name in (S.TRUTH_TRACKS_FILE, S.TRUTH_CENTRELINES_FILE):
        (big / name).write_bytes((small / name).read_bytes())
    record["layout"]["um_per_px"] /= 2
    record["frames_file"] = "frames"
    (big / S.SCENE_FILE).write_text(json.dumps(record), encoding="utf-8")
    errors, acc, tracks, truth = _track(big, tmp_path / "tracked", f"sample {sample} scaled up 2x")
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


def test_a_relief_tube_s_end_face_does_not_bend_its_tip(tmp_path):
    """DIC, sample 1: the last section runs nearly along the shear, so its side
    edges fade, while the end face, across the shear, shows as a line pair as
    strong as the tube's edges. The profiles within 2 px of the end ran along
    that line's flank and found edges in it: the tip bent 11 deg off on one
    frame (p95 5.3 deg). A relief's side edges now stop half a width short of
    its end."""
    look = {"name": "dic", "shear_deg": 161.72}
    errors, acc, tracks, truth = _render_and_track(tmp_path, 1, seed=9008, look=look, width=640,
                                                   height=480, n_frames=12,
                                                   base_angle_deg=18.26, p_max_mpa=0.14)
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


def test_a_fresh_find_whose_coarse_spline_runs_on_keeps_the_tube_s_length(tmp_path):
    """A faint 1024x768 MP4 (sample 7, low contrast): on the frame after the
    start the tube was found afresh, its fine spline's end 5.5 % out (within
    the length step, so not questioned) and the coarse spline it was rewritten
    to 9.8 % out: the frame was lost. The end is now looked for again where the
    last frame's length puts it after the rewrite as well."""
    look = {"name": "low_contrast", "dust": 51}
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 7, fmt="mp4", seed=20369126, look=look, width=1024, height=768, n_frames=12,
        base_angle_deg=134.76690104468386, mirror=True, eps_max=0.5736668252294416)
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


def test_a_noisy_low_contrast_tube_is_seen_through_smoother_profiles(tmp_path):
    """Sample 3, low contrast, 1390 photons and 1.55 px blur at 320x240: its
    edges stand only 1.8 times above the noise of the 0.8 px edge filter. The
    edge midpoints scattered by 0.7–1.8 px, and every frame was lost ("edges do
    not fit"). The tracker now smooths the profiles as much as the edges need to
    stand clear of the noise (here 2.4 px)."""
    look = {"name": "low_contrast", "photons": 1390.8758761077218,
            "blur_px": 1.5520312662324183}
    errors, acc, tracks, truth = _render_and_track(tmp_path, 3, seed=5029, look=look,
                                                   width=320, height=240, n_frames=16,
                                                   base_angle_deg=133.16449825246616)
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, lost.to_string(index=False)
    assert acc.centreline_rms_px <= CENTRELINE_RMS_PX
    # both ends within a pixel, so the length within 1 %: the tip (median 0.70 px;
    # 0.95 with the wide filter alone) and the base, no pipette seen, put at the
    # median of where the first 8 frames show it (0.83 px; 1.8 px from the first
    # frame alone, which with the narrow-filter tip gave a length 1.5 % short)
    assert errors["tip_error_px"].median() <= 0.8
    assert errors["base_error_px"].max() <= 1.0
    assert acc.length_error_max_pct <= LENGTH_ERROR_PCT
    _assert_same_sign(tracks, truth)
    # (the angle is noise-limited here: median 0.9, max 4.0 deg, left unasserted)
    notes = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["left_out_and_why"]
    assert any(n.startswith("edge profiles smoothed over 2.4 px, not the narrowest")
               for n in notes), notes


def test_a_faint_width_step_near_the_tip_is_taken_for_a_joint(tmp_path):
    """Fluorescent sample 5 with few photons: its tip section (the last tenth,
    1.4 widths) is 8 % narrower and nearly straight. The width step stood only
    ~5 standard errors out, under the old threshold of 8, and no kink test sees
    a joint so near the tip: the spline carried the curl on, and the tip angle
    ran 16 deg ahead. The step is now taken from 5 standard errors."""
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 5, seed=5030, width=480, height=360, n_frames=16,
        base_angle_deg=125.58863320897778, look={"name": "fluorescent", "photons": 538.87})
    notes = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["left_out_and_why"]
    found = [float(x) for n in notes if "section joints found" in n
             for x in re.findall(r"0\.\d+", n.split("of the length")[0])]
    assert any(abs(j - 0.9) < 0.02 for j in found), notes
    assert acc.frames_lost == 0
    assert acc.angle_max <= ANGLE_MAX_DEG, f"max {acc.angle_max:.2f} deg"
    _assert_same_sign(tracks, truth)


@pytest.mark.parametrize("seed", [1014, 2])
def test_width_steps_too_faint_for_one_frame_are_found_over_several(tmp_path, seed):
    """Noisy fluorescent sample 1 at 480x360 without --sample: its width steps
    (2-3 % at 0.43 and 0.67, 8 % at 0.9) do not stand out on one frame (1 px
    of scatter per profile), nor its kinks in the shape, and the spline ran
    through the curvature step at 0.9: 16 deg off at 290 deg (seed 1014).
    The mean width over the first frames shows all three within a few frames
    and places them to a few pixels. What is left is the fluorescent look's
    own midpoint scatter (median 1.6-2.4 deg here, still over the spec's 0.5)."""
    scene = default_scene(1, seed=seed, width=480, height=360, n_frames=16,
                          base_angle_deg=29.19,
                          look={"name": "fluorescent", "photons": 940.0, "blur_px": 1.66})
    scene_dir = render_scene(scene, tmp_path / "scene")
    errors, acc, tracks, truth = _track(scene_dir, tmp_path / "tracked")
    notes = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text())["left_out_and_why"]
    found = [float(x) for n in notes if "section joints found" in n
             for x in re.findall(r"0\.\d+", n.split("of the length")[0])]
    assert found == pytest.approx([0.43, 0.67, 0.9], abs=0.015), notes
    assert acc.frames_lost == 0
    assert acc.angle_max <= 7.0, f"max {acc.angle_max:.2f} deg"
    _assert_same_sign(tracks, truth)


def test_the_frame_after_a_start_is_also_found_afresh_when_its_fit_fails(tmp_path):
    """A 6 px low-contrast sample 7 whose width steps give both joints on the
    first frame: the coarse jointed spline, pulled from the first shape to the
    second frame, settled on a curl 145 deg off that fitted well enough, and
    every later frame followed it. The frame after a start whose fast fit
    fails now also gets a fresh detection, and the better fit is kept."""
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 7, seed=1023, width=320, height=240, n_frames=16, mirror=True,
        base_angle_deg=291.7621671246772, look="low_contrast")
    assert acc.frames_lost == 0
    assert abs(errors["angle_error_deg"].iloc[1]) <= ANGLE_MAX_DEG
    assert acc.angle_max <= ANGLE_MAX_DEG, f"max {acc.angle_max:.2f} deg"
    assert acc.angle_median <= 1.0, f"median {acc.angle_median:.2f} deg"


def test_a_skeleton_that_stops_short_of_the_tip_is_carried_on_to_it(tmp_path):
    """A 28 px wide transparent tube whose mask broke up a quarter of its
    length before the tip (its lumen and rims apart): the skeleton stopped
    90 px short, the end search (two widths) did not reach, and the first
    frame was lost. The curve is now carried on straight while the tube's
    edges run to its end, and cut back to where they stop."""
    look = {"name": "transmitted", "photons": 1210.6720130515869,
            "vignetting": 0.3579867247693005}
    errors, acc, tracks, truth = _render_and_track(tmp_path, 5, fmt="png", seed=20261132,
                                                   width=480, height=360, n_frames=12,
                                                   base_angle_deg=186.7418840596137,
                                                   mirror=True, look=look)
    lost = errors.loc[errors[S.STATUS] != S.STATUS_OK, [S.FRAME, S.STATUS]]
    assert acc.frames_lost == 0, lost.to_string(index=False)
    assert abs(errors["length_error_pct"].iloc[0]) <= LENGTH_ERROR_PCT
    _assert_meets_spec(errors, acc)


@pytest.mark.parametrize("seed", [2, 4])
def test_a_transparent_tube_on_a_mottled_background_is_tracked(tmp_path, seed):
    """Sample 2, transmitted light, over a background mottled by 5 % at 2, 6 and
    20 px (a textured substrate): the tube is no darker than the darker patches,
    and every frame was lost ("no tube found", or a rim tracked for the tube).
    The start now also finds the tube by its outline, and takes that when the
    contrast's mask yields none or a much shorter one."""
    errors, acc, tracks, truth = _render_and_track(
        tmp_path, 2, fmt="png", seed=seed, width=480, height=360, n_frames=8,
        look={"name": "transmitted", "texture": 0.05})
    _assert_meets_spec(errors, acc)
    _assert_same_sign(tracks, truth)


def test_a_short_last_section_is_held_in_proportion_to_the_rest(tmp_path, monkeypatch):
    """Sample 7's last section is 12 % of the tube: at 480x360 (a tube 6 px
    wide, fluorescent) its curvature rests on a few profiles, and the tip
    angle followed their noise. Held at the one ratio to the rest of the tube
    that the frames tell (both of the paper's models bend every section in
    proportion to one load), the angle error's median falls 0.38 -> 0.10 deg
    (fails without the hold). With the end's side edges left out as well
    (:class:`pipeline.track._EndVotes`, which this scene's frames ask for),
    0.18 deg against 0.24 deg without the hold: measured here with them kept,
    to see the hold alone."""
    from pipeline import track, tracks

    scene = default_scene(7, seed=2, width=480, height=360, n_frames=12, look="fluorescent")
    scene_dir = render_scene(scene, tmp_path / "scene")
    errors, acc, _, _ = _track(scene_dir, tmp_path / "both", "sample 7, held, end left out")
    _assert_meets_spec(errors, acc)
    monkeypatch.setattr(track, "END_OFFSET_MIN_PX", np.inf)
    errors, acc, _, _ = _track(scene_dir, tmp_path / "held", "sample 7, held")
    _assert_meets_spec(errors, acc)
    notes = json.loads((tmp_path / "held" / S.RUN_FILE).read_text())["left_out_and_why"]
    note = next(n for n in notes if n.startswith("last section"))
    assert "held at" in note, note
    # the ratio held is the tube's: the truth's, over its last 12 % and the rest
    truth = pd.read_csv(scene_dir / S.TRUTH_CENTRELINES_FILE)
    last = truth[truth[S.FRAME] == truth[S.FRAME].max()].sort_values(S.S)
    z = (last[S.X] + 1j * last[S.Y]).to_numpy()
    phi = np.unwrap(np.angle(np.diff(z)))
    s = 0.5 * (last[S.S].to_numpy()[1:] + last[S.S].to_numpy()[:-1]) / last[S.S].max()
    joint = 1.0 - get_sample(7).fractions[-1] / np.sum(get_sample(7).fractions)
    turn_at = lambda u: np.interp(u, s, phi)  # noqa: E731
    true_ratio = (((turn_at(1.0) - turn_at(joint)) / (1 - joint))
                  / ((turn_at(joint) - turn_at(0.0)) / joint))
    held = float(re.search(r"held at ([-\d.]+) times", note).group(1))
    assert held == pytest.approx(true_ratio, rel=0.08)

    monkeypatch.setattr(tracks, "hold_section_ratio", lambda results: (results, "not held"))
    _, unheld, _, _ = _track(scene_dir, tmp_path / "unheld", "sample 7, not held")
    assert acc.angle_median < 0.5 * unheld.angle_median


@pytest.mark.parametrize(("bits", "black"), [(10, 0), (12, 0), (10, 30000)])
def test_a_camera_s_few_bits_in_16_bit_files_are_tracked_as_the_full_range(tmp_path, bits,
                                                                           black):
    """A 10-bit camera's counts written into 16-bit TIFFs span 1/64 of the range
    the tracker reads 16-bit frames in, under its floors set in 8-bit grey levels:
    the pipette's faint edges were lost (sample #2's 640x480 scene: base 44 px
    into the pipette, length 13 % long), as they were when the counts started
    high in the range (a black level, a dim exposure). The frames are brought
    to the full range by the bits the first one spans, and the run says so."""
    import tifffile

    from pipeline.frames import open_frames

    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    for name in (S.SCENE_FILE, S.TRUTH_TRACKS_FILE, S.TRUTH_CENTRELINES_FILE):
        (scene_dir / name).write_bytes((SAMPLE_FRAMES / "sample2" / name).read_bytes())
    record = json.loads((scene_dir / S.SCENE_FILE).read_text(encoding="utf-8"))
    with open_frames(SAMPLE_FRAMES / "sample2" / record["frames_file"]) as reader:
        counts = np.stack([black + np.round(f / 255.0 * (2**bits - 1))
                           for f in reader]).astype(np.uint16)
    tifffile.imwrite(scene_dir / "counts.tif", counts)
    record["frames_file"] = "counts.tif"
    (scene_dir / S.SCENE_FILE).write_text(json.dumps(record), encoding="utf-8")
    errors, acc, tracks, truth = _track(scene_dir, tmp_path / "tracked", f"{bits}-bit counts")
    _assert_meets_spec(errors, acc)
    assert acc.base_error_max_px < 1.0
    run = json.loads((tmp_path / "tracked" / S.RUN_FILE).read_text(encoding="utf-8"))
    assert any(f"({bits}-bit) from" in n for n in run["left_out_and_why"])
