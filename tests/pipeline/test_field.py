"""A microscope's round field of view (:mod:`pipeline.field`)."""

import json

import cv2
import numpy as np
import pytest

from pipeline.accuracy import score_folder
from pipeline.field import Field, field_stop
from pipeline.render import Scene, render_scene
from pipeline.tracks import track_video


def _stop(frame: np.ndarray, centre: complex, radius: float, ramp_px: float = 6.0,
          seed: int = 0) -> np.ndarray:
    """``frame`` (uint8) seen through a field stop: lit inside ``radius`` px of
    ``centre`` (col + 1j·row), a linear ramp ``ramp_px`` wide inside that
    radius, black (3 grey levels, noisy) beyond."""
    rows, cols = frame.shape
    yy, xx = np.mgrid[0:rows, 0:cols]
    lit = np.clip((radius - np.abs(xx + 1j * yy - centre)) / ramp_px, 0.0, 1.0)
    dark = 3.0 + np.random.default_rng(seed).normal(0.0, 1.5, frame.shape)
    return np.clip(frame * lit + (1 - lit) * dark, 0, 255).astype(np.uint8)


def _background(shape=(360, 480), level=180.0, vignetting=0.0, seed=1) -> np.ndarray:
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols]
    rho2 = ((xx - cols / 2) ** 2 + (yy - rows / 2) ** 2) / ((cols / 2) ** 2 + (rows / 2) ** 2)
    noise = np.random.default_rng(seed).normal(0.0, 3.0, shape)
    return np.clip(level * (1 - vignetting * rho2) + noise, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("centre", [240 + 180j, 290 + 150j])
def test_the_field_stop_s_disc_is_found_and_its_lit_part_ends_inside_the_ramp(centre):
    frame = _stop(_background(), centre, 240.0)
    stop = field_stop(frame)
    assert stop
    assert abs(stop.centre - centre) < 1.5
    # the dark's edge is at the ramp's outer end (240 px); the field's own
    # level ends at its inner end (234 px): nothing of the ramp is kept
    assert 236.0 <= stop.radius <= 241.0
    assert 228.0 <= stop.lit_radius <= 234.0


@pytest.mark.parametrize("frame", [
    _background(),                                   # a plain field
    _background(vignetting=0.6),                     # corners fading to 40 %
    _background(level=12.0),                         # a fluorescent frame's dark background
    np.pad(_background((300, 400)), ((30, 30), (40, 40))),  # letterbox bars, no disc
], ids=["plain", "vignetted", "fluorescent", "bars"])
def test_no_field_stop_where_there_is_none(frame):
    assert not field_stop(frame)


def test_the_dark_beyond_the_disc_is_filled_from_its_edge_and_the_field_left_alone():
    frame = _stop(_background(), 240 + 180j, 240.0)
    stop = field_stop(frame)
    filled = stop.fill(frame)
    rows, cols = frame.shape
    yy, xx = np.mgrid[0:rows, 0:cols]
    inside = np.abs(xx + 1j * yy - stop.centre) <= stop.lit_radius
    np.testing.assert_array_equal(filled[inside], frame[inside])
    # the corners now carry the field's level, and the frame itself is untouched
    assert abs(float(np.median(filled[~inside])) - 180.0) < 5.0
    assert float(np.median(frame[~inside])) < 60.0
    assert Field().fill(frame) is frame


def test_a_video_through_a_field_stop_is_tracked_as_without_it(tmp_path):
    """A rendered scene (sample 2, 480x360, low contrast, shot noise, dust)
    seen through a disc 0.8 of the half-diagonal wide about the frame's
    centre, its pipette crossing the disc's edge into the dark. Without the
    field stop's handling no frame was measured (the edges did not fit)."""
    scene = Scene(sample="2", eps_max=0.5846, k_de_per_um=-0.002, p_max_mpa=0.14, n_frames=6,
                  width=480, height=360, base_angle_deg=20.02, seed=20761133,
                  look={"name": "low_contrast", "photons": 1268.0, "dust": 58})
    plain = render_scene(scene, tmp_path / "plain", fmt="png")
    seen = tmp_path / "stop"
    (seen / "frames").mkdir(parents=True)
    for i, path in enumerate(sorted((plain / "frames").iterdir())):
        frame = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(seen / "frames" / f"{i:03d}.png"), _stop(frame, 239.5 + 179.5j, 240.0))
    for name in ("truth_tracks.csv", "truth_centrelines.csv", "scene.json"):
        (seen / name).write_bytes((plain / name).read_bytes())
    um_per_px = json.loads((plain / "scene.json").read_text())["layout"]["um_per_px"]
    run = track_video(seen / "frames", tmp_path / "out", um_per_px=um_per_px)
    assert any("round field of view" in note for note in run.notes)
    _, acc = score_folder(seen, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.angle_median <= 0.5 and acc.angle_max <= 2.0
    assert acc.length_error_max_pct <= 1.0
    assert acc.centreline_rms_px <= 0.5


def test_the_note_gives_the_disc_in_the_whole_frame_s_pixels():
    # found on a frame cropped 3 px from the left and 4 from the top
    assert "about (13, 24)" in Field(10 + 20j, 5.0, 4.0).describe((3, 4))
