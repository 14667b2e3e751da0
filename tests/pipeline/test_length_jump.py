"""A tip that runs onto a holder lying across its way (two dark glass walls):
the end search took the far wall for the tube's end, 1-3 % long and the tip
angle a few degrees off, every check passed. A tube keeps its length from
frame to frame: a fit whose length jumps by more than
:data:`pipeline.track.LENGTH_JUMP` is fitted again at the tube's own length."""

import json

import cv2
import numpy as np
import pandas as pd

from pipeline import track
from pipeline.accuracy import score_folder
from pipeline.render import default_scene, render_scene
from pipeline.tracks import track_video

#: The frame the walls are drawn on.
AT = 8


def _walls_across_the_tip(folder, um, beyond_px):
    """Draw two dark lines 2 px wide across frame ``AT``'s tip, at right angles
    to it: one 6 px before the tip, one ``beyond_px`` past it."""
    line = pd.read_csv(folder / "truth_centrelines.csv")
    line = line[line.frame == AT]
    z = (line.x_um.to_numpy() + 1j * line.y_um.to_numpy()) / um      # px, y up
    along = (z[-1] - z[-5]) / abs(z[-1] - z[-5])
    path = sorted((folder / "frames").iterdir())[AT]
    frame = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(np.float32)
    mask = np.zeros(frame.shape, np.float32)
    for off in (-6.0, beyond_px):
        # (image coordinates: col + 1j·row is the conjugate of the y-up point)
        a = np.conj(z[-1] + off * along - 60j * along)
        b = np.conj(z[-1] + off * along + 60j * along)
        cv2.line(mask, (round(a.real), round(a.imag)), (round(b.real), round(b.imag)), 1.0, 2,
                 cv2.LINE_AA)
    cv2.imwrite(str(path), np.clip(frame * (1 - 0.6 * mask), 0, 255).astype(np.uint8))


def test_a_tip_run_onto_a_holder_s_walls_keeps_the_tube_s_length(tmp_path, monkeypatch):
    folder = render_scene(default_scene(1, n_frames=12, seed=3, width=640, height=480),
                          tmp_path / "scene", fmt="png")
    um = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    _walls_across_the_tip(folder, um, beyond_px=10.0)

    track_video(folder / "frames", tmp_path / "held", um_per_px=um)
    errors, acc = score_folder(folder, tmp_path / "held")
    assert acc.frames_lost == 0
    assert abs(errors.length_error_pct[AT]) < 0.3
    assert abs(errors.angle_error_deg[AT]) < 0.5

    monkeypatch.setattr(track, "LENGTH_JUMP", np.inf)
    track_video(folder / "frames", tmp_path / "free", um_per_px=um)
    free, _ = score_folder(folder, tmp_path / "free")
    assert free.length_error_pct[AT] > 1.5
    assert abs(free.angle_error_deg[AT]) > 2.0
