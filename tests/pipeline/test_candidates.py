"""Which structure of a frame the detector takes for the tube
(:func:`pipeline.segment.detect`): the one holding most of a structure's
area along its path, not the longest line, and a long one, not a stubby
region filling a corner of the frame."""

import cv2
import numpy as np
import pytest

from pipeline import segment
from pipeline.segment import detect
from tests.pipeline.synthetic import tube_image

SHAPE = (360, 480)
BASE = 60 - 240j          # the pipette's end, 60 px from the left border (px, y up)
LENGTH, HALF_WIDTH = 300.0, 9.0


def _tube(kappa: float = -1e-12) -> np.ndarray:
    """A tube 300 px long and 9 px in half-width, held by a narrower pipette
    from the left border (its base at (60, 240)), bending by ``kappa`` per px."""
    return tube_image(SHAPE, BASE, 0.0, LENGTH, kappa, HALF_WIDTH, pipette_half_width=5.0,
                      pipette_contrast=1.0, noise=0.01, seed=1).astype(np.float32)


def _tip(kappa: float) -> complex:
    """The tube's true tip (px, y up)."""
    if abs(kappa) < 1e-9:
        return BASE + LENGTH
    return BASE + (np.exp(1j * kappa * LENGTH) - 1) / (1j * kappa)


def _reticle(img: np.ndarray) -> np.ndarray:
    """``img`` with a burned-in crosshair: two dark lines 1 px wide across
    the whole frame (col 200, row 240: along and across the tube), ticks on
    them every 40 px."""
    mask = np.zeros(img.shape, np.float32)
    rows, cols = img.shape
    cv2.line(mask, (200, 0), (200, rows - 1), 1.0, 1)
    cv2.line(mask, (0, 150), (cols - 1, 150), 1.0, 1)
    for k in range(0, cols, 40):
        cv2.line(mask, (k, 144), (k, 156), 1.0, 1)
    for k in range(0, rows, 40):
        cv2.line(mask, (194, k), (206, k), 1.0, 1)
    return img * (1 - 0.7 * mask)


@pytest.mark.parametrize("kappa", [-1e-12, 0.006])
def test_a_reticle_across_the_tube_is_not_taken_for_it(kappa):
    """A straight tube crossed by the reticle's vertical line, and one bent
    up across its horizontal line: the reticle's lines are longer than the tube
    (360 and 480 px against 300) and touch it, and the longest path ran
    down a line from the crossing (the tube's stretch back to the pipette
    was then taken for the tube and the pipette for its tip). The path
    holding the most area is the tube's, base to tip."""
    det = detect(_reticle(_tube(kappa)))
    assert det is not None
    assert abs(det.path[-1] - _tip(kappa)) < 2 * HALF_WIDTH, (det.path[-1], _tip(kappa))
    assert abs(det.base - BASE) < 2 * HALF_WIDTH, det.base
    assert abs(det.length / LENGTH - 1) < 0.1, det.length


def test_a_dark_region_filling_a_corner_is_passed_over_for_the_tube():
    """Past a dish's wall, a darker region fills the frame's top right corner:
    more area than the tube, touching the border along 330 px, only a few
    of its half-widths long (stubby). The next structure, the tube, is taken."""
    img = _tube(0.004)
    rows, cols = img.shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    # (the wall: a circle's arc about a centre beyond the top right corner)
    inside = np.hypot(rr + 300, cc - cols - 200) < 440
    dark = img * np.where(inside, 0.55, 1.0).astype(np.float32)
    assert inside.sum() > LENGTH * 2 * HALF_WIDTH  # more than the tube's area
    det = detect(dark)
    assert det is not None
    assert abs(det.path[-1] - _tip(0.004)) < 2 * HALF_WIDTH, (det.path[-1], _tip(0.004))
    assert abs(det.base - BASE) < 2 * HALF_WIDTH, det.base


def test_a_stubby_region_alone_is_still_found():
    """Where no longer structure stands out, the stubby one is kept (the
    tracker then tells whether it is a tube): the search for a longer one
    does not lose what was found."""
    img = np.full(SHAPE, 0.8, np.float32)
    img[150:210, 100:400] = 0.4          # 300 px by 60: 10 half-widths long
    det = detect(img)
    assert det is not None
    assert det.found_length < segment.TUBE_MIN_HW * det.half_width


def test_a_base_given_on_a_fainter_tube_picks_it_over_a_larger_structure():
    """A static dark rod, wider and longer than the tube, across the frame's
    top: the detector takes it for the tube. Given ``--base`` at the tube's
    base, the structure there is taken (the rod was kept, the base put at
    its nearest point, 150 px off)."""
    img = _tube(0.002)
    rows, cols = img.shape
    rod = np.zeros(img.shape, np.float32)
    cv2.line(rod, (20, 60), (cols - 20, 60), 1.0, 30)
    img = img * (1 - 0.5 * rod)
    assert abs(detect(img).base - BASE) > 100            # the rod
    det = detect(img, base_hint=(BASE.real, -BASE.imag))
    assert abs(det.path[-1] - _tip(0.002)) < 2 * HALF_WIDTH, (det.path[-1], _tip(0.002))
    assert abs(det.base - BASE) < 2.0, det.base
