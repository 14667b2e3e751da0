import numpy as np
import pytest

from pipeline.levels import levels_of


def test_eight_bit_and_full_range_frames_are_left_as_they_are():
    for first in (np.full((4, 4), 3, np.uint8),
                  np.array([[0, 40000]], np.uint16),
                  np.array([[0.1, 0.9]], np.float32)):
        levels = levels_of(first)
        assert not levels
        assert levels.frame(first) is first


@pytest.mark.parametrize(("top", "full"), [(1023, 1023), (1000, 1023), (4095, 4095),
                                          (300, 511), (8191, 8191)])
def test_sixteen_bit_counts_are_scaled_by_the_bits_the_first_frame_uses(top, full):
    first = np.array([[0, top // 2, top]], np.uint16)
    levels = levels_of(first)
    assert levels and levels.full == full
    scaled = levels.frame(first)
    assert scaled.dtype == np.float32
    np.testing.assert_allclose(scaled, first / full, rtol=1e-6)
    assert f"({int(np.log2(full + 1))}-bit)" in levels.describe()
    # a later, brighter frame goes above 1: nothing is clipped
    assert levels.frame(np.array([[2 * full]], np.uint16))[0, 0] == pytest.approx(2.0)


@pytest.mark.parametrize("top", [4000.0, 0.01])
def test_float_frames_in_another_unit_are_scaled_by_their_largest_value(top):
    first = np.array([[0.0, 0.5 * top, top, np.nan]], np.float32)
    levels = levels_of(first)
    assert levels and levels.full == pytest.approx(top)
    np.testing.assert_allclose(levels.frame(first)[0, :3], [0.0, 0.5, 1.0], rtol=1e-6)


def test_a_black_first_frame_is_not_scaled():
    assert not levels_of(np.zeros((3, 3), np.uint16))
    assert not levels_of(np.zeros((3, 3), np.float32))


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_a_span_high_in_the_range_has_its_black_level_taken_off(dtype):
    first = np.array([[30000, 30500, 31023]], dtype)
    levels = levels_of(first)
    assert levels and levels.black == 30000
    assert levels.full == (1023 if dtype == np.uint16 else pytest.approx(1023))
    np.testing.assert_allclose(levels.frame(first), [[0.0, 500 / 1023, 1.0]], rtol=1e-5)


def test_the_overlay_shows_a_few_bits_counts_as_bright_as_full_range_frames(tmp_path):
    import cv2
    import tifffile

    from pipeline.overlay import write_overlay
    from pipeline.track import FrameTrack

    ramp = np.tile(np.linspace(0.0, 0.9, 64), (48, 1))
    results = [FrameTrack(i, "no tube found", None, "") for i in range(2)]
    means = []
    for name, frames in (("full.tif", [np.round(ramp * 65535).astype(np.uint16)] * 2),
                         ("few.tif", [np.round(ramp * 1023).astype(np.uint16)] * 2)):
        tifffile.imwrite(tmp_path / name, np.stack(frames))
        write_overlay(tmp_path / name, results, tmp_path / f"{name}.png")
        means.append(cv2.imread(str(tmp_path / f"{name}.png")).mean())
    assert means[1] == pytest.approx(means[0], rel=0.02)
