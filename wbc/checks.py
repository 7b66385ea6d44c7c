"""Input checks shared by the core, the robots and the solvers.

:func:`all_finite` is the one meant for the control tick: it sums the vector as Python floats
(NaN and ±inf propagate through a sum), which costs a fraction of ``np.isfinite(x).all()`` or of
a BLAS dot product when, as in a control loop that shares the core with other work, numpy's
dispatch code and BLAS are not in the CPU caches. A finite vector whose sum overflows (entries
near 1e308) is reported as non-finite, which no physical quantity of a controller reaches.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import BoundsOrderError, NonFiniteError, ShapeError

_ndarray, _FLOAT = np.ndarray, np.dtype(float)


def all_finite(vector: np.ndarray) -> bool:
    """Whether a 1-D float array holds neither NaN nor ±inf (see the module docstring)."""
    return math.isfinite(sum(vector.tolist()))


def checked_array(value, shape: tuple[int, int], what: str,
                  allow_inf: bool = False) -> np.ndarray:
    """``value`` as a float array of ``shape = (rows, cols)``: a scalar fits ``(1, 1)`` and a
    1-D array of ``rows`` entries fits a column. Raises :class:`ShapeError` or
    :class:`NonFiniteError` naming ``what`` (NaN is always refused, ``±inf`` unless
    ``allow_inf``)."""
    # (a float array of the right shape, a reference set every tick, skips the conversions)
    arr = value if type(value) is _ndarray and value.dtype is _FLOAT else np.asarray(
        value, dtype=float)
    if arr.shape != shape:
        rows, cols = shape
        if arr.ndim == 0 and rows * cols == 1:
            arr = arr.reshape(1, 1)
        elif arr.ndim == 1 and cols == 1 and arr.shape[0] == rows:
            arr = arr.reshape(rows, 1)
        else:
            raise ShapeError(f"{what} expects shape {(rows,) if cols == 1 else shape}, "
                             f"got {np.shape(value)}")
    check_finite(arr, what, allow_inf)
    return arr


def check_finite(arr: np.ndarray, what: str, allow_inf: bool = False) -> None:
    """Raise :class:`NonFiniteError` naming ``what`` if ``arr`` holds NaN (or inf)."""
    if allow_inf:
        if np.isnan(arr).any():
            raise NonFiniteError(f"{what} contains NaN")
    elif not all_finite(arr.reshape(-1)):
        raise NonFiniteError(f"{what} contains NaN or inf")


def check_bounds_order(lower: np.ndarray, upper: np.ndarray, what: str) -> None:
    """Raise :class:`BoundsOrderError` naming the first index where ``lower > upper``."""
    bad = np.flatnonzero(np.asarray(lower) > np.asarray(upper))
    if bad.size:
        i = int(bad[0])
        raise BoundsOrderError(f"{what}: lower > upper at index {i} "
                               f"({np.ravel(lower)[i]} > {np.ravel(upper)[i]})")
