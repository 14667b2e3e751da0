"""Frame I/O: round trips per format, folder ordering, colour, errors, atomicity."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import tifffile

from pipeline import frames as F
from pipeline.frames import FrameError, open_frames, to_float, write_frames


def smooth(rows=48, cols=64, phase=0.0):
    """A smooth float image in [0.1, 0.9] (friendly to lossy codecs)."""
    r, c = np.mgrid[0:rows, 0:cols]
    return (0.5 + 0.4 * np.sin(c / 9.0 + phase) * np.cos(r / 7.0)).astype(np.float32)


def ramp16(rows=20, cols=30, k=0):
    """uint16 frame using the full 16-bit range, distinct per k."""
    return ((np.arange(rows * cols).reshape(rows, cols) * 109 + k * 7919) % 65536).astype(
        np.uint16)


def ramp8(rows=20, cols=30, k=0):
    return ((np.arange(rows * cols).reshape(rows, cols) * 7 + k * 31) % 256).astype(np.uint8)


def read_all(source):
    with open_frames(source) as reader:
        return reader, list(reader)


def names(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir())


# --------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("bit_depth, make", [(8, ramp8), (16, ramp16)])
def test_png_folder_round_trip_is_exact(tmp_path, bit_depth, make):
    truth = [make(k=k) for k in range(12)]
    out = write_frames(iter(truth), tmp_path / "frames", bit_depth=bit_depth)
    assert out == tmp_path / "frames"
    assert (out / "frame_00000.png").is_file() and (out / "frame_00011.png").is_file()
    reader, got = read_all(out)
    assert len(reader) == 12 and reader.fps is None and reader.kind == "folder"
    assert reader.frame_shape == (20, 30) and reader.dtype == truth[0].dtype
    for a, b in zip(truth, got, strict=True):
        assert b.dtype == a.dtype
        np.testing.assert_array_equal(b, a)


@pytest.mark.parametrize("bit_depth, make", [(8, ramp8), (16, ramp16)])
def test_tiff_round_trip_is_exact_and_keeps_fps(tmp_path, bit_depth, make, caplog):
    truth = np.stack([make(k=k) for k in range(7)])
    out = write_frames(truth, tmp_path / "stack.tif", fps=12.5, bit_depth=bit_depth)
    with caplog.at_level("WARNING"):
        reader, got = read_all(out)
        whole = tifffile.imread(out)  # other programs see one stack of all frames
    assert not caplog.records  # (tifffile logs what it finds wrong in a file)
    np.testing.assert_array_equal(whole, truth)
    assert reader.kind == "tiff" and len(reader) == 7 and reader.fps == 12.5
    assert reader.frame_shape == (20, 30) and reader.dtype == truth.dtype
    np.testing.assert_array_equal(np.stack(got), truth)


def test_float_frames_are_rounded_and_clipped(tmp_path):
    f = np.array([[-0.5, 0.0, 0.25, 0.5], [1 / 255, 0.999, 1.0, 7.0]])
    write_frames([f], tmp_path / "a.tif", bit_depth=8)
    write_frames([f], tmp_path / "b.tif", bit_depth=16)
    (a,), (b,) = read_all(tmp_path / "a.tif")[1], read_all(tmp_path / "b.tif")[1]
    np.testing.assert_array_equal(a, np.round(np.clip(f, 0, 1) * 255).astype(np.uint8))
    np.testing.assert_array_equal(b, np.round(np.clip(f, 0, 1) * 65535).astype(np.uint16))


def test_integer_frames_are_rescaled_between_bit_depths(tmp_path):
    x8 = np.arange(256, dtype=np.uint8).reshape(16, 16)
    write_frames([x8], tmp_path / "up.tif", bit_depth=16)
    (up,) = read_all(tmp_path / "up.tif")[1]
    np.testing.assert_array_equal(up, x8.astype(np.uint16) * 257)
    x16 = np.arange(0, 65536, 16, dtype=np.uint16).reshape(64, 64)
    write_frames([x16], tmp_path / "down.tif", bit_depth=8)
    (down,) = read_all(tmp_path / "down.tif")[1]
    np.testing.assert_array_equal(down, np.round(x16 / 257.0).astype(np.uint8))


def test_avi_round_trip_is_close(tmp_path):
    truth = [smooth(96, 128, phase=0.3 * k) for k in range(6)]
    out = write_frames(truth, tmp_path / "movie.avi", fps=25.0)
    reader, got = read_all(out)
    assert reader.kind == "video" and reader.fps == pytest.approx(25.0)
    assert reader.frame_shape == (96, 128) and reader.dtype == np.uint8
    assert len(reader) == 6 and len(got) == 6
    for a, b in zip(truth, got, strict=True):
        assert b.ndim == 2
        assert np.abs(b.astype(float) - np.round(a * 255)).mean() < 2.0


def colour_mjpg(path, n=6, rows=64, cols=96):
    """A colour Motion-JPEG AVI whose channels differ. Returns the luminance
    (BGR2GRAY) of the frames written, and of the frames as OpenCV decodes them."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (cols, rows))
    written = []
    for k in range(n):
        img = np.stack([smooth(rows, cols, phase=0.4 * k + c) for c in range(3)], axis=2)
        img = (img * 255).astype(np.uint8)
        writer.write(img)
        written.append(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(int))
    writer.release()
    cap = cv2.VideoCapture(str(path))
    decoded = []
    while (got := cap.read())[0]:
        decoded.append(cv2.cvtColor(got[1], cv2.COLOR_BGR2GRAY))
    cap.release()
    assert len(decoded) == n
    return written, decoded


def test_motion_jpeg_is_decoded_to_luminance_straight_from_its_bytes(tmp_path, monkeypatch):
    written, decoded = colour_mjpg(tmp_path / "c.avi")
    calls = []
    real = cv2.imdecode
    monkeypatch.setattr(F.cv2, "imdecode", lambda *a: calls.append(1) or real(*a))
    reader, got = read_all(tmp_path / "c.avi")
    assert len(calls) == 1 + len(written)  # the first on opening, then every frame
    assert reader.frame_shape == (64, 96) and reader.dtype == np.uint8
    np.testing.assert_array_equal(reader_first(tmp_path / "c.avi"), got[0])
    for truth, a, b in zip(written, decoded, got, strict=True):
        # the JPEG's own luminance channel: no chroma upsampling nor colour
        # round trip, so at least as close to what was written
        assert np.abs(truth - b).mean() <= np.abs(truth - a).mean() + 0.05
        assert np.abs(a.astype(int) - b).max() <= 4


def reader_first(path):
    """The first frame ``open_frames`` decodes when it opens ``path``."""
    reader = open_frames(path)
    first = next(iter(reader))
    reader.close()
    return first


@pytest.mark.parametrize("refusal", ["none", "wrong size"])
@pytest.mark.parametrize("refused_from", [0, 3])
def test_a_jpeg_frame_refused_hands_the_rest_to_opencv(tmp_path, monkeypatch, refusal,
                                                         refused_from):
    written, want = colour_mjpg(tmp_path / "c.avi")
    real, calls = cv2.imdecode, []

    def imdecode(buf, flags):
        calls.append(1)
        if len(calls) - 1 < refused_from:
            return real(buf, flags)
        return None if refusal == "none" else np.zeros((32, 96), np.uint8)

    monkeypatch.setattr(F.cv2, "imdecode", imdecode)
    with open_frames(tmp_path / "c.avi") as reader:
        calls.clear()
        got = list(reader)
    assert len(calls) == refused_from + 1  # no JPEG decoding after the refusal
    assert len(got) == len(want)
    for k, (a, b) in enumerate(zip(want, got, strict=True)):
        if k < refused_from:
            assert np.abs(written[k] - b).mean() < 1.5
        else:
            np.testing.assert_array_equal(a, b)  # OpenCV's decoding, exactly


def test_damaged_motion_jpeg_frames_are_decoded_without_a_word_on_stderr(tmp_path, capfd):
    """libjpeg prints its warnings on a damaged frame straight to the process's
    stderr ("Corrupt JPEG data: ..."), where they broke the command line's
    one-line messages; the frames still come, as FFmpeg gives them."""
    path = write_frames([smooth(96, 128, phase=0.3 * k) for k in range(6)], tmp_path / "m.avi")
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(1)
    for i in rng.integers(len(data) // 2, len(data) - 400, 20):
        data[i] ^= 0x5A
    path.write_bytes(bytes(data))
    capfd.readouterr()
    _, got = read_all(path)
    assert capfd.readouterr().err == ""
    assert len(got) >= 1 and all(g.shape == (96, 128) for g in got)


def test_mp4_writes_or_says_why(tmp_path):
    truth = [smooth(64, 96, phase=k) for k in range(4)]
    try:
        out = write_frames(truth, tmp_path / "movie.mp4", fps=10.0)
    except FrameError as exc:
        assert "cannot write MP4" in str(exc)
        assert names(tmp_path) == []
        return
    reader, got = read_all(out)
    assert reader.frame_shape == (64, 96) and len(got) == 4
    assert np.abs(got[0].astype(float) - np.round(truth[0] * 255)).mean() < 4.0


def test_existing_folder_of_frames_is_replaced(tmp_path):
    (tmp_path / "out.d").mkdir()  # has a suffix, but is an existing folder: PNGs
    write_frames([ramp8(k=k) for k in range(5)], tmp_path / "out.d")
    assert len(open_frames(tmp_path / "out.d")) == 5
    write_frames([ramp8(k=9)] * 2, tmp_path / "out.d")
    reader, got = read_all(tmp_path / "out.d")
    assert len(reader) == 2
    np.testing.assert_array_equal(got[1], ramp8(k=9))
    assert names(tmp_path) == ["out.d"]


def test_folder_with_other_files_is_not_replaced(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(FrameError, match="mine.*other files"):
        write_frames([ramp8()], tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"


# --------------------------------------------------------------------------- reading

def test_folder_natural_sort_and_non_images_ignored(tmp_path):
    for k in (10, 2, 1, 33):
        cv2.imwrite(str(tmp_path / f"frame{k}.png"), np.full((8, 9), k, np.uint8))
    (tmp_path / "tracks.csv").write_text("a,b\n1,2\n")
    (tmp_path / "scene.json").write_text("{}")
    (tmp_path / "README").write_text("not an image")
    (tmp_path / ".hidden.png").write_bytes(b"junk")
    (tmp_path / "sub.png").mkdir()
    reader, got = read_all(tmp_path)
    assert len(reader) == 4
    assert [int(f[0, 0]) for f in got] == [1, 2, 10, 33]


def test_natural_key_orders_numbers_numerically():
    from pathlib import Path

    paths = [Path(n) for n in ("img10.tif", "img9.tif", "img100.tif", "IMG1.tif", "a.png")]
    assert [p.name for p in sorted(paths, key=F._natural_key)] == [
        "a.png", "IMG1.tif", "img9.tif", "img10.tif", "img100.tif"]


@pytest.mark.parametrize("channels", [3, 4])
def test_colour_images_become_luminance_grey(tmp_path, channels):
    bgr = np.zeros((10, 12, channels), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 200, 100, 50  # B, G, R
    if channels == 4:
        bgr[..., 3] = 255
    cv2.imwrite(str(tmp_path / "c.png"), bgr)
    reader, (grey,) = read_all(tmp_path / "c.png")
    assert reader.kind == "image" and len(reader) == 1 and grey.shape == (10, 12)
    assert grey.dtype == np.uint8
    expected = 0.299 * 50 + 0.587 * 100 + 0.114 * 200  # ITU-R 601 luma, R G B
    assert np.all(np.abs(grey.astype(float) - expected) <= 1)


def test_rgb_tiff_is_read_as_rgb_not_bgr(tmp_path):
    rgb = np.zeros((6, 7, 3), np.uint16)
    rgb[..., 0] = 60000  # pure red: luma 0.299, not blue's 0.114
    tifffile.imwrite(tmp_path / "rgb.tif", rgb, photometric="rgb")
    reader, (grey,) = read_all(tmp_path / "rgb.tif")
    assert grey.dtype == np.uint16 and grey.shape == (6, 7)
    assert abs(int(grey[0, 0]) - round(0.299 * 60000)) <= 2


def test_sixteen_bit_png_and_single_tiff_keep_depth(tmp_path):
    img = ramp16()
    cv2.imwrite(str(tmp_path / "a.png"), img)
    tifffile.imwrite(tmp_path / "b.tiff", img)
    for name in ("a.png", "b.tiff"):
        reader, (got,) = read_all(tmp_path / name)
        assert reader.dtype == np.uint16 and len(reader) == 1
        np.testing.assert_array_equal(got, img)


@pytest.mark.parametrize("compression", ["lzw", "zstd", "jpeg"])
def test_compressed_tiff_stacks_are_read(tmp_path, compression):
    # microscope cameras and OpenCV write compressed TIFFs (LZW by default):
    # tifffile needs imagecodecs for those codecs
    stack = np.stack([(255 * smooth(phase=k)).astype(np.uint8) for k in range(3)])
    tifffile.imwrite(tmp_path / "c.tif", stack, compression=compression, photometric="minisblack")
    reader, got = read_all(tmp_path / "c.tif")
    assert len(got) == 3
    tol = 3 if compression == "jpeg" else 0  # (JPEG is lossy)
    np.testing.assert_allclose(np.stack(got).astype(int), stack.astype(int), atol=tol)


def test_folder_of_lzw_tiffs_written_by_opencv_is_read(tmp_path):
    frames = [ramp8(k=k) for k in range(3)]
    for k, img in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"img{k + 1}.tif"), img)  # LZW-compressed
    reader, got = read_all(tmp_path)
    np.testing.assert_array_equal(np.stack(got), np.stack(frames))


@pytest.mark.parametrize(("suffix", "lossless"), [(".pgm", True), (".webp", False),
                                               (".jp2", False), (".pnm", True)])
def test_a_folder_of_other_image_formats_is_read(tmp_path, suffix, lossless):
    frames = [(255 * smooth(phase=k)).astype(np.uint8) for k in range(3)]
    for k, img in enumerate(frames):
        assert cv2.imwrite(str(tmp_path / f"f{k}{suffix}"), img)
    reader, got = read_all(tmp_path)
    assert len(got) == 3 and got[0].dtype == np.uint8
    np.testing.assert_allclose(np.stack(got).astype(int), np.stack(frames).astype(int),
                               atol=0 if lossless else 8)


def test_stack_along_one_axis_is_frames_whatever_its_label(tmp_path):
    # tifffile labels a plain ImageJ stack as channels; ImageJ, as slices
    stack = np.stack([ramp8(k=k) for k in range(4)])
    tifffile.imwrite(tmp_path / "s.tif", stack, imagej=True)
    reader, got = read_all(tmp_path / "s.tif")
    np.testing.assert_array_equal(np.stack(got), stack)


@pytest.mark.parametrize("axes", ["TCYX", "TZYX"])
def test_hyperstack_is_refused_not_tracked_page_by_page(tmp_path, axes):
    stack = np.stack([np.stack([ramp8(k=k), 255 - ramp8(k=k)]) for k in range(3)])
    tifffile.imwrite(tmp_path / "h.tif", stack, imagej=True, metadata={"axes": axes})
    with pytest.raises(FrameError, match=r"hyperstack \(3 times x 2 (channels|z-slices)\)"):
        open_frames(tmp_path / "h.tif")


def test_float_tiff_is_passed_through(tmp_path):
    img = smooth(10, 11) * 3.0
    tifffile.imwrite(tmp_path / "f.tif", img.astype(np.float64))
    reader, (got,) = read_all(tmp_path / "f.tif")
    assert got.dtype == np.float32 and reader.dtype == np.float32
    np.testing.assert_allclose(got, img, rtol=1e-6)
    assert to_float(got) is got  # float32 passes through, not copied


def test_imagej_tiff_frame_interval_gives_fps(tmp_path):
    stack = np.stack([ramp8(k=k) for k in range(3)])
    tifffile.imwrite(tmp_path / "ij.tif", stack, imagej=True,
                     metadata={"axes": "TYX", "finterval": 0.25})
    reader, got = read_all(tmp_path / "ij.tif")
    assert reader.fps == pytest.approx(4.0) and len(got) == 3


def test_multipage_tiff_is_streamed_page_by_page(tmp_path, monkeypatch):
    n = 40
    with tifffile.TiffWriter(tmp_path / "big.tif") as tif:
        for k in range(n):
            tif.write(ramp16(k=k), contiguous=False)
    decoded = []
    real = tifffile.TiffPage.asarray

    def counting(self, *args, **kwargs):
        decoded.append(self.index)
        return real(self, *args, **kwargs)

    def forbidden(*args, **kwargs):
        raise AssertionError("whole-stack read")

    monkeypatch.setattr(tifffile.TiffPage, "asarray", counting)
    monkeypatch.setattr(tifffile.TiffFile, "asarray", forbidden)
    monkeypatch.setattr(tifffile, "imread", forbidden)
    with open_frames(tmp_path / "big.tif") as reader:
        assert len(reader) == n and decoded == [0]  # open decodes the first page only
        it = iter(reader)
        np.testing.assert_array_equal(next(it), ramp16(k=0))
        np.testing.assert_array_equal(next(it), ramp16(k=1))
        assert decoded == [0, 0, 1]
        rest = sum(1 for _ in it)
    assert rest == n - 2 and len(decoded) == n + 1


def test_reader_can_be_iterated_twice_and_closes_open_iterations(tmp_path):
    write_frames([ramp8(k=k) for k in range(4)], tmp_path / "s.tif")
    with open_frames(tmp_path / "s.tif") as reader:
        first = [f.copy() for f in reader]
        second = list(reader)
        pending = iter(reader)
        next(pending)
    assert len(first) == len(second) == 4
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    assert next(pending, None) is None  # closed on exit


@pytest.mark.parametrize("name", ["v.avi", "s.tif", "folder"])
def test_first_frame_is_the_one_iteration_yields_and_read_only(tmp_path, name):
    write_frames([ramp8(k=k) for k in range(3)], tmp_path / name)
    with open_frames(tmp_path / name) as reader:
        np.testing.assert_array_equal(reader.first, next(iter(reader)))
        assert reader.first.dtype == next(iter(reader)).dtype
        with pytest.raises(ValueError):
            reader.first[0, 0] = 1


def test_video_attributes(tmp_path):
    write_frames([smooth(32, 48, k) for k in range(5)], tmp_path / "v.avi", fps=7.5)
    with open_frames(str(tmp_path / "v.avi")) as reader:
        assert reader.source == tmp_path / "v.avi"
        assert (len(reader), reader.fps, reader.frame_shape) == (5, pytest.approx(7.5), (32, 48))
        assert sum(1 for _ in reader) == 5 and sum(1 for _ in reader) == 5


def test_animated_gif_is_read_as_a_video(tmp_path):
    from PIL import Image

    frames = [(smooth(32, 48, k) * 255).astype(np.uint8) for k in range(4)]
    Image.fromarray(frames[0]).save(tmp_path / "a.gif", save_all=True, duration=100,
                                    append_images=[Image.fromarray(f) for f in frames[1:]])
    reader, got = read_all(tmp_path / "a.gif")
    assert len(got) == 4 and got[0].shape == (32, 48)
    assert reader.fps == pytest.approx(10.0)  # (100 ms a frame)
    # (a grey palette: each frame's levels come back to within rounding)
    for want, have in zip(frames, got, strict=True):
        assert np.abs(have.astype(int) - want).max() <= 2


def test_to_float_scales_by_dtype():
    assert to_float(np.array([[0, 255]], np.uint8)).tolist() == [[0.0, 1.0]]
    assert to_float(np.array([[0, 65535]], np.uint16)).tolist() == [[0.0, 1.0]]
    f = to_float(np.array([[0.5, 2.0]]))
    assert f.dtype == np.float32 and f.tolist() == [[0.5, 2.0]]
    x = ramp8()
    assert to_float(x).dtype == np.float32
    np.testing.assert_array_equal(np.round(to_float(x) * 255).astype(np.uint8), x)
    with pytest.raises(FrameError, match="int32"):
        to_float(np.zeros((2, 2), np.int32))


# --------------------------------------------------------------------------- read errors

def one_line_naming(exc_info, name):
    msg = str(exc_info.value)
    assert "\n" not in msg and name in msg
    return msg


def test_missing_path(tmp_path):
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path / "nothing.avi")
    assert "no such" in one_line_naming(e, "nothing.avi")


@pytest.mark.parametrize("name", ["empty.avi", "empty.png", "empty.tif"])
def test_zero_byte_file(tmp_path, name):
    (tmp_path / name).touch()
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path / name)
    assert "0 bytes" in one_line_naming(e, name)


@pytest.mark.parametrize("name", ["junk.avi", "junk.mp4", "junk.mov", "junk.mkv"])
def test_corrupt_video(tmp_path, name):
    (tmp_path / name).write_bytes(np.random.default_rng(1).bytes(4096))
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path / name)
    one_line_naming(e, name)


@pytest.mark.parametrize("name", ["junk.png", "junk.tif", "junk.jpg"])
def test_corrupt_image(tmp_path, name):
    (tmp_path / name).write_bytes(b"\x00garbage" * 100)
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path / name)
    one_line_naming(e, name)


def test_video_without_frames(tmp_path):
    path = tmp_path / "blank.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (32, 24),
                             isColor=False)
    writer.release()
    assert path.stat().st_size > 0
    with pytest.raises(FrameError) as e:
        open_frames(path)
    msg = one_line_naming(e, "blank.avi")
    assert "no frames" in msg or "not a readable video" in msg


def test_folder_without_images(tmp_path):
    (tmp_path / "notes.csv").write_text("x\n")
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path)
    assert "no images" in one_line_naming(e, tmp_path.name)


def test_unreadable_image_in_folder_is_named_with_index(tmp_path):
    for k in range(4):
        cv2.imwrite(str(tmp_path / f"f{k}.png"), ramp8(k=k))
    (tmp_path / "f2.png").write_bytes(b"not a png at all")
    reader = open_frames(tmp_path)
    it = iter(reader)
    next(it), next(it)
    with pytest.raises(FrameError) as e:
        next(it)
    assert "image 2 of 4" in one_line_naming(e, "f2.png")


def test_differing_shapes_in_folder_name_first_offender(tmp_path):
    cv2.imwrite(str(tmp_path / "a1.png"), ramp8())
    cv2.imwrite(str(tmp_path / "a2.png"), ramp8())
    cv2.imwrite(str(tmp_path / "a3.png"), ramp8(rows=21))
    cv2.imwrite(str(tmp_path / "a4.png"), ramp8(rows=22))
    with pytest.raises(FrameError) as e:
        list(open_frames(tmp_path))
    assert "a4" not in one_line_naming(e, "a3.png")


def test_differing_bit_depths_in_folder(tmp_path):
    cv2.imwrite(str(tmp_path / "a1.png"), ramp8())
    cv2.imwrite(str(tmp_path / "a2.png"), ramp16())
    with pytest.raises(FrameError) as e:
        list(open_frames(tmp_path))
    assert "uint16" in one_line_naming(e, "a2.png")


def test_unsupported_extension(tmp_path):
    (tmp_path / "data.csv").write_text("1,2\n")
    with pytest.raises(FrameError) as e:
        open_frames(tmp_path / "data.csv")
    assert "unsupported" in one_line_naming(e, "data.csv")


def test_frame_error_is_a_value_error():
    assert issubclass(FrameError, ValueError)


# --------------------------------------------------------------------------- write errors

def failing(n_good):
    for k in range(n_good):
        yield smooth(phase=k)
    raise RuntimeError("camera unplugged")


@pytest.mark.parametrize("name", ["out.avi", "out.tif", "outdir"])
def test_interrupted_write_leaves_nothing(tmp_path, name):
    with pytest.raises(RuntimeError, match="camera unplugged"):
        write_frames(failing(3), tmp_path / name)
    assert names(tmp_path) == []


def test_interrupted_write_keeps_previous_output(tmp_path):
    write_frames([ramp8(k=1)], tmp_path / "keep.tif")
    with pytest.raises(RuntimeError):
        write_frames(failing(2), tmp_path / "keep.tif")
    assert names(tmp_path) == ["keep.tif"]
    (got,) = read_all(tmp_path / "keep.tif")[1]
    np.testing.assert_array_equal(got, ramp8(k=1))


@pytest.mark.parametrize("name", ["v.avi", "v.mp4"])
def test_sixteen_bit_video_refused(tmp_path, name):
    with pytest.raises(FrameError, match="8-bit"):
        write_frames([ramp16()], tmp_path / name, bit_depth=16)
    assert names(tmp_path) == []


@pytest.mark.parametrize("frames, match", [
    ([np.zeros((4, 5, 3))], "2-D"),
    ([np.zeros((4, 5)), np.zeros((5, 4))], "frame 1"),
    ([np.full((4, 5), np.nan)], "NaN"),
    ([np.zeros((4, 5), np.int64)], "int64"),
    ([], "no frames"),
])
@pytest.mark.parametrize("name", ["bad.avi", "bad.tif", "bad"])
def test_bad_frames_refused_atomically(tmp_path, frames, match, name):
    with pytest.raises(FrameError, match=match) as e:
        write_frames(iter(frames), tmp_path / name)
    one_line_naming(e, name)
    assert names(tmp_path) == []


@pytest.mark.parametrize("kwargs, match", [
    ({"bit_depth": 12}, "bit depth"), ({"bit_depth": True}, "bit depth"),
    ({"fps": 0}, "fps"), ({"fps": float("nan")}, "fps"),
])
def test_bad_options_refused(tmp_path, kwargs, match):
    with pytest.raises(FrameError, match=match):
        write_frames([ramp8()], tmp_path / "x.tif", **kwargs)
    assert names(tmp_path) == []


def test_unknown_output_format_and_file_in_the_way(tmp_path):
    with pytest.raises(FrameError, match="unknown output format"):
        write_frames([ramp8()], tmp_path / "x.png")
    (tmp_path / "plain").write_text("a file")
    with pytest.raises(FrameError, match="not a folder"):
        write_frames([ramp8()], tmp_path / "plain")
    assert names(tmp_path) == ["plain"]


def test_missing_parent_folders_are_created(tmp_path):
    out = write_frames([ramp8()], tmp_path / "a" / "b" / "s.tif")
    assert len(open_frames(out)) == 1
