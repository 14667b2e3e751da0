"""A thin fibre across the tube, or touching its tip, is not taken for the
tube, nor for its pipette (:func:`pipeline.segment.detect`)."""

import json

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline.frames import open_frames
from pipeline.render import default_scene, render_scene
from pipeline.segment import AMBIGUOUS_BASE, detect
from pipeline.track import as_float
from pipeline.tracks import _static_end, track_video
from tests.pipeline.synthetic import tube_image


def _darken_along(frame: np.ndarray, a: complex, b: complex, width: int, depth: float):
    """``frame`` with a dark line from ``a`` to ``b`` (col + 1j·row), ``depth``
    of the frame's median deep."""
    mask = np.zeros(frame.shape[:2], np.float32)
    cv2.line(mask, (int(a.real), int(a.imag)), (int(b.real), int(b.imag)), 1.0, width,
             cv2.LINE_AA)
    return frame * (1 - depth * mask) + depth * mask * 0.2 * np.median(frame)


def test_a_fibre_across_the_tube_is_not_followed(tmp_path):
    """A fibre crossing the straight tube at right angles, running on to the
    border: the longest path ran along the tube and turned down the fibre
    (which then passed for the tube, the rest for its holder); it now runs
    on through the crossing."""
    whole = render_scene(default_scene(2, n_frames=1, seed=3, width=480, height=360),
                         tmp_path / "whole", fmt="png")
    um = json.loads((whole / "scene.json").read_text())["layout"]["um_per_px"]
    line = pd.read_csv(whole / "truth_centrelines.csv")
    z = (line.x_um.to_numpy() + 1j * line.y_um.to_numpy()) / um   # px, y up
    at = int(0.7 * z.size)
    across = 1j * (z[at + 5] - z[at - 5]) / abs(z[at + 5] - z[at - 5])
    frame = cv2.imread(str(next((whole / "frames").iterdir())), cv2.IMREAD_GRAYSCALE)
    # (image coordinates: col + 1j·row is the conjugate of the y-up point)
    a, b = np.conj(z[at] + 40 * across), np.conj(z[at] - 400 * across)
    image = _darken_along(frame.astype(np.float32), a, b, 3, 0.8) / 255
    det = detect(image.astype(np.float32))
    assert abs(det.path[-1] - z[-1]) < 6.0, (det.path[-1], z[-1])
    assert abs(det.base - z[0]) < 10.0, (det.base, z[0])


@pytest.fixture(scope="module", params=[11.0, 16.0])
def held_and_touched(tmp_path_factory, request):
    """A tube 7 px in half-width leaving a wider holder (11 or 16 px: the
    fibre's step or the holder's the larger) at the left border, bending
    down 12 deg per frame; a still fibre runs from its tip, in line, to the
    right border on the first frame. Returns the frames' folder and the
    true bends (deg)."""
    folder = tmp_path_factory.mktemp("held") / "frames"
    folder.mkdir()
    base, length = 90 - 100j, 250.0
    bends = -12.0 * np.arange(8)
    for k, bend in enumerate(bends):
        img = tube_image((320, 480), base, 0.0, length, np.radians(bend) / length - 1e-12, 7.0,
                         pipette_half_width=request.param, pipette_contrast=1.0, noise=0.01,
                         seed=k)
        img = _darken_along(img, 340 + 100j, 479 + 80j, 2, 0.35)
        cv2.imwrite(str(folder / f"f{k:02d}.png"), np.clip(img * 255, 0, 255).round()
                    .astype(np.uint8))
    return folder, bends


def test_a_fibre_at_the_tip_and_a_holder_leave_the_base_to_the_video(held_and_touched,
                                                                     tmp_path):
    """Both ends of the path run to the border: a narrower stretch (the
    fibre) at one, a wider holder at the other. The fibre, in line with the
    tube, passed for a pipette holding it by its tip; now the video tells
    which step holds the tube (the other moves away), and the tube is cut
    to the stretch between them."""
    folder, bends = held_and_touched
    with open_frames(folder) as reader:
        det = detect(as_float(reader.first))
        assert det.base_source == AMBIGUOUS_BASE
        held = sorted(det.held_at, key=lambda z: z.real)
        # (the width steps a detection's skeleton gives, within about a tube
        # half-width of the true ends: the tracker places the base, below)
        assert abs(held[0] - (90 - 100j)) < 8.0 and abs(held[1] - (340 - 100j)) < 8.0, held
        base_end, note, first = _static_end(reader, det)
    assert abs(complex(*base_end) - (90 + 100j)) < 8.0, base_end
    assert "wider holder" in note
    assert abs(first.path[0] - (90 - 100j)) < 8.0 and abs(first.path[-1] - (340 - 100j)) < 8.0
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all()
    assert np.abs(t.bend_angle_deg - bends).max() < 1.0
    assert np.hypot(t.base_x_um - 90.0, t.base_y_um + 100.0).max() < 2.0


@pytest.mark.parametrize(("wide_px", "turn_deg", "cut"), [
    (150, 90.0, True),     # a tube 30 half-widths long, a fibre off it at right angles
    (150, 30.0, False),    # ... running on near its line: a narrower holder's
    (60, 90.0, False),     # a blob 12 half-widths long (a faint tube's noisy outline)
])
def test_the_path_is_cut_only_where_it_turns_off_a_tube_into_a_thinner_branch(
        wide_px, turn_deg, cut):
    from pipeline.segment import _crossing_branch

    wide = np.c_[np.full(wide_px, 50.0), np.arange(wide_px, dtype=float)]
    heading = np.radians(turn_deg)
    thin = wide[-1] + np.arange(1, 61)[:, None] * np.array([np.sin(heading), np.cos(heading)])
    path = np.vstack([wide, thin])
    width = np.r_[np.full(wide_px, 10.0), np.full(60, 3.0)]
    got = _crossing_branch(path, width)
    assert (got is not None) == cut
    if cut:
        # the thinner branch from a wide half-width and a pixel past the turn on
        assert np.array_equal(got, path[wide_px + 6:])
    back = _crossing_branch(path[::-1], width[::-1])
    assert (back is not None) == cut
    if cut:
        assert np.array_equal(back[::-1], path[wide_px + 6:])


@pytest.mark.parametrize("holder", [10.0, 20.0])
def test_a_narrower_stretch_and_a_wider_holder_are_found_whichever_steps_more(holder):
    """A fibre (3 px) at one end of the path, a tube (7) and a holder (10 or
    20) at the other: the two steps, the narrower's first, whichever of them
    the single split found; read from either end; none without the holder."""
    from pipeline.segment import _narrow_and_holder, _split_point

    width = np.r_[np.full(60, 3.0), np.full(200, 7.0), np.full(80, holder)]
    for w, steps in ((width, (60, 260)), (width[::-1], (280, 80))):
        split, ratio = _split_point(w, 4)
        assert _narrow_and_holder(w, split, ratio, 4, 14.0) == steps
    plain = width[:260]
    split, ratio = _split_point(plain, 4)
    assert _narrow_and_holder(plain, split, ratio, 4, 14.0) is None
