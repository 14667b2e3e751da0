"""The tracker's settings: validated, threaded through, and the default unchanged."""

import json

import numpy as np
import pytest

from pipeline.render import Renderer, default_scene, render_scene
from pipeline.track import TrackSettings, track_frames
from pipeline.tracks import track_video

LOOK = {"name": "opaque", "photons": 0.0, "read_noise": 0.0, "flicker": 0.0, "dust": 0}


def _scene():
    return default_scene(3, n_frames=5, seed=3, width=320, height=240, base_angle_deg=0.0,
                         look=LOOK)


def _frames():
    scene = _scene()
    r = Renderer(scene)
    return [r.frame(i) for i in range(scene.n_frames)]


@pytest.mark.parametrize("field, value", [
    ("rounds", 0), ("rounds", 2.5), ("rounds", True), ("rounds", "3"),
    ("first_rounds", -1), ("tol_px", 0.0), ("tol_px", -0.1), ("tol_px", float("nan")),
    ("fast_tol_px", 0.0), ("fast_tol_px", float("nan")),
    ("widths_per_coef", float("inf")), ("widths_per_coef", "0.75"),
    ("jointed_widths_per_coef", 0.0), ("jointed_widths_per_coef", float("nan")),
])
def test_bad_settings_are_refused_naming_the_field(field, value):
    with pytest.raises(ValueError, match=rf"TrackSettings\.{field} must be"):
        TrackSettings(**{field: value})


def test_explicit_default_settings_track_exactly_as_no_settings():
    frames = _frames()
    plain = list(track_frames(frames))
    explicit = list(track_frames(frames, settings=TrackSettings()))
    assert [r.status for r in plain] == [r.status for r in explicit]
    assert all(r.ok for r in plain)
    for a, b in zip(plain, explicit, strict=True):
        assert (a.stage, a.residual_px, a.valid_fraction) == (b.stage, b.residual_px,
                                                              b.valid_fraction)
        np.testing.assert_array_equal(a.curve.coef, b.curve.coef)
        assert (a.curve.length, a.curve.base, a.curve.base_angle) == (
            b.curve.length, b.curve.base, b.curve.base_angle)


def test_settings_reach_the_tracker_and_run_json(tmp_path):
    frames = _frames()
    # sample 3's joint is seen (its width steps): the jointed spacing applies
    jointed = next(track_frames(frames[:1]))
    assert len(jointed.curve.joints) == 1
    coarse = next(track_frames(frames[:1], settings=TrackSettings(jointed_widths_per_coef=3.0)))
    assert coarse.curve.coef.size < jointed.curve.coef.size
    # a single section, its joints not known: the fine spacing applies
    single = Renderer(default_scene(8, n_frames=1, seed=3, width=320, height=240,
                                    look=LOOK)).frame(0)
    fine = next(track_frames([single]))
    assert fine.curve.joints == ()
    coarse = next(track_frames([single], settings=TrackSettings(widths_per_coef=3.0)))
    assert coarse.curve.coef.size < fine.curve.coef.size
    folder = render_scene(_scene(), tmp_path / "scene", fmt="png")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]
    track_video(folder / "frames", tmp_path / "out", um_per_px=scale,
                settings=TrackSettings(rounds=1, tol_px=0.1))
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert run["tracker_settings"] == {"rounds": 1, "first_rounds": 20, "tol_px": 0.1,
                                       "fast_tol_px": 0.1, "widths_per_coef": 0.75,
                                       "jointed_widths_per_coef": 1.5}


def test_the_fast_path_stops_at_its_own_tolerance_and_the_searches_at_theirs(monkeypatch):
    import pipeline.track as T

    seen = []
    refine = T.refine

    def recording(*args, **kwargs):
        seen.append((kwargs.get("iterations"), kwargs.get("tol_px"), kwargs.get("origin")))
        return refine(*args, **kwargs)

    monkeypatch.setattr(T, "refine", recording)
    settings = TrackSettings(tol_px=0.03, fast_tol_px=0.3)
    results = list(track_frames(_frames(), settings=settings))
    assert all(r.ok for r in results)
    # the fast path refines on a crop (its origin given) from the prediction:
    # with a velocity (from the third frame on) at fast_tol_px
    fast = [tol for rounds, tol, origin in seen if origin is not None and rounds == 3]
    assert fast and set(fast) == {0.3}
    others = {tol for rounds, tol, origin in seen if origin is None}
    assert others == {0.03}
