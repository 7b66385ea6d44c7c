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

from wbc.checks import (
    as_float_array,
    check_bounds_order,
    check_finite,
    checked_matrix,
    checked_name,
    checked_vector,
    checked_weights,
)
from wbc.errors import ShapeError
from wbc.terms import Cost, Inequality, Task, VariableBounds


class _Numeric(Task):
    """Shared plumbing: the variable block the coefficients act on, and parameter creation."""

    def __init__(self, name: str | None, block: str | None, kind: str) -> None:
        self.name = checked_name(name, f"name of {kind}")
        self.block = checked_name(block, f"block of {kind} {name!r}")

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
        weight: scalar ≥ 0, ``(m,)`` per-row weights, or a CasADi SX expression (1 × 1 or
            m × 1) of the stack's parameters, evaluated every tick (see
            :func:`wbc.checks.checked_weights`).
        name: task name; its parameters are ``"<name>.A"`` and ``"<name>.b"``.
        block: variable block the task acts on (``None``: all of ``x``).
    """

    def __init__(self, A, b, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        super().__init__(name, block, "task")
        self.A = checked_matrix(A, f"A of task {name!r}")
        self.b = checked_vector(b, self.A.shape[0], f"b of task {name!r}")
        self.weight = checked_weights(weight, self.A.shape[0], f"weight of task {name!r}")

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
        super().__init__(name, block, "constraint")
        self.C = checked_matrix(C, f"C of constraint {name!r}")
        m = self.C.shape[0]
        self.lower = checked_vector(lower, m, f"lower of constraint {name!r}", allow_inf=True)
        self.upper = checked_vector(upper, m, f"upper of constraint {name!r}", allow_inf=True)
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
        lower, upper: scalars or ``(n_block,)`` arrays; ``±inf`` allowed. Two arrays must have
            the same length (checked here; their length against the block's when added).
    Parameters: ``"<name>.lower"``, ``"<name>.upper"``.
    """

    def __init__(self, lower, upper, name: str | None = None,
                 block: str | None = None) -> None:
        super().__init__(name, block, "bounds")
        sides = []
        for side, value in (("lower", lower), ("upper", upper)):
            what = f"{side} of bounds {name!r}"
            arr = as_float_array(value, what)
            if arr.ndim == 2 and 1 in arr.shape:
                arr = arr.reshape(-1)
            if arr.ndim > 1 or arr.shape == (0,):
                raise ShapeError(f"{what} must be a scalar or a non-empty vector, got shape "
                                 f"{np.shape(value)}")
            check_finite(arr, what, allow_inf=True)
            sides.append(arr)
        lo, up = sides
        if lo.ndim and up.ndim and lo.shape != up.shape:
            raise ShapeError(f"bounds {name!r}: lower has {lo.shape[0]} entries but upper has "
                             f"{up.shape[0]}")
        lo_full, up_full = np.broadcast_arrays(lo, up)
        check_bounds_order(lo_full, up_full, f"bounds {name!r}")
        self._lower, self._upper = lo, up

    def terms(self, stack):
        size = stack.variables.size(self.block) if self.block else stack.variables.n
        lower = checked_vector(self._lower, size, f"lower of bounds {self.name!r}",
                               allow_inf=True)
        upper = checked_vector(self._upper, size, f"upper of bounds {self.name!r}",
                               allow_inf=True)
        check_bounds_order(lower, upper, f"bounds {self.name!r}")
        lo = stack.parameter(f"{self.name}.lower", size, lower, allow_inf=True)
        up = stack.parameter(f"{self.name}.upper", size, upper, allow_inf=True)
        return [VariableBounds(lo, up, self.block, self.name)]
