"""A tracked structure that stood still while the scene moved elsewhere is not
the tube (:func:`pipeline.motion.moved_elsewhere`, ``tracks._stood_still``)."""

import json

import cv2
import numpy as np
import pandas as pd

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


def _with_fibre(src, dst):
    """Copy the rendered scene ``src`` into ``dst`` with a long static dark
    fibre across the frame, darker than the tube, its path clear of the
    tube's."""
    (dst / "frames").mkdir(parents=True)
    for i, path in enumerate(sorted((src / "frames").iterdir())):
        frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float32)
        h, w = frame.shape[:2]
        t = np.linspace(0.0, 1.0, 80)
        pts = np.c_[0.05 * w + 0.9 * w * t, 0.88 * h + 0.08 * h * np.sin(7 * t)]
        mask = np.zeros((h, w), np.float32)
        cv2.polylines(mask, [np.rint(pts).astype(np.int32)], False, 1.0, 3, cv2.LINE_AA)
        frame = frame * (1 - 0.8 * mask) + 0.8 * mask * 0.2 * np.median(frame)
        cv2.imwrite(str(dst / "frames" / f"{i:03d}.png"), np.clip(frame, 0, 255).astype(np.uint8))
    for name in ("truth_tracks.csv", "truth_centrelines.csv", "scene.json"):
        (dst / name).write_bytes((src / name).read_bytes())


def test_a_fibre_taken_for_the_tube_gives_no_angle(tmp_path):
    """A dark fibre longer and darker than the tube, static: the detector takes
    it for the tube. Without the check every frame came out ok with the
    fibre's 'bend'; now none of the fibre's frames is measured."""
    scene = default_scene(2, n_frames=6, seed=3, width=480, height=360)
    whole = render_scene(scene, tmp_path / "whole", fmt="png")
    fibre = tmp_path / "fibre"
    _with_fibre(whole, fibre)
    um_per_px = json.loads((whole / "scene.json").read_text())["layout"]["um_per_px"]
    run = track_video(fibre / "frames", tmp_path / "out", um_per_px=um_per_px)
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
