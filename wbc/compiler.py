"""Compilation of a :class:`~wbc.Stack` into one CasADi function per QP of the cascade.

Every QP the tick solves (a level's least-squares QP, a scaling level's LP, the final
minimum-norm QP) is a *block* with a compiled function ``p -> (H, g, Aᵀ_top, l_top, u_top, lb,
ub, Eᵀ)``, where ``p`` is the stack's parameter vector. The rows the cascade adds at run time
(frozen soft-inequality rows of earlier levels) are appended by the workspace; the block only
records how many there can be, so that every backend sees fixed shapes. The earlier levels'
cost rows ``E`` are eliminated, not appended (see :mod:`wbc.workspace`); the block keeps room
for them (``m_frozen_eq``) only to write them back when a failed QP's conflict is named.

Matrices ``A_top`` and ``E`` are returned transposed: CasADi writes column-major, so the
transpose lands row-major, straight into row blocks of C-ordered numpy arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from .errors import InvalidValueError, NonAffineError, WbcError
from .terms import Cost, Equality, Inequality, VariableBounds, as_sx_column
from .variables import Variables

LEVEL, SCALING_LP, MIN_NORM = "level", "scaling_lp", "min_norm"
PINNED = "zero mobility"  # the name of the hard rows and bounds that pin a direction


@dataclass(frozen=True)
class HardNames:
    """Where a level's hard rows and bounds come from.

    Attributes:
        rows: the constraint name of each hard row (``"zero mobility"`` for a pinned direction).
        bounds: per variable, the names of the constraints bounding it (several when bounds
            overlap; the tightest one holds).
        bound_owners: the names of the constraints that bound variables, each once.
        bound_values: ``p -> (L, U)``, each ``(n, len(bound_owners))``: column ``j`` is the
            lower and upper bound constraint ``bound_owners[j]`` alone puts on ``x`` (±inf
            where it does not bound), in ``x``'s units; ``lb``/``ub`` are their row-wise
            max/min. ``None`` when not compiled.
    """

    rows: tuple[str, ...]
    bounds: tuple[tuple[str, ...], ...]
    bound_owners: tuple[str, ...] = ()
    bound_values: ca.Function | None = None


@dataclass(frozen=True)
class QPBlock:
    """One QP solved each tick, with the sizes the workspace allocates for it.

    Attributes:
        kind: ``"level"``, ``"scaling_lp"`` or ``"min_norm"``.
        priority: the stack priority it belongs to (``None`` for the min-norm level).
        task_names: tasks at this level (for reports and error messages).
        function: ``p -> (H, g, Aᵀ_top, l_top, u_top, lb, ub, Eᵀ)``.
        n_z: decision size of this QP (``n`` plus slacks, or plus the scale ``s``).
        m_hard: hard rows (first rows of ``A_top``).
        m_soft: own soft-inequality rows (after the hard rows; slack columns follow ``x``).
        m_task: own equality rows of a scaling LP.
        m_cost: cost rows this level adds to the frozen-row store ``E``.
        e_offset: first row of this level in ``E``.
        s_offset: first row of this level's soft rows in the frozen soft-row store ``S``.
        n_frozen_soft: rows of ``S`` frozen by earlier levels.
        n_frozen_cost: rows of ``E`` frozen by earlier levels (before compression).
        m_frozen_eq: room for an orthonormal basis of the frozen cost rows,
            ``min(n_frozen_cost, n)``: filled only to name a failed QP's conflict.
        scale_index: index in ``p`` of this level's scale ``s`` (scaling levels only).
        hard_names: which hard constraint each hard row and each variable's bounds come from
            (for naming the constraints of an infeasible level, see :mod:`wbc.infeasibility`).
    """

    kind: str
    priority: int | None
    task_names: tuple[str, ...]
    function: ca.Function
    n_z: int
    m_hard: int
    m_soft: int
    m_task: int
    m_cost: int
    e_offset: int
    s_offset: int
    n_frozen_soft: int
    n_frozen_cost: int
    m_frozen_eq: int
    scale_index: int | None
    hard_names: HardNames | None = None

    @property
    def m_top(self) -> int:
        return self.m_hard + self.m_soft + self.m_task

    @property
    def m_total(self) -> int:
        return self.m_top + self.n_frozen_soft + self.m_frozen_eq

    @cached_property
    def label(self) -> str:
        if self.kind == MIN_NORM:
            return "min-norm level"
        what = "scaling LP of level" if self.kind == SCALING_LP else "level"
        return f"{what} {self.priority} (tasks: {', '.join(self.task_names)})"


@dataclass(frozen=True)
class CompiledStack:
    """The immutable, shareable result of compiling a stack.

    Attributes:
        variables: the decision vector's layout.
        parameters: ``name -> (offset, shape, allow_inf)`` in the parameter vector ``p``
            (matrices stored column-major).
        defaults: initial ``p`` (NaN where a parameter has no default).
        blocks: the QPs in solving order.
        n_e: rows of the frozen cost-row store; ``n_s``: rows of the frozen soft-row store.
        rank_tol: relative tolerance of the rank compression.
        quantities: names of the parameters declared as model quantities
            (:meth:`wbc.Stack.quantity`), which a controller fills from its robot.
        residuals: ``(p, x) -> r``: every task's residual at ``x`` (see :data:`residual_rows`),
            ``None`` for a stack compiled without (see :meth:`wbc.Solution.residuals`).
        residual_rows: task name -> its rows in ``r``.
        x_above_offset: first index in ``p`` of :meth:`wbc.Stack.x_above` (``n`` entries the
            workspace writes after every level), or ``None`` if no task uses it.
    """

    variables: Variables
    parameters: dict
    defaults: np.ndarray
    blocks: tuple[QPBlock, ...]
    n_e: int
    n_s: int
    rank_tol: float
    quantities: frozenset[str] = frozenset()
    x_above_offset: int | None = None
    residuals: ca.Function | None = None
    residual_rows: dict[str, slice] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.variables.n


class _Affine:
    """Coefficients of an affine expression ``expr = C x + c0``."""

    def __init__(self, expr, x: ca.SX, rows: int | None, what: str) -> None:
        expr = as_sx_column(expr, rows, what)
        C = ca.jacobian(expr, x)
        if ca.depends_on(C, x):
            raise NonAffineError(f"{what} is not affine in the decision vector "
                                 "(its Jacobian depends on x)")
        self.C = C
        self.c0 = ca.substitute(expr, x, ca.SX.zeros(x.shape))
        self.rows = expr.shape[0]


def _independent(value, x: ca.SX, rows: int, what: str, allow_inf: bool = False) -> ca.SX:
    sx = as_sx_column(value, rows, what, allow_inf)
    if ca.depends_on(sx, x):
        raise NonAffineError(f"{what} must not depend on the decision vector")
    return sx


def compile_stack(stack) -> CompiledStack:
    """Compile ``stack`` (see module docstring). Raises on non-affine or ill-shaped tasks."""
    variables: Variables = stack.variables
    x, n = variables.symbol, variables.n
    if not stack.levels:
        raise WbcError("the stack has no task: add one with stack.add(task, priority=...)")

    params = list(stack.parameters.values())
    scale_syms = {k: ca.SX.sym(f"scale_{k}") for k in sorted(stack.scaling_levels)}
    x_above = [] if stack._x_above is None else [stack._x_above]
    p_sym = ca.vertcat(*[ca.vec(P.symbol) for P in params], *scale_syms.values(), *x_above)
    layout, offset = {}, 0
    for P in params:
        layout[P.name] = (offset, P.shape, P.allow_inf)
        offset += P.size
    defaults = np.full(p_sym.shape[0], np.nan)
    for P in params:
        if P.default is not None:
            o = layout[P.name][0]
            defaults[o:o + P.size] = P.default.reshape(-1, order="F")
    scale_index = {k: offset + i for i, k in enumerate(scale_syms)}
    defaults[list(scale_index.values())] = 1.0
    x_above_offset = offset + len(scale_syms) if x_above else None
    if x_above:
        defaults[x_above_offset:] = 0.0

    blocks: list[QPBlock] = []
    n_e = n_s = 0
    residuals: dict[str, list[ca.SX]] = {}  # task name -> its residual rows
    for k in sorted(stack.levels):
        C_h, l_h, u_h, lb, ub, hard_names = _hard_constraints(stack, x, n, k, p_sym)
        W = _metric(stack, k)
        entries = stack.levels[k]
        names = tuple(dict.fromkeys(e.task_name for e in entries))
        costs, softs = _level_terms(entries, x)
        for e in entries:
            residuals.setdefault(e.task_name, []).append(_residual(e.term, x))
        A_c = ca.vertcat(*[c[0] for c in costs]) if costs else ca.SX(0, n)
        r0 = ca.vertcat(*[c[1] for c in costs]) if costs else ca.SX(0, 1)
        t = ca.vertcat(*[c[2] for c in costs]) if costs else ca.SX(0, 1)
        common = dict(priority=k, task_names=names, n_frozen_soft=n_s, n_frozen_cost=n_e,
                      m_frozen_eq=min(n_e, n), hard_names=hard_names)
        if k in scale_syms:
            # LP over z = [x; s]: maximise s with A x + r0 = s t exactly.
            A_lp = ca.horzcat(A_c, -t)
            hard = ca.horzcat(C_h, ca.SX(C_h.shape[0], 1))
            fn = _block_function(
                f"scaling_lp_{k}", p_sym, ca.SX(n + 1, n + 1),
                ca.vertcat(ca.SX.zeros(n), -1), ca.vertcat(hard, A_lp),
                ca.vertcat(l_h, -r0), ca.vertcat(u_h, -r0), lb, ub, ca.SX(n, 0))
            blocks.append(QPBlock(SCALING_LP, function=fn, n_z=n + 1, m_hard=C_h.shape[0],
                                  m_soft=0, m_task=A_c.shape[0], m_cost=0, e_offset=n_e,
                                  s_offset=n_s, scale_index=scale_index[k], **common))
            t = scale_syms[k] * t
        b = t - r0
        m_s = sum(s[0].shape[0] for s in softs)
        C_s = ca.vertcat(*[s[0] for s in softs]) if softs else ca.SX(0, n)
        l_s = ca.vertcat(*[s[1] for s in softs]) if softs else ca.SX(0, 1)
        u_s = ca.vertcat(*[s[2] for s in softs]) if softs else ca.SX(0, 1)
        w_s = ca.vertcat(*[s[3] for s in softs]) if softs else ca.SX(0, 1)
        H = ca.diagcat(A_c.T @ A_c + stack.damping(k) ** 2 * W, ca.diag(w_s))
        g = ca.vertcat(-A_c.T @ b, ca.SX.zeros(m_s))
        A_top = ca.vertcat(ca.horzcat(C_h, ca.SX(C_h.shape[0], m_s)),
                           ca.horzcat(C_s, -ca.SX.eye(m_s)))
        fn = _block_function(f"level_{k}", p_sym, H, g, A_top, ca.vertcat(l_h, l_s),
                             ca.vertcat(u_h, u_s), lb, ub, A_c)
        blocks.append(QPBlock(LEVEL, function=fn, n_z=n + m_s, m_hard=C_h.shape[0],
                              m_soft=m_s, m_task=0, m_cost=A_c.shape[0], e_offset=n_e,
                              s_offset=n_s, scale_index=scale_index.get(k), **common))
        n_e += A_c.shape[0]
        n_s += m_s

    if stack.min_norm:
        C_h, l_h, u_h, lb, ub, hard_names = _hard_constraints(stack, x, n, None, p_sym)
        W = _metric(stack, None)
        fn = _block_function("min_norm", p_sym, W, ca.SX.zeros(n), C_h, l_h, u_h, lb, ub,
                             ca.SX(n, 0))
        blocks.append(QPBlock(MIN_NORM, None, (), fn, n_z=n, m_hard=C_h.shape[0], m_soft=0,
                              m_task=0, m_cost=0, e_offset=n_e, s_offset=n_s,
                              n_frozen_soft=n_s, n_frozen_cost=n_e, m_frozen_eq=min(n_e, n),
                              scale_index=None, hard_names=hard_names))
    residual_rows, start = {}, 0
    for name, rows in residuals.items():
        size = sum(r.shape[0] for r in rows)
        residual_rows[name] = slice(start, start + size)
        start += size
    r = ca.vertcat(*[row for rows in residuals.values() for row in rows])
    return CompiledStack(variables, layout, defaults, tuple(blocks), n_e, n_s, stack.rank_tol,
                         frozenset(P.name for P in params if P.quantity),
                         x_above_offset, ca.Function("residuals", [p_sym, x], [r]),
                         residual_rows)


def _residual(term, x: ca.SX) -> ca.SX:
    """A task term's residual at ``x``, unweighted, in the task's units: the cost's own
    ``residual`` expression if it has one, else ``expr − target`` of a cost or equality (the
    target unscaled: a scaling level's ``s < 1`` shows), the signed violation
    ``min(expr − lower, 0) + max(expr − upper, 0)`` of a soft inequality (0 inside)."""
    if isinstance(term, Inequality):
        expr = as_sx_column(term.expr, None, "")
        rows = expr.shape[0]
        lower = as_sx_column(term.lower, rows, "", True)
        upper = as_sx_column(term.upper, rows, "", True)
        return ca.fmin(expr - lower, 0) + ca.fmax(expr - upper, 0)
    if isinstance(term, Cost) and term.residual is not None:
        return as_sx_column(term.residual, None, "")
    expr = as_sx_column(term.expr, None, "")
    return expr - as_sx_column(term.target, expr.shape[0], "")


#: A per-tick mobility entry at or below this value is zero: the variable is pinned.
ZERO_MOBILITY = 1e-12


def _metric(stack, priority: int | None) -> ca.SX:
    """``W`` of the regularisation at level ``priority`` (``None``: the min-norm level):
    ``M⁺`` where the mobility holds, else the identity."""
    n = stack.variables.n
    if not stack.mobility_holds_at(priority):
        return ca.SX.eye(n)
    m = stack.mobility_diagonal
    if m is None:
        return ca.SX(ca.DM(stack.metric))
    free = m > ZERO_MOBILITY
    return ca.diag(ca.if_else(free, 1.0 / ca.if_else(free, m, 1.0), 0.0))


def _level_terms(entries, x):
    """Split a level's entries into cost rows ``(√w·A, √w·r0, √w·t)`` and soft inequality rows
    ``(C, l − c0, u − c0, w)``."""
    costs, softs = [], []
    for e in entries:
        term, what = e.term, f"task {e.task_name!r}"
        if isinstance(term, (Cost, Equality)):
            aff = _Affine(term.expr, x, None, what)
            target = _independent(term.target, x, aff.rows, f"target of {what}")
            weight = term.weight if isinstance(term, Cost) else 1.0
            if not isinstance(weight, ca.SX) and np.any(np.asarray(weight) < 0):
                raise InvalidValueError(f"weight of {what} must be >= 0, got {weight!r}")
            w = _independent(weight, x, aff.rows, f"weight of {what}") * e.weight
            sq = ca.sqrt(w)
            costs.append((ca.diag(sq) @ aff.C, sq * aff.c0, sq * target))
        elif isinstance(term, Inequality):
            aff = _Affine(term.expr, x, None, what)
            lo = _independent(term.lower, x, aff.rows, f"lower bound of {what}", True)
            up = _independent(term.upper, x, aff.rows, f"upper bound of {what}", True)
            w = _independent(e.weight, x, aff.rows, f"weight of {what}")
            softs.append((aff.C, lo - aff.c0, up - aff.c0, w))
        else:
            raise WbcError(f"{what}: unsupported term {type(term).__name__}")
    return costs, softs


def _hard_constraints(stack, x, n, priority: int | None, p_sym: ca.SX | None = None):
    """Rows ``l_h <= C_h x <= u_h`` and bounds ``lb <= x <= ub`` of level ``priority``
    (``None``: the min-norm level): constraints of every level, those local to this level, and
    the mobility's pins where it holds; and the :class:`HardNames` of those rows and bounds
    (with ``HardNames.bound_values`` a function of ``p_sym`` when given)."""
    rows, lows, ups = [], [], []
    row_names: list[str] = []
    bound_names: list[list[str]] = [[] for _ in range(n)]
    lb, ub = ca.SX(ca.DM.ones(n) * -np.inf), ca.SX(ca.DM.ones(n) * np.inf)
    owned: dict[str, tuple[ca.SX, ca.SX]] = {}  # name -> the bounds it alone puts on x

    def own(name: str, index, lo, up) -> None:
        lower, upper = owned.setdefault(name, (ca.SX(ca.DM.ones(n) * -np.inf),
                                               ca.SX(ca.DM.ones(n) * np.inf)))
        lower[index] = ca.fmax(lower[index], lo)
        upper[index] = ca.fmin(upper[index], up)
    for e in stack.constraints:
        if not e.holds_at(priority):
            continue
        term, what = e.term, f"constraint {e.task_name!r}"
        if isinstance(term, VariableBounds):
            sl = stack.variables.slice(term.block)
            size = sl.stop - sl.start
            lo = _independent(term.lower, x, size, f"lower bound of {what}", True)
            up = _independent(term.upper, x, size, f"upper bound of {what}", True)
            lb[sl] = ca.fmax(lb[sl], lo)
            ub[sl] = ca.fmin(ub[sl], up)
            own(e.task_name, sl, lo, up)
            for names in bound_names[sl]:
                names.append(e.task_name)
            continue
        aff = _Affine(term.expr, x, None, what)
        if isinstance(term, Equality):
            target = _independent(term.target, x, aff.rows, f"target of {what}")
            lo = up = target - aff.c0
        else:
            lo = _independent(term.lower, x, aff.rows, f"lower bound of {what}", True) - aff.c0
            up = _independent(term.upper, x, aff.rows, f"upper bound of {what}", True) - aff.c0
        rows.append(aff.C)
        lows.append(lo)
        ups.append(up)
        row_names += [e.task_name] * aff.rows
    pins = stack.mobility_holds_at(priority)
    if pins and stack.mobility_diagonal is not None:
        free = stack.mobility_diagonal > ZERO_MOBILITY
        lb = ca.fmax(lb, ca.if_else(free, -np.inf, 0.0))
        ub = ca.fmin(ub, ca.if_else(free, np.inf, 0.0))
        own(PINNED, slice(0, n), ca.if_else(free, -np.inf, 0.0), ca.if_else(free, np.inf, 0.0))
        for names in bound_names:
            names.append(PINNED)
    if pins and stack.pinned is not None:
        for row in stack.pinned:  # zero-mobility directions: bounds if axis-aligned, else rows
            axis = np.flatnonzero(np.abs(row) > 1e-12)
            if axis.size == 1:
                lb[int(axis[0])] = ca.fmax(lb[int(axis[0])], 0)
                ub[int(axis[0])] = ca.fmin(ub[int(axis[0])], 0)
                own(PINNED, int(axis[0]), 0, 0)
                bound_names[int(axis[0])].append(PINNED)
            else:
                rows.append(ca.SX(ca.DM(row.reshape(1, -1))))
                lows.append(ca.SX(0))
                ups.append(ca.SX(0))
                row_names.append(PINNED)
    values = None
    if p_sym is not None:
        columns = list(owned.values())
        values = ca.Function("bound_values", [p_sym], [
            ca.densify(ca.horzcat(*[c[0] for c in columns])) if columns else ca.SX(n, 0),
            ca.densify(ca.horzcat(*[c[1] for c in columns])) if columns else ca.SX(n, 0)])
    names = HardNames(tuple(row_names), tuple(tuple(dict.fromkeys(b)) for b in bound_names),
                      tuple(owned), values)
    if rows:
        return ca.vertcat(*rows), ca.vertcat(*lows), ca.vertcat(*ups), lb, ub, names
    return ca.SX(0, n), ca.SX(0, 1), ca.SX(0, 1), lb, ub, names


def _block_function(name, p_sym, H, g, A_top, l_top, u_top, lb, ub, E) -> ca.Function:
    outputs = [H, g, A_top.T, l_top, u_top, lb, ub, E.T]
    try:
        return ca.Function(name, [p_sym], [ca.densify(ca.SX(o)) for o in outputs],
                           ["p"], ["H", "g", "AT", "lA", "uA", "lb", "ub", "ET"])
    except RuntimeError as err:
        if "free" in str(err):
            raise WbcError(f"{name}: a task uses CasADi symbols that are neither the stack's "
                           "variables nor parameters declared with stack.parameter(): "
                           f"{str(err).split('variables')[-1].split('are free')[0].strip()}"
                           ) from None
        raise
