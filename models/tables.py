"""Chain evaluators for runs of equally spaced points, from small exponential tables.

When *every* point of a run of equally spaced points is wanted (all vertices of
a segment chain, or an arc chain on a uniform grid), the headings along one
section form an arithmetic progression ``α + mβ``, and the cost of the direct
evaluators of :mod:`models.shape` is dominated by one complex exponential per
point. Here such runs are evaluated from two small tables per section,
``√M`` "giant" steps (``a``) and ``√M`` "baby" steps (``b``, ``m = aB + b``),
and one complex product per point: about ``2√M`` transcendental calls
instead of ``M``.

* :func:`cis_runs` — ``e^{i(α + mβ)} = e^{i(α + aBβ)}·e^{ibβ}``; the segment
  vectors of all vertices of a line-segment chain (Eq. 9),
  :func:`segment_chain_vertices`;
* :func:`arc_chain_grid` — the piecewise Euler–Bernoulli arcs (Eqs. 1–8) on a
  uniform grid: each arc is cut at its row start and the chord splits as
  ``c(D + δ) = c(D) + e^{iκD} c(δ)``, each piece in the sinc form of
  :func:`models.shape.arc_chain`.

Each point is still one rounding of exactly evaluated factors — nothing is
accumulated, unlike a rotation recurrence — and both factors turn the same
way, so small deflections keep their *relative* accuracy (the stiff limit).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .shape import _exclusive_cumsum, arc_starts


class Runs(NamedTuple):
    """Layout of runs of points along which an angle grows arithmetically.

    Run ``i`` holds ``lengths[i]`` points ``m = 0 … lengths[i] − 1`` (runs are
    concatenated in order). Its values live in a dense table of ``rows`` giant
    steps × ``baby`` baby steps (``m = a·baby + b``); ``flat`` picks the points
    out of the flattened table (None when the table holds exactly the points).

    Attributes
    ----------
    lengths : (n,) int ndarray
    baby : int
        Baby steps per giant step, B ≈ √(longest run).
    baby_m : (B,) float ndarray
        0, 1, …, B − 1.
    row_run : (R,) int ndarray
        Run of each giant row.
    row_m : (R,) float ndarray
        Index ``m`` of the first point of each row (a·B).
    flat : (Σ lengths,) int ndarray or None
        Position of every point in the flattened (R·B) table.
    """

    lengths: np.ndarray
    baby: int
    baby_m: np.ndarray
    row_run: np.ndarray
    row_m: np.ndarray
    flat: np.ndarray | None


def progression_runs(lengths) -> Runs:
    """The :class:`Runs` layout for runs of the given lengths (some may be 0)."""
    lengths = np.asarray(lengths, dtype=np.int64)
    # B baby steps per run and ⌈M_i/B⌉ giant rows cost Σ (B + ⌈M_i/B⌉) exponentials:
    # take the B that minimises it (near √M for one run)
    longest = max(int(lengths.max()), 1)
    used = int(np.count_nonzero(lengths))
    babies = np.arange(1, min(longest, 2 * int(np.sqrt(longest)) + 2) + 1)  # B* ≤ √longest
    cost = used * babies + (-(-lengths[:, None] // babies)).sum(axis=0)
    baby = int(babies[np.argmin(cost)])
    rows = -(-lengths // baby)
    first_row = np.cumsum(rows) - rows
    row_run = np.repeat(np.arange(lengths.size), rows)
    row_m = ((np.arange(rows.sum()) - first_row[row_run]) * baby).astype(float)
    point_run = np.repeat(np.arange(lengths.size), lengths)
    m = np.arange(lengths.sum()) - (np.cumsum(lengths) - lengths)[point_run]
    flat = first_row[point_run] * baby + m
    if flat.size == rows.sum() * baby:  # no padding: the table is the points
        flat = None
    layout = Runs(lengths, baby, np.arange(baby, dtype=float), row_run, row_m, flat)
    for arr in layout:
        if isinstance(arr, np.ndarray):
            arr.flags.writeable = False
    return layout


def run_tables(alpha, beta, runs: Runs):
    """Giant and baby factors of ``e^{i(α + mβ)}`` on the rows of ``runs``.

    Returns
    -------
    giant : (..., R) complex ndarray
        ``e^{i(α + a·B·β)}`` of each row's run.
    baby : (..., R or 1, B) complex ndarray
        ``e^{i b β}`` of each row's run (one shared row when there is one run).
    """
    baby = np.exp(1j * (beta[..., :, None] * runs.baby_m))
    if beta.shape[-1] > 1:
        baby = baby.take(runs.row_run, axis=-2)
        alpha = alpha.take(runs.row_run, axis=-1)
        beta = beta.take(runs.row_run, axis=-1)
    giant = np.exp(1j * (alpha + beta * runs.row_m))
    return giant, baby


def cis_runs(alpha, beta, runs: Runs, scale=None):
    """``scale_i · e^{i(α_i + m β_i)}`` at every point of every run.

    Parameters
    ----------
    alpha, beta : (..., n) ndarray
        Start angle and step of each run, rad.
    runs : Runs
    scale : (..., n) ndarray, optional
        A factor per run (e.g. a segment length).

    Returns
    -------
    (..., Σ lengths) complex ndarray
    """
    giant, baby = run_tables(alpha, beta, runs)
    if scale is not None:
        giant = giant * (scale.take(runs.row_run, axis=-1) if scale.shape[-1] > 1 else scale)
    dense = giant[..., :, None] * baby
    dense = dense.reshape(dense.shape[:-2] + (-1,))
    return dense if runs.flat is None else dense.take(runs.flat, axis=-1)


#: |κ| below which an arc is treated as straight in :func:`arc_chain_grid`
#: (1/µm), so that 2/κ stays finite: the bend dropped within such an arc is
#: below 1e-240 rad over any length met here (positions move by < 1e-230 µm).
_TINY_CURVATURE = 1e-250


class ArcGrid(NamedTuple):
    """Uniformly spaced points on a chain of arcs, laid out for :func:`arc_chain_grid`.

    Attributes
    ----------
    s : (M,) ndarray
        Arc lengths of the points, µm.
    d : (M,) ndarray
        Distance of each point from the start of its arc, µm.
    point_arc : (M,) int ndarray
        Arc of each point.
    runs : Runs
        Points per arc, as table rows of ``runs.baby`` points.
    row_d : (R,) ndarray
        Distance of each row's first point from the start of its arc, µm.
    baby_d : (B,) ndarray
        Distance of each point from its row's first point, µm (b·h).
    d_table : (R, B) ndarray
        ``d`` laid out like the table (0 in its padding).
    blocks : tuple of (int, int, int, int, int)
        Per arc holding points: (arc, first point, first row, whole rows,
        points in a last partial row).
    """

    s: np.ndarray
    d: np.ndarray
    point_arc: np.ndarray
    runs: Runs
    row_d: np.ndarray
    baby_d: np.ndarray
    d_table: np.ndarray
    blocks: tuple


def arc_grid(lengths, n_points: int) -> ArcGrid:
    """The :class:`ArcGrid` of ``n_points`` points from 0 to ``sum(lengths)``."""
    lengths = np.asarray(lengths, dtype=float)
    starts = _exclusive_cumsum(lengths)
    total = float(starts[-1] + lengths[-1])
    s = np.linspace(0.0, total, n_points)
    point_arc = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, lengths.size - 1)
    d = s - starts[point_arc]
    counts = np.bincount(point_arc, minlength=lengths.size)
    first = np.cumsum(counts) - counts
    d0 = np.where(counts > 0, d[np.minimum(first, n_points - 1)], 0.0)
    runs = progression_runs(counts)
    step = total / (n_points - 1)
    d_table = np.zeros(runs.row_m.size * runs.baby)
    d_table[np.arange(n_points) if runs.flat is None else runs.flat] = d
    rows = -(-counts // runs.baby)
    first_row = np.cumsum(rows) - rows
    blocks = tuple((i, int(first[i]), int(first_row[i]), int(counts[i] // runs.baby),
                    int(counts[i] % runs.baby)) for i in np.flatnonzero(counts))
    grid = ArcGrid(s, d, point_arc, runs, d0[runs.row_run] + runs.row_m * step,
                   runs.baby_m * step, d_table.reshape(-1, runs.baby), blocks)
    for arr in grid:
        if isinstance(arr, np.ndarray):
            arr.flags.writeable = False
    return grid


def _chords(kappa, two_over_k, length):
    """Chords ``length·sinc(κ length/2)·e^{iκ length/2}`` and ``e^{iκ length/2}``.

    ``length·sinc(x) = (2/κ)·sin x`` with ``x = κ length/2``: one cos and one
    sin give both factors. Straight arcs (``two_over_k`` = 0) get 0 here; the
    caller puts them back.
    """
    half = np.multiply(kappa, 0.5 * length)
    turn = np.empty(half.shape, dtype=complex)
    np.cos(half, out=turn.real)
    np.sin(half, out=turn.imag)
    np.multiply(turn.imag, two_over_k, out=half)  # (2/κ)·sin x, in place of x
    return turn * half, turn


#: Shapes × points handled per chunk by :func:`arc_chain_grid` (16 MB of
#: complex points; the chunk's tables stay near 1 MB, so a call needs little
#: memory beyond its result, and the allocator does not return and re-fault
#: pages between calls).
_CHUNK_ELEMENTS = 1 << 20


def _row_tables(kappa, two_over_k, rot, z_start, row_d):
    """Per table row: ``e^{i(φ + κD)}`` and the point ``z + e^{iφ} c(D)`` at its start."""
    lead, turn = _chords(kappa, two_over_k, row_d)
    row_lead = rot * lead
    row_lead += z_start
    return rot * (turn * turn), row_lead


#: From this many shapes on, :func:`arc_chain_grid` writes every arc's points
#: straight into the output (a few array calls per arc); below it, one gather
#: of the tables and one pick of the points (fewer calls). Same formulas;
#: positions agree to the last bit or two (NumPy's complex products take
#: fused-multiply-add SIMD or scalar kernels depending on the array layout),
#: headings exactly.
_BLOCKWISE_MIN_SHAPES = 32


def arc_chain_grid(kappa, lengths, grid: ArcGrid):
    """:func:`models.shape.arc_chain` at the points of a uniform :class:`ArcGrid`, by run tables.

    Point ``m = aB + b`` of arc i lies ``D_a = d0 + aBh`` into the arc plus
    ``δ_b = bh`` more. An arc is cut anywhere into two arcs of the same
    curvature, so its chord splits exactly::

        z = z_i + e^{iφ_i} c(D_a) + e^{i(φ_i + κ D_a)} c(δ_b),
        c(ℓ) = ℓ·sinc(κℓ/2)·e^{iκℓ/2} = (2/κ)·sin(κℓ/2)·e^{iκℓ/2}

    — every piece in the cancellation-free sinc form of :func:`models.shape.arc_chain`,
    evaluated once per table row (``≈√M`` per arc) or per baby step
    (``≈√M``), then one complex multiply-add per point. For a curvature of
    one sign both chords turn the same way, so nothing cancels and small
    deflections keep their relative accuracy. Straight arcs (|κ| < 1e-250
    /µm, e.g. p = 0) take ``z_i + e^{iφ_i} d`` exactly as :func:`models.shape.arc_chain`.
    The heading is ``φ_i + κ_i d``, also as there.

    The work is laid out points-major (shapes along the fastest axis), so
    every array operation runs over long contiguous rows; the results are
    returned as transposed views of that layout (not C-contiguous).

    Returns
    -------
    z : (..., M) complex ndarray
    phi : (..., M) ndarray
    """
    kappa = np.asarray(kappa, dtype=float)
    batch, n = kappa.shape[:-1], kappa.shape[-1]
    count = int(np.prod(batch, dtype=np.int64))
    # points-major: one row per arc (or table row), one column per shape
    k = np.ascontiguousarray(kappa.reshape(count, n).T)
    phi0, z0 = arc_starts(k, np.asarray(lengths, dtype=float)[:, None], axis=0)
    rot = np.exp(1j * phi0)
    straight = np.abs(k) < _TINY_CURVATURE
    two_over_k = 2.0 / np.where(straight, 1.0, k)
    two_over_k[straight] = 0.0
    runs = grid.runs
    m = grid.d.size
    if count >= _BLOCKWISE_MIN_SHAPES or runs.flat is None:
        # arc by arc, for a chunk of shapes at a time: the tables stay small
        # (no large temporaries) and the points are written in place
        z = np.empty((m, count), dtype=complex)
        phi = np.empty((m, count))
        b_len = runs.baby
        width = max(64, _CHUNK_ELEMENTS // m)
        for c0 in range(0, count, width):
            cols = slice(c0, min(c0 + width, count))
            w = cols.stop - cols.start
            for i, first, row, whole, rest in grid.blocks:
                k_i, tok_i = k[i, cols], two_over_k[i, cols]
                baby, _ = _chords(k_i, tok_i, grid.baby_d[:, None])
                rows = slice(row, row + whole + (rest > 0))
                row_turn, row_lead = _row_tables(k_i, tok_i, rot[i, cols], z0[i, cols],
                                                 grid.row_d[rows, None])
                if whole:
                    block = z[first:first + whole * b_len, cols].reshape(whole, b_len, w)
                    np.multiply(baby, row_turn[:whole, None, :], out=block)
                    block += row_lead[:whole, None, :]
                if rest:
                    part = z[first + whole * b_len:first + whole * b_len + rest, cols]
                    np.multiply(baby[:rest], row_turn[whole], out=part)
                    part += row_lead[whole]
                pts = slice(first, first + whole * b_len + rest)
                np.multiply(grid.d[pts, None], k_i, out=phi[pts, cols])
                phi[pts, cols] += phi0[i, cols]
    else:
        # all arcs at once: gather the tables by row, pick the points at the end
        rows = runs.row_run
        baby, _ = _chords(k[:, None, :], two_over_k[:, None, :], grid.baby_d[:, None])
        row_turn, row_lead = _row_tables(k[rows], two_over_k[rows], rot[rows], z0[rows],
                                         grid.row_d[:, None])
        z = np.multiply(baby[rows] if n > 1 else baby, row_turn[:, None, :])
        z += row_lead[:, None, :]
        z = np.take(z.reshape(-1, count), runs.flat, axis=0)
        phi = k[rows][:, None, :] * grid.d_table[:, :, None]
        phi += phi0[rows][:, None, :]
        phi = np.take(phi.reshape(-1, count), runs.flat, axis=0)
    if straight.any():
        for i in np.flatnonzero(straight.any(axis=1)):
            cols = np.flatnonzero(straight[i])
            pts = np.flatnonzero(grid.point_arc == i)
            if pts.size:
                z[pts[:, None], cols] = z0[i, cols] + rot[i, cols] * grid.d[pts, None]
    return z.T.reshape(batch + (-1,)), phi.T.reshape(batch + (-1,))


def segment_chain_vertices(theta, counts, seg_length, section, j, runs: Runs | None = None):
    """Every vertex of a segment chain: exact headings, positions by summation.

    When all N + 1 vertices are wanted the output is O(N) anyway: the segment
    vectors ``ℓ_i e^{i(Φ_i + mθ_i)}`` come from :func:`cis_runs` (about 2√n_i
    complex exponentials per section, one complex product per segment) and
    the positions from a running sum. Headings are the exact
    ``Φ_i + (j + 1)θ_i`` (never a running sum of tilts), so they carry no
    accumulated rounding; positions carry ~√N·ε relative rounding (1e-13 at
    N = 10⁶).

    Parameters are as for :func:`models.shape.segment_chain`, with ``section`` and ``j``
    locating vertex k ≥ 1 at the end of segment k, and vertex 0 (the base) as
    (0, 0), carrying the first segment's heading. ``runs`` is
    ``progression_runs(counts)`` (computed when not given).
    """
    theta = np.asarray(theta, dtype=float)
    runs = progression_runs(counts) if runs is None else runs
    phi_start = _exclusive_cumsum(counts * theta)
    steps = cis_runs(phi_start + theta, theta, runs, scale=seg_length)
    z = np.empty(steps.shape[:-1] + (steps.shape[-1] + 1,), dtype=complex)
    z[..., 0] = 0.0
    np.cumsum(steps, axis=-1, out=z[..., 1:])
    phi = phi_start.take(section, axis=-1) + (j + 1) * theta.take(section, axis=-1)
    return z, phi
