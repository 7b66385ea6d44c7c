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
* :func:`check_pose` — a homogeneous transform whose rotation is one (≈ 0.7 µs on a 4 × 4,
  pure Python floats).

On the control tick, :meth:`wbc.Controller.step` checks and writes ``q``, ``v`` and the
references with one call in C (:data:`STAGE_SOURCE`), which accepts a subset of what the
functions above accept and leaves every other call, every refusal included, to them.
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


# ---------------------------------------------------------------------- the tick's checks in C
#: C source of the Python extension ``wbc_stage`` (built by :func:`wbc.cbuild.compiled_extension`
#: with numpy's headers, see :meth:`wbc.Controller.step`): one function,
#: ``stage(p, q, v, layout, references, specs) -> bool``, that checks a tick's inputs and writes
#: them into the parameter vector ``p`` (a writable contiguous float64 vector) in one call —
#: references first, then ``q`` and ``v``, as the Python path writes them. ``layout`` is
#: ``(q_at, nq, v_at, nv)``: where ``"q"`` and ``"v"`` start in ``p`` (``-1``: the stack has no
#: such parameter; the value is checked, not written) and their sizes; ``v`` may be ``None``
#: (nothing to check or write). ``references`` maps keywords to values, ``specs`` keywords to
#: ``(at, rows, cols, allow_inf, pose)`` (the parameter's offset in ``p``, its shape, stored
#: column-major, whether ``±inf`` is allowed, whether it is a pose).
#:
#: It returns ``True`` when every value was accepted and written, ``False`` — having written
#: nothing — when the call needs Python's path: a keyword without a spec, a value that is not
#: exactly a float64 ``numpy.ndarray`` (a list, ints, a subclass, another byte order: Python
#: converts them), or a value it does not accept. It accepts a subset of what
#: :func:`checked_array` and :func:`check_pose` accept, never more: ``q`` and ``v`` 1-D of their
#: size; a reference of its shape (a column also as 1-D, ``(1, 1)`` also as 0-D); entries
#: without NaN, and, unless ``allow_inf``, of magnitude at most 1e300 (so that
#: :func:`all_finite`'s sum cannot overflow either); a pose whose rotation test
#: (:func:`check_pose`'s expression, with plain square roots) is below ``ROTATION_TOL − 1e-14``
#: (a margin far above the rounding differences between the two evaluations, ≈ 1e-16) and whose
#: last row is exactly ``(0, 0, 0, 1)``. So Python's path decides every refusal and every
#: borderline value, with its own messages, and a value is written bit for bit the same either
#: way. The call costs ≈ 0.1 µs for a Panda ``q`` and a pose (≈ 1.7 µs in Python).
STAGE_SOURCE = f"#define ROTATION_TOL {ROTATION_TOL!r}\n" + r"""
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <string.h>

#define POSE_MARGIN 1e-14  /* accepted: below ROTATION_TOL - POSE_MARGIN (rounding) */
#define LARGE 1e300        /* beyond it, Python's path decides (its sum may overflow) */
#define MAX_VALUES 18      /* q, v and 16 references; more: Python's path */

typedef struct {
    PyArrayObject *array;
    Py_ssize_t at, rows, cols;  /* where in p (at < 0: nowhere), its shape (column-major) */
} Value;

static double entry(PyArrayObject *array, Py_ssize_t i, Py_ssize_t j)
{
    const char *at = PyArray_BYTES(array);
    double x;
    if (PyArray_NDIM(array) > 0)
        at += i * PyArray_STRIDES(array)[0];
    if (PyArray_NDIM(array) > 1)
        at += j * PyArray_STRIDES(array)[1];
    memcpy(&x, at, sizeof x);
    return x;
}

/* wbc.checks.check_pose's test, below the margin */
static int is_pose(PyArrayObject *T)
{
    double a = entry(T, 0, 0), b = entry(T, 0, 1), c = entry(T, 0, 2);
    double d = entry(T, 1, 0), e = entry(T, 1, 1), f = entry(T, 1, 2);
    double g = entry(T, 2, 0), h = entry(T, 2, 1), i = entry(T, 2, 2);
    double n0 = sqrt(a * a + d * d + g * g) - 1.0, n1 = sqrt(b * b + e * e + h * h) - 1.0;
    double r0 = a * b + d * e + g * h, r1 = d * h - g * e - c, r2 = g * b - a * h - f;
    double r3 = a * e - d * b - i;
    return sqrt(n0 * n0 + n1 * n1 + r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
        < ROTATION_TOL - POSE_MARGIN
        && entry(T, 3, 0) == 0.0 && entry(T, 3, 1) == 0.0 && entry(T, 3, 2) == 0.0
        && entry(T, 3, 3) == 1.0;
}

/* Whether obj is accepted (see wbc.checks.STAGE_SOURCE) as a value of shape (rows, cols) —
   only 1-D if vector — to be written at `at`; value holds it either way. */
static int take(PyObject *obj, Value *value, Py_ssize_t at, Py_ssize_t rows, Py_ssize_t cols,
                int vector, int allow_inf, int pose)
{
    PyArrayObject *array = (PyArrayObject *)obj;
    npy_intp *shape;
    int ndim, ok;
    value->array = array;
    value->at = at;
    value->rows = rows;
    value->cols = cols;
    if (Py_TYPE(obj) != &PyArray_Type || PyArray_TYPE(array) != NPY_DOUBLE
        || PyArray_ISBYTESWAPPED(array))
        return 0;
    ndim = PyArray_NDIM(array);
    shape = PyArray_DIMS(array);
    ok = vector ? ndim == 1 && shape[0] == rows
        : (ndim == 2 && shape[0] == rows && shape[1] == cols)
          || (ndim == 1 && cols == 1 && shape[0] == rows)
          || (ndim == 0 && rows == 1 && cols == 1);
    for (Py_ssize_t j = 0; ok && j < cols; j++)
        for (Py_ssize_t i = 0; ok && i < rows; i++) {
            double x = entry(array, i, j);
            ok = allow_inf ? x == x : fabs(x) <= LARGE;
        }
    return ok && (!pose || (rows == 4 && cols == 4 && is_pose(array)));
}

static PyObject *stage(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    Value values[MAX_VALUES];
    Py_ssize_t n = 0, size, position = 0, layout[4];
    PyObject *references, *specs, *key, *value;
    PyArrayObject *p;
    double *to;
    int ok = 1;
    (void)module;
    if (nargs != 6 || Py_TYPE(args[0]) != &PyArray_Type || !PyTuple_Check(args[3])
        || PyTuple_GET_SIZE(args[3]) != 4 || !PyDict_Check(args[4]) || !PyDict_Check(args[5])) {
        PyErr_SetString(PyExc_TypeError,
                        "stage(p, q, v, (q_at, nq, v_at, nv), references, specs)");
        return NULL;
    }
    p = (PyArrayObject *)args[0];
    if (PyArray_TYPE(p) != NPY_DOUBLE || PyArray_ISBYTESWAPPED(p) || PyArray_NDIM(p) != 1
        || !PyArray_IS_C_CONTIGUOUS(p) || !PyArray_ISWRITEABLE(p)) {
        PyErr_SetString(PyExc_TypeError, "stage: p must be a writable contiguous float64 vector");
        return NULL;
    }
    size = PyArray_DIM(p, 0);
    to = (double *)PyArray_DATA(p);
    for (int k = 0; k < 4; k++)
        layout[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(args[3], k));
    if (PyErr_Occurred())
        return NULL;
    if (layout[0] + layout[1] > size || layout[2] + layout[3] > size) {
        PyErr_SetString(PyExc_ValueError, "stage: q or v lies outside p");
        return NULL;
    }
    references = args[4];
    specs = args[5];
    if (PyDict_GET_SIZE(references) > MAX_VALUES - 2)
        Py_RETURN_FALSE;
    while (ok && PyDict_Next(references, &position, &key, &value)) {
        PyObject *spec = PyDict_GetItemWithError(specs, key);
        Py_ssize_t at, rows, cols;
        if (spec == NULL) {
            if (PyErr_Occurred())
                return NULL;
            Py_RETURN_FALSE;  /* a keyword Python's path has not seen yet */
        }
        if (!PyTuple_Check(spec) || PyTuple_GET_SIZE(spec) != 5) {
            PyErr_SetString(PyExc_TypeError, "stage: a spec is (at, rows, cols, allow_inf, pose)");
            return NULL;
        }
        at = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 0));
        rows = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 1));
        cols = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 2));
        if (PyErr_Occurred())
            return NULL;
        if (at < 0 || rows < 0 || cols < 0 || at + rows * cols > size) {
            PyErr_SetString(PyExc_ValueError, "stage: a reference lies outside p");
            return NULL;
        }
        ok = take(value, &values[n++], at, rows, cols, 0, PyTuple_GET_ITEM(spec, 3) == Py_True,
                  PyTuple_GET_ITEM(spec, 4) == Py_True);
    }
    ok = ok && take(args[1], &values[n++], layout[0], layout[1], 1, 1, 0, 0);
    if (ok && args[2] != Py_None)
        ok = take(args[2], &values[n++], layout[2], layout[3], 1, 1, 0, 0);
    if (!ok)
        Py_RETURN_FALSE;
    for (Py_ssize_t k = 0; k < n; k++) {  /* every value accepted: write them, in order */
        Value *item = &values[k];
        if (item->at >= 0)
            for (Py_ssize_t j = 0; j < item->cols; j++)
                for (Py_ssize_t i = 0; i < item->rows; i++)
                    to[item->at + i + j * item->rows] = entry(item->array, i, j);
    }
    Py_RETURN_TRUE;
}

static PyMethodDef methods[] = {
    {"stage", (PyCFunction)(void (*)(void))stage, METH_FASTCALL,
     "stage(p, q, v, layout, references, specs) -> bool: see wbc.checks.STAGE_SOURCE"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef definition = {
    PyModuleDef_HEAD_INIT, "wbc_stage", NULL, -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit_wbc_stage(void)
{
    import_array();
    return PyModule_Create(&definition);
}
"""
