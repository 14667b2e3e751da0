"""A tracked structure that stood still while the scene moved elsewhere is not
the tube (:func:`pipeline.motion.moved_elsewhere`, ``tracks._stood_still``)."""

import json
from dataclasses import replace

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline import tracks as tracks_module
from pipeline.accuracy import score_folder
from pipeline.motion import moved_elsewhere
from pipeline.render import default_scene, render_scene
from pipeline.tracks import NOT_THE_TUBE, track_video


def _bar(angle_deg: float, shape=(120, 160), centre=(60, 110), length=60) -> np.ndarray:
    """A frame with a bright bar 5 px wide about ``centre`` (col, row)."""
    img = np.zeros(shape, np.float32)
    d = 0.5 * length * np.exp(1j * np.radians(angle_deg))
    ends = [(int(centre[0] - d.real), int(centre[1] - d.imag)),
            (int(centre[0] + d.real), int(centre[1] + d.imag))]
    cv2.line(img, *ends, 1.0, 5)
    return img


def test_what_moves_far_from_the_structure_is_measured_against_its_area():
    rng = np.random.default_rng(0)

    def noisy(img):
        return 0.3 + 0.5 * img + rng.normal(0.0, 0.02, img.shape).astype(np.float32)

    static = np.zeros((120, 160), np.float32)
    cv2.line(static, (10, 20), (150, 20), 1.0, 5)  # the structure looked at: row 20
    path = np.c_[np.full(141, 20.0), np.arange(10.0, 151.0)]
    still = [noisy(static + _bar(0.0)) for _ in range(5)]
    turning = [noisy(static + _bar(a)) for a in (0.0, 20.0, 40.0, 60.0, 80.0)]
    assert moved_elsewhere(still, path, 2.5) == 0.0
    assert moved_elsewhere(turning, path, 2.5) > 0.5
    # the change on the structure itself does not count
    blinking = [noisy(static * g) for g in (1.0, 0.5, 1.0, 0.5, 1.0)]
    assert moved_elsewhere(blinking, path, 2.5) == 0.0


def _with_fibre(src, dst, thickness_px=3, row=0.88, wave=0.08):
    """Copy the rendered scene ``src`` into ``dst`` with a long static dark
    fibre ``thickness_px`` wide across the frame, waving by ``wave`` about
    ``row`` (shares of the height), darker than the tube."""
    (dst / "frames").mkdir(parents=True)
    for i, path in enumerate(sorted((src / "frames").iterdir())):
        frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float32)
        h, w = frame.shape[:2]
        t = np.linspace(0.0, 1.0, 80)
        pts = np.c_[0.05 * w + 0.9 * w * t, row * h + wave * h * np.sin(7 * t)]
        mask = np.zeros((h, w), np.float32)
        cv2.polylines(mask, [np.rint(pts).astype(np.int32)], False, 1.0, thickness_px, cv2.LINE_AA)
        frame = frame * (1 - 0.8 * mask) + 0.8 * mask * 0.2 * np.median(frame)
        cv2.imwrite(str(dst / "frames" / f"{i:03d}.png"), np.clip(frame, 0, 255).astype(np.uint8))
    for name in ("truth_tracks.csv", "truth_centrelines.csv", "scene.json"):
        (dst / name).write_bytes((src / name).read_bytes())


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A rendered scene (a tube 14 px wide): its folder and scale, um/px."""
    tmp = tmp_path_factory.mktemp("rendered")
    scene = default_scene(2, n_frames=6, seed=3, width=480, height=360)
    whole = render_scene(scene, tmp / "whole", fmt="png")
    return whole, json.loads((whole / "scene.json").read_text())["layout"]["um_per_px"]


@pytest.fixture(scope="module")
def fibre_scene(rendered, tmp_path_factory):
    """The rendered scene with a static dark band across its top, clear of
    the tube, longer and darker and of more area (a scratch, a chamber's
    edge: see :func:`_with_fibre`), that the detector takes for the tube."""
    whole, um_per_px = rendered
    dst = tmp_path_factory.mktemp("fibre") / "fibre"
    _with_fibre(whole, dst, thickness_px=35, row=0.08, wave=0.01)
    return dst, um_per_px


def test_a_thin_fibre_longer_than_the_tube_is_not_taken_for_it(rendered, tmp_path):
    """A fibre 3 px wide runs over 1.6x the tube's length, darker: the
    skeleton path holding the most of a structure's area (not the longest)
    is the tube's, found on the first frame without hiding anything."""
    whole, um_per_px = rendered
    _with_fibre(whole, tmp_path / "thin")
    run = track_video(tmp_path / "thin" / "frames", tmp_path / "out", um_per_px=um_per_px)
    _, acc = score_folder(tmp_path / "thin", tmp_path / "out")
    assert acc.meets_targets(), acc
    assert not any("stood still" in note for note in run.notes)


def test_a_fibre_taken_for_the_tube_is_hidden_and_the_tube_measured(fibre_scene, tmp_path):
    """A dark fibre longer and darker than the tube, static: the detector takes
    it for the tube. Without the stood-still check every frame came out ok
    with the fibre's 'bend'; with the check alone none was measured. The
    fibre is now hidden and the tube tracked past it: every frame meets the
    targets (the first track followed part of the fibre, the second the rest
    of it: both are hidden)."""
    fibre, um_per_px = fibre_scene
    run = track_video(fibre / "frames", tmp_path / "out", um_per_px=um_per_px)
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (tracks.status == "ok").all()
    _, acc = score_folder(fibre, tmp_path / "out")
    assert acc.meets_targets(), acc
    assert any("stood still" in note and "hidden" in note for note in run.notes)


def test_a_tube_found_past_a_hidden_fibre_whose_length_jumps_is_not_measured(
        fibre_scene, tmp_path, monkeypatch):
    """The tube tracked past what was hidden is kept only where its length
    holds (:data:`pipeline.tracks.HIDDEN_LENGTH_JITTER`); asked to hold it
    exactly, the same scene's frames stay unmeasured, and the note says why."""
    monkeypatch.setattr(tracks_module, "HIDDEN_LENGTH_JITTER", 0.0)
    fibre, um_per_px = fibre_scene
    run = track_video(fibre / "frames", tmp_path / "out", um_per_px=um_per_px)
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (tracks.status == NOT_THE_TUBE).all()
    assert tracks.bend_angle_deg.isna().all()
    assert any("its length jumped" in note for note in run.notes)


def test_a_tube_found_past_a_hidden_fibre_measured_on_few_frames_is_not_measured(
        fibre_scene, tmp_path, monkeypatch):
    """... and only where it was measured on half the frames
    (:data:`pipeline.tracks.HIDDEN_MIN_SHARE`); asked for more than all of
    them, the same scene's frames stay unmeasured, and the note says why."""
    monkeypatch.setattr(tracks_module, "HIDDEN_MIN_SHARE", 1.01)
    fibre, um_per_px = fibre_scene
    run = track_video(fibre / "frames", tmp_path / "out", um_per_px=um_per_px)
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert tracks.bend_angle_deg.isna().all()
    assert any("was measured on only 6 of 6 frames" in note for note in run.notes)


def test_nothing_tube_like_past_what_stood_still_gives_no_angle(tmp_path):
    """A static dark bar (taken for the tube) while a disc moves elsewhere:
    with the bar hidden no tube is found, so the bar's frames stay
    unmeasured, and the note says why."""
    rng = np.random.default_rng(1)
    (tmp_path / "frames").mkdir()
    for i in range(6):
        img = np.full((240, 320), 180.0, np.float32)
        cv2.line(img, (10, 60), (300, 70), 40.0, 7, cv2.LINE_AA)
        cv2.circle(img, (60 + 40 * i, 170), 14, 120.0, -1, cv2.LINE_AA)
        img += rng.normal(0.0, 3.0, img.shape).astype(np.float32)
        cv2.imwrite(str(tmp_path / "frames" / f"{i:03d}.png"),
                    np.clip(img, 0, 255).astype(np.uint8))
    run = track_video(tmp_path / "frames", tmp_path / "out", um_per_px=1.0)
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (tracks.status == NOT_THE_TUBE).all()
    assert tracks.bend_angle_deg.isna().all()
    assert any("stood still" in note for note in run.notes)


def test_a_tube_that_stays_put_is_measured(tmp_path):
    """A video of a tube that does not move (a held pressure): nothing moves
    elsewhere either, so it is measured as ever."""
    scene = default_scene(2, n_frames=6, seed=3, width=480, height=360)
    whole = render_scene(scene, tmp_path / "whole", fmt="png")
    still = tmp_path / "still"
    (still / "frames").mkdir(parents=True)
    first = sorted((whole / "frames").iterdir())[3]
    for i in range(5):
        (still / "frames" / f"{i:03d}.png").write_bytes(first.read_bytes())
    truth = pd.read_csv(whole / "truth_tracks.csv")
    lines = pd.read_csv(whole / "truth_centrelines.csv")
    pd.concat([truth[truth.frame == 3].assign(frame=i) for i in range(5)]).to_csv(
        still / "truth_tracks.csv", index=False)
    pd.concat([lines[lines.frame == 3].assign(frame=i) for i in range(5)]).to_csv(
        still / "truth_centrelines.csv", index=False)
    (still / "scene.json").write_bytes((whole / "scene.json").read_bytes())
    um_per_px = json.loads((whole / "scene.json").read_text())["layout"]["um_per_px"]
    run = track_video(still / "frames", tmp_path / "out", um_per_px=um_per_px)
    assert run.n_ok == 5
    assert not any("stood still" in note for note in run.notes)
    _, acc = score_folder(still, tmp_path / "out")
    assert acc.meets_targets()


def _unmeasured(n):
    from pipeline.track import FrameTrack

    return [FrameTrack(i, "tube found but its edges do not fit", None, "init") for i in range(n)]


def test_what_no_frame_measured_is_hidden_where_the_scene_moved_elsewhere():
    """What the first frame showed most (a reticle's line, a dish's wall) and
    no frame could fit as a tube is looked at as it was found: where the scene
    moved elsewhere, it is handed on to be hidden, as a tracked structure
    that stood still is."""
    from pipeline.segment import detect

    rng = np.random.default_rng(1)
    static = np.zeros((120, 160), np.float32)
    cv2.line(static, (5, 20), (155, 20), 1.0, 7)  # longer and wider than the bar

    def noisy(img):
        return 0.3 + 0.5 * img + rng.normal(0.0, 0.02, img.shape).astype(np.float32)

    turning = [noisy(static + _bar(a)) for a in (0.0, 20.0, 40.0, 60.0, 80.0)]
    det = detect(turning[0])
    assert det is not None and abs(-det.path.imag.mean() - 20) < 2  # the static line
    results = _unmeasured(5)
    out, note, still = tracks_module._stood_still(turning, results, det)
    assert out == results  # (nothing to mark)
    assert still is not None and "could not be measured on any frame" in note
    curve, half_width = still
    assert half_width == det.half_width and abs(curve.length - det.length) < 0.05 * det.length
    # nothing moved: nothing handed on
    steady = [noisy(static + _bar(0.0)) for _ in range(5)]
    assert tracks_module._stood_still(steady, results, detect(steady[0]))[2] is None
    # a frame measured: the check of a tracked structure's tip holds instead
    measured = [replace(results[0], status="ok")] + results[1:]
    assert tracks_module._stood_still(turning, measured, det)[2] is None
