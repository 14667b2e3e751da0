"""Hiding a structure that stood still (:mod:`pipeline.static_mask`)."""

import numpy as np
import pytest

from pipeline.centreline import fit_to_polyline, from_image
from pipeline.static_mask import MARGIN_PX, static_mask


def _straight(c0, r0, c1, r1) -> tuple:
    """A straight curve from (c0, r0) to (c1, r1), image px."""
    a, b = complex(from_image(c0, r0)), complex(from_image(c1, r1))
    pts = a + (b - a) * np.linspace(0.0, 1.0, 50)
    return fit_to_polyline(pts, float(np.angle(b - a)), n_coef=4), a, b


def test_a_holder_from_the_border_is_masked_to_the_border_and_square_at_its_end():
    # tracked from 6 px inside the top border down to row 100, 10 px half-width
    curve, _, _ = _straight(80, 6, 80, 100)
    hide = static_mask(curve, 10.0, (200, 160))
    reach = 10.0 + MARGIN_PX
    assert hide.mask[0, 80] and hide.mask[0, 80 - int(reach) + 1]  # out to the border
    # square at the free end: as deep on its sides as on its axis
    assert hide.mask[100 + int(MARGIN_PX) - 1, 80]
    assert hide.mask[100 + int(MARGIN_PX) - 1, 80 + int(reach) - 1]
    assert not hide.mask[100 + int(MARGIN_PX) + 2, 80]
    # sideways: the half-width and the margin
    assert hide.mask[50, 80 + int(reach) - 1] and not hide.mask[50, 80 + int(reach) + 2]
    # the free end is the tracked end away from the border
    assert hide.end == pytest.approx(complex(from_image(80, 100)), abs=1.0)
    # the ring about the mask is outside it and hugs it
    assert not (hide.ring & hide.mask).any()
    assert hide.ring[50, 80 + int(reach) + 2]


def test_the_free_end_is_the_one_away_from_the_border_whichever_way_it_was_tracked():
    curve, _, _ = _straight(80, 100, 80, 6)
    hide = static_mask(curve, 10.0, (200, 160))
    assert hide.end == pytest.approx(complex(from_image(80, 100)), abs=1.0)
    assert hide.mask[0, 80]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_the_fill_is_the_background_plane_about_the_mask(dtype):
    rows, cols = np.mgrid[0:200, 0:160].astype(float)
    scale = 1.0 if dtype == np.float32 else (255.0 if dtype == np.uint8 else 65535.0)
    plane = (0.5 + 0.001 * rows - 0.0005 * cols) * scale
    frame = plane.copy()
    frame[0:101, 72:89] = 0.05 * scale  # the dark holder
    frame[110:150, 79:82] = 0.3 * scale  # a tube leaving its end: not part of the fit
    frame = frame.astype(dtype)
    curve, _, _ = _straight(80, 6, 80, 100)
    hide = static_mask(curve, 8.0, frame.shape)
    out = hide.fill(frame)
    assert out.dtype == frame.dtype and out is not frame
    tol = 1.5 if dtype != np.float32 else 1e-4  # (the ring itself is quantised)
    assert np.abs(out[hide.mask].astype(float) - plane[hide.mask]).max() <= tol
    np.testing.assert_array_equal(out[~hide.mask], frame[~hide.mask])
    # the frame itself is left as it was
    assert float(frame[50, 80]) == pytest.approx(0.05 * scale, abs=1.0)
