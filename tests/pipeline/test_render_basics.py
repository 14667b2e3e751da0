"""The renderer: truth where the drawing is, regeneration, orientation, validation."""

import numpy as np
import pandas as pd
import pytest

from pipeline import schema as S
from pipeline.cli import main
from pipeline.frames import open_frames, to_float
from pipeline.render import Renderer, default_scene, load_scene, render_scene, truth_tables

CLEAN = {"name": "opaque", "photons": 0.0, "read_noise": 0.0, "flicker": 0.0, "dust": 0,
         "gradient": 0.0, "vignetting": 0.0}


def _small(**changes):
    base = dict(n_frames=4, width=320, height=240, seed=1)
    base.update(changes)
    return default_scene(3, **base)


def test_drawn_axis_lies_on_the_truth_to_five_hundredths_of_a_pixel():
    from scipy.ndimage import map_coordinates

    scene = _small(look=CLEAN, base_angle_deg=23.0)
    r = Renderer(scene)
    tracks, lines, _ = truth_tables(scene, r.layout)
    dark = 1 - r.tube_layers(3)  # attenuation, symmetric across the opaque tube
    pts = lines[lines[S.FRAME] == 3]
    z = (pts[S.X].to_numpy() + 1j * pts[S.Y].to_numpy()) / r.layout.um_per_px
    tangent = np.gradient(z)
    normal = 1j * tangent / np.abs(tangent)
    # cross-sections well inside the tube (away from the base, the tip and section joints)
    idx = np.linspace(0.15, 0.45, 12) * len(z)
    offsets = np.arange(-30, 30.01, 0.25)
    errors = []
    for i in idx.astype(int):
        line = z[i] + normal[i] * offsets
        w = map_coordinates(dark, [-line.imag, line.real], order=1)
        errors.append(np.sum(w * offsets) / np.sum(w))
    assert np.max(np.abs(errors)) < 0.05


def test_scene_regenerates_bit_for_bit_from_its_json(tmp_path):
    scene = _small(look="transmitted")
    a = render_scene(scene, tmp_path / "a", fmt="png")
    again, fmt, depth = load_scene(a / S.SCENE_FILE)
    assert again == scene and fmt == "png" and depth == 8
    b = render_scene(again, tmp_path / "b", fmt="png")
    with open_frames(a / "frames") as ra, open_frames(b / "frames") as rb:
        for fa, fb in zip(ra, rb, strict=True):
            np.testing.assert_array_equal(fa, fb)
    truth = pd.read_csv(a / S.TRUTH_TRACKS_FILE)
    assert list(truth.columns) == S.TRUTH_COLUMNS
    lines = pd.read_csv(a / S.TRUTH_CENTRELINES_FILE)
    assert list(lines.columns) == S.CENTRELINE_COLUMNS
    step = np.hypot(*np.diff(lines[lines[S.FRAME] == 3][[S.X, S.Y]].to_numpy(), axis=0).T)
    assert step.max() <= Renderer(again).layout.um_per_px  # ≤ 1 px apart


def test_render_command_regenerates_a_scene_in_its_own_format_and_depth(tmp_path):
    scene = _small(look=CLEAN)
    a = render_scene(scene, tmp_path / "a", fmt="tiff", bit_depth=16)
    assert main(["render", "--scene", str(a / S.SCENE_FILE), "--out", str(tmp_path / "b"),
                 "-q"]) == 0
    assert (tmp_path / "b" / S.SCENE_FILE).read_text() == (a / S.SCENE_FILE).read_text()
    with open_frames(a / "frames.tif") as ra, open_frames(tmp_path / "b" / "frames.tif") as rb:
        assert rb.dtype == np.uint16
        for fa, fb in zip(ra, rb, strict=True):
            np.testing.assert_array_equal(fa, fb)


def test_mirror_curls_clockwise_with_a_negative_angle():
    ccw = truth_tables(_small())[0][S.BEND].to_numpy()
    cw = truth_tables(_small(mirror=True))[0][S.BEND].to_numpy()
    assert ccw[-1] > 100
    np.testing.assert_allclose(cw, -ccw)


def test_sixteen_bit_tiff_keeps_the_rendered_values(tmp_path):
    scene = _small(look=CLEAN)
    out = render_scene(scene, tmp_path / "t", fmt="tiff", bit_depth=16)
    with open_frames(out / "frames.tif") as reader:
        frames = list(reader)
    assert frames[0].dtype == np.uint16 and len(frames) == scene.n_frames
    np.testing.assert_allclose(to_float(frames[2]), Renderer(scene).frame(2), atol=1e-4)


@pytest.mark.parametrize("change, match", [
    ({"pressures_mpa": [0.0, -0.1]}, "pressures"),
    ({"width": 0}, "width"),
    ({"look": "sparkly"}, "look"),
    ({"look": {"name": "transmitted", "texture": -0.05}}, "texture"),
    ({"um_per_px": 1.0}, "leaves the"),
])
def test_impossible_scenes_are_refused(change, match):
    with pytest.raises(ValueError, match=match):
        Renderer(_small(**change))


def test_a_mottled_background_is_fixed_across_frames_and_as_strong_as_asked():
    # the tube's own frames differ only where the tube moved and by the noise;
    # the mottle is the same in every frame, so a corner far from the tube
    # keeps its pattern
    look = {**CLEAN, "name": "transmitted", "texture": 0.05}
    r = Renderer(_small(look=look))
    first, last = r.frame(0), r.frame(r.scene.n_frames - 1)
    corner = (slice(0, 40), slice(-60, None))
    np.testing.assert_allclose(first[corner], last[corner], atol=1e-5)
    flat = Renderer(_small(look={**CLEAN, "name": "transmitted"})).frame(0)[corner]
    # three fields of 5 % each: about 8.7 % together, over a corner 40x60 px
    spread = float(np.std(first[corner] / flat))
    assert 0.06 < spread < 0.11
