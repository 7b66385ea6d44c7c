"""Tasks whose coefficients are numbers: the simplest way in, and what the equivalence tests use.

Each coefficient becomes a stack parameter named ``"<task name>.<coefficient>"`` whose default
is the number given, so the task can be updated every tick without recompiling::

    task = LinearTask(J, v, name="ee")
    stack.add(task)
    ws = stack.workspace("daqp")
    ws.set(**{"ee.A": J_new, "ee.b": v_new})
"""

from __future__ import annotations

import numpy as np

from wbc.checks import check_bounds_order, check_finite
from wbc.errors import ShapeError
from wbc.terms import Cost, Inequality, Task, VariableBounds


def _matrix(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2:
        raise ShapeError(f"{what} must be a matrix, got shape {np.shape(value)}")
    check_finite(arr, what)
    return arr


def _vector(value, rows: int, what: str, allow_inf: bool = False) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(rows, float(arr))
    arr = arr.reshape(-1) if arr.ndim == 2 and 1 in arr.shape else arr
    if arr.shape != (rows,):
        raise ShapeError(f"{what} must have shape ({rows},), got {np.shape(value)}")
    check_finite(arr, what, allow_inf)
    return arr


class _Numeric(Task):
    """Shared plumbing: the variable block the coefficients act on, and parameter creation."""

    def __init__(self, name: str | None, block: str | None) -> None:
        self.name = name
        self.block = block

    def _columns(self, stack, A: np.ndarray, what: str):
        """The symbol of the acted-on variables, checking ``A``'s column count against it."""
        xs = stack.variables.symbol[stack.variables.slice(self.block)]
        if A.shape[1] != xs.shape[0]:
            where = f"block {self.block!r}" if self.block else "the decision vector"
            raise ShapeError(f"{what} has {A.shape[1]} columns but {where} has "
                             f"{xs.shape[0]} entries")
        return xs


class LinearTask(_Numeric):
    """Cost ``weight/2 · ||A x − b||²`` on ``x`` (or on one variable block).

    Args:
        A: ``(m, n_block)`` coefficients.
        b: ``(m,)`` target (scaled by a task-scaling level).
        weight: scalar ≥ 0 or ``(m,)`` per-row weights.
        name: task name; its parameters are ``"<name>.A"`` and ``"<name>.b"``.
        block: variable block the task acts on (``None``: all of ``x``).
    """

    def __init__(self, A, b, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        super().__init__(name, block)
        self.A = _matrix(A, f"A of task {name!r}")
        self.b = _vector(b, self.A.shape[0], f"b of task {name!r}")
        self.weight = weight

    def terms(self, stack):
        xs = self._columns(stack, self.A, f"A of task {self.name!r}")
        A = stack.parameter(f"{self.name}.A", self.A.shape, self.A)
        b = stack.parameter(f"{self.name}.b", self.b.shape[0], self.b)
        return [Cost(A @ xs, b, self.weight, self.name)]


class LinearConstraint(_Numeric):
    """``lower <= C x <= upper`` (equal sides make an equality; ``±inf`` a missing side).

    Hard with ``stack.constrain``, soft (slack-minimising) with ``stack.add``.
    Parameters: ``"<name>.C"``, ``"<name>.lower"``, ``"<name>.upper"``.
    """

    def __init__(self, C, lower, upper, name: str | None = None,
                 block: str | None = None) -> None:
        super().__init__(name, block)
        self.C = _matrix(C, f"C of constraint {name!r}")
        m = self.C.shape[0]
        self.lower = _vector(lower, m, f"lower of constraint {name!r}", allow_inf=True)
        self.upper = _vector(upper, m, f"upper of constraint {name!r}", allow_inf=True)
        check_bounds_order(self.lower, self.upper, f"constraint {name!r}")

    def terms(self, stack):
        xs = self._columns(stack, self.C, f"C of constraint {self.name!r}")
        m = self.C.shape[0]
        C = stack.parameter(f"{self.name}.C", self.C.shape, self.C)
        lo = stack.parameter(f"{self.name}.lower", m, self.lower, allow_inf=True)
        up = stack.parameter(f"{self.name}.upper", m, self.upper, allow_inf=True)
        return [Inequality(C @ xs, lo, up, self.name)]


class Bounds(_Numeric):
    """``lower <= x[block] <= upper`` element-wise (always hard; passed as solver bounds).

    Args:
        lower, upper: scalars or ``(n_block,)`` arrays; ``±inf`` allowed.
    Parameters: ``"<name>.lower"``, ``"<name>.upper"``.
    """

    def __init__(self, lower, upper, name: str | None = None,
                 block: str | None = None) -> None:
        super().__init__(name, block)
        lo, up = np.broadcast_arrays(np.asarray(lower, float), np.asarray(upper, float))
        check_finite(lo, f"lower of bounds {name!r}", allow_inf=True)
        check_finite(up, f"upper of bounds {name!r}", allow_inf=True)
        check_bounds_order(lo, up, f"bounds {name!r}")
        self._lower, self._upper = lower, upper

    def terms(self, stack):
        size = stack.variables.size(self.block) if self.block else stack.variables.n
        lower = _vector(self._lower, size, f"lower of bounds {self.name!r}", allow_inf=True)
        upper = _vector(self._upper, size, f"upper of bounds {self.name!r}", allow_inf=True)
        check_bounds_order(lower, upper, f"bounds {self.name!r}")
        lo = stack.parameter(f"{self.name}.lower", size, lower, allow_inf=True)
        up = stack.parameter(f"{self.name}.upper", size, upper, allow_inf=True)
        return [VariableBounds(lo, up, self.block, self.name)]
