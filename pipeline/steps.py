"""The best single step along a sequence: a two-level least-squares fit.

Where a pipette ends and the tube begins, where a tube's width steps at a
section joint, where a skeleton's width steps from pipette to tube: each is
found as the split of a sequence of measurements into a stretch before and
one after, each at its own level, that leaves the least squared residual.
"""

from __future__ import annotations

import numpy as np


def two_level_fit(values) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two-level least-squares fit of ``values`` at every split.

    Split ``k`` (1 … n−1) puts ``values[:k]`` at one level (their mean) and
    ``values[k:]`` at another; computed for all splits at once from running
    sums.

    Parameters
    ----------
    values : (n,) array_like
        The sequence, n ≥ 2 (any unit).

    Returns
    -------
    sse : (n − 1,) ndarray
        Residual sum of squares of split ``k`` at ``sse[k − 1]`` (the unit of
        ``values``, squared).
    before, after : (n − 1,) ndarray
        The two levels of each split.
    """
    x = np.asarray(values, dtype=float)
    n = x.size
    k = np.arange(1, n)
    c1 = np.cumsum(x)
    c2 = np.cumsum(x**2)
    head, head2 = c1[:-1], c2[:-1]
    before = head / k
    after = (c1[-1] - head) / (n - k)
    sse = (head2 - head * before) + (c2[-1] - head2 - (c1[-1] - head) * after)
    return sse, before, after


def trend_level_fit(values) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares fit of a straight trend, then a level, at every split.

    Split ``k`` (2 … n−1) fits ``values[:k]`` with a straight line in the
    index and ``values[k:]`` with their mean: a pipette pulled to a taper,
    narrowing towards its mouth, then the tube's constant width. Computed
    for all splits at once from running sums, as :func:`two_level_fit`.

    Parameters
    ----------
    values : (n,) array_like
        The sequence, n ≥ 3 (any unit).

    Returns
    -------
    sse : (n − 2,) ndarray
        Residual sum of squares of split ``k`` at ``sse[k − 2]`` (the unit of
        ``values``, squared).
    end, after : (n − 2,) ndarray
        The trend's value at the last index before each split, and the level
        after it.
    """
    y = np.asarray(values, dtype=float)
    n = y.size
    x = np.arange(n, dtype=float)
    k = np.arange(2, n)
    sx, sxx = np.cumsum(x)[k - 1], np.cumsum(x * x)[k - 1]
    c1, c2 = np.cumsum(y), np.cumsum(y * y)
    sy, syy, sxy = c1[k - 1], c2[k - 1], np.cumsum(x * y)[k - 1]
    # centred sums of the first k points: the line's slope and its residual
    vxx = sxx - sx * sx / k
    vxy = sxy - sx * sy / k
    vyy = syy - sy * sy / k
    slope = vxy / vxx
    head_sse = np.maximum(vyy - slope * vxy, 0.0)
    end = sy / k + slope * (k - 1 - sx / k)
    tail, tail2 = c1[-1] - sy, c2[-1] - syy
    after = tail / (n - k)
    return head_sse + np.maximum(tail2 - tail * after, 0.0), end, after
