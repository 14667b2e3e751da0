"""The side edges near a tube's end: measured against the rest of the tube's
line, and left out once the frames show that they sit off it."""
import json

import numpy as np
import pytest

from pipeline import schema as S
from pipeline import track
from pipeline.accuracy import score_folder
from pipeline.centreline import fit_to_polyline
from pipeline.refine import END_CLEAR_HW, TubeLook, refine
from pipeline.render import default_scene, render_scene
from pipeline.track import END_VOTE_FRAMES, _EndVotes
from pipeline.tracks import track_video
from tests.pipeline.synthetic import arc_axis, tube_image

SHAPE = (240, 520)
BASE = 40 - 120j
LENGTH = 440.0
HW = 16.0


def _straight_tube(end_shift: float, polarity: int = 1):
    """A straight tube along +x whose last 6 px sit ``end_shift`` px to its left."""
    body = tube_image(SHAPE, BASE, 0.0, LENGTH, 0.0, HW, polarity=polarity, background=0.2)
    end = tube_image(SHAPE, BASE + 1j * end_shift, 0.0, LENGTH, 0.0, HW, polarity=polarity,
                     background=0.2)
    cols = np.arange(SHAPE[1])[None, :]
    return np.where(cols >= BASE.real + LENGTH - 6, end, body).astype(np.float32)


def _truth():
    z, _ = arc_axis(BASE, 0.0, LENGTH, 0.0)
    return fit_to_polyline(z, 0.0, n_coef=12)


@pytest.mark.parametrize("shift", [0.0, 0.3, -0.3])
def test_the_end_offset_is_how_far_the_ends_edges_sit_off_the_rests_line(shift):
    look = TubeLook(1, np.full(5, HW), 0.05)
    r = refine(_straight_tube(shift), _truth(), look, iterations=8, tol_px=0.005)
    assert r.end_offset == pytest.approx(shift, abs=0.06)


def test_leaving_the_ends_edges_out_keeps_the_tip_on_the_rests_line():
    img = _straight_tube(0.4)
    kept = refine(img, _truth(), TubeLook(1, np.full(5, HW), 0.05), iterations=8,
                  tol_px=0.005)
    left_out = refine(img, _truth(), TubeLook(1, np.full(5, HW), 0.05, end_clear=True),
                      iterations=8, tol_px=0.005)
    # the truth's tip tangent is the rest's: 0 (the end is shifted, not turned)
    assert abs(np.degrees(kept.curve.coef[-1])) > 0.2
    assert abs(np.degrees(left_out.curve.coef[-1])) < 0.5 * abs(np.degrees(kept.curve.coef[-1]))
    assert np.isnan(left_out.end_offset)  # not measured once left out


def test_a_steady_offset_leaves_the_ends_edges_out_and_scatter_does_not():
    bright = TubeLook(1, np.full(5, 5.0), 0.05)
    votes, look = _EndVotes(), bright
    for k in range(END_VOTE_FRAMES):
        assert not look.end_clear, k  # not before enough frames
        look = votes.add(-0.2 + 0.01 * (-1) ** k, look)
    assert look.end_clear
    # zero-mean scatter, however many frames; NaN (no profile that near) is skipped
    rng = np.random.default_rng(1)
    votes, look = _EndVotes(), bright
    for x in rng.normal(0.0, 0.2, 60):
        look = votes.add(float(x), look)
        look = votes.add(np.nan, look)
    assert not look.end_clear
    # a dark-edged tube keeps its end's edges (see _EndVotes)
    votes, look = _EndVotes(), TubeLook(-1, np.full(5, 5.0), 0.05)
    for _ in range(10):
        look = votes.add(-0.2, look)
    assert not look.end_clear


def _run(scene_dir, out):
    rec = json.loads((scene_dir / "scene.json").read_text())
    track_video(scene_dir / rec["frames_file"], out, um_per_px=rec["layout"]["um_per_px"])
    _, acc = score_folder(scene_dir, out)
    notes = json.loads((out / S.RUN_FILE).read_text())["left_out_and_why"]
    return acc, next(n for n in notes if n.startswith("side edges"))


def test_a_fluorescent_tubes_end_edges_are_left_out(tmp_path, monkeypatch):
    """Sample 1 fluorescent (walls glowing in proportion to their thickness):
    the thin wall's blurred edge sits further out than the thick one's, so the
    edge midpoints lie ~0.2 px off the axis, except on the last profile, where
    the end face's glow fills the lumen. Fitting that last profile bent the
    tip: angle error median 1.0 deg on this noise-free scene; left out,
    0.16 deg (fails without)."""
    scene = default_scene(1, n_frames=16, seed=24, mirror=True, base_angle_deg=90.0,
                          width=640, height=480,
                          look={"name": "fluorescent", "photons": 1e8, "read_noise": 0.0})
    scene_dir = render_scene(scene, tmp_path / "scene", fmt="png")
    acc, note = _run(scene_dir, tmp_path / "out")
    assert note.startswith(f"side edges within {END_CLEAR_HW:g} half-widths"), note
    assert acc.frames_lost == 0 and acc.angle_median < 0.3 and acc.angle_p95 < 0.6
    monkeypatch.setattr(track, "END_OFFSET_MIN_PX", np.inf)
    kept, note = _run(scene_dir, tmp_path / "kept")
    assert note.startswith("side edges kept"), note
    assert acc.angle_median < 0.5 * kept.angle_median


def test_a_dark_rimmed_tube_keeps_its_end_edges(tmp_path):
    scene = default_scene(1, n_frames=8, seed=24, mirror=True, base_angle_deg=90.0,
                          width=640, height=480,
                          look={"name": "transmitted", "photons": 1e8, "read_noise": 0.0,
                                "dust": 0})
    acc, note = _run(render_scene(scene, tmp_path / "scene", fmt="png"), tmp_path / "out")
    assert note.startswith("side edges kept up to 2 px"), note
    assert acc.angle_median < 0.3
