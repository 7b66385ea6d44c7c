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
#: with numpy's headers, see :meth:`wbc.Controller.step`): the stage,
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
#: way. The call costs ≈ 0.1 µs for a Panda ``q`` and a pose (≈ 1.7 µs in Python). When ``v`` is
#: ``None`` and the stack has a ``"v"``, it writes zeros there (the Python path does the same).
#:
#: The fused tick (:mod:`wbc.fused`) is called from here too, so that a tick it answers runs no
#: Python between the stage and the command:
#:
#: * ``fused_call(library, name, p, outputs)`` — a handle (a capsule) on the generated C
#:   function ``name`` of the shared library ``library`` (:func:`wbc.cbuild.compiled_library`,
#:   already loaded by :func:`casadi.external`: the same code and static memory), reading ``p``
#:   and writing ``outputs`` (contiguous float64 arrays, one per output: ``x``, ``done``, ...;
#:   sizes checked against the function's); it holds them, and its work vectors;
#: * ``arm(call, armed)`` — whether ``tick`` may make the call (the fused workspace's closure
#:   arms it after an answered tick and disarms it whenever the ordinary path solved, so that
#:   the back-off and its bookkeeping stay in Python: :meth:`wbc.fused.FusedWorkspace.solver`);
#: * ``tick(p, q, v, layout, references, specs, out, times, call)`` — what
#:   :meth:`wbc.Controller.step` calls. ``times`` is a float64 4-vector ``(started, called,
#:   model, solve)``: the first two scratch clock readings (:func:`time.perf_counter`) of the
#:   tick, the last two the answered tick's durations [s] (the fused solution's ``timings``
#:   read them). It writes ``started`` first; returns ``None`` (nothing else written) when
#:   ``out`` is not ``None`` and not exactly a writable float64 ``(n,)`` array (``layout`` is
#:   ``(q_at, nq, v_at, nv, n)``) or when the stage does not accept the inputs; else stages
#:   them, and returns ``True`` when ``call`` is ``None`` or not armed. Else it sets ``done``
#:   to NaN and calls the function after reading ``called``; ``False`` (disarmed) when
#:   ``done`` stayed NaN (the call did not answer), else it writes ``model = called − started``
#:   and ``solve`` (the call's time) and returns the command: ``x`` copied into ``out``
#:   (returned), or else into an array nothing else references — a new one, or one it returned
#:   on an earlier tick that every holder has dropped since (reference count 1, no weak
#:   reference, still a writable contiguous float64 ``(n,)`` array owning its data: nobody can
#:   see it change), which spares an allocation in a loop that drops its commands.
STAGE_SOURCE = f"#define ROTATION_TOL {ROTATION_TOL!r}\n" + r"""
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
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

/* the stage (see wbc.checks.STAGE_SOURCE): 1 accepted and written, 0 Python's path (nothing
   written), -1 an exception is set. args: p, q, v, layout (q_at, nq, v_at, nv, ...), references,
   specs, already checked by the caller to be an array, a tuple of >= 4, two dicts. */
static int stage_values(PyObject *const *args)
{
    Value values[MAX_VALUES];
    Py_ssize_t n = 0, size, position = 0, layout[4];
    PyObject *references = args[4], *specs = args[5], *key, *value;
    PyArrayObject *p = (PyArrayObject *)args[0];
    double *to;
    int ok = 1;
    if (PyArray_TYPE(p) != NPY_DOUBLE || PyArray_ISBYTESWAPPED(p) || PyArray_NDIM(p) != 1
        || !PyArray_IS_C_CONTIGUOUS(p) || !PyArray_ISWRITEABLE(p)) {
        PyErr_SetString(PyExc_TypeError, "stage: p must be a writable contiguous float64 vector");
        return -1;
    }
    size = PyArray_DIM(p, 0);
    to = (double *)PyArray_DATA(p);
    for (int k = 0; k < 4; k++)
        layout[k] = PyLong_AsSsize_t(PyTuple_GET_ITEM(args[3], k));
    if (PyErr_Occurred())
        return -1;
    if (layout[0] + layout[1] > size || layout[2] + layout[3] > size) {
        PyErr_SetString(PyExc_ValueError, "stage: q or v lies outside p");
        return -1;
    }
    if (PyDict_GET_SIZE(references) > MAX_VALUES - 2)
        return 0;
    while (ok && PyDict_Next(references, &position, &key, &value)) {
        PyObject *spec = PyDict_GetItemWithError(specs, key);
        Py_ssize_t at, rows, cols;
        if (spec == NULL)
            return PyErr_Occurred() ? -1 : 0;  /* a keyword Python's path has not seen yet */
        if (!PyTuple_Check(spec) || PyTuple_GET_SIZE(spec) != 5) {
            PyErr_SetString(PyExc_TypeError, "stage: a spec is (at, rows, cols, allow_inf, pose)");
            return -1;
        }
        at = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 0));
        rows = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 1));
        cols = PyLong_AsSsize_t(PyTuple_GET_ITEM(spec, 2));
        if (PyErr_Occurred())
            return -1;
        if (at < 0 || rows < 0 || cols < 0 || at + rows * cols > size) {
            PyErr_SetString(PyExc_ValueError, "stage: a reference lies outside p");
            return -1;
        }
        ok = take(value, &values[n++], at, rows, cols, 0, PyTuple_GET_ITEM(spec, 3) == Py_True,
                  PyTuple_GET_ITEM(spec, 4) == Py_True);
    }
    ok = ok && take(args[1], &values[n++], layout[0], layout[1], 1, 1, 0, 0);
    if (ok && args[2] != Py_None)
        ok = take(args[2], &values[n++], layout[2], layout[3], 1, 1, 0, 0);
    if (!ok)
        return 0;
    for (Py_ssize_t k = 0; k < n; k++) {  /* every value accepted: write them, in order */
        Value *item = &values[k];
        if (item->at >= 0)
            for (Py_ssize_t j = 0; j < item->cols; j++)
                for (Py_ssize_t i = 0; i < item->rows; i++)
                    to[item->at + i + j * item->rows] = entry(item->array, i, j);
    }
    if (args[2] == Py_None && layout[2] >= 0)  /* no v: the stack's "v" is zero */
        memset(to + layout[2], 0, (size_t)layout[3] * sizeof *to);
    return 1;
}

static int stage_arguments(PyObject *const *args, Py_ssize_t nargs, Py_ssize_t expected,
                           Py_ssize_t layout_size, const char *usage)
{
    if (nargs != expected || Py_TYPE(args[0]) != &PyArray_Type || !PyTuple_Check(args[3])
        || PyTuple_GET_SIZE(args[3]) != layout_size || !PyDict_Check(args[4])
        || !PyDict_Check(args[5])) {
        PyErr_SetString(PyExc_TypeError, usage);
        return 0;
    }
    return 1;
}

static PyObject *stage(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    int staged;
    (void)module;
    if (!stage_arguments(args, nargs, 6, 4,
                         "stage(p, q, v, (q_at, nq, v_at, nv), references, specs)"))
        return NULL;
    staged = stage_values(args);
    if (staged < 0)
        return NULL;
    return PyBool_FromLong(staged);
}

/* ---- the fused call: the generated function of wbc.fused, called from here ---- */

#define SPARES 3  /* commands kept for reuse, see command_array */
typedef long long casadi_int;  /* the generated code's (checked against <name>_casadi_int_size) */
typedef int (*Generated)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

typedef struct {
    void *library;
    Generated function;
    void (*release)(int);
    void (*decref)(void);
    int mem;
    const double **arg;
    double **res, *w, *x, *done;
    casadi_int *iw;
    Py_ssize_t n;           /* entries of x */
    int armed;              /* see wbc.checks.STAGE_SOURCE: tick calls only when set */
    PyObject *arrays;       /* p and the outputs, kept alive */
    PyObject *spare[SPARES];  /* commands returned before, see command_array */
    int next_spare;
} Call;

static const char *CALL = "wbc_stage.call";

/* time.perf_counter() [s] */
static double now(void)
{
#if PY_VERSION_HEX >= 0x030D0000
    PyTime_t t;
    (void)PyTime_PerfCounterRaw(&t);
    return PyTime_AsSecondsDouble(t);
#else
    return _PyTime_AsSecondsDouble(_PyTime_GetPerfCounter());
#endif
}

static void call_free(PyObject *capsule)
{
    Call *call = PyCapsule_GetPointer(capsule, CALL);
    if (call == NULL)
        return;
    if (call->release != NULL)
        call->release(call->mem);
    if (call->decref != NULL)
        call->decref();
    if (call->library != NULL)
        dlclose(call->library);
    free(call->arg);
    free(call->res);
    free(call->iw);
    free(call->w);
    Py_XDECREF(call->arrays);
    for (int k = 0; k < SPARES; k++)
        Py_XDECREF(call->spare[k]);
    free(call);
}

static void *symbol(Call *call, const char *name, const char *suffix)
{
    char full[256];
    if (snprintf(full, sizeof full, "%s%s", name, suffix) >= (int)sizeof full)
        return NULL;
    return dlsym(call->library, full);
}

/* nonzeros of a generated sparsity pattern: (nrow, ncol, 1) if dense (colind[0] is 0 else),
   (nrow, ncol, colind[ncol + 1], row[...]) if not */
static casadi_int nonzeros(const casadi_int *sparsity)
{
    return sparsity[2] == 1 ? sparsity[0] * sparsity[1] : sparsity[2 + sparsity[1]];
}

/* whether array is a contiguous native float64 array of `size` entries (writable if output) */
static int buffer_of(PyObject *obj, casadi_int size, int output)
{
    PyArrayObject *array = (PyArrayObject *)obj;
    return PyArray_Check(obj) && PyArray_TYPE(array) == NPY_DOUBLE
        && !PyArray_ISBYTESWAPPED(array) && PyArray_IS_C_CONTIGUOUS(array)
        && (!output || PyArray_ISWRITEABLE(array)) && PyArray_SIZE(array) == size;
}

static PyObject *fused_call(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    const char *path, *name;
    PyObject *capsule, *outputs;
    Call *call;
    int (*work)(casadi_int *, casadi_int *, casadi_int *, casadi_int *);
    int (*int_size)(void), (*checkout)(void);
    void (*incref)(void);
    casadi_int (*n_in)(void), (*n_out)(void);
    const casadi_int *(*sparsity_in)(casadi_int), *(*sparsity_out)(casadi_int);
    casadi_int sz_arg, sz_res, sz_iw, sz_w, count;
    (void)module;
    if (nargs != 4 || !PyUnicode_Check(args[0]) || !PyUnicode_Check(args[1])
        || !PyList_Check(args[3])) {
        PyErr_SetString(PyExc_TypeError, "fused_call(library, name, p, outputs)");
        return NULL;
    }
    path = PyUnicode_AsUTF8(args[0]);
    name = PyUnicode_AsUTF8(args[1]);
    if (path == NULL || name == NULL)
        return NULL;
    call = calloc(1, sizeof *call);
    if (call == NULL)
        return PyErr_NoMemory();
    call->mem = -1;
    capsule = PyCapsule_New(call, CALL, call_free);
    if (capsule == NULL) {
        free(call);
        return NULL;
    }
    call->library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (call->library == NULL) {
        PyErr_Format(PyExc_RuntimeError, "fused_call: %s", dlerror());
        goto fail;
    }
    call->function = (Generated)symbol(call, name, "");
    *(void **)&work = symbol(call, name, "_work");
    *(void **)&int_size = symbol(call, name, "_casadi_int_size");
    *(void **)&checkout = symbol(call, name, "_checkout");
    *(void **)&incref = symbol(call, name, "_incref");
    *(void **)&n_in = symbol(call, name, "_n_in");
    *(void **)&n_out = symbol(call, name, "_n_out");
    *(void **)&sparsity_in = symbol(call, name, "_sparsity_in");
    *(void **)&sparsity_out = symbol(call, name, "_sparsity_out");
    if (call->function == NULL || work == NULL || int_size == NULL || checkout == NULL
        || incref == NULL || n_in == NULL || n_out == NULL || sparsity_in == NULL
        || sparsity_out == NULL || int_size() != (int)sizeof(casadi_int)) {
        PyErr_Format(PyExc_RuntimeError, "fused_call: %s is not a generated function %s",
                     path, name);
        goto fail;
    }
    outputs = args[3];
    count = PyList_GET_SIZE(outputs);
    if (n_in() != 1 || n_out() != count || count < 2
        || !buffer_of(args[2], nonzeros(sparsity_in(0)), 0)) {
        PyErr_SetString(PyExc_ValueError, "fused_call: p and outputs do not fit the function");
        goto fail;
    }
    for (casadi_int i = 0; i < count; i++)
        if (!buffer_of(PyList_GET_ITEM(outputs, i), nonzeros(sparsity_out(i)), 1)) {
            PyErr_Format(PyExc_ValueError, "fused_call: output %lld does not fit", i);
            goto fail;
        }
    if (work(&sz_arg, &sz_res, &sz_iw, &sz_w)) {
        PyErr_SetString(PyExc_RuntimeError, "fused_call: no work sizes");
        goto fail;
    }
    call->arg = calloc((size_t)(sz_arg > 1 ? sz_arg : 1), sizeof *call->arg);
    call->res = calloc((size_t)(sz_res > count ? sz_res : count), sizeof *call->res);
    call->iw = calloc((size_t)(sz_iw > 1 ? sz_iw : 1), sizeof *call->iw);
    call->w = calloc((size_t)(sz_w > 1 ? sz_w : 1), sizeof *call->w);
    if (call->arg == NULL || call->res == NULL || call->iw == NULL || call->w == NULL) {
        PyErr_NoMemory();
        goto fail;
    }
    call->arg[0] = PyArray_DATA((PyArrayObject *)args[2]);
    for (casadi_int i = 0; i < count; i++) {  /* an empty output: not written (NULL) */
        PyArrayObject *out = (PyArrayObject *)PyList_GET_ITEM(outputs, i);
        call->res[i] = PyArray_SIZE(out) ? PyArray_DATA(out) : NULL;
    }
    call->x = PyArray_DATA((PyArrayObject *)PyList_GET_ITEM(outputs, 0));
    call->n = PyArray_SIZE((PyArrayObject *)PyList_GET_ITEM(outputs, 0));
    call->done = PyArray_DATA((PyArrayObject *)PyList_GET_ITEM(outputs, 1));
    call->arrays = Py_BuildValue("(OO)", args[2], outputs);
    if (call->arrays == NULL)
        goto fail;
    incref();
    call->decref = (void (*)(void))symbol(call, name, "_decref");
    call->mem = checkout();
    if (call->mem < 0) {
        PyErr_SetString(PyExc_RuntimeError, "fused_call: no memory for the call");
        goto fail;
    }
    *(void **)&call->release = symbol(call, name, "_release");
    return capsule;
fail:
    Py_DECREF(capsule);
    return NULL;
}

/* A new reference to a float64 (n,) array for the command: one of the arrays returned on
   earlier ticks that nothing but this call references any more (its reference count is 1, no
   weak reference: nobody can see it change) and that is still a writable contiguous (n,)
   float64 array owning its data — the previous command is still the controller's
   last_command, the one before it is free in a loop that dropped it — or else a new one,
   kept in place of the oldest. An allocation is ≈ 0.05 µs of a ≈ 2 µs tick. */
static PyObject *command_array(Call *call)
{
    npy_intp size = call->n;
    PyObject *array;
    for (int k = 0; k < SPARES; k++) {
        PyArrayObject *spare = (PyArrayObject *)call->spare[k];
        if (spare != NULL && Py_REFCNT(spare) == 1
            && ((PyArrayObject_fields *)spare)->weakreflist == NULL
            && PyArray_NDIM(spare) == 1 && PyArray_DIM(spare, 0) == size
            && PyArray_TYPE(spare) == NPY_DOUBLE && !PyArray_ISBYTESWAPPED(spare)
            && PyArray_CHKFLAGS(spare, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_OWNDATA
                                        | NPY_ARRAY_WRITEABLE)) {
            Py_INCREF(spare);
            return (PyObject *)spare;
        }
    }
    array = PyArray_SimpleNew(1, &size, NPY_DOUBLE);
    if (array == NULL)
        return NULL;
    Py_INCREF(array);
    Py_XSETREF(call->spare[call->next_spare], array);
    call->next_spare = (call->next_spare + 1) % SPARES;
    return array;
}

static Call *call_of(PyObject *capsule)
{
    return PyCapsule_GetPointer(capsule, CALL);  /* NULL, an exception set: not a call */
}

/* one call of the generated function, timed (times: see wbc.checks.STAGE_SOURCE); 1 when it
   answered ("done" finite) */
static int answered(Call *call, double *times)
{
    double called, returned;
    *call->done = NAN;
    times[1] = called = now();
    call->function(call->arg, call->res, call->iw, call->w, call->mem);
    returned = now();
    if (*call->done != *call->done)
        return 0;
    times[2] = called - times[0];
    times[3] = returned - called;
    return 1;
}

static PyObject *arm(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    Call *call;
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "arm(call, armed)");
        return NULL;
    }
    call = call_of(args[0]);
    if (call == NULL)
        return NULL;
    call->armed = PyObject_IsTrue(args[1]);
    if (call->armed < 0)
        return NULL;
    Py_RETURN_NONE;
}

static PyObject *tick(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    PyObject *out, *command;
    PyArrayObject *times_array, *target;
    double *times, started = now();
    Call *call = NULL;
    Py_ssize_t n;
    int staged;
    (void)module;
    if (!stage_arguments(args, nargs, 9, 5, "tick(p, q, v, (q_at, nq, v_at, nv, n), references, "
                                            "specs, out, times, call)"))
        return NULL;
    times_array = (PyArrayObject *)args[7];
    if (!buffer_of(args[7], 4, 1)) {
        PyErr_SetString(PyExc_TypeError, "tick: times must be a writable float64 4-vector");
        return NULL;
    }
    times = PyArray_DATA(times_array);
    times[0] = started;
    if (args[8] != Py_None && (call = call_of(args[8])) == NULL)
        return NULL;
    n = PyLong_AsSsize_t(PyTuple_GET_ITEM(args[3], 4));
    if (n < 0 && PyErr_Occurred())
        return NULL;
    out = args[6];
    target = (PyArrayObject *)out;
    if (out != Py_None && (Py_TYPE(out) != &PyArray_Type || PyArray_TYPE(target) != NPY_DOUBLE
                           || PyArray_ISBYTESWAPPED(target) || PyArray_NDIM(target) != 1
                           || PyArray_DIM(target, 0) != n || !PyArray_ISWRITEABLE(target)))
        Py_RETURN_NONE;  /* Python's path checks it (and refuses it, or writes it there) */
    staged = stage_values(args);
    if (staged < 0)
        return NULL;
    if (!staged)
        Py_RETURN_NONE;
    if (call == NULL || !call->armed)
        Py_RETURN_TRUE;
    if (!answered(call, times)) {
        call->armed = 0;
        Py_RETURN_FALSE;
    }
    if (call->n != n) {
        PyErr_SetString(PyExc_ValueError, "tick: the call's x is not of size n");
        return NULL;
    }
    if (out == Py_None) {
        command = command_array(call);
        if (command == NULL)
            return NULL;
        memcpy(PyArray_DATA((PyArrayObject *)command), call->x, (size_t)n * sizeof(double));
        return command;
    }
    for (Py_ssize_t i = 0; i < n; i++)  /* out may be strided */
        memcpy(PyArray_BYTES(target) + i * PyArray_STRIDES(target)[0], call->x + i,
               sizeof(double));
    Py_INCREF(out);
    return out;
}

static PyMethodDef methods[] = {
    {"stage", (PyCFunction)(void (*)(void))stage, METH_FASTCALL,
     "stage(p, q, v, layout, references, specs) -> bool: see wbc.checks.STAGE_SOURCE"},
    {"tick", (PyCFunction)(void (*)(void))tick, METH_FASTCALL,
     "tick(p, q, v, layout, references, specs, out, times, call): see wbc.checks.STAGE_SOURCE"},
    {"fused_call", (PyCFunction)(void (*)(void))fused_call, METH_FASTCALL,
     "fused_call(library, name, p, outputs) -> call: see wbc.checks.STAGE_SOURCE"},
    {"arm", (PyCFunction)(void (*)(void))arm, METH_FASTCALL,
     "arm(call, armed): see wbc.checks.STAGE_SOURCE"},
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
