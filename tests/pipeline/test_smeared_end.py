"""A tip that moves fast smears sideways over the exposure: its side edges
are not the tube's for a few half-widths, but its end lies where the tube's
length puts it (:data:`pipeline.track.SMEARED_END_GAP_HW`)."""

import cv2
import numpy as np
import pandas as pd
import pytest

from pipeline import track
from pipeline.tracks import track_video
from tests.pipeline.synthetic import tube_image

HW, LENGTH, BASE = 6.0, 300.0, 60 - 120j
SHAPE = (240, 480)


def _frame(k: int, smeared: bool) -> np.ndarray:
    """A straight tube from a pipette, round-capped; ``smeared``: its last
    40 px averaged over a sideways sweep of ±9 px (three half-widths)."""
    img = tube_image(SHAPE, BASE, 0.0, LENGTH, 1e-12, HW, noise=0.005, seed=k,
                     round_cap=True, pipette_half_width=1.6 * HW)
    if smeared:
        sweep = np.mean([np.roll(img, j, axis=0) for j in range(-9, 10)], axis=0)
        w = np.clip((np.arange(SHAPE[1])[None, :] - (BASE.real + LENGTH - 40)) / 10.0, 0, 1)
        img = (1 - w) * img + w * sweep
    return img


def _video(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(8):
        img = _frame(k, smeared=k >= 4)
        cv2.imwrite(str(folder / f"f{k:02d}.png"),
                    (np.clip(img, 0, 1) * 255).round().astype(np.uint8))
    return folder


def test_frames_whose_tip_is_smeared_are_measured(tmp_path, monkeypatch):
    folder = _video(tmp_path)
    track_video(folder, tmp_path / "out", um_per_px=1.0)
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all(), t.status.tolist()
    # (the smeared stretch bridged by the spline: its tip tangent off by up
    # to about 2 deg, measured)
    assert np.abs(t.bend_angle_deg).max() < 3.0
    assert np.abs(t.length_um / LENGTH - 1).max() < 0.01

    # held to the usual stretch without side edges, the smeared frames are lost
    monkeypatch.setattr(track, "SMEARED_END_GAP_HW", track.END_GAP_HW)
    track_video(folder, tmp_path / "off", um_per_px=1.0)
    off = pd.read_csv(tmp_path / "off" / "tracks.csv")
    assert (off.status[:4] == "ok").all()
    assert off.status[4:].str.contains("ran on past the tube's side edges").all()


def test_a_long_end_gap_counts_only_at_the_tube_s_own_length():
    r, look, _ = track.initialise(_frame(0, smeared=True))
    assert r.tip_found
    assert r.end_gap_px > track.END_GAP_HW * look.mean_half_width
    assert not track._good(r, look)
    assert track._accepted(r, look, r.curve.length)
    # an end that far past the side edges, 2 % off the neighbouring frame's
    # length, is something beyond the tip
    assert not track._accepted(r, look, r.curve.length * 1.02)
    assert track._end_gap_hw(r, r.curve.length * 1.02) == pytest.approx(track.END_GAP_HW)
