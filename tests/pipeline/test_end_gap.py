"""A fit whose end runs on past the tube's side edges (over the background,
to dust or a blob taken for the tube's end) is not accepted."""
import numpy as np
import pytest

from pipeline import track
from pipeline.centreline import fit_to_polyline
from pipeline.refine import Refined, TubeLook
from tests.pipeline.synthetic import arc_axis

HW = 8.0


def _curve(length):
    z, _ = arc_axis(0j, 0.0, length, 0.0)
    return fit_to_polyline(z, 0.0, n_coef=12)


def _refined(valid, usable=None, in_view=None, length=200.0):
    u = np.linspace(0.01, 0.99, valid.size)
    return Refined(_curve(length), u, np.full(valid.size, 2 * HW),
                   valid, 0.1, True, 3, 0.05, usable, in_view=in_view)


def test_a_fit_whose_end_runs_on_without_the_tubes_edges_is_not_accepted():
    look = TubeLook(-1, np.full(5, HW), 0.05)
    valid = np.ones(100, bool)
    assert track._good(_refined(valid), look)
    # the last 6 profiles (12 px, 1.5 half-widths) without edges: a round end
    valid[-6:] = False
    assert _refined(valid).end_gap_px == pytest.approx(6 * 0.98 / 99 * 200.0)
    assert track._good(_refined(valid), look)
    # the last 16 (32 px, 4 half-widths): run on over the background
    valid[-16:] = False
    assert not track._good(_refined(valid), look)
    # ... unless a crossing dropped profiles there (the spline bridges it)
    usable = np.ones(100, bool)
    usable[-3:] = False
    assert _refined(valid, usable).end_gap_px == 0.0
    assert track._good(_refined(valid, usable), look)
    # ... or where the last profiles reach the image's border (the view check's job)
    in_view = np.ones(100, bool)
    in_view[-2:] = False
    assert _refined(valid, in_view=in_view).end_gap_px == 0.0
