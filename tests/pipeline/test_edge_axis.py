"""A holder half out of the frame: its axis from the edges that show
(:func:`pipeline.pipette.edge_axis`)."""

import json

from pipeline import pipette
from pipeline.accuracy import score_folder
from pipeline.render import default_scene, render_scene
from pipeline.tracks import track_video


def test_a_capillary_along_the_frames_border_gives_its_axis_by_the_edge_in_view(
        tmp_path, monkeypatch):
    # a tube pushed into a capillary 1.5x its width, which runs along the top
    # border 5 deg off it (its upper wall out of the frame), deflating from a
    # curl: the tube past the capillary is bent on the first frame, and no
    # centre of the capillary's profiles shows
    scene = default_scene(1, n_frames=10, seed=4, width=640, height=480, base_px=(560, 14),
                          base_angle_deg=185.0, pipette_ratio=1.5, margin_px=2.0,
                          um_per_px=30.0)
    scene = scene.replace(pressures_mpa=tuple(float(p) for p in scene.pressures()[::-1]))
    folder = render_scene(scene, tmp_path / "scene", fmt="png")
    um = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    track_video(folder / "frames", tmp_path / "out", um_per_px=um)
    _, acc = score_folder(folder, tmp_path / "out")
    assert acc.frames_lost == 0
    assert acc.angle_median < 0.3 and acc.angle_max < 1.0, acc

    # without it, the fit's mean direction through the capillary's stretch
    # is the base tangent: every angle off by as much
    monkeypatch.setattr(pipette, "edge_axis", lambda *a: None)
    track_video(folder / "frames", tmp_path / "off", um_per_px=um)
    _, off = score_folder(folder, tmp_path / "off")
    assert off.angle_median > 1.0, off
