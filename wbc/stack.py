"""`Stack`: a prioritised stack of tasks over an explicit decision vector."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .checks import (
    as_float_array,
    check_finite,
    check_symbols,
    checked_array,
    checked_integer,
    checked_name,
    checked_number,
    checked_shape,
)
from .errors import InvalidValueError, NonAffineError, ShapeError, WbcError
from .quantities import STATE_QUANTITIES
from .terms import Cost, Inequality, Task, Term, VariableBounds
from .variables import Variables


@dataclass
class Parameter:
    """A named numeric input of a stack (a matrix), written into the workspace every tick.

    Attributes:
        name: unique within the stack; tasks sharing a quantity share the name.
        shape: ``(rows, cols)``.
        symbol: the CasADi symbol (``SX.sym(name, rows, cols)``).
        default: value used until set, or ``None`` (then it must be set before solving).
        allow_inf: bounds may hold ``±inf``; other coefficients may not.
        quantity: a model quantity (``stack.quantity``): a controller fills it from the robot
            every tick (see :mod:`wbc.quantities`); otherwise a reference the user sets.
    """

    name: str
    shape: tuple[int, int]
    symbol: ca.SX
    default: np.ndarray | None = None
    allow_inf: bool = False
    quantity: bool = False

    @property
    def size(self) -> int:
        return self.shape[0] * self.shape[1]


@dataclass
class Entry:
    """A term placed in the stack: at a level (soft) or as a hard constraint."""

    term: Term
    task_name: str
    weight: float | ca.SX = 1.0
    levels: frozenset[int] | None = None  # hard constraints: where they hold (None: everywhere)

    def holds_at(self, priority: int | None) -> bool:
        """Whether this hard constraint is part of the QP of level ``priority`` (``None``: the
        final minimum-norm level, which only constraints of every level reach)."""
        return self.levels is None or (priority is not None and priority in self.levels)


class Stack:
    """Ordered priority levels of tasks, plus hard constraints, over ``variables``.

    Within a level tasks are weighted; between levels priorities are strict (lexicographic),
    solved as a cascade: level ``k`` minimises its own cost while every earlier level's optimum
    is kept (cost rows at their optimal values, by elimination: the level solves in their null
    space; slacks of soft inequalities frozen). Lower ``priority`` numbers come first.

    Args:
        variables: a :class:`Variables`, a mapping ``name -> size``, or an ``int`` (one block
            ``"x"``).
        damping: ``ρ`` of the regularisation ``ρ²/2 · xᵀ W x`` added to every level, or a
            mapping ``priority -> ρ`` (unlisted levels undamped). The regularisation is not
            frozen: later levels see only the earlier levels' task rows.
        metric: ``W`` (symmetric PSD ``(n, n)``, or ``(n,)`` diagonal); identity by default.
        mobility: alternative to ``metric``: a symmetric PSD mobility ``M = W⁻¹``. Directions
            in its null space are pinned to zero (hard), and ``W = M⁺`` elsewhere — so that the
            one-level stack reproduces ``M Jᵀ(J M Jᵀ + ρ² I)⁻¹ v`` (docs/DESIGN.md, math note 1). A
            mobility that changes every tick, or that holds at some levels only: see
            :meth:`set_mobility`.
        min_norm: add a final level minimising ``xᵀ W x`` under everything above, which makes
            the answer unique when the levels leave freedom. Default: on when the last level
            is undamped.
        rank_tol: relative tolerance of the rank of the frozen rows (pivots of a
            rank-revealing QR: the levels below move in their null space, see
            :mod:`wbc.workspace`) and of a scaling level's task rows (singular values).
        freeze_tol: deprecated and ignored (a warning says so): the levels above are kept
            exactly, by elimination, since 0.2 (it was the half-width of a band the frozen
            equality rows were held in).

    Example:
        >>> import numpy as np, wbc
        >>> from wbc.tasks import LinearTask, Bounds
        >>> stack = wbc.Stack(wbc.Variables(qd=3))
        >>> _ = stack.add(LinearTask(np.eye(2, 3), [1.0, 2.0], name="track"), priority=0)
        >>> _ = stack.constrain(Bounds(-1.5, 1.5))
        >>> stack.solve("daqp").x.round(6)
        array([1. , 1.5, 0. ])
    """

    def __init__(
        self,
        variables: Variables | Mapping[str, int] | int,
        damping: float | Mapping[int, float] = 0.0,
        metric: np.ndarray | None = None,
        mobility: np.ndarray | None = None,
        min_norm: bool | None = None,
        rank_tol: float = 1e-9,
        freeze_tol: float = 0.0,
    ) -> None:
        if isinstance(variables, (int, np.integer)):
            variables = Variables(x=int(variables))
        elif not isinstance(variables, Variables):
            variables = Variables(variables)
        self.variables = variables
        n = variables.n
        per_level: Mapping[int, float] = damping if isinstance(damping, Mapping) else {}
        default = 0.0 if isinstance(damping, Mapping) else float(damping)
        for rho in [*per_level.values(), default]:
            if not np.isfinite(rho) or rho < 0:
                raise InvalidValueError(f"damping must be a finite number >= 0, got {rho!r}")
        self._damping = {int(k): float(v) for k, v in per_level.items()}
        self._default_damping = default
        if metric is not None and mobility is not None:
            raise WbcError("give either metric or mobility, not both")
        self.metric, self.pinned = _metric_and_pins(n, metric, mobility)
        self.mobility_diagonal: ca.SX | None = None  # per-tick diagonal (set_mobility)
        self.mobility_levels: frozenset[int] | None = None  # None: every level
        self._x_above: ca.SX | None = None
        self._min_norm = min_norm
        self.rank_tol = float(rank_tol)
        if freeze_tol:
            warnings.warn("wbc.Stack: freeze_tol is ignored: strict priorities are kept "
                          "exactly, by elimination (see wbc.workspace)", DeprecationWarning,
                          stacklevel=2)
        self.parameters: dict[str, Parameter] = {}
        self.levels: dict[int, list[Entry]] = {}
        self.scaling_levels: set[int] = set()
        self.constraints: list[Entry] = []
        self._names: set[str] = set()
        self._compiled = None
        self._controlled = False  # a Controller was built from it: edits are refused
        self._workspaces: dict = {}

    # ------------------------------------------------------------------ composition
    def parameter(self, name: str, shape: int | tuple[int, ...], default=None,
                  allow_inf: bool = False) -> ca.SX:
        """Declare (or fetch, if already declared with the same shape) a parameter.

        Args:
            name: unique name; set its value with ``workspace.set(name=value)``.
            shape: ``rows`` or ``(rows, cols)``.
            default: initial value (numbers of that shape), or ``None``.
            allow_inf: whether ``±inf`` entries are legal (bounds).

        Returns:
            The CasADi symbol, to be used in task expressions.
        """
        checked_name(name, "name of stack.parameter", optional=False)
        shape = checked_shape(shape, f"parameter {name!r}")
        if not isinstance(allow_inf, (bool, np.bool_)):
            raise InvalidValueError(f"allow_inf of parameter {name!r} must be True or False, "
                                    f"got {allow_inf!r}")
        if name in self.parameters:
            known = self.parameters[name]
            if known.shape != shape:
                raise ShapeError(f"parameter {name!r} is declared with shape {shape} but "
                                 f"exists with shape {known.shape}")
            if default is not None:
                known.default = checked_array(default, known.shape, f"parameter {name!r}",
                                              known.allow_inf)
            return known.symbol
        param = Parameter(name, shape, ca.SX.sym(name, *shape), None, allow_inf)
        if default is not None:
            param.default = checked_array(default, shape, f"parameter {name!r}", allow_inf)
        self.parameters[name] = param
        self._edited()
        return param.symbol

    def quantity(self, name: str, shape: int | tuple[int, ...]) -> ca.SX:
        """Declare (or fetch) a *model quantity*: a parameter that a :class:`~wbc.Controller`
        fills from its robot every tick — ``"q"``, ``"v"``, ``"dt"`` or a name the robot's
        quantity registry offers (``"pose[ee]"``, ``"J[ee]"``, ``"Jdot_v[ee]"``, ``"com"``, ...;
        see :mod:`wbc.quantities`). Outside a controller it is set like any parameter.

        Returns:
            The CasADi symbol, of ``shape`` (``rows`` or ``(rows, cols)``).
        """
        if name in self._names:  # a task "com" and the quantity "com": one keyword
            raise WbcError(_shadowing_message(name, name))
        symbol = self.parameter(name, shape)
        self.parameters[name].quantity = True
        return symbol

    def add(self, task: Task, priority: int = 0, weight: float | ca.SX = 1.0,
            scaling: bool = False) -> Stack:
        """Add ``task`` at ``priority`` (0 first) with a weight inside its level.

        Equalities become costs, inequalities become soft (slack-minimising).

        Args:
            weight: one number ``>= 0`` for the whole task (per-row weights are the task's own
                ``weight=``), or a ``1 × 1`` CasADi SX expression of this stack's parameters
                (``stack.parameter("w", 1)``), set every tick like any parameter. It
                multiplies the task's own weight.
            scaling: make the level a task-scaling level: first maximise ``s ∈ [0, 1]`` such
                that its costs hold exactly with their targets scaled by ``s`` (an LP), then
                solve the level with ``s`` fixed (the QP form of SNS).

        Refused, each with a :class:`~wbc.WbcError` naming the task, and leaving the stack as
        it was: a name already in the stack; a name that is a model quantity's — ``"q"``,
        ``"v"``, ``"dt"``, or one the stack declares (``"com"`` of a
        :class:`~wbc.tasks.com.ComTask`): a reference keyword ``com=...`` could not tell the
        task's target from the quantity (the :class:`~wbc.Controller` refuses the names of the
        plain parameters its robot fills); a symbolic weight, here or the task's own, that
        holds symbols other than this stack's parameters or depends on the decision vector.
        """
        what = f"stack.add({getattr(task, 'name', None)!r})"
        checked_integer(priority, f"priority of {what}", low=None)
        if isinstance(weight, ca.DM) and weight.numel() == 1:  # CasADi's number: a number
            weight = float(weight)
        if not isinstance(weight, ca.SX):
            if isinstance(weight, (np.ndarray, list, tuple, ca.DM)):
                array = as_float_array(weight.full() if isinstance(weight, ca.DM) else weight,
                                       f"weight of {what}")
                if array.size != 1:
                    raise ShapeError(f"weight of {what} is one number for the whole task, got "
                                     f"shape {array.shape}; give per-row weights to the task "
                                     "(its weight=)")
                weight = array.reshape(())
            weight = checked_number(weight, f"weight of {what}")
        elif weight.shape != (1, 1):  # per-row weights are the task's (e.g. LinearTask's)
            raise ShapeError(f"weight of {what}: a symbolic weight must be 1 x 1, got "
                             f"{weight.shape}; give per-row weights to the task")
        else:
            self._check_weight(weight, f"weight of {what}")
        if not isinstance(scaling, (bool, np.bool_)):
            raise InvalidValueError(f"scaling of {what} must be True or False, got {scaling!r}")
        entries = self._entries(task, weight)
        for e in entries:
            if isinstance(e.term, VariableBounds):
                raise WbcError(f"task {e.task_name!r}: bounds are hard; use stack.constrain()")
            if scaling and isinstance(e.term, Inequality):
                raise WbcError(f"task {e.task_name!r}: a scaling level takes costs and "
                               "equalities only")
        self.levels.setdefault(int(priority), []).extend(entries)
        if scaling:
            self.scaling_levels.add(int(priority))
        self._edited()
        return self

    def constrain(self, task: Task, levels=None) -> Stack:
        """Add a hard constraint (equality, inequality or bounds).

        Args:
            levels: ``None`` (default): enforced at every level, the minimum-norm level
                included. An iterable of priorities: a *level-local* constraint, part of those
                levels' QPs only. Later levels do not inherit it: like every level they keep
                only the earlier levels' task rows (cost rows at their optimal values, soft
                rows at their optimal slacks), so they may move what it held. The minimum-norm
                level takes only constraints of every level.
        """
        levels = self._levels(levels, "constrain")
        entries = self._entries(task, 1.0)
        for e in entries:
            if isinstance(e.term, Cost):
                raise WbcError(f"task {e.task_name!r} is a cost; add it with stack.add()")
            e.levels = levels
        self.constraints.extend(entries)
        self._edited()
        return self

    def set_mobility(self, mobility, levels=None) -> Stack:
        """Set the mobility ``M = W⁻¹`` of the regularisation ``ρ²/2 · xᵀ W x``.

        Args:
            mobility: a constant symmetric PSD ``(n, n)`` matrix or diagonal ``(n,)`` (as the
                constructor's ``mobility``), or a *per-tick* diagonal: a CasADi SX column of
                ``n`` entries built from this stack's parameters (e.g. ``(1 − ψ, ..., ψ, ...)``
                with ``ψ = stack.parameter("psi", 1)`` or an expression of model quantities).
                It is evaluated every tick inside the compiled functions: no recompilation,
                and its singular values are exact — an entry ``m_i <= 1e-12`` pins ``x_i = 0``
                (a bound ``0 <= x_i <= 0``, added per tick) and takes ``W_ii = 0``; any other
                entry takes ``W_ii = 1/m_i``. Entries must be ``>= 0`` (negative ones are
                treated as zero: pinned).
            levels: priorities at which the mobility holds (its metric *and* its pins, both
                level-local, see :meth:`constrain`); ``None``: every level and the
                minimum-norm level. Elsewhere the metric is the identity and nothing is
                pinned. Sorour et al.'s eq. 9 needs ``levels=[0]``: the pins of ψ ∈ {0, 1}
                hold while the task is solved, and the null-space level below still moves the
                pinned joints.
        """
        n = self.variables.n
        if not isinstance(mobility, (ca.SX, ca.MX, ca.DM)):
            mobility = as_float_array(mobility, "mobility")
        elif isinstance(mobility, ca.SX) and mobility.numel() == n:
            check_symbols(mobility, [self.variables.symbol,
                                     *(p.symbol for p in self.parameters.values())], "mobility")
        if isinstance(mobility, (ca.SX, ca.MX, ca.DM)):
            if isinstance(mobility, ca.MX):
                raise WbcError("mobility: MX expressions are not supported, build with ca.SX")
            diagonal = ca.SX(mobility)
            if diagonal.shape == (1, n):
                diagonal = diagonal.T
            if diagonal.shape != (n, 1):
                raise ShapeError(f"a per-tick mobility is the diagonal, an SX column of {n} "
                                 f"entries; got shape {diagonal.shape}")
            if ca.depends_on(diagonal, self.variables.symbol):
                raise WbcError("mobility must not depend on the decision vector")
            self.metric, self.pinned = np.eye(n), None
            self.mobility_diagonal = diagonal
        else:
            self.metric, self.pinned = _metric_and_pins(n, None, mobility)
            self.mobility_diagonal = None
        self.mobility_levels = self._levels(levels, "set_mobility")
        self._edited()
        return self

    def x_above(self) -> ca.SX:
        """The decision vector found by the levels above, as a symbol for task expressions.

        When a level is evaluated, this holds the cascade's ``x`` so far (the last solved
        level's optimum; zeros at the first level). It makes the exact QP form of an additive
        null-space term possible (docs/DESIGN.md, math note 3): a level minimising
        ``||x − x_above − λz||²`` under the frozen rows of the level above.

        Returns:
            SX column of ``n`` entries.
        """
        if self._x_above is None:
            self._x_above = ca.SX.sym("x_above", self.variables.n)
            self._edited()
        return self._x_above

    def _edited(self) -> None:
        """Drop the cached compilation after an edit — refused once a :class:`~wbc.Controller`
        was built from this stack: it compiled a snapshot, and the edit would silently not
        reach it."""
        if self._controlled:
            raise WbcError("this stack was compiled into a wbc.Controller, which keeps what it "
                           "compiled: an edit now would not reach it. Finish the stack before "
                           "building controllers, or build a new stack (and controller)")
        self._compiled = None

    @staticmethod
    def _levels(levels, what: str) -> frozenset[int] | None:
        if levels is None:
            return None
        if isinstance(levels, (int, np.integer)):
            levels = [levels]
        try:
            chosen = frozenset(int(k) for k in levels)
        except (TypeError, ValueError, OverflowError):
            raise WbcError(f"{what}: levels must be None or integer priorities, "
                           f"got {levels!r}") from None
        if not chosen:
            raise WbcError(f"{what}: levels is empty (use None for every level)")
        return chosen

    def mobility_holds_at(self, priority: int | None) -> bool:
        """Whether the mobility (metric and pins) is part of level ``priority``'s QP
        (``None``: the minimum-norm level)."""
        return self.mobility_levels is None or (priority is not None
                                                and priority in self.mobility_levels)

    def _entries(self, task: Task, weight) -> list[Entry]:
        if not isinstance(task, Task):
            raise WbcError(f"expected a wbc task, got {type(task).__name__}")
        if isinstance(weight, (int, float, np.floating)):
            if not np.isfinite(weight) or weight < 0:
                raise InvalidValueError(f"weight must be a finite number >= 0, got {weight!r}")
        name = task.name or f"{type(task).__name__.lower()}{len(self._names)}"
        if not isinstance(name, str):
            raise InvalidValueError(f"a task's name must be a str, got {name!r}")
        if name in self._names:
            raise WbcError(f"a task named {name!r} is already in the stack")
        if name in STATE_QUANTITIES:
            raise WbcError(_shadowing_message(name, name))
        # a task the stack refuses leaves it as it was: the parameters its terms() declared
        # are dropped again
        before, x_above = dict(self.parameters), self._x_above
        flags = {k: p.quantity for k, p in before.items()}
        try:
            task.name = name  # unnamed tasks are named by the stack, so their parameters too
            terms = list(task.terms(self))
            if not terms:
                raise WbcError(f"task {name!r} produced no terms")
            for term in terms:
                if isinstance(term, Cost) and isinstance(term.weight, ca.SX):
                    self._check_weight(term.weight, f"weight of task {name!r}")
            quantities = [k for k, p in self.parameters.items() if p.quantity]
            for quantity in quantities:  # "com" and the task's "com.target": one keyword
                if name == quantity:
                    raise WbcError(_shadowing_message(name, quantity))
        except BaseException:
            self.parameters, self._x_above = before, x_above
            for key, flag in flags.items():
                before[key].quantity = flag
            raise
        self._names.add(name)
        return [Entry(t, name, weight) for t in terms]

    def _check_weight(self, weight: ca.SX, what: str) -> None:
        """A symbolic weight must be an expression of this stack's parameters (and of
        :meth:`x_above`), never of the decision vector (the cost would not be quadratic)."""
        if ca.depends_on(weight, self.variables.symbol):
            raise NonAffineError(f"{what} depends on the decision vector; a weight is an "
                                 "expression of the stack's parameters (stack.parameter(...))")
        known = [p.symbol for p in self.parameters.values()]
        if self._x_above is not None:
            known.append(self._x_above)
        check_symbols(weight, known, what)

    @property
    def task_names(self) -> list[str]:
        """The names of the tasks and constraints added so far, sorted."""
        return sorted(self._names)

    # ------------------------------------------------------------------ use
    @property
    def priorities(self) -> list[int]:
        """The priorities in solving order."""
        return sorted(self.levels)

    def damping(self, priority: int) -> float:
        """``ρ`` of level ``priority``."""
        return self._damping.get(priority, self._default_damping)

    @property
    def min_norm(self) -> bool:
        """Whether a final minimum-norm level is solved."""
        if self._min_norm is not None:
            return bool(self._min_norm)
        return not self.levels or self.damping(self.priorities[-1]) == 0.0

    def compile(self):
        """Compile (once; cached until the stack changes) into an immutable
        :class:`~wbc.compiler.CompiledStack`."""
        if self._compiled is None:
            from .compiler import compile_stack

            self._compiled = compile_stack(self)
            self._workspaces.clear()
        return self._compiled

    def workspace(self, backend="daqp", profile: str = "default", jit: bool = False,
                  **options):
        """A new mutable :class:`~wbc.workspace.Workspace` (buffers + live solvers).

        Args:
            jit: evaluate the level functions as compiled C instead of CasADi's virtual
                machine (needs a C compiler; each function is built once per machine and
                cached on disk, see :mod:`wbc.jit`).
        """
        from .passes import jit_compiled
        from .workspace import Workspace

        compiled = jit_compiled(self.compile()) if jit else self.compile()
        return Workspace(compiled, backend, profile, **options)

    def solve(self, backend="daqp", profile: str = "default",
              params: Mapping[str, np.ndarray] | None = None, **values):
        """One-off solve with the given parameter values; returns a :class:`~wbc.Solution`.

        Workspaces are cached per backend and profile, so repeated calls reuse live solvers.
        Parameter names with dots (``"task.A"``) go in ``params``.
        """
        key = (backend, profile)
        compiled = self.compile()
        ws = self._workspaces.get(key)
        if ws is None:
            from .workspace import Workspace

            ws = self._workspaces[key] = Workspace(compiled, backend, profile)
        if params:
            ws.set(**params)
        if values:
            ws.set(**values)
        return ws.solve()



def _shadowing_message(task_name: str, quantity: str) -> str:
    """The message of a task name that is also a model quantity's (see :meth:`Stack.add`)."""
    return (f"task name {task_name!r} shadows the model quantity {quantity!r}: the controller "
            f"fills {quantity!r} every tick, and a reference keyword {task_name}=... would "
            f"name the quantity, not the task's target; name the task otherwise, e.g. "
            f"{task_name + '_task'!r}")


def _metric_and_pins(n: int, metric, mobility) -> tuple[np.ndarray, np.ndarray | None]:
    """Return ``(W, P)``: the regularisation metric and the rows ``P`` with ``P x = 0`` pinned
    (``None`` if nothing is pinned)."""
    if mobility is None:
        if metric is None:
            return np.eye(n), None
        W = np.asarray(metric, dtype=float)
        if W.ndim == 1:
            W = np.diag(W)
        _check_psd(W, n, "metric")
        return W, None
    M = np.asarray(mobility, dtype=float)
    if M.ndim == 1:
        M = np.diag(M)
    _check_psd(M, n, "mobility")
    eigval, eigvec = np.linalg.eigh(M)
    keep = eigval > 1e-12 * max(1.0, eigval.max())
    W = (eigvec[:, keep] / eigval[keep]) @ eigvec[:, keep].T
    pinned = eigvec[:, ~keep].T
    return W, (pinned if pinned.shape[0] else None)


def _check_psd(W: np.ndarray, n: int, what: str) -> None:
    if W.shape != (n, n):
        raise ShapeError(f"{what} must be ({n},) or ({n}, {n}), got {W.shape}")
    check_finite(W, what)
    if not np.allclose(W, W.T, atol=1e-12):
        raise InvalidValueError(f"{what} must be symmetric")
    if np.linalg.eigvalsh(W).min() < -1e-12 * max(1.0, np.abs(W).max()):
        raise InvalidValueError(f"{what} must be positive semi-definite")

