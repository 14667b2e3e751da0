"""Colour frames: the tube is tracked in the grey in which its edges are
measured most precisely (``pipeline.colour``): the luminance, or a channel
alone where the tube shows in that one only (a dyed tube)."""

import json

import cv2
import numpy as np
import pytest

import pipeline.colour as colour
from pipeline.accuracy import score_folder
from pipeline.frames import FrameError, first_colour, open_frames
from pipeline.render import default_scene, render_scene
from pipeline.tracks import track_video


def _dyed(tmp_path, n_frames=6):
    """Sample 1 as a yellow-dyed tube would show on a colour camera: dark in
    blue (an opaque look), and in red and green only the faint rims of a
    low-contrast transparent tube; written as RGB PNGs."""
    looks = {}
    for look in ("opaque", "low_contrast"):
        scene = default_scene(1, n_frames=n_frames, seed=5, width=480, height=360,
                              base_angle_deg=20.0, look=look)
        looks[look] = render_scene(scene, tmp_path / look, fmt="png")
    folder = tmp_path / "dyed"
    (folder / "frames").mkdir(parents=True)
    for name in ("scene.json", "truth_tracks.csv", "truth_centrelines.csv"):
        (folder / name).write_bytes((looks["opaque"] / name).read_bytes())
    for path in sorted((looks["opaque"] / "frames").iterdir()):
        blue = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        faint = cv2.imread(str(looks["low_contrast"] / "frames" / path.name),
                           cv2.IMREAD_GRAYSCALE)
        # (BGR, as OpenCV writes)
        cv2.imwrite(str(folder / "frames" / path.name), np.dstack([blue, faint, faint]))
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    return folder, scale


def test_a_dyed_tube_is_tracked_in_the_channel_it_shows_in(tmp_path, monkeypatch):
    folder, scale = _dyed(tmp_path)
    run = track_video(folder / "frames", tmp_path / "out", um_per_px=scale)
    note = next(n for n in run.notes if n.startswith("colour frames"))
    assert "blue channel alone" in note
    _, acc = score_folder(folder, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.angle_max < 1.0 and acc.centreline_rms_px < 0.2, acc

    # the luminance kept: the faint look it is mostly made of measures the
    # edges less precisely, and the tube is tracked worse
    monkeypatch.setattr(colour, "CHANNEL_GAIN", np.inf)
    run = track_video(folder / "frames", tmp_path / "luma", um_per_px=scale)
    assert any(n.startswith("colour frames: tracked on their luminance") for n in run.notes)
    _, luma = score_folder(folder, tmp_path / "luma")
    assert luma.centreline_rms_px > 1.5 * acc.centreline_rms_px, (luma, acc)


def test_grey_frames_are_not_looked_at_in_colour(tmp_path):
    scene = default_scene(1, n_frames=2, seed=5, width=320, height=240)
    folder = render_scene(scene, tmp_path / "grey", fmt="png")
    with open_frames(folder / "frames") as reader:
        assert first_colour(reader) is None
    run = track_video(folder / "frames", tmp_path / "out",
                      um_per_px=json.loads((folder / "scene.json").read_text())
                      ["layout"]["um_per_px"])
    assert not any(n.startswith("colour frames") for n in run.notes)


def test_the_frame_reader_takes_a_channel(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (40, 60, 3), dtype=np.uint8)
    folder = tmp_path / "f"
    folder.mkdir()
    for i in range(2):
        cv2.imwrite(str(folder / f"img{i}.png"), rgb[:, :, ::-1])
    video = tmp_path / "v.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 5.0, (60, 40))
    for _ in range(2):
        writer.write(np.ascontiguousarray(rgb[:, :, ::-1]))
    writer.release()
    for source in (folder, video):
        with open_frames(source) as reader:
            assert np.array_equal(first_colour(reader), rgb)
        for name, k in (("red", 0), ("green", 1), ("blue", 2)):
            with open_frames(source, channel=name) as reader:
                frames = list(reader)
            assert len(frames) == 2 and all(np.array_equal(f, rgb[:, :, k]) for f in frames)
    with pytest.raises(FrameError, match="colour channel"):
        open_frames(folder, channel="violet")


def test_a_motion_jpeg_video_is_read_in_colour_too(tmp_path):
    # (lossy: compared within a few levels, on smooth channels)
    rows, cols = np.mgrid[0:64, 0:96]
    rgb = np.dstack([2 * cols, 3 * rows, 255 - 2 * cols]).astype(np.uint8)
    video = tmp_path / "v.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, (96, 64))
    for _ in range(2):
        writer.write(np.ascontiguousarray(rgb[:, :, ::-1]))
    writer.release()
    with open_frames(video) as reader:
        assert np.abs(first_colour(reader).astype(float) - rgb).mean() < 4
    with open_frames(video, channel="blue") as reader:
        frames = list(reader)
    assert len(frames) == 2 and np.abs(frames[1].astype(float) - rgb[:, :, 2]).mean() < 4


def test_signed_colour_tiffs_are_read_in_colour(tmp_path):
    # (int16 counts, some below 0: as their luminance is, read as float)
    import tifffile

    rng = np.random.default_rng(2)
    rgb = rng.integers(-20, 236, (40, 60, 3)).astype(np.int16)
    tifffile.imwrite(tmp_path / "s.tif", rgb, photometric="rgb")
    with open_frames(tmp_path / "s.tif") as reader:
        got = first_colour(reader)
    assert got.dtype == np.float32 and np.array_equal(got, rgb.astype(np.float32))
    with open_frames(tmp_path / "s.tif", channel="green") as reader:
        assert np.array_equal(reader.first, rgb[:, :, 1].astype(np.float32))


def test_grey_stored_as_colour_with_offset_channels_is_grey(tmp_path):
    # (an MPEG-4 video of grey frames decodes with its channels a few levels apart)
    rng = np.random.default_rng(1)
    grey = rng.integers(10, 240, (40, 60)).astype(np.int16)
    bgr = np.dstack([grey + 3, grey, grey - 2]).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), bgr)
    with open_frames(tmp_path / "a.png") as reader:
        assert first_colour(reader) is None
