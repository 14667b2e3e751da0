"""Which side of a profile another layer of the tube leaves clear
(:func:`pipeline.refine.contact_sides`): the side whose edge still places the
tube where a coil runs beside or over it."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from pipeline import refine as refine_module
from pipeline.centreline import fit_to_polyline, resample
from pipeline.refine import TubeLook, contact_mask, contact_sides, edges_at, refine
from tests.pipeline.synthetic import axis_image

HW = 6.0
GAP = 0.5


def _polyline(*pieces):
    """Points GAP px apart along straight runs and arcs: each piece is
    ("line", length) or ("arc", radius, turn_deg) from the current heading."""
    z, heading = [0j], 0.0
    for piece in pieces:
        if piece[0] == "line":
            n = int(round(piece[1] / GAP))
            step = GAP * np.exp(1j * heading)
            z.extend(z[-1] + step * np.arange(1, n + 1))
        else:
            _, radius, turn = piece
            n = int(round(abs(np.radians(turn)) * radius / GAP))
            dphi = np.radians(turn) / n
            for _ in range(n):
                heading += dphi
                z.append(z[-1] + GAP * np.exp(1j * (heading - dphi / 2)))
    z = np.asarray(z)
    t = np.gradient(z)
    return z, t / np.abs(t)


def _sides(z, t, idx, reach=2.7 * HW + 2.0):
    normals = 1j * t[idx]
    return contact_sides(z, t, idx, reach=reach, gap=GAP, normals=normals, half_width=HW,
                         clear=4.0)


def test_a_coil_running_beside_the_tube_leaves_its_far_side_clear():
    # a hairpin: out along +x, round a half turn, back 14 px above (2.3 half-widths)
    z, t = _polyline(("line", 100.0), ("arc", 7.0, 180.0), ("line", 100.0))
    out = np.argmin(np.abs(z - 50))            # on the way out, at x = 50
    back = np.argmin(np.abs(z - (50 + 14j)))   # on the way back
    idx = np.array([out, back])
    contact, free = _sides(z, t, idx)
    assert contact.all()
    # each run's other layer lies on its left (+ normal): the right side is clear
    assert free.tolist() == [-1, -1]
    # the same as contact_mask says
    assert np.array_equal(contact, contact_mask(z, idx, reach=2.7 * HW + 2.0, gap=GAP,
                                                normals=1j * t[idx], half_width=HW))


def test_a_steep_crossing_or_layers_on_both_sides_leave_no_side_clear():
    # out along +x, a loop of radius 30 turning left 270 deg, then straight down
    # across the first run at x = 70, square to it
    z, t = _polyline(("line", 100.0), ("arc", 30.0, 270.0), ("line", 80.0))
    at = np.argmin(np.abs(z - 70))
    contact, free = _sides(z, t, np.array([at]))
    assert contact[0] and free[0] == 0
    # a run between two others (the middle coil of three): no side clear
    z, t = _polyline(("line", 100.0), ("arc", 7.0, 180.0), ("line", 100.0),
                     ("arc", 7.0, -180.0), ("line", 100.0))
    middle = np.argmin(np.abs(z - (50 + 14j)))
    contact, free = _sides(z, t, np.array([middle]))
    assert contact[0] and free[0] == 0
    # a coil too near to leave the far edge's search its reach: none either
    z, t = _polyline(("line", 100.0), ("arc", 1.5, 180.0), ("line", 100.0))
    contact, free = _sides(z, t, np.array([np.argmin(np.abs(z - 50))]))
    assert contact[0] and free[0] == 0


def test_no_other_layer_no_contact():
    z, t = _polyline(("line", 60.0), ("arc", 40.0, 90.0))
    contact, free = _sides(z, t, np.arange(0, z.size, 10))
    assert not contact.any() and not free.any()


#: The hairpin's tube's half-width, px.
PIN_HW = 8.0


def _hairpin_image(radius=1.1 * PIN_HW, run=200.0, step=0.05, base=40 - 100j):
    """A dark tube out along +x, round a half turn of ``radius``, and back:
    its two runs touch (2.2 half-widths apart). The frame, the axis points
    and the curve through them."""
    arc = np.pi * radius
    s = np.arange(0.0, 2 * run + arc + step / 2, step)
    kappa = np.where((s > run) & (s < run + arc), 1 / radius, 0.0)
    phi = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s))])
    z = base + np.concatenate([[0j], np.cumsum(np.exp(1j * 0.5 * (phi[1:] + phi[:-1]))
                                               * np.diff(s))])
    img = axis_image((200, 320), z, s, phi, PIN_HW, noise=0.003)
    return img, z, fit_to_polyline(z[::10], 0.0, n_coef=60)


def _off(curve, z):
    """RMS distance (px) of ``curve``'s points from the axis points ``z``."""
    _, pts = resample(curve, 1.0)
    d, _ = cKDTree(np.c_[z.real, z.imag]).query(np.c_[pts.real, pts.imag])
    return float(np.sqrt(np.mean(d**2)))


def test_touching_runs_are_placed_by_the_edges_they_leave_clear(monkeypatch):
    """Along a hairpin whose runs touch, every pair is left out (the other
    run lies within reach); the fit is held to the tube by
    its clear edges alone (4 px RMS off at the start)."""
    img, z, truth = _hairpin_image()
    look = TubeLook(-1, np.full(9, PIN_HW), 0.0)
    # (the look's strength: the pairs' where the runs lie apart, by the turn)
    strength = float(np.median(edges_at(img, truth, look, np.linspace(0.47, 0.53, 9)).strength))
    look = replace(look, strength=strength)
    start = truth.with_params(truth.coef * 1.02, truth.length)
    assert _off(start, z) > 3.0
    fit = refine(img, start, look, iterations=10, avoid_contact=True, fit_length=False)
    assert _off(fit.curve, z) < 0.3
    monkeypatch.setattr(refine_module, "SIDE_WEIGHT", 0.0)
    blind = refine(img, start, look, iterations=10, avoid_contact=True, fit_length=False)
    assert _off(blind.curve, z) > 1.0


def test_profiles_placed_by_a_clear_edge_count_as_covering_the_tube():
    """Along the touching hairpin nearly every profile is dropped for its
    pairs (the other run within reach), which alone would read as a tube
    hidden under itself (:data:`pipeline.track.MIN_COVERAGE`); the clear
    edges place the tube there, and count."""
    from pipeline.track import MIN_COVERAGE

    img, z, truth = _hairpin_image()
    look = TubeLook(-1, np.full(9, PIN_HW), 0.0)
    strength = float(np.median(edges_at(img, truth, look, np.linspace(0.47, 0.53, 9)).strength))
    fit = refine(img, truth, replace(look, strength=strength), iterations=4,
                 avoid_contact=True, fit_length=False)
    assert fit.usable.mean() < MIN_COVERAGE
    assert not (fit.sided & fit.usable).any()
    assert fit.sided.mean() > 0.5
    assert fit.coverage == pytest.approx((fit.usable | fit.sided).mean())
    assert fit.coverage >= 0.8


def test_a_relief_or_a_frame_without_contact_takes_no_single_edge(monkeypatch):
    img, z, truth = _hairpin_image()

    def refused(*args, **kwargs):
        raise AssertionError("an edge alone looked for")

    monkeypatch.setattr(refine_module, "side_edges", refused)
    # (no crossing handling asked: the pairs alone)
    refine(img, truth, TubeLook(-1, np.full(9, PIN_HW), 0.05), iterations=2, fit_length=False)
    # a relief's edges step alike: one alone tells no side
    refine(img, truth, TubeLook(0, np.full(9, PIN_HW), 0.05), iterations=2, avoid_contact=True,
           fit_length=False)
