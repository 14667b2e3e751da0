"""Boundary checks shared by the model functions.

Every check raises ``ValueError`` whose message names the field and echoes the
offending value, so that a command-line user sees *what* is wrong in one line.
"""

from __future__ import annotations

import math

import numpy as np


def _first_bad(arr: np.ndarray, bad: np.ndarray) -> str:
    value = arr[bad].flat[0] if arr.ndim else arr[()]
    return repr(float(value))


def finite(name: str, value, *, dtype=np.float64) -> np.ndarray:
    """Return ``value`` as a float array, raising if any element is NaN or inf."""
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a number, got {value!r}") from exc
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(f"{name} must be finite, got {_first_bad(arr, bad)}")
    return arr


def positive(name: str, value) -> np.ndarray:
    """Finite and strictly positive."""
    arr = finite(name, value)
    bad = arr <= 0
    if bad.any():
        raise ValueError(f"{name} must be positive, got {_first_bad(arr, bad)}")
    return arr


def nonnegative(name: str, value) -> np.ndarray:
    """Finite and >= 0."""
    arr = finite(name, value)
    bad = arr < 0
    if bad.any():
        raise ValueError(f"{name} must be >= 0, got {_first_bad(arr, bad)}")
    return arr


def _real_scalar(value) -> bool:
    return isinstance(value, float) or (isinstance(value, int) and not isinstance(value, bool))


def nonnegative_float(name: str, value) -> float | None:
    """Fast path of :func:`nonnegative` for one real number.

    Returns ``value`` as a float when it is a Python or NumPy real scalar
    (``bool`` excluded) that is finite and >= 0; raises as :func:`nonnegative`
    when such a scalar is bad; returns None for anything else (arrays,
    sequences, strings …), which the caller then hands to :func:`nonnegative`.
    """
    if not _real_scalar(value):
        return None
    try:
        v = float(value)
    except OverflowError:  # an int beyond float range
        raise ValueError(f"{name} must be finite, got {value!r}") from None
    if 0.0 <= v < math.inf:
        return v
    return float(nonnegative(name, v))  # raises, with the usual message


def positive_float(name: str, value) -> float | None:
    """Fast path of :func:`positive` for one real number (as :func:`nonnegative_float`)."""
    if not _real_scalar(value):
        return None
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be finite, got {value!r}") from None
    if 0.0 < v < math.inf:
        return v
    return float(positive(name, v))  # raises, with the usual message


def positive_int(name: str, value, *, minimum: int = 1) -> int:
    """A whole number >= ``minimum`` (bools and floats with a fraction refused)."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    try:
        as_int = int(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a whole number, got {value!r}") from exc
    if as_int != value:
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    if as_int < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {as_int}")
    return as_int
