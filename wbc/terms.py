"""Task terms: the affine pieces a stack is made of, and the base class of every task.

All terms are affine in the decision vector ``x`` with coefficients that may depend on
parameters (numbers set every tick):

* :class:`Cost` — ``weight/2 · ||expr − target||²`` (soft; ``weight`` scalar or per row),
* :class:`Equality` — ``expr = target``,
* :class:`Inequality` — ``lower <= expr <= upper``,
* :class:`VariableBounds` — ``lower <= x[block] <= upper``.

Where a term goes decides how hard it is: ``stack.add(term, priority=k)`` makes equalities
costs and inequalities soft (slack-minimising) at level ``k``; ``stack.constrain(term)`` makes
it hard at every level. Affinity in ``x`` is checked when the stack is compiled.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .checks import check_finite
from .errors import ShapeError

Expr = ca.SX | np.ndarray | float | int


def as_sx_column(value: Expr, rows: int | None, what: str, allow_inf: bool = False) -> ca.SX:
    """Return ``value`` as an SX column of ``rows`` entries (a scalar is broadcast).

    Numbers are checked: NaN is always refused, ``±inf`` unless ``allow_inf``.
    """
    if isinstance(value, (ca.SX, ca.MX, ca.DM)):
        if isinstance(value, ca.MX):
            raise ShapeError(f"{what}: MX expressions are not supported, build with ca.SX")
        sx = ca.SX(value)
        if sx.shape[1] != 1 and sx.shape[0] == 1:
            sx = sx.T
        if sx.shape[1] != 1:
            raise ShapeError(f"{what}: expected a column expression, got shape {sx.shape}")
        if rows is not None and sx.shape[0] != rows:
            if sx.shape[0] == 1:
                return ca.repmat(sx, rows, 1)
            raise ShapeError(f"{what}: expected {rows} rows, got {sx.shape[0]}")
        return sx
    arr = np.asarray(value, dtype=float)
    check_finite(arr, what, allow_inf)
    if arr.ndim == 0:
        if rows is None:
            rows = 1
        arr = np.full(rows, float(arr))
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1 or (rows is not None and arr.shape[0] != rows):
        raise ShapeError(f"{what}: expected shape ({rows},), got {np.shape(value)}")
    return ca.SX(ca.DM(arr))


class Task:
    """Base class of everything that can be added to a stack.

    A task turns itself into terms when added: :meth:`terms` receives the
    :class:`~wbc.Stack`, whose ``variables``, :meth:`~wbc.Stack.parameter` and
    :meth:`~wbc.Stack.quantity` it may use to create its symbols. (The stack is not annotated:
    ``wbc.stack`` imports this module, and the core keeps its imports one-way.)
    """

    name: str | None = None

    def terms(self, stack) -> Sequence[Term]:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"


class Term(Task):
    """A single affine term; it is its own task."""

    def terms(self, stack) -> Sequence[Term]:
        return [self]


@dataclass(repr=False)
class Cost(Term):
    """Soft task ``weight/2 · ||expr − target||²``.

    Args:
        expr: SX column, affine in the stack's decision vector.
        target: SX or numbers, independent of ``x``; it is what a task-scaling level scales
            (``s·target``), so put drift terms such as ``J̇q̇`` in ``expr``, not here.
        weight: scalar or per-row weights (numbers ≥ 0, or an SX parameter).
        name: used in error messages and solution reports.
        residual: what :attr:`wbc.Solution.residuals` reports for this term, an expression
            of ``x`` and the parameters in the task's own units (default ``expr − target``).
    """

    expr: Expr
    target: Expr = 0.0
    weight: Expr = 1.0
    name: str | None = None
    residual: Expr | None = None


@dataclass(repr=False)
class Equality(Term):
    """``expr = target``; a cost at a priority level, hard in ``stack.constrain``."""

    expr: Expr
    target: Expr = 0.0
    name: str | None = None


@dataclass(repr=False)
class Inequality(Term):
    """``lower <= expr <= upper`` (use ``±numpy.inf`` for a missing side)."""

    expr: Expr
    lower: Expr = -np.inf
    upper: Expr = np.inf
    name: str | None = None


@dataclass(repr=False)
class VariableBounds(Term):
    """``lower <= x[block] <= upper`` element-wise; always hard (``stack.constrain``).

    Bounds are passed to the backends as bounds, never as rows of ``A``.
    """

    lower: Expr = -np.inf
    upper: Expr = np.inf
    block: str | None = None
    name: str | None = None
