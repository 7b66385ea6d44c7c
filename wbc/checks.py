"""Input checks shared by the core, the robots and the solvers.

:func:`all_finite` is the one meant for the control tick: it sums the vector as Python floats
(NaN and ±inf propagate through a sum), which costs a fraction of ``np.isfinite(x).all()`` or of
a BLAS dot product when, as in a control loop that shares the core with other work, numpy's
dispatch code and BLAS are not in the CPU caches. A finite vector whose sum overflows (entries
near 1e308) is reported as non-finite, which no physical quantity of a controller reaches.

The constructors of tasks, stacks and robots check every argument with the helpers below, so that
a bad argument is a :class:`~wbc.WbcError` naming it when the object is built — never numpy's,
CasADi's or pinocchio's own exception, never at the first tick:

* :func:`as_float_array` — real numbers only (no ``str``, ``None``, ``dict``, complex, CasADi
  symbol, ragged list), as a float array;
* :func:`checked_array` — that, of a given shape, finite (or ``±inf`` where allowed);
* :func:`checked_matrix`, :func:`checked_vector` — a coefficient matrix, a vector of given length
  (a scalar is broadcast, unless ``broadcast=False``); :func:`checked_2d` — a matrix of any
  shape ``(m, n)``, empty ones included (the closed forms' Jacobians);
* :func:`checked_bounds` — lower and upper bounds of given length, ``±inf`` for none, ordered;
* :func:`checked_number` — one real number in a range (gains, periods, scales, lengths);
  :func:`checked_scalar` — the same given as a number or a 0-d array, any other shape a
  :class:`ShapeError`; :func:`checked_integer` — a count;
* :func:`checked_weights` — a cost weight: a number, one per row, or a CasADi SX expression of the
  stack's parameters (evaluated every tick);
* :func:`checked_name`, :func:`checked_shape`, :func:`check_robot`, :func:`check_frame`,
  :func:`check_symbols` — names, parameter shapes, robots, a robot's frame names, the symbols of
  an expression; :func:`checked_flag` — a switch (``True`` / ``False``); :func:`checked_path`
  — a file path (``str`` or ``os.PathLike``);
* :func:`check_pose` — a homogeneous transform whose rotation is one (on the control tick:
  ≈ 0.7 µs on a 4 × 4, pure Python floats).
"""

from __future__ import annotations

import math
import numbers
import os
from typing import Literal, overload

import casadi as ca
import numpy as np

from .errors import (
    BoundsOrderError,
    InvalidValueError,
    NonFiniteError,
    ShapeError,
    UnknownNameError,
)

_ndarray, _FLOAT = np.ndarray, np.dtype(float)
_REAL_KINDS = "iuf"  # numpy dtype kinds of real numbers (booleans are not numbers here)
#: tolerance of :func:`check_pose`: ``‖(c₀ᵀc₀ − 1, c₁ᵀc₁ − 1, c₀ᵀc₁, c₀ × c₁ − c₂)‖₂`` [-]
ROTATION_TOL = 1e-6
_hypot = math.hypot
#: the largest size (entries) of a parameter or a count (rows, joints, wheels) the checks accept
MAX_SIZE = 10 ** 6


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
    arr = value if type(value) is _ndarray and value.dtype is _FLOAT else as_float_array(
        value, what)
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


def _kind(value) -> str:
    """A short description of ``value``'s type for messages."""
    return f"{type(value).__name__} {value!r}"[:80]


def as_float_array(value, what: str) -> np.ndarray:
    """``value`` as a float array. Raises :class:`InvalidValueError` naming ``what`` unless it
    holds real numbers (a ``str``, ``None``, a ``dict``, a complex number, a CasADi symbol are
    refused; booleans too), :class:`ShapeError` for a ragged nesting of lists."""
    if type(value) is _ndarray and value.dtype is _FLOAT:
        return value
    if isinstance(value, (ca.SX, ca.MX)):
        raise InvalidValueError(f"{what} must be numbers, got a CasADi {type(value).__name__} "
                                "expression")
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise InvalidValueError(f"{what} must be numbers, got {_kind(value)}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as err:  # ragged lists, objects numpy cannot read
        raise ShapeError(f"{what} is not an array of numbers ({err})") from None
    if arr.dtype.kind not in _REAL_KINDS:
        raise InvalidValueError(f"{what} must be real numbers, got {arr.dtype} "
                                f"({_kind(value)})")
    return arr.astype(float, copy=False)


def checked_matrix(value, what: str) -> np.ndarray:
    """A finite float matrix (a 1-D array is one row) with at least one column; raises
    :class:`ShapeError` / :class:`NonFiniteError` / :class:`InvalidValueError` naming ``what``."""
    arr = as_float_array(value, what)
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2 or arr.shape[1] == 0:
        raise ShapeError(f"{what} must be a matrix with at least one column, got shape "
                         f"{np.shape(value)}")
    check_finite(arr, what)
    return arr


def checked_vector(value, size: int, what: str, allow_inf: bool = False,
                   broadcast: bool = True) -> np.ndarray:
    """A float vector of ``size`` entries, in the caller's units (a scalar is broadcast, a row
    or column flattened; with ``broadcast=False`` only a 1-D array of ``size`` entries is
    accepted, a float one returned as is, not copied); NaN refused, ``±inf`` unless
    ``allow_inf``. Raises :class:`ShapeError` / :class:`NonFiniteError` /
    :class:`InvalidValueError` naming ``what``."""
    arr = as_float_array(value, what)
    if broadcast:
        if arr.ndim == 0:
            arr = np.full(size, float(arr))
        elif arr.ndim == 2 and 1 in arr.shape:
            arr = arr.reshape(-1)
    if arr.shape != (size,):
        raise ShapeError(f"{what} must have shape ({size},){' or be a scalar' if broadcast else ''}"
                         f", got {np.shape(value)}")
    check_finite(arr, what, allow_inf)
    return arr


def checked_2d(value, what: str) -> np.ndarray:
    """A finite float array of exactly two dimensions ``(m, n)``, in the caller's units; ``m``
    or ``n`` may be 0 (a level without rows). Unlike :func:`checked_matrix` a 1-D array is not
    read as a row: it is a :class:`ShapeError`. Raises :class:`ShapeError` /
    :class:`NonFiniteError` / :class:`InvalidValueError` naming ``what``."""
    arr = as_float_array(value, what)
    if arr.ndim != 2:
        raise ShapeError(f"{what} must be a 2-D array (m, n), got shape {arr.shape}")
    check_finite(arr, what)
    return arr


def checked_bounds(lower, upper, size: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` as two float vectors of ``size`` entries, in the units of the bounded
    quantity (each as :func:`checked_vector`: a scalar is broadcast), copies of the arguments.
    ``-inf`` in ``lower`` and ``+inf`` in ``upper`` mean "no bound"; NaN, ``lower = +inf`` and
    ``upper = -inf`` are a :class:`NonFiniteError`, ``lower > upper`` anywhere a
    :class:`BoundsOrderError`, a wrong shape a :class:`ShapeError`, each naming ``what``."""
    lo = checked_vector(lower, size, f"{what}: lower", allow_inf=True).copy()
    up = checked_vector(upper, size, f"{what}: upper", allow_inf=True).copy()
    if (lo == np.inf).any() or (up == -np.inf).any():
        raise NonFiniteError(f"{what}: a lower bound is +inf or an upper bound is -inf")
    check_bounds_order(lo, up, what)
    return lo, up


def checked_number(value, what: str, low: float | None = 0.0, strict: bool = False,
                   high: float | None = None) -> float:
    """``value`` as a finite ``float`` with ``low <= value`` (``<`` if ``strict``; ``low=None``:
    no lower bound) and ``value <= high``. Raises :class:`InvalidValueError` (not a real number:
    ``str``, ``None``, ``bool``, complex, an array; or out of range) or
    :class:`NonFiniteError` naming ``what``."""
    if isinstance(value, _ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidValueError(f"{what} must be a real number, got {_kind(value)}")
    try:
        number = float(value)
    except OverflowError:  # an int beyond float's range
        raise NonFiniteError(f"{what} must be finite, got an integer beyond float's "
                             "range") from None
    if not math.isfinite(number):
        raise NonFiniteError(f"{what} must be finite, got {number}")
    if low is not None and (number < low or (strict and number == low)):
        raise InvalidValueError(f"{what} = {number}: must be {'>' if strict else '>='} {low}")
    if high is not None and number > high:
        raise InvalidValueError(f"{what} = {number}: must be <= {high}")
    return number


def checked_scalar(value, what: str, low: float | None = 0.0, strict: bool = False,
                   high: float | None = None) -> float:
    """One real number in the caller's units, given as a number or as an array of shape ``()``:
    a list, a tuple or an array of any other shape is a :class:`ShapeError` naming ``what``
    (a vector where one number is expected); then as :func:`checked_number` (range, finite)."""
    if isinstance(value, (list, tuple)) or (isinstance(value, _ndarray) and value.ndim != 0):
        got = f"shape {value.shape}" if isinstance(value, _ndarray) else _kind(value)
        raise ShapeError(f"{what} must be a scalar, got {got}")
    return checked_number(value, what, low, strict, high)


def checked_integer(value, what: str, low: int | None = 0, high: int | None = MAX_SIZE) -> int:
    """``value`` as an ``int`` in ``[low, high]`` (``None``: no bound) — a Python or numpy
    integer, not a ``bool``; else :class:`InvalidValueError` naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidValueError(f"{what} must be an integer, got {_kind(value)}")
    if low is not None and value < low:
        raise InvalidValueError(f"{what} must be >= {low}, got {value}")
    if high is not None and value > high:
        raise InvalidValueError(f"{what} must be <= {high}, got {str(value)[:40]}")
    return int(value)


def checked_weights(value, rows: int, what: str) -> float | np.ndarray | ca.SX:
    """A cost weight over ``rows`` rows: a number ``>= 0``, ``(rows,)`` numbers ``>= 0`` (a
    CasADi ``DM`` is read as numbers), or a CasADi SX expression (``1 × 1``, ``rows × 1`` or
    ``1 × rows``) of the stack's parameters — ``stack.parameter("w", 1)``, set every tick —
    evaluated inside the compiled functions (a negative value there makes the level's QP fail
    with a status, ``NUMERICAL``). That its symbols are the stack's parameters, not the decision
    vector, is checked when the task is added (:meth:`wbc.Stack.add`). Raises a
    :class:`~wbc.WbcError` naming ``what``."""
    if isinstance(value, ca.MX):
        raise InvalidValueError(f"{what}: MX expressions are not supported, build with ca.SX")
    if isinstance(value, ca.DM):  # CasADi numbers: read as numbers (a column or a scalar)
        value = np.asarray(value.full(), dtype=float)
        value = value.reshape(()) if value.size == 1 else value.reshape(-1)
    if isinstance(value, ca.SX):
        sx = value.T if value.shape == (1, rows) else value
        if sx.shape not in ((1, 1), (rows, 1)):
            raise ShapeError(f"{what}: a symbolic weight must be 1 x 1 or {rows} x 1, got "
                             f"{value.shape}")
        return sx
    arr = as_float_array(value, what)
    if arr.ndim == 0:
        return checked_number(value, what)
    if arr.shape != (rows,):
        raise ShapeError(f"{what} must be a scalar or have shape ({rows},), got {arr.shape}")
    check_finite(arr, what)
    if (arr < 0).any():
        raise InvalidValueError(f"{what} must be >= 0, got {arr}")
    return arr


def check_symbols(expr: ca.SX, parameters, what: str) -> None:
    """Raise :class:`InvalidValueError` naming ``what`` if the SX ``expr`` holds a symbol that
    is none of ``parameters`` (SX symbols, e.g. a stack's ``stack.parameter(...)``)."""
    known = ca.vertcat(*[ca.vec(p) for p in parameters]) if parameters else None
    free = [str(s) for s in ca.symvar(expr) if known is None or not ca.depends_on(s, known)]
    if free:
        raise InvalidValueError(f"{what} uses CasADi symbols {free[:5]} that are not parameters "
                                "of this stack; declare them with stack.parameter(...)")


@overload
def checked_name(value, what: str, optional: Literal[False]) -> str: ...
@overload
def checked_name(value, what: str, optional: bool = True) -> str | None: ...
def checked_name(value, what: str, optional: bool = True) -> str | None:
    """A name: a ``str`` (or ``None`` if ``optional``); else :class:`InvalidValueError`."""
    if value is None and optional:
        return None
    if not isinstance(value, str):
        raise InvalidValueError(f"{what} must be a str{' or None' if optional else ''}, got "
                                f"{_kind(value)}")
    return value


def checked_flag(value, what: str) -> bool:
    """A switch: ``True`` or ``False`` (numpy's ``bool_`` too) as a ``bool``; anything else —
    ``0``, ``None``, an array — is an :class:`InvalidValueError` naming ``what``."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidValueError(f"{what} must be True or False, got {_kind(value)}")
    return bool(value)


@overload
def checked_path(value, what: str, optional: Literal[False]) -> str: ...
@overload
def checked_path(value, what: str, optional: bool = True) -> str | None: ...
def checked_path(value, what: str, optional: bool = True) -> str | None:
    """A file path: a ``str`` or an ``os.PathLike`` (``pathlib.Path``), returned as a ``str``
    (``None`` if ``optional``); else :class:`InvalidValueError`. Whether the file exists is the
    loader's to say (:class:`~wbc.ModelLoadError`)."""
    if value is None and optional:
        return None
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str):
        raise InvalidValueError(f"{what} must be a file path (str or pathlib.Path)"
                                f"{' or None' if optional else ''}, got {_kind(value)}")
    return value


def checked_shape(shape, what: str) -> tuple[int, int]:
    """A parameter shape: ``rows`` or ``(rows,)`` or ``(rows, cols)``, non-negative integers,
    as ``(rows, cols)``. Raises :class:`ShapeError` naming ``what``."""
    dims = (shape,) if isinstance(shape, (int, np.integer)) else shape
    if isinstance(dims, (str, bytes)) or not hasattr(dims, "__len__"):
        raise ShapeError(f"{what}: shape must be rows or (rows, cols), got {_kind(shape)}")
    dims = tuple(dims)
    if (not 1 <= len(dims) <= 2 or any(isinstance(d, bool) or not isinstance(d, (int, np.integer))
                                       or d < 0 for d in dims)):
        raise ShapeError(f"{what}: shape must be rows or (rows, cols) of integers >= 0, got "
                         f"{_kind(shape)}")
    rows, cols = int(dims[0]), int(dims[1]) if len(dims) == 2 else 1
    if rows * cols > MAX_SIZE:
        raise ShapeError(f"{what}: shape {(rows, cols)} has more than {MAX_SIZE} entries")
    return rows, cols


def check_robot(robot, what: str) -> tuple[int, int]:
    """``(nq, nv)`` of an object with the robot protocol (positive integer ``nq`` and ``nv``);
    anything else is an :class:`InvalidValueError` naming ``what``."""
    nq, nv = getattr(robot, "nq", None), getattr(robot, "nv", None)
    if not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0
               for n in (nq, nv)):
        raise InvalidValueError(f"{what} must be a robot (positive integers nq, nv; see "
                                f"wbc.robots), got {_kind(robot)}")
    return int(nq), int(nv)  # type: ignore[arg-type]



def check_frame(robot, frame: str, what: str) -> None:
    """Raise :class:`~wbc.UnknownNameError` if ``robot`` knows its frames (``has_frame`` or
    ``frame_names``) and ``frame`` is not one of them."""
    known = getattr(robot, "frame_names", None)
    has_frame = getattr(robot, "has_frame", None)
    if has_frame is not None:
        ok = has_frame(frame)
    elif known is not None:
        ok = frame in known
    else:
        return
    if not ok:
        raise UnknownNameError(f"{what}: unknown frame {frame!r}"
                               + (f"; frames are {sorted(known)}" if known else ""))

def check_pose(T: np.ndarray, what: str) -> None:
    """Raise :class:`InvalidValueError` naming ``what`` unless the ``(4, 4)`` float array ``T``
    is a homogeneous transform: bottom row ``(0, 0, 0, 1)`` and a rotation block ``R = (c₀, c₁,
    c₂)`` with ``c₀``, ``c₁`` orthonormal and ``c₂ = c₀ × c₁`` (so ``RᵀR = I``, ``det R = +1``)
    to :data:`ROTATION_TOL`. Meant for the control tick: Python floats, no numpy call but one
    ``tolist`` (≈ 0.7 µs, see the module docstring). ``T`` must be finite (checked before)."""
    a, b, c, _, d, e, f, _, g, h, i, _, p, q, r, s = T.ravel().tolist()
    if not (_hypot(_hypot(a, d, g) - 1.0, _hypot(b, e, h) - 1.0, a * b + d * e + g * h,
                   d * h - g * e - c, g * b - a * h - f, a * e - d * b - i) < ROTATION_TOL
            and p == q == r == 0.0 and s == 1.0):
        R = T[:3, :3]
        raise InvalidValueError(
            f"{what} is not a homogeneous transform: its rotation block must be orthonormal "
            f"with det +1 (max |RᵀR − I| = {np.abs(R.T @ R - np.eye(3)).max():.3g}, det = "
            f"{np.linalg.det(R):.6g}) and its last row (0, 0, 0, 1) (got {T[3].tolist()})")
