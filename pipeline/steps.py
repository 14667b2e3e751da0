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
