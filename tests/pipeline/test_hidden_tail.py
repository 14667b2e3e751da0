"""A tube whose end the crossing hides, when its joints are not known: the
hidden stretch's curvature is held at the multiple of the stretch before it
that the last shape seen whole had (:func:`pipeline.refine._tail_hold`); and
of fits at a crossing that fit the edges alike, the one from the prediction is
kept (:func:`pipeline.track._least_residual`)."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from models import get_sample
from pipeline import joints, refine, track
from pipeline.accuracy import score_folder
from pipeline.centreline import fit_to_polyline
from pipeline.render import default_scene, render_scene, strain_for_angle
from pipeline.tracks import track_video

LENGTH = 400.0
#: Profiles' positions, as fractions of the length.
U = np.linspace(0.01, 0.99, 99)
#: A half-width of 6 px, as a fraction of the length.
HW_U = 6.0 / LENGTH


def _stepped(k_body, k_tip, joint=0.8):
    """The spline (no joints: as the tracker has it when it has found none) of
    a tube whose curvature steps from ``k_body`` to ``k_tip`` (1/px) at
    ``joint``."""
    s = np.linspace(0.0, LENGTH, 4001)
    phi = np.where(s < joint * LENGTH, k_body * s,
                   k_body * joint * LENGTH + k_tip * (s - joint * LENGTH))
    z = np.concatenate([[0j], np.cumsum(np.exp(0.5j * (phi[1:] + phi[:-1])) * np.diff(s))])
    return fit_to_polyline(z, 0.0, n_coef=40)


def test_a_hidden_end_keeps_the_curvature_ratio_of_the_last_whole_shape():
    whole = _stepped(1 / 80, 1 / 250)
    hold = refine._tail_hold(whole.coef, (), U, U > 0.8, HW_U)
    assert hold is not None
    # the same tube bent less or further (the same load on every section:
    # the same ratio), fitted on its own, keeps it
    for load in (0.5, 1.6):
        other = _stepped(load / 80, load / 250)
        assert hold @ other.coef == pytest.approx(0.0, abs=2e-3 * load * LENGTH / 80)
    # a tip that carried on at the curvature before it (what the spline's
    # roughness penalty alone gives a stretch without data) does not: its
    # mean curvature is 1/80 where the held one is 1/250 (1/px)
    arc = _stepped(1 / 80, 1 / 80)
    assert abs(hold @ arc.coef) * (1 / LENGTH) == pytest.approx(1 / 80 - 1 / 250, rel=0.05)


def test_the_end_is_held_only_where_the_crossing_hides_it():
    whole = _stepped(1 / 80, 1 / 250)
    # hidden in the middle, the end seen: the spline bridges it from both sides
    assert refine._tail_hold(whole.coef, (), U, (U > 0.4) & (U < 0.6), HW_U) is None
    # hidden over less than TAIL_HOLD_MIN_HW half-widths at the end
    short = U > 1.0 - 0.9 * refine.TAIL_HOLD_MIN_HW * HW_U
    assert short.any()
    assert refine._tail_hold(whole.coef, (), U, short, HW_U) is None
    # the whole tube hidden: there is nothing to hold it to
    assert refine._tail_hold(whole.coef, (), U, np.ones(U.size, bool), HW_U) is None
    # a last whole shape that hardly bent before the end: its ratio is noise
    nearly_straight = _stepped(1 / 20000, 1 / 250)
    assert refine._tail_hold(nearly_straight.coef, (), U, U > 0.8, HW_U) is None


def test_the_last_whole_shape_is_carried_into_joints_found_since():
    """Joints found after the tube was last seen whole (a kink search on a
    crossing frame) change the prediction's spline: the last whole shape is
    rewritten into it, and still holds the hidden end to its ratio."""
    whole = _stepped(1 / 80, 1 / 250)
    assert track._whole_mode(None, whole) is None
    assert np.array_equal(track._whole_mode(whole, whole), whole.coef)
    pred = joints.rewritten(_stepped(1.2 / 80, 1.2 / 250), (0.35, 0.4), 44)
    mode = track._whole_mode(whole, pred)
    assert mode.size == pred.coef.size
    hold = refine._tail_hold(mode, pred.joints, U, U > 0.8, HW_U)
    assert hold is not None
    # the same tube bent further, in the new spline, keeps the ratio ...
    other = joints.rewritten(_stepped(1.6 / 80, 1.6 / 250), pred.joints, pred.coef.size)
    assert hold @ other.coef == pytest.approx(0.0, abs=2e-3 * 1.6 * LENGTH / 80)
    # ... and a tip carried on at the curvature before it does not
    arc = joints.rewritten(_stepped(1 / 80, 1 / 80), pred.joints, pred.coef.size)
    assert abs(hold @ arc.coef) * (1 / LENGTH) == pytest.approx(1 / 80 - 1 / 250, rel=0.05)


def test_of_fits_alike_the_one_from_the_prediction_is_kept():
    fits = [SimpleNamespace(residual_px=r, name=n)
            for r, n in ((0.020, "prediction"), (0.018, "last shape"), (0.019, "freed"))]
    assert track._least_residual(fits).name == "prediction"
    # one that fits clearly better wins
    fits[1].residual_px = 0.012
    assert track._least_residual(fits).name == "last shape"
    assert track._least_residual([]) is None


def test_a_tip_hidden_over_the_body_without_known_joints_follows_the_curl(tmp_path,
                                                                          monkeypatch):
    """Sample 7 (a straighter last tenth) curling to ~450°, with its joints
    not found (as when its sections do not differ in width, and the kinks do
    not show): once its tip lies over the base, the roughness penalty alone
    carried the hidden tip on at the curvature before it (11° off)."""
    for module in (track, joints):
        monkeypatch.setattr(module, "width_steps", lambda *a, **k: [])
    monkeypatch.setattr(track, "find_joints", lambda *a, **k: ())
    spec = get_sample("7")
    eps = strain_for_angle(spec, 450.0, p_max=spec.p_max_mpa or 0.15)
    scene = default_scene(7, eps_max=eps, n_frames=24, seed=11, look="opaque", width=640,
                          height=480, base_angle_deg=30.0)
    folder = render_scene(scene, tmp_path / "scene", fmt="avi")
    scale = json.loads((folder / "scene.json").read_text())["layout"]["um_per_px"]

    track_video(folder / "frames.avi", tmp_path / "held", um_per_px=scale)
    _, acc = score_folder(folder, tmp_path / "held")
    run = json.loads((tmp_path / "held" / "run.json").read_text())
    assert not run["first_curve"]["joints"]
    assert acc.frames_lost == 0
    assert acc.angle_p95 <= 2.0 and acc.angle_max <= 5.0, acc
    assert acc.length_error_max_pct <= 1.0, acc

    monkeypatch.setattr(refine, "_tail_hold", lambda *a, **k: None)
    track_video(folder / "frames.avi", tmp_path / "free", um_per_px=scale)
    _, free = score_folder(folder, tmp_path / "free")
    assert free.angle_max > 8.0, free
