"""Blank margins (letterbox bars, a resampled frame's dark edge line) are found and
cropped away, and nothing is taken from a frame that has none."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline import schema as S
from pipeline.accuracy import score_folder
from pipeline.frames import open_frames
from pipeline.margins import EDGE_LINES, Margins, blank_margins
from pipeline.render import default_scene, render_scene
from pipeline.tracks import track_video

from .synthetic import tube_image


def _scene_frame(seed=0, noise=0.01):
    """A 240x320 frame: a dark tube whose pipette end touches the top border,
    uneven illumination and noise."""
    img = tube_image((240, 320), complex(160, -2), -np.pi / 2 + 0.3, 200, 0.004, 8,
                     noise=noise, seed=seed)
    rr, cc = np.mgrid[0:240, 0:320]
    shade = 1 - 0.1 * cc / 320 - 0.15 * ((rr - 120) ** 2 + (cc - 160) ** 2) / 200**2
    return np.clip(img * shade, 0, 1)


def _u8(img):
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def test_a_frame_without_margins_keeps_every_line():
    """The tube touching the border, illumination falling off and noise are scene."""
    assert not blank_margins(_u8(_scene_frame()))
    # noise-free, so every background line is flat: flat is not blank unless it steps
    assert not blank_margins(_u8(_scene_frame(noise=0.0)))


def test_a_smooth_ramp_into_the_border_is_scene():
    """Illumination that darkens fastest at the very edge (a grey level a line) is
    no margin, though the border line lies far from the lines inside."""
    img = np.full((240, 320), 0.8)
    img[-6:] -= (np.arange(6)[::-1, None] + 1) / 255
    img += np.random.default_rng(1).normal(0, 0.5 / 255, img.shape)
    assert not blank_margins(_u8(img))


def test_letterbox_bars_and_a_pillar_are_found_to_the_line():
    frame = _u8(_scene_frame())
    padded = cv2.copyMakeBorder(frame, 30, 30, 0, 20, cv2.BORDER_CONSTANT, value=0)
    padded[:, -20:] = 255   # a white pillar on the right
    assert blank_margins(padded) == Margins(top=30, bottom=30, left=0, right=20)
    # the same in 16 bits and in floats: levels are fractions of full scale
    assert blank_margins(padded.astype(np.uint16) * 257) == blank_margins(padded)
    assert blank_margins(padded / np.float32(255)) == blank_margins(padded)
    # under JPEG the bars' edges ring: the ringing lines go with the bar, no scene line does
    ok, buf = cv2.imencode(".jpg", padded, [cv2.IMWRITE_JPEG_QUALITY, 75])
    m = blank_margins(cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE))
    for found, bar in ((m.top, 30), (m.bottom, 30), (m.right, 20)):
        assert bar <= found <= bar + EDGE_LINES
    assert m.left == 0


def test_a_resampled_frame_s_dark_edge_line_is_found():
    """A frame scaled up by 2 with no pixel beyond its last: the last line and
    column mix in black (half the scene's level) and are not flat."""
    small = _u8(_scene_frame())
    big = cv2.warpAffine(small, np.float32([[2, 0, 0], [0, 2, 0]]), (640, 480),
                         flags=cv2.INTER_LINEAR)
    assert blank_margins(big) == Margins(bottom=1, right=1)


def _pad_frames(src_dir: Path, dst_dir: Path, *, top: int, bottom: int, right_line: bool):
    """The scene's frames with black bars above and below, and (optionally) a
    half-dark line along the right edge, as a folder of PNGs."""
    rec = json.loads((src_dir / S.SCENE_FILE).read_text(encoding="utf-8"))
    dst_dir.mkdir()
    with open_frames(src_dir / rec["frames_file"]) as reader:
        for i, frame in enumerate(reader):
            out = cv2.copyMakeBorder(frame, top, bottom, 0, 1 if right_line else 0,
                                     cv2.BORDER_CONSTANT, value=0)
            if right_line:
                out[top:out.shape[0] - bottom, -1] = frame[:, -1] // 2
            cv2.imwrite(str(dst_dir / f"frame_{i:03d}.png"), out)
    return rec


@pytest.fixture(scope="module")
def plain_and_padded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("margins")
    scene_dir = render_scene(default_scene(3, seed=0, width=480, height=360, n_frames=5),
                             tmp / "scene", fmt="png")
    rec = _pad_frames(scene_dir, tmp / "padded", top=40, bottom=40, right_line=True)
    scale = rec["layout"]["um_per_px"]
    track_video(scene_dir / rec["frames_file"], tmp / "plain_out", um_per_px=scale)
    return scene_dir, tmp, scale


def test_a_letterboxed_video_tracks_as_the_scene_alone(plain_and_padded):
    """Tracked with its bars and edge line, a video gives the unpadded video's
    numbers, moved by the bar (before, no frame was measured: the bars' step
    swamped the background model)."""
    scene_dir, tmp, scale = plain_and_padded
    run = track_video(tmp / "padded", tmp / "padded_out", um_per_px=scale)
    assert run.n_ok == run.n_frames == 5
    assert any(n.startswith("blank margins cropped away") and "40 top, 40 bottom, 1 right" in n
               for n in run.notes)
    plain = pd.read_csv(tmp / "plain_out" / S.TRACKS_FILE)
    padded = pd.read_csv(tmp / "padded_out" / S.TRACKS_FILE)
    shift = 40 * scale   # 40 rows more above: y (up) is 40 px lower
    for col in (S.BASE_Y, S.TIP_Y):
        np.testing.assert_allclose(padded[col], plain[col] - shift, atol=1e-6)
    for col in (S.BEND, S.BASE_X, S.TIP_X, S.LENGTH):
        np.testing.assert_allclose(padded[col], plain[col], atol=1e-6)
    lines = pd.read_csv(tmp / "padded_out" / S.CENTRELINES_FILE)
    plain_lines = pd.read_csv(tmp / "plain_out" / S.CENTRELINES_FILE)
    np.testing.assert_allclose(lines[S.Y], plain_lines[S.Y] - shift, atol=1e-3)
    # and against the truth, which does not move with the bars, the plain one meets the spec
    _, acc = score_folder(scene_dir, tmp / "plain_out")
    assert acc.meets_targets()


def test_a_base_given_on_the_padded_frame_is_moved_with_the_crop(plain_and_padded):
    scene_dir, tmp, scale = plain_and_padded
    truth = pd.read_csv(scene_dir / S.TRUTH_TRACKS_FILE)
    col, row = truth[S.BASE_X][0] / scale, -truth[S.BASE_Y][0] / scale
    padded = track_video(tmp / "padded", tmp / "hint_out", um_per_px=scale,
                         base=f"{col:.2f},{row + 40:.2f}")
    assert padded.n_ok == 5
    got = pd.read_csv(tmp / "hint_out" / S.TRACKS_FILE)
    # the base on the padded frame is the true one, 40 rows lower
    assert np.all(np.abs(got[S.BASE_Y] / scale + row + 40) < 1.0)
    assert np.all(np.abs(got[S.BASE_X] / scale - col) < 1.0)
    with pytest.raises(ValueError, match="blank margin"):
        track_video(tmp / "padded", tmp / "bad_out", um_per_px=scale, base=f"{col:.2f},10")
    assert not (tmp / "bad_out").exists()
