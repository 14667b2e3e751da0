"""Tracking a tube many pixels wide on binned frames (:mod:`pipeline.binning`)."""

import json

import cv2
import numpy as np
import pytest

from pipeline.accuracy import score_folder
from pipeline.binning import MAX_HALF_WIDTH_PX, Binning
from pipeline.centreline import Curve
from pipeline.render import Scene, render_scene
from pipeline.tracks import track_video


@pytest.mark.parametrize(("half_width", "factor"), [
    (5.0, 1), (MAX_HALF_WIDTH_PX, 1), (MAX_HALF_WIDTH_PX + 0.1, 2),
    (2 * MAX_HALF_WIDTH_PX, 2), (2.5 * MAX_HALF_WIDTH_PX, 3), (np.nan, 1)])
def test_the_binning_brings_the_tube_to_a_usual_width(half_width, factor):
    assert Binning.for_half_width(half_width).factor == factor


def test_a_binned_pixel_is_its_block_s_mean_and_maps_back_to_its_centre():
    rng = np.random.default_rng(0)
    image = rng.random((31, 44)).astype(np.float32)
    binning = Binning(3)
    small = binning.frame(image)
    assert small.shape == (10, 14)
    assert small[4, 7] == pytest.approx(image[12:15, 21:24].mean(), rel=1e-5)
    # the binned pixel (7, 4) is the block whose centre is the pixel (22, 13)
    assert binning.to_binned(22.0, 13.0) == pytest.approx((7.0, 4.0))
    curve = Curve(base=7.0 - 4.0j, base_angle=0.3, coef=np.array([0.1, 0.2, 0.4]),
                  length=20.0)
    back = binning.curve_back(curve)
    assert back.base == pytest.approx(22.0 - 13.0j)
    assert back.length == pytest.approx(60.0)
    np.testing.assert_array_equal(back.coef, curve.coef)
    assert back.base_angle == curve.base_angle


def test_a_wide_tube_in_a_rescaled_video_is_tracked_whole(tmp_path):
    """A 480x360 scene (sample 3, transmitted light, shot noise, vignetting,
    dust) scaled up 3x (cubic), as a video exported at a larger size is: the
    tube is 80 px wide and the noise correlated over a few pixels. Tracked at
    the frame's own pixels, the tip ran on into the background from the first
    frame on (5 of 6 frames lost, the one measured 12 % long)."""
    scene = Scene(sample="3", eps_max=0.5868, k_de_per_um=0.0, p_max_mpa=0.17, n_frames=6,
                  width=480, height=360, base_angle_deg=151.48, mirror=True, seed=20368127,
                  look={"name": "transmitted", "photons": 766.0, "blur_px": 1.12,
                        "vignetting": 0.39, "dust": 15, "contrast": 0.44})
    small = render_scene(scene, tmp_path / "small", fmt="png")
    big = tmp_path / "big"
    (big / "frames").mkdir(parents=True)
    for i, path in enumerate(sorted((small / "frames").iterdir())):
        frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        # pixel centre (c, r) -> (3c, 3r), as the truth below is scaled
        up = cv2.warpAffine(frame, np.float32([[3, 0, 0], [0, 3, 0]]), (1440, 1080),
                            flags=cv2.INTER_CUBIC)
        cv2.imwrite(str(big / "frames" / f"{i:03d}.png"), up)
    for name in ("truth_tracks.csv", "truth_centrelines.csv"):
        (big / name).write_bytes((small / name).read_bytes())
    record = json.loads((small / "scene.json").read_text())
    um_per_px = record["layout"]["um_per_px"] / 3
    record["layout"]["um_per_px"] = um_per_px
    (big / "scene.json").write_text(json.dumps(record))
    run = track_video(big / "frames", tmp_path / "out", um_per_px=um_per_px)
    assert any("binned 2x2" in note for note in run.notes)
    _, acc = score_folder(big, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.angle_max <= 2.0
    assert acc.length_error_max_pct <= 1.0
    assert acc.centreline_rms_px <= 0.5
