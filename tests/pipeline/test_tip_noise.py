"""A noisy tube's end: found on the mean of the lines across its end face, so
that a curve already past the end is pulled back to it rather than held out
on the noise beyond (which the next frame's prediction then carries further)."""
import numpy as np
import pytest

from pipeline.centreline import basis_of, evaluate, fit_to_polyline
from pipeline.refine import STRIP_LINES, TubeLook, _tip_offset
from tests.pipeline.synthetic import arc_axis, tube_image

SHAPE = (120, 300)
BASE = 20 - 60j
LENGTH = 240.0
HW = 8.0
#: an edge step of 0.2 under noise of 0.2 per pixel, blurred over 2 px: the
#: side edges then need strips of about 9 lines (pipeline.track.strip_lines)
IMAGES = [tube_image(SHAPE, BASE, 0.0, LENGTH, 0.0, HW, contrast=0.25, edge_px=2.0,
                     noise=0.2, seed=seed) for seed in range(100)]


def _end_errors(over_px: float, lines: int) -> np.ndarray:
    z, _ = arc_axis(BASE, 0.0, LENGTH + over_px, 0.0)
    curve = fit_to_polyline(z, 0.0, n_coef=10)
    smp = evaluate(curve, basis_of(curve))
    look = TubeLook(-1, np.full(5, HW), 0.05, smooth_px=2.4, strip_lines=lines)
    found = [_tip_offset(img, smp, 0j, look, 0.5 * HW, 0.5) for img in IMAGES]
    assert all(f[1] for f in found)
    return np.array([over_px + f[0] for f in found])


@pytest.mark.parametrize("over_px", [-4.0, 0.0, 4.0])
def test_a_noisy_tubes_end_is_found_on_the_lines_mean(over_px):
    err = _end_errors(over_px, 9)
    assert abs(err.mean()) < 0.6
    # (each line's outermost strong step, their median: a curve 4 px past the
    # end stayed out by 0.9 px on average, and by over 2 px on 21 % of frames)
    assert (err > 2.0).mean() <= 0.08
    assert err.std() < 1.6


def test_a_clean_frames_end_is_each_lines_own():
    # (3 lines, the default strip: the median of the lines' ends, robust to a
    # speck on one of them, is kept where noise does not call for the mean)
    z, _ = arc_axis(BASE, 0.0, LENGTH + 2.0, 0.0)
    curve = fit_to_polyline(z, 0.0, n_coef=10)
    img = tube_image(SHAPE, BASE, 0.0, LENGTH, 0.0, HW, contrast=0.25, edge_px=0.7)
    # a dark speck just past the end on the middle line only
    img[60, int(BASE.real + LENGTH) + 3] = 0.0
    look = TubeLook(-1, np.full(5, HW), 0.05, smooth_px=0.8, strip_lines=STRIP_LINES)
    off, found, _ = _tip_offset(img, evaluate(curve, basis_of(curve)), 0j, look, 0.5 * HW, 0.5)
    assert found and abs(2.0 + off) < 0.3
