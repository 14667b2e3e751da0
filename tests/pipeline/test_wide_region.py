"""A tube that touches a wide region of the frame a little darker than the rest
(beyond a meniscus or a dish's edge: a brightness step the smooth background
model does not follow): their one structure in the foreground is no longer
tube-like, and the tube, of far more contrast, is found at raised thresholds
(``pipeline.segment.NETWORK_RAISE``)."""

import numpy as np
import pytest

from pipeline import segment


def _frame(step, softness, seed=1):
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:480, 0:640].astype(float)
    image = 0.8 + 0.01 * rng.standard_normal(rows.shape)
    # darker above a curved edge across the whole field
    edge = 280 - 40 * np.sin(cols / 640 * np.pi)
    image -= step / (1 + np.exp((rows - edge) / softness))
    # a dark tube 10 px wide along row 300 from the left border to column 430:
    # its top edge runs into the region's blurred edge
    tube = np.exp(-0.5 * np.maximum(np.abs(rows - 300.0) - 5, 0) ** 2) * (cols < 430)
    return (image - 0.45 * tube).astype(np.float32)


@pytest.mark.parametrize("step, softness", [(0.08, 6.0), (0.1, 10.0)])
def test_a_tube_touching_a_darker_region_is_found_not_the_region(monkeypatch, step, softness):
    image = _frame(step, softness)
    det = segment.detect(image)
    # along the tube's row ((col, -row) coordinates), its whole length
    assert np.abs(det.path.imag + 300).max() < 3.0
    assert abs(det.length - 430) < 0.03 * 430
    assert det.half_width < 12

    # the plain thresholds only: the region and the tube are taken as one
    # wide structure
    monkeypatch.setattr(segment, "NETWORK_RAISE", ())
    off = segment.detect(image)
    assert off.half_width > 30 or np.abs(off.path.imag + 300).max() > 20
