"""The chain evaluators of models.shape and models.tables: tables against direct forms."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models import PAPER_SAMPLES, Sample, Section, eb_curvatures, eb_shape
from models.shape import arc_chain, sinc
from models.tables import (
    _BLOCKWISE_MIN_SHAPES,
    arc_chain_grid,
    arc_grid,
    cis_runs,
    progression_runs,
)

S1 = PAPER_SAMPLES[1]


def test_sinc_is_one_at_zero_and_exact_for_tiny_arguments():
    x = np.array([0.0, -0.0, 1e-300, 1e-8, 1.0, -2.0])
    expected = np.array([1.0, 1.0, 1.0, 1.0, np.sin(1.0), np.sin(2.0) / 2.0])
    np.testing.assert_allclose(sinc(x), expected, rtol=1e-16)
    assert sinc(0.0) == 1.0 and sinc(np.array(0.0)) == 1.0


@settings(max_examples=60, deadline=None)
@given(lengths=st.lists(st.integers(0, 300), min_size=1, max_size=5).filter(any),
       scale=st.sampled_from([1e-12, 1e-6, 1e-2, 1.0, 30.0]),
       seed=st.integers(0, 2**32 - 1))
def test_cis_runs_match_direct_exponentials(lengths, scale, seed):
    rng = np.random.default_rng(seed)
    runs = progression_runs(lengths)
    n = len(lengths)
    alpha = rng.uniform(0, 1, (3, n)) * scale
    beta = rng.uniform(0, 1, (3, n)) * scale / max(lengths)
    run = np.repeat(np.arange(n), lengths)
    m = np.concatenate([np.arange(k) for k in lengths])
    angle = alpha[:, run] + m * beta[:, run]
    got = cis_runs(alpha, beta, runs)
    assert got.shape == (3, sum(lengths))
    np.testing.assert_allclose(got, np.exp(1j * angle), rtol=0, atol=4e-16 * (1 + angle.max()))
    # both factors turn the same way: sin keeps its relative accuracy at small angles
    small = angle < 1.0
    np.testing.assert_allclose(got.imag[small], np.sin(angle[small]), rtol=1e-15, atol=1e-300)


def _samples():
    equal = Sample("equal", 9000.0, 235.0, (Section(0.5, 100.0, 100.0), Section(0.3, 134.0, 67.0),
                                            Section(0.2, 80.0, 80.0)))
    tiny = Sample("tiny", 9000.0, 235.0, (Section(0.5, 134.0, 67.0), Section(1e-6, 30.0, 200.0),
                                          Section(0.5 - 1e-6, 166.0, 72.0)))
    return [S1, PAPER_SAMPLES[2], PAPER_SAMPLES[8], equal, tiny]


@pytest.mark.parametrize("sample", _samples(), ids=lambda s: s.name)
@pytest.mark.parametrize("n_points", [16, 17, 201, 1000])
@pytest.mark.parametrize("n_shapes", [1, 5, _BLOCKWISE_MIN_SHAPES + 3])
def test_grid_tables_match_the_direct_arc_chain(sample, n_points, n_shapes):
    lengths = sample.section_lengths_um
    p = np.r_[0.0, 1e-300, np.geomspace(1e-9, 2.0, max(n_shapes - 2, 1))][:n_shapes]
    kappa = eb_curvatures(sample, p)
    grid = arc_grid(lengths, n_points)
    z, phi = arc_chain_grid(kappa, lengths, grid)
    z_ref, phi_ref = arc_chain(kappa, lengths, grid.s)
    assert z.shape == phi.shape == (n_shapes, n_points)
    scale = sample.length_um
    np.testing.assert_allclose(z, z_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(phi, phi_ref, rtol=1e-14, atol=1e-300)
    # deflections keep their relative accuracy down to tiny bends (1e-9 MPa here);
    # below |κ| = 1e-250 /µm (p = 1e-300 MPa) an arc is taken as straight
    for row in range(2, n_shapes):
        y_max = np.abs(z_ref[row].imag).max()
        assert np.abs(z[row].imag - z_ref[row].imag).max() <= 1e-12 * y_max
    # p = 0 is exactly straight, bit for bit as in the direct form
    assert np.all(z[0].imag == 0) and np.all(phi[0] == 0)
    np.testing.assert_array_equal(z[0].real, z_ref[0].real)
    assert np.abs(z[:2].imag).max() < 1e-290


def test_one_shape_and_the_same_shape_in_a_batch_agree():
    p = np.linspace(0.0, 0.3, 2 * _BLOCKWISE_MIN_SHAPES)
    batch = eb_shape(S1, p[:, None], E_mpa=np.array([0.7, 1.4, 9.0]), n_points=201)
    for i in (0, 1, 17, len(p) - 1):
        for k, E in enumerate((0.7, 1.4, 9.0)):
            one = eb_shape(S1, p[i], E_mpa=E, n_points=201)
            # headings are real arithmetic: identical; positions differ at most in the
            # last bits (NumPy's complex products use FMA in their SIMD kernels)
            np.testing.assert_array_equal(one.phi_rad, batch.phi_rad[i, k])
            np.testing.assert_allclose(one.x_um, batch.x_um[i, k], rtol=0,
                                       atol=4e-16 * S1.length_um)
            np.testing.assert_allclose(one.y_um, batch.y_um[i, k], rtol=0,
                                       atol=4e-16 * S1.length_um)


def test_runs_layout_covers_every_point_once():
    runs = progression_runs([430, 240, 0, 230, 100])
    assert runs.flat is not None and runs.flat.size == 1000
    assert np.unique(runs.flat).size == 1000
    assert runs.flat.max() < runs.row_m.size * runs.baby
    exact = progression_runs([9])
    assert exact.baby == 3 and exact.flat is None  # 3 × 3: the table is the points
