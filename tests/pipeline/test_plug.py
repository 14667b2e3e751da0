"""A sealed tube's straight end plug is told by its offsets growing with the bend."""


import numpy as np
import pandas as pd
import pytest
from scipy.spatial import cKDTree
from scipy.special import erf

from pipeline import pipette, plug
from pipeline.centreline import Curve, fit_to_polyline, resample, tip_point
from pipeline.refine import END_PROFILE_HW, END_STEP_ZONES_HW
from pipeline.track import FrameTrack
from pipeline.tracks import track_video
from tests.pipeline.synthetic import arc_axis

HW = 8.0


def _frames(bends_deg, offsets, step_px=16.0):
    """FrameTracks bent by ``bends_deg`` whose end stretch (zone nearest
    ``step_px``) sat ``offsets`` px off the rest's line, that stretch told."""
    zone = int(np.argmin(np.abs(np.asarray(END_STEP_ZONES_HW) * HW - step_px)))
    out = []
    for k, (bend, off) in enumerate(zip(bends_deg, offsets, strict=True)):
        steps = np.full((len(END_STEP_ZONES_HW), 3), np.nan)
        steps[zone] = (off, 10.0, 0.02)
        curve = Curve(0j, 0.0, 300.0, np.linspace(0.0, np.radians(bend), 8))
        out.append(FrameTrack(k, "ok", curve, "fast", end_steps=steps,
                              end_step=(step_px, 0.2)))
    return out


BENDS = np.linspace(0.0, -200.0, 10)


@pytest.mark.parametrize(("offsets", "told"), [
    (-0.15 * np.radians(BENDS), True),                      # a plug: with the bend, outwards
    (np.full(10, 0.2), False),                              # a lumen's step: steady
    (0.15 * np.radians(BENDS), False),                      # with the bend, but inwards
    (np.where(np.arange(10) == 5, 0.8, -0.15 * np.radians(BENDS)), True),  # one misread
])
def test_a_plug_is_an_offset_in_proportion_to_the_bend(offsets, told):
    rng = np.random.default_rng(1)
    results = _frames(BENDS, offsets + rng.normal(0, 0.01, 10))
    length = plug.plug_length(results, HW)
    assert (length is not None) == told
    if told:
        assert length == pytest.approx(16.0 * plug.PLUG_PER_STRETCH)


@pytest.mark.parametrize(("offsets", "told"), [
    (-0.15 * np.radians(BENDS), True),
    (np.full(10, 0.2), False),
])
def test_the_offsets_measured_after_the_stretch_was_told_count(offsets, told):
    """A stretch told on the first frames, when few and little bent: the
    offsets measured as itself after (``told_offset``) tell the plug."""
    results = _frames(BENDS[:3], offsets[:3])
    for k, (bend, off) in enumerate(zip(BENDS[3:], offsets[3:], strict=True)):
        curve = Curve(0j, 0.0, 300.0, np.linspace(0.0, np.radians(bend), 8))
        results.append(FrameTrack(k + 3, "ok", curve, "fast", end_step=(16.0, 0.2),
                                  told_offset=float(off)))
    assert (plug.plug_length(results, HW) is not None) == told
    assert plug.plug_length(results[:3], HW) is None


def _profiled(plug_px, bends_deg, rng, *, section=0.0):
    """FrameTracks of a 300 px tube at constant curvature, whose edge
    midpoints near the end sit off the arc as a straight plug ``plug_px``
    long puts them, plus a last section's curvature step ``section`` (times
    the bend's curvature) over the profiles' reach, a face's pull on the
    nearest and noise."""
    reach = END_PROFILE_HW * HW
    d = np.arange(1.0, reach, 1.5)
    out = []
    for k, bend in enumerate(np.radians(bends_deg)):
        kappa = bend / 300.0
        curve = fit_to_polyline(arc_axis(0j, 0.0, 300.0, kappa)[0], 0.0, n_coef=12)
        off = (-kappa * np.clip(plug_px - d, 0, None) ** 2 / 2
               + section * kappa * (reach - d) ** 2 / 2
               + np.where(d < 0.4 * HW, 0.5, 0.0) + rng.normal(0, 0.03, d.size))
        out.append(FrameTrack(k, "ok", curve, "fast", end_step=(0.6 * plug_px, 0.2),
                              end_profile=np.c_[d, off, np.ones(d.size)]))
    return out


@pytest.mark.parametrize("section", [0.0, 0.3, -0.3])
@pytest.mark.parametrize("plug_px", [18.0, 34.0])
def test_a_plug_s_length_is_fitted_to_the_midpoints_near_the_end(plug_px, section):
    """The stretch told is short of the plug (0.6 of it here; 0.6-0.85 seen):
    the plug's length is fitted to the edge midpoints near the end instead,
    whatever a last section's curvature adds there."""
    rng = np.random.default_rng(2)
    results = _profiled(plug_px, BENDS, rng, section=section)
    assert plug.fitted_length(results, HW, 0.6 * plug_px) == pytest.approx(plug_px, abs=0.5)
    # no plug's share in them: no length fitted (the shortest tried is best)
    results = _profiled(0.0, BENDS, rng, section=section)
    assert plug.fitted_length(results, HW, 0.6 * plug_px) is None
    # too few frames to fit one
    assert plug.fitted_length(_profiled(plug_px, BENDS[:2], rng), HW, 0.6 * plug_px) is None


def test_too_few_or_too_little_bent_frames_tell_no_plug():
    assert plug.plug_length(_frames(BENDS[:4], -0.15 * np.radians(BENDS[:4])), HW) is None
    small = np.linspace(0.0, -30.0, 10)
    assert plug.plug_length(_frames(small, -0.15 * np.radians(small)), HW) is None


def test_a_straight_end_keeps_the_arc_before_it():
    arc = Curve(100 - 200j, 0.3, 300.0, np.linspace(0.0, 2.0, 12))
    plugged = plug.straight_end(arc, 30.0)
    s, z = resample(arc, 1.0)
    s2, z2 = resample(plugged, 1.0)
    before = s <= 270.0 - 8.0
    assert np.abs(z[before] - z2[: before.sum()]).max() < 0.1
    # the tip's direction is the arc's where the plug begins
    _, _, phi, _ = pipette._sampled(arc, 0.25)
    assert plugged.coef[-1] == pytest.approx(phi[1080] - arc.base_angle, abs=2e-3)
    # and the last 30 px run straight along it
    end = s2 >= 272.0
    turn = np.unwrap(np.angle(np.diff(z2[end])))
    assert np.ptp(turn) < np.radians(0.5)
    assert abs(tip_point(plugged) - (z2[np.argmin(np.abs(s2 - 270.0))]
                                     + 30.0 * np.exp(1j * (0.3 + plugged.coef[-1])))) < 0.3


def _plugged_tube(shape, base, angle, length, kappa, plug_px, hw, noise, seed):
    """A dark tube bending at ``kappa`` (1/px) up to its last ``plug_px``,
    which run straight on: drawn from each pixel's distance to the centreline
    (4x supersampled across the edges by erf), its end cut flat."""
    s = np.linspace(0.0, length, int(length * 4) + 1)
    bend = np.minimum(s, length - plug_px)
    phi = angle + kappa * bend
    step = np.exp(1j * phi) * np.gradient(s)
    z = base + np.concatenate([[0], np.cumsum(0.5 * (step[1:] + step[:-1]))])
    rows, cols = shape
    rr, cc = np.mgrid[0:rows, 0:cols]
    pix = cc - 1j * rr
    dist, k = cKDTree(np.c_[z.real, z.imag]).query(np.c_[pix.real.ravel(), pix.imag.ravel()])
    along = ((pix.ravel() - z[k]) * np.exp(-1j * phi[k])).real
    inside = 0.5 * (1 + erf((hw - dist) / 0.7))
    inside *= np.where((k == 0) & (along < 0), 0.5 * (1 + erf(along / 0.7)), 1.0)
    inside *= np.where((k == s.size - 1) & (along > 0), 0.5 * (1 + erf(-along / 0.7)), 1.0)
    img = 0.8 * (1 - 0.35 * inside.reshape(shape))
    img += np.random.default_rng(seed).normal(0, noise, shape)
    tip_phi = angle + kappa * (length - plug_px)
    return np.clip(img, 0, 1).astype(np.float32), z, np.degrees(tip_phi - angle)


def test_a_tube_with_a_straight_plug_is_tracked_to_the_plug_s_direction(tmp_path, monkeypatch):
    import cv2

    folder = tmp_path / "frames"
    folder.mkdir()
    base, angle, length, plug_px = 520 - 400j, np.pi, 420.0, 24.0
    truth = []
    for k in range(12):
        kappa = -3.6 * k / 11 / (length - plug_px)
        img, z, bend = _plugged_tube((480, 640), base, angle, length, kappa - 1e-12, plug_px,
                                     HW, 0.01, k)
        cv2.imwrite(str(folder / f"f{k:02d}.png"), (img * 255).round().astype(np.uint8))
        truth.append(bend)
    truth = np.array(truth)
    run = track_video(folder, tmp_path / "out", um_per_px=1.0, base=(520, 400))
    t = pd.read_csv(tmp_path / "out" / "tracks.csv")
    assert (t.status == "ok").all()
    err = np.abs(t.bend_angle_deg - truth)
    told = [n for n in run.notes if "straight plug" in n and "fitted to the edges" in n]
    assert told, run.notes
    assert abs(float(told[0].split("straight plug ")[1].split(" px")[0]) - plug_px) < 1.5
    # (the plug's start is no section joint)
    assert any(n.startswith("section joints: none found") for n in run.notes), run.notes
    # (the frames fitted before the stretch was told kept the plug's edges,
    # and bent less where it begins: 0.3-1.2 deg off, before the direction
    # was read from the arc before it)
    assert err.max() < 0.6, err.round(2).tolist()
    # the arc carried on to the end turns the tip on by the plug's share of the bend
    monkeypatch.setattr(plug, "PROPORTION_SAD", -1.0)
    track_video(folder, tmp_path / "arc", um_per_px=1.0, base=(520, 400))
    arc = pd.read_csv(tmp_path / "arc" / "tracks.csv")
    assert np.abs(arc.bend_angle_deg - truth).max() > 4.0


def test_a_straight_end_s_direction_can_be_read_from_the_arc_before_it():
    """A fit that kept the plug's first edges bends less just before the
    plug: read ``arc_px`` before the start and carried on at the arc's
    curvature, the direction is the arc's; read at the start, it is short."""
    kappa, length, plug_px = 0.01, 300.0, 30.0
    start = length - plug_px
    s = np.linspace(0.0, length, 601)
    # the arc's heading, flattened over the last 10 px before the plug
    phi = kappa * np.minimum(s, start - 10.0) + 0.5 * kappa * np.clip(s - start + 10.0, 0, 10.0)
    z = np.concatenate([[0j], np.cumsum(np.exp(1j * 0.5 * (phi[1:] + phi[:-1])) * np.diff(s))])
    curve = fit_to_polyline(z, 0.0, n_coef=40)
    true = kappa * start
    assert abs(plug.straight_end(curve, plug_px).coef[-1] - true) > np.radians(2.0)
    read = plug.straight_end(curve, plug_px, 12.0).coef[-1]
    assert read == pytest.approx(true, abs=np.radians(0.3))


def test_a_straight_end_fits_a_curve_with_the_fewest_coefficients_its_joints_allow():
    # three section joints on 14 coefficients (the fewest a short tube gets):
    # the plug's joint costs two more, and the shape before it is kept
    arc = Curve(0j, 0.0, 300.0, np.linspace(0.0, 2.0, 14), (0.25, 0.5, 0.75))
    plugged = plug.straight_end(arc, 20.0)
    assert plugged.joints == (0.25, 0.5, 0.75, pytest.approx(280.0 / 300.0))
    assert plugged.coef.size >= 3 + 3 * 4
    s, z = resample(arc, 1.0)
    s2, z2 = resample(plugged, 1.0)
    before = s <= 270.0
    assert np.abs(z[before] - z2[: before.sum()]).max() < 0.1
