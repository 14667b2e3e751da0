"""A pulled glass pipette narrows towards its mouth: where the tube is wider
than the mouth but narrower than the pipette at the frame's border, the
pipette's mean width is about the tube's and only a trend-then-level fit of
the width along the structure finds the step (:func:`pipeline.segment.detect`)."""

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline.segment import PIPETTE_STEP, detect
from pipeline.tracks import track_video
from tests.pipeline.synthetic import tube_image

SHAPE = (400, 560)
LENGTH, HALF_WIDTH = 300.0, 9.0


@pytest.mark.parametrize("angle_deg", [0.0, 35.0])
def test_the_base_is_found_at_a_tapered_pipettes_mouth(angle_deg):
    angle = np.radians(angle_deg)
    # the mouth 150 px from the border along the pipette: 5 px in half-width
    # there, 15.5 px at the border
    back = 150.0
    base = complex(back * np.cos(angle), -200.0)
    img = tube_image(SHAPE, base, angle, LENGTH, -0.002, HALF_WIDTH, pipette_half_width=5.0,
                     pipette_taper=0.07, pipette_contrast=1.0, noise=0.01, seed=3)
    det = detect(img)
    assert det is not None
    assert det.base_source == PIPETTE_STEP
    assert abs(det.base - base) < HALF_WIDTH, det.base
    assert abs(det.length / LENGTH - 1) < 0.05, det.length


def test_a_tube_held_by_a_tapered_pipette_is_tracked_from_its_mouth(tmp_path):
    # a pipette at 35 deg narrowing to a mouth 150 px in, the tube bent and
    # still over four frames: no motion tells the holder, its width must
    angle = np.radians(35.0)
    base = complex(150.0 * np.cos(angle), -200.0)
    folder = tmp_path / "frames"
    folder.mkdir()
    kappas = (-0.002,) * 4
    for k, kappa in enumerate(kappas):
        img = tube_image(SHAPE, base, angle, LENGTH, kappa, HALF_WIDTH, pipette_half_width=5.0,
                         pipette_taper=0.07, pipette_contrast=1.0, noise=0.01, seed=k)
        cv2.imwrite(str(folder / f"f{k}.png"), (img * 255).round().astype(np.uint8))
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    tracks = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (tracks.status == "ok").all()
    assert np.abs(tracks.base_x_um - base.real).max() < 1.5
    assert np.abs(tracks.base_y_um - base.imag).max() < 1.5
    assert np.abs(tracks.length_um / LENGTH - 1).max() < 0.01
    assert np.abs(tracks.bend_angle_deg - np.degrees(np.array(kappas) * LENGTH)).max() < 0.5
