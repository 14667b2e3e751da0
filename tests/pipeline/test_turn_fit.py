"""Where the base vote moves the base forward along the held-back frames'
curves, their tangents there are fitted over a stretch past it (:func:`pipeline.track._cut_at`)."""

import numpy as np
import pytest

from pipeline.centreline import Curve, basis_of, make_basis
from pipeline.track import _cut_at


def _curve(phi_of_s, length: float = 400.0, n: int = 40) -> Curve:
    """A curve from the origin along +x whose tangent angle (rad, less the
    base's) is ``phi_of_s`` (px of arc), least-squares on its spline."""
    basis = make_basis(n, basis_of(Curve(0j, 0.0, length, np.zeros(n))).n_grid)
    s = basis.u * length
    coef, *_ = np.linalg.lstsq(basis.values, phi_of_s(s), rcond=None)
    return Curve(0j, 0.0, length, coef)


@pytest.mark.parametrize("kappa", [0.0, 1e-3, 4e-3])
def test_the_fitted_tangent_is_the_arc_s_own(kappa):
    curve = _curve(lambda s: kappa * s)
    at, phi = _cut_at(curve, 60.0 + 0j, reach=40.0)
    # (the curve gets 60 px along its base axis a little later, the more it bends)
    assert phi == pytest.approx(kappa * at, abs=2e-4)
    assert _cut_at(curve, 60.0 + 0j)[1] == pytest.approx(kappa * at, abs=2e-4)


def test_a_wiggle_inside_the_holder_does_not_turn_the_fitted_tangent():
    # a straight stretch whose spline wiggles (+-5 deg over 40 px, as between
    # two joints inside a clear holder): the tangent at a point is up to 5 deg
    # off, the one fitted over a wavelength well within a degree
    wiggle = np.radians(5.0)
    curve = _curve(lambda s: wiggle * np.sin(2 * np.pi * s / 40.0) * (s < 120))
    point = [abs(_cut_at(curve, x + 0j)[1]) for x in (30.0, 50.0, 70.0)]
    fitted = [abs(_cut_at(curve, x + 0j, reach=40.0)[1]) for x in (30.0, 50.0, 70.0)]
    assert max(point) > np.radians(3.0)
    assert max(fitted) < np.radians(1.0)
