"""`Workspace`: the mutable half of a compiled stack (parameter vector, buffers, live solvers).

A :class:`~wbc.compiler.CompiledStack` is immutable and can be shared; each workspace owns the
parameter vector ``p``, one set of preallocated QP arrays per block, the CasADi evaluation
buffers that write into them, and one persistent backend per block. The tick is::

    for each block (level, scaling LP, min-norm):   # a loop over levels, never over tasks
        evaluate its compiled function into its arrays         (≈ 1–3 µs)
        below the first level: eliminate what the levels above froze (numpy, see below)
        if they leave a single point: that is the level's answer, no solve
        backend.update(...); backend.solve(warm start: its last solution, with the level
                                             above's x in place of its own)

Strict priorities by elimination
--------------------------------
Level ``k`` keeps every earlier level's optimum: ``E_j x = E_j x_j*`` for the cost rows
``E_j`` of each level ``j < k`` (the optimal set of a least-squares level is exactly that
affine set intersected with the feasible set). Those rows are not handed to the backend as
equalities: the workspace parametrises the affine set, ``x = x0 + N y`` — ``x0`` the level
above's ``x`` (with the variables this level fixes, ``lb == ub``, at their value), ``N`` an
orthonormal basis of the null space of the stacked rows (and of the fixed variables' unit
rows), from a QR factorisation with column pivoting whose rank counts the pivots above
``rank_tol·|R_00|`` (:class:`~wbc.Stack`) — and the level solves for ``y``. The variable
bounds become the rows ``lb − x0 <= N y <= ub − x0``. Why: frozen equality rows pass through a
vertex of the bounds as soon as limits saturate, the QP is then degenerate (dependent active
constraints, multipliers of 1e7) and solvers return answers 1e-3–1e-2 off or report failures
that are not there; the reduced QP has no equality rows at all, and ``y = 0`` (the level
above's optimum) is feasible by construction: the hard rows and frozen soft rows are widened
by at most what the level above violated them by (its solver's tolerance), so a level below
the first never fails as infeasible. The reduced QP has the block's size (``N`` is padded
with zero columns whose variables get a unit Hessian and stay 0), so each backend is set up
once.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np
from scipy.linalg import get_lapack_funcs

from .checks import check_bounds_order, checked_array
from .compiler import SCALING_LP, CompiledStack, QPBlock
from .errors import UnknownNameError, WbcError
from .infeasibility import Diagnosis
from .qp import Backend, QPResult, Status
from .solution import LevelResult, Solution, TaskResiduals, Timings

BackendSpec = str | Callable[[], Backend]

_ABS_RANK_TOL = 1e-12
try:  # the ufunc behind np.clip: one call, where np.clip's Python wrappers cost 4x more
    from numpy._core.umath import clip as _clip  # type: ignore[attr-defined]
except ImportError:  # numpy < 2
    from numpy.core.umath import clip as _clip  # type: ignore[no-redef]

_GESDD, _GEQP3, _ORGQR = get_lapack_funcs(("gesdd", "geqp3", "orgqr"), dtype=np.float64)
#: How far (relative) the level above's ``x`` may violate a constraint of the level below and
#: still count as meeting it (the largest default tolerance of the backends is osqp's 1e-5).
WIDEN_TOL = 1e-4
#: How close (relative) to a side the level above's ``x`` counts as on it: the side is moved
#: onto ``x`` (a sliver of the feasible set this thin is what solvers call infeasible).
SNAP_TOL = 1e-9
#: A row of the reduced QP whose coefficients are at most this (relative to the row's in ``x``)
#: is one the levels above determine completely: inert, or a conflict if ``x0`` violates it.
#: (1e-9 made quadprog's "inconsistent" slivers of the audit disappear, but moved the referees'
#: answers apart by 0.3 on two saturating ticks of ``wbc exactness``: kept at 1e-12.)
DEAD_TOL = 1e-12
#: After a failed solve, how close (relative) to a side ``x`` above counts as on it when the
#: level's implicit equalities are looked for (see :func:`_implicit_equalities`).
RETRY_ACTIVE_TOL = 1e-5
#: The largest weight of a row in the certificate of implicit equalities
#: (:func:`_implicit_equalities`): 1/√ε, so a row whose weight is below √ε of the largest —
#: roundoff of an exact dependence among the others — is not taken for one. Missing a row
#: leaves the level failed (a status); taking a wrong one would change its answer silently.
GORDAN_MAX = 1.0 / np.sqrt(np.finfo(float).eps)
_FIXED_ABOVE = ("a constraint of this level that the levels above fix completely is violated "
                "at their optimum")
_INCONSISTENT = ("the task's equations are inconsistent (target outside the range of its "
                 "Jacobian): no scale s > 0 can hold them")


def _svd(M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thin SVD ``(U, s, Vt)`` by calling LAPACK directly: for the few-row matrices of a tick
    numpy's wrapper costs more than the factorisation."""
    U, s, Vt, info = _GESDD(M, compute_uv=1, full_matrices=0)
    if info != 0:  # did not converge: let numpy raise or retry its way
        return np.linalg.svd(M, full_matrices=False)
    return U, s, Vt


def _null_space(M: np.ndarray, rank_tol: float, out: np.ndarray) -> int:
    """Write into the first columns of ``out`` (``n × n``) an orthonormal basis of the null
    space of ``M`` (``m × n``) and zero the rest; return the rank ``r`` of ``M`` (the basis
    has ``n − r`` columns). By QR with column pivoting of ``Mᵀ`` (LAPACK geqp3 + orgqr: half the
    time of an SVD for a tick's few rows); the rank counts the pivots ``|R_ii|`` above
    ``rank_tol·|R_00|`` (and an absolute floor)."""
    n = M.shape[1]
    qr, _, tau, _, _ = _GEQP3(M.T)
    pivots = qr.diagonal().tolist()  # few: Python beats numpy's per-call cost here
    tol = max(_ABS_RANK_TOL, rank_tol * abs(pivots[0])) if pivots else 0.0
    rank = sum(abs(pivot) > tol for pivot in pivots)
    k = tau.shape[0]
    reflectors = np.zeros((n, n))
    reflectors[:, :k] = qr[:, :k]
    Q, _, _ = _ORGQR(reflectors, tau)
    d = n - rank
    out[:, :d] = Q[:, rank:]
    out[:, d:] = 0.0
    return rank


def make_backend(spec: BackendSpec, profile: str, **options) -> Backend:
    """A fresh backend from a registered name (see :func:`wbc.solvers.make_backend`) or from a
    zero-argument factory."""
    if isinstance(spec, str):
        from wbc.solvers import make_backend as from_registry

        return from_registry(spec, profile=profile, **options)
    if callable(spec):
        return spec()
    raise WbcError(f"backend must be a name or a factory, got {type(spec).__name__}")


def _snap(side: np.ndarray, original: np.ndarray, kept: np.ndarray, sign: float) -> None:
    """Move to 0, in place, the reduced QP's lower (``sign`` −1) or upper (+1) sides ``side =
    original − a·x0`` of the rows in ``kept`` that ``x0`` violates by at most
    :data:`WIDEN_TOL` or meets within :data:`SNAP_TOL` (both relative): ``y = 0`` is then
    feasible whenever the level above met them to its solver's tolerance, a side it ends on is
    exactly active (so that degenerate vertices are recognised, see
    :func:`_implicit_equalities`), and a real conflict (a constraint of this level only that
    the level above's optimum violates) stays one. Infinite sides stay as they are."""
    scale = np.abs(original)
    scale += 1.0  # inf for an infinite side: neither comparison below then holds
    if sign < 0:
        near = side <= WIDEN_TOL * scale
        near &= side > -SNAP_TOL * scale
    else:
        near = side >= -WIDEN_TOL * scale
        near &= side < SNAP_TOL * scale
    near &= kept
    side[near] = 0.0


def _implicit_equalities(state: _BlockState) -> np.ndarray:
    """The rows (in ``x``) of the constraints that every feasible point of an eliminating
    block's reduced QP keeps (nearly) active: its implicit equalities. ``y = 0`` is feasible; a
    row active there (its side within :data:`RETRY_ACTIVE_TOL` of 0, relative: the level above's
    solver leaves its optimum that far inside a side it ends on, and the sliver between is what
    solvers call infeasible) holds as an equality on the whole feasible set if and only if some
    non-negative combination of the active rows, oriented into the feasible side, with a
    positive weight on it, is zero (Gordan). One LP finds every such row: maximise ``Σ t``
    over ``0 <= t <= 1``, ``t <= λ``, ``0 <= λ <=`` :data:`GORDAN_MAX`,
    ``Σ λ_i s_i g_i = 0``. Runs only when a level failed (milliseconds, scipy's HiGHS)."""
    from scipy.optimize import linprog

    m, n = state.m_rows, state.N.shape[0]
    A, lA, uA = state.Ar[:, :n], state.lAr, state.uAr
    considered = state.kept_rows
    lower = (lA >= -RETRY_ACTIVE_TOL * (1.0 + np.abs(state.lower0))) & np.isfinite(lA)
    lower &= considered
    upper = (uA <= RETRY_ACTIVE_TOL * (1.0 + np.abs(state.upper0))) & np.isfinite(uA)
    upper &= considered
    active = np.flatnonzero(lower | upper)
    if active.size == 0:
        return np.zeros((0, n))
    # each active side as a row g with g·y >= 0 on the feasible side; a row active on both
    # sides enters twice (it is an equality: both orientations cancel)
    rows = [(i, A[i]) for i in active if lower[i]] + [(i, -A[i]) for i in active if upper[i]]
    k = len(rows)
    G = np.array([g for _, g in rows])
    # variables [λ (k), t (k)]: maximise Σ t
    cost = np.concatenate((np.zeros(k), -np.ones(k)))
    A_eq = np.hstack((G.T, np.zeros((n, k))))
    A_ub = np.hstack((-np.eye(k), np.eye(k)))  # t − λ <= 0
    # λ <= GORDAN_MAX: a row counts (t > 1/2, so λ > 1/2) only with a weight above about
    # 1/GORDAN_MAX of the largest; an exact dependence among the other rows, scaled up without
    # bound, would otherwise lift a row whose weight in it is roundoff (1e-14 of the largest)
    # to λ >= 1 and freeze a row that is not an implicit equality — a smaller feasible set, a
    # "solved" level 0.1–0.8 rad/s off (ticks of `wbc bench`, mpo700_lwr4 / three_levels)
    bounds = [(0, GORDAN_MAX)] * k + [(0, 1)] * k
    result = linprog(cost, A_ub=A_ub, b_ub=np.zeros(k), A_eq=A_eq, b_eq=np.zeros(n),
                     bounds=bounds, method="highs")
    if result.status != 0:
        # HiGHS's presolve gives up ("numerical difficulties") on active rows that are
        # dependent to roundoff — the very case this LP is for (4 false INFEASIBLE levels in
        # 350 ticks of mpo700_lwr4 / three_levels / unreachable in `wbc bench`); the same LP
        # without presolve solves them
        result = linprog(cost, A_ub=A_ub, b_ub=np.zeros(k), A_eq=A_eq, b_eq=np.zeros(n),
                         bounds=bounds, method="highs", options={"presolve": False})
    if result.status != 0:
        return np.zeros((0, n))
    implicit = sorted({i for (i, _), t in zip(rows, result.x[k:], strict=True) if t > 0.5})
    # back in x: a bound row is its variable's unit row, the others the block's own rows
    return np.array([state.A[i, :n] if i < m else np.eye(n)[i - m] for i in implicit]
                    ).reshape(-1, n)


class _BlockState:
    """Arrays, CasADi buffer and backend of one QP block."""

    def __init__(self, block: QPBlock, n: int, p: np.ndarray, E: np.ndarray,
                 backend: Backend) -> None:
        self.block = block
        nz, m = block.n_z, block.m_total
        # CasADi writes H column-major; read row-major, that is Hᵀ, the same quadratic form (and
        # the same matrix: the compiled H is symmetric). C order spares backends a conversion.
        self.H = np.zeros((nz, nz))
        self.g = np.zeros(nz)
        self.A = np.zeros((m, nz))  # C order: row blocks are contiguous
        self.lA = np.full(m, -np.inf)
        self.uA = np.full(m, np.inf)
        self.lb = np.full(nz, -np.inf)
        self.ub = np.full(nz, np.inf)
        if block.kind == SCALING_LP:
            self.lb[n], self.ub[n] = 0.0, 1.0
        self.buffer, self.evaluate = block.function.buffer()
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        self.buffer.set_arg(0, memoryview(p))  # type: ignore[call-arg, arg-type]
        top = block.m_top
        outputs = [self.H.reshape(-1), self.g, self.A[:top].reshape(-1),
                   self.lA[:top], self.uA[:top], self.lb[:n], self.ub[:n],
                   E[block.e_offset:block.e_offset + block.m_cost].reshape(-1)]
        for i, out in enumerate(outputs):
            if out.size:
                self.buffer.set_res(i, memoryview(out))  # type: ignore[call-arg, arg-type]
        soft = slice(top, top + block.n_frozen_soft)  # earlier levels' soft rows, appended
        self.soft_rows, self.soft_lA, self.soft_uA = self.A[soft, :n], self.lA[soft], self.uA[soft]
        self.lb_x, self.ub_x = self.lb[:n], self.ub[:n]
        self.qp = (self.H, self.g, self.A, self.lA, self.uA, self.lb, self.ub)
        self.eliminates = block.n_frozen_cost > 0
        if self.eliminates:
            # The reduced QP in w = [y; the block's other variables] that the backend sees
            # (see the module docstring): its own rows and the frozen soft rows, then the
            # variable bounds of x as rows in y.
            m = soft.stop
            self.m_rows = m
            self.N = np.zeros((n, n))  # null-space basis, padded with zero columns
            self.x0 = np.zeros(n)
            self.Hr = np.zeros((nz, nz))
            self.gr = np.zeros(nz)
            self.Ar = np.zeros((m + n, nz))
            self.lAr = np.full(m + n, -np.inf)
            self.uAr = np.full(m + n, np.inf)
            self.lbr = np.full(nz, -np.inf)
            self.ubr = np.full(nz, np.inf)
            # rows y = 0 must satisfy: hard rows, frozen soft rows and the bounds (not own soft
            # rows, whose slack absorbs, nor a scaling LP's task equalities)
            self.kept_rows = np.ones(m + n, dtype=bool)
            self.kept_rows[block.m_hard:top] = False
            self.lower0, self.upper0 = np.zeros(m + n), np.zeros(m + n)  # sides before the shift
            self.shift = np.zeros(m + n)
            self.row_scale = np.ones(m + n)  # largest |entry| of each row in x
            self.qp = (self.Hr, self.gr, self.Ar, self.lAr, self.uAr, self.lbr, self.ubr)
        self.has_frozen_rows = bool(block.n_frozen_cost or block.n_frozen_soft)
        self.conflicting = False  # a row the levels above fix is violated (see _freeze)
        self.backend = backend
        self.ready = False  # backend.setup done
        self.warm: np.ndarray | None = None
        self.result: QPResult | None = None  # last backend result (multipliers included)


class Workspace:
    """Mutable state for solving a compiled stack every tick.

    Args:
        compiled: the compiled stack (``stack.compile()``).
        backend: a backend name (``wbc.solvers.available_backends()``) or a factory.
        profile: tolerance profile, ``"default"`` or ``"tight"``.
        warm_start: warm-start every QP from its previous solution.
        **options: backend options overriding the profile.

    Example:
        >>> ws = stack.workspace("proxqp")               # doctest: +SKIP
        >>> ws.set(J=J, v=v); sol = ws.solve()           # doctest: +SKIP
        >>> ws.view("J")[:] = J                          # zero-check fast path  # doctest: +SKIP
    """

    def __init__(self, compiled: CompiledStack, backend: BackendSpec = "daqp",
                 profile: str = "default", warm_start: bool = True, **options) -> None:
        self.compiled = compiled
        self.backend_name = backend if isinstance(backend, str) else getattr(
            backend, "__name__", "custom")
        self.profile = profile
        self.warm_start = warm_start
        n = compiled.n
        self.p = compiled.defaults.copy()
        self._unset = {name for name, (o, shape, _) in compiled.parameters.items()
                       if np.isnan(self.p[o:o + shape[0] * shape[1]]).any()}
        self._views = {name: self.p[o:o + shape[0] * shape[1]].reshape(shape, order="F")
                       for name, (o, shape, _) in compiled.parameters.items()}
        # "<t>.lower" and "<t>.upper" -> (stem, lower name, upper name), for pairs that exist
        self._bound_pairs = {f"{stem}.{side}": (stem, f"{stem}.lower", f"{stem}.upper")
                             for stem in {name.rpartition(".")[0] for name in self._views}
                             if f"{stem}.lower" in self._views and f"{stem}.upper" in self._views
                             for side in ("lower", "upper")}
        self._E = np.zeros((compiled.n_e, n))  # weighted cost rows of every level
        self._S = np.zeros((compiled.n_s, n))  # soft-inequality rows of every level
        self._lS = np.zeros(compiled.n_s)  # their bounds shifted by the optimal slacks
        self._uS = np.zeros(compiled.n_s)
        self._solved: list[_BlockState] = []  # blocks a backend solved in the last tick
        o = compiled.x_above_offset  # Stack.x_above(): the cascade's x, written per level
        self._x_above = None if o is None else self.p[o:o + n]
        self._blocks = [_BlockState(b, n, self.p, self._E,
                                    make_backend(backend, profile, **options))
                        for b in compiled.blocks]
        caveat = getattr(self._blocks[0].backend, "cascade_caveat", None)
        if caveat and len(self._blocks) > 1:
            warnings.warn(f"wbc: {self.backend_name} ({profile} profile) on a stack of "
                          f"{len(self._blocks)} QPs is not exact where limits saturate; "
                          f"measured: {caveat}. daqp and quadprog give the exact answer (see "
                          "the README's backend table)", RuntimeWarning, stacklevel=3)

    # ------------------------------------------------------------------ parameters
    @property
    def parameter_names(self) -> list[str]:
        return list(self._views)

    def view(self, name: str) -> np.ndarray:
        """Writable view of parameter ``name`` inside ``p`` (shape as declared, column-major).

        Writing into it is the zero-copy, zero-check path for controllers; :meth:`set` checks
        shapes and finiteness.
        """
        try:
            view = self._views[name]
        except KeyError:
            raise UnknownNameError(f"unknown parameter {name!r}; parameters are "
                                   f"{sorted(self._views)}") from None
        self._unset.discard(name)
        return view

    def set(self, **values) -> Workspace:
        """Set parameters by name, checked: known name, shape, NaN (and inf where illegal), and
        for a pair ``"<t>.lower"`` / ``"<t>.upper"`` (the numeric tasks' bounds) lower <=
        upper. All-or-nothing: every value is checked before any is written, so a refused
        call leaves the workspace as it was."""
        checked = {name: self.checked_value(name, value) for name, value in values.items()}
        self.check_bound_pairs(checked)
        for name, value in checked.items():
            self.view(name)[...] = value
        return self

    def check_bound_pairs(self, values: dict[str, np.ndarray]) -> None:
        """Raise :class:`~wbc.BoundsOrderError` if new ``values`` of a parameter pair
        ``"<t>.lower"`` / ``"<t>.upper"`` would cross (a side not in ``values`` keeps its
        current value)."""
        pairs = self._bound_pairs
        for name in values:
            pair = pairs.get(name)
            if pair is not None:
                stem, lower_name, upper_name = pair
                lower = values.get(lower_name, self._views[lower_name])
                upper = values.get(upper_name, self._views[upper_name])
                check_bounds_order(lower, upper, f"parameters {stem!r}.lower/.upper")

    def checked_value(self, name: str, value, what: str | None = None) -> np.ndarray:
        """``value`` checked for parameter ``name`` (shape, NaN, inf where illegal), as an
        array of its declared shape; nothing is written. ``what`` names it in errors."""
        if name not in self._views:
            raise UnknownNameError(f"unknown parameter {name!r}; parameters are "
                                   f"{sorted(self._views)}")
        _, shape, allow_inf = self.compiled.parameters[name]
        return checked_array(value, shape, what or f"parameter {name!r}", allow_inf)

    def variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` bounds of the decision vector ``x`` (hard bounds and pins) as
        evaluated by the last :meth:`solve` — live buffers, copy to keep."""
        first = self._blocks[0]
        return first.lb_x, first.ub_x

    def last_qps(self) -> list[tuple]:
        """For diagnostics and tests: per QP of the last tick, ``(label, (H, g, A, lA, uA, lb,
        ub), QPResult)`` — the exact arrays the backend saw (live buffers, copy to keep)."""
        return [(s.block.label, s.qp, s.result) for s in self._solved]

    def last_library_times(self) -> list[float | None]:
        """Per QP of :meth:`last_qps`, the seconds its backend spent inside the solver
        library's own calls (setup or update, and solve) in the last tick — the backend's
        ``library_time``; ``None`` for a backend that does not report it. The rest of the tick's
        ``timings.solve`` is the adapters' and the cascade's. For benchmarks (``wbc bench``)."""
        return [getattr(s.backend, "library_time", None) for s in self._solved]

    def cold_start(self) -> None:
        """Forget every backend's state: the next :meth:`solve` sets each QP's backend up
        afresh (a new solver model: no active set, factorization or iterate kept, no warm start)
        — a real cold start, the same for every backend, whose cost (the setup) the next
        solve's time includes. For benchmarks (``wbc bench --cold``); a fused tick
        (:mod:`wbc.fused`) always starts cold."""
        for state in self._blocks:
            state.ready = False
            state.warm = None

    # ------------------------------------------------------------------ the tick
    def solve(self) -> Solution:
        """Solve the cascade for the current parameters. Never raises on a numerical failure:
        the :class:`~wbc.Solution` carries the status."""
        if self._unset:
            raise WbcError(f"parameters never set: {sorted(self._unset)}")
        n = self.compiled.n
        clock = time.perf_counter
        assembly = solving = 0.0
        levels: list[LevelResult] = []
        scales: dict[int, float] = {}
        x: np.ndarray | None = None  # the decision vector after the last level solved
        status, message = Status.SOLVED, ""
        self._solved = solved = []
        x_above = self._x_above
        if x_above is not None:
            x_above[:] = 0.0
        for state in self._blocks:
            block = state.block
            t0 = clock()
            state.evaluate()
            # (x is set whenever a block has frozen rows: a solved level precedes it)
            rank = (self._freeze(state, x)  # type: ignore[arg-type]
                    if state.has_frozen_rows else 0)
            consistent = rank < 0 or block.kind != SCALING_LP or self._compress_task_rows(state)
            t1 = clock()
            result: QPResult | None = None  # None: the feasible set is the point x0
            if rank < 0:
                pass
            elif state.eliminates and state.conflicting:
                result = QPResult(np.zeros(block.n_z), Status.INFEASIBLE,
                                  np.zeros(block.m_total), np.zeros(block.n_z),
                                  message=_FIXED_ABOVE)
            elif not consistent:
                result = QPResult(np.zeros(block.n_z), Status.INFEASIBLE, np.zeros(block.m_total),
                                  np.zeros(block.n_z), message=_INCONSISTENT)
            elif state.ready:
                state.backend.update(*state.qp)
                warm = state.warm
                if warm is not None and x is not None:
                    # the level above's optimum is feasible here, and often near-optimal (in
                    # an eliminating block, it is y = 0)
                    warm = warm.copy()
                    warm[:n] = 0.0 if state.eliminates else x
                result = state.backend.solve(warm)
            else:
                state.backend.setup(*state.qp)
                state.ready = True
                result = state.backend.solve(None)
            if result is not None and result.status is not Status.SOLVED and state.eliminates \
                    and consistent and not state.conflicting:
                # y = 0 is feasible here by construction: a failure is the solver's, at a
                # degenerate vertex (more constraints active at y = 0 than they leave
                # directions). Eliminate the implicit equalities too and solve once more,
                # from a fresh setup (a hot start from the failed active set fails again).
                implicit = _implicit_equalities(state)
                if implicit.shape[0]:
                    rank = self._freeze(state, x, implicit)  # type: ignore[arg-type]
                if rank < 0:
                    result = None
                else:
                    state.backend.setup(*state.qp)
                    result = state.backend.solve(None)
            t2 = clock()
            assembly += t1 - t0
            solving += t2 - t1
            if result is None:  # the levels above (and their vertex) leave one point
                x = _clip(state.x0, state.lb_x, state.ub_x)
                if x_above is not None:
                    x_above[:] = x
                levels.append(LevelResult(block.label, Status.SOLVED, x.copy(), -rank, 0))
                continue
            state.result = result
            solved.append(state)
            if result.status is not Status.SOLVED:
                state.warm = None
                status = result.status
                # Which hard constraints conflict (one LP, found when first read): when the
                # backend says infeasible, or when the first QP failed (the command is then a
                # fallback; some backends stop at their iteration limit on an infeasible
                # problem). Named on the block's own arrays (x, not the reduced y).
                diagnosis = (Diagnosis(block, *self._with_frozen_rows(state),
                                       self.compiled.variables, p=self.p)
                             if status is Status.INFEASIBLE or x is None else None)
                message = f"{block.label}: {result.status.value}" + (
                    f" ({result.message})" if result.message else "") + self._diagnose(state)
                levels.append(LevelResult(block.label, result.status, np.zeros(n), rank,
                                          result.iterations, result.message, 0.0, diagnosis))
                break
            z = result.x
            if self.warm_start:
                state.warm = z
            z_x = state.x0 + state.N @ z[:n] if state.eliminates else z[:n]
            if block.kind == SCALING_LP:
                s = min(max(float(z[n]), 0.0), 1.0)
                scales[block.priority] = s  # type: ignore[index]  # a level's: not None
                self.p[block.scale_index] = s
                level_x = z_x.copy()
            else:
                # Exactly within the bounds: solvers meet them only to their tolerance (daqp
                # ~1e-11, osqp ~1e-5), and commands and the point frozen at x must not leave
                # them.
                x = level_x = _clip(z_x, state.lb_x, state.ub_x)
                if x_above is not None:
                    x_above[:] = x
                if block.m_soft:
                    self._freeze_soft_rows(state, z[n:])
            levels.append(LevelResult(block.label, result.status, level_x, rank,
                                      result.iterations, ""))
        partial = x is not None and status is not Status.SOLVED
        x = np.zeros(n) if x is None else x
        residuals = (None if self.compiled.residuals is None
                     else TaskResiduals(self.compiled, self.p.copy(), x))
        return Solution(x, status, levels, self.compiled.variables, scales,
                        Timings(0.0, assembly, solving), message, partial,
                        diagnosis=levels[-1].diagnosis if levels else None,
                        task_residuals=residuals)

    def _freeze(self, state: _BlockState, x: np.ndarray,
                implicit: np.ndarray | None = None) -> int:
        """Keep what the levels above achieved (see the module docstring): append their soft
        rows at their optimal slacks, and, under frozen cost rows, write the reduced QP in
        ``y`` (``x = x0 + N y``) into the block's backend arrays. Returns the rank of the
        frozen rows (with the unit rows of the variables this level fixes), negated when they
        leave the single point ``x0`` and the block has no other variable: nothing to solve.
        ``implicit``: more rows ``a`` to keep at ``a x0`` (see :func:`_implicit_equalities`)."""
        block = state.block
        if block.n_frozen_soft:
            state.soft_rows[...] = self._S[:block.n_frozen_soft]
            state.soft_lA[...] = self._lS[:block.n_frozen_soft]
            state.soft_uA[...] = self._uS[:block.n_frozen_soft]
        if not state.eliminates:
            return 0
        n = self.compiled.n
        lb, ub = state.lb_x, state.ub_x
        fixed = lb == ub
        x0, N = state.x0, state.N
        x0[:] = x
        E = self._E[:block.n_frozen_cost]
        if fixed.any():
            # a variable this level fixes (a per-level pin) is held at its value: a unit row
            # of its own, and out of the frozen rows, which would repeat it
            x0[fixed] = lb[fixed]
            E = np.vstack((E * ~fixed, np.eye(n)[fixed]))
        if implicit is not None:
            E = np.vstack((E, implicit))
        rank = _null_space(E, self.compiled.rank_tol, N)
        if rank == n and block.n_z == n:
            return -rank
        H, g, A, lA, uA = state.H, state.g, state.A, state.lA, state.uA
        Hr, gr, Ar, lAr, uAr = state.Hr, state.gr, state.Ar, state.lAr, state.uAr
        m = state.m_rows
        # w = T u with T = diag(N, I): H ← Tᵀ H T, g ← Tᵀ (H z0 + g), A ← A T, sides − A z0
        Hr[:n, :n] = N.T @ (H[:n, :n] @ N)
        nz = block.n_z
        Hr.flat[(n - rank) * (nz + 1):n * (nz + 1):nz + 1] = 1.0  # padding: unit Hessian, stays 0
        gr[:n] = N.T @ (H[:n, :n] @ x0 + g[:n])
        if nz > n:
            Hr[:n, n:] = N.T @ H[:n, n:]
            Hr[n:, :n] = Hr[:n, n:].T
            Hr[n:, n:] = H[n:, n:]
            gr[n:] = H[n:, :n] @ x0 + g[n:]
            Ar[:m, n:] = A[:m, n:]
            state.lbr[n:] = state.lb[n:]
            state.ubr[n:] = state.ub[n:]
        # the block's rows, then the bounds of x as rows in y; sides shifted by x0
        Ar[:m, :n] = A[:m, :n] @ N
        Ar[m:, :n] = N
        lower, upper, shift = state.lower0, state.upper0, state.shift
        lower[:m], lower[m:] = lA[:m], lb
        upper[:m], upper[m:] = uA[:m], ub
        shift[:m] = A[:m, :n] @ x0
        shift[m:] = x0
        np.subtract(lower, shift, out=lAr)
        np.subtract(upper, shift, out=uAr)
        kept = state.kept_rows
        _snap(lAr, lower, kept, -1.0)
        _snap(uAr, upper, kept, 1.0)
        # Rows the levels above determine (no y in them, to DEAD_TOL): inert when x0 meets them,
        # a conflict with the levels above when it does not (backends skip such zero rows).
        scale = state.row_scale
        scale[:m] = np.abs(A[:m]).max(axis=1, initial=0.0)
        dead = np.abs(Ar).max(axis=1) <= DEAD_TOL * (1.0 + scale)
        dead &= kept
        state.conflicting = False
        if dead.any():
            state.conflicting = bool(np.any(((lAr > 0.0) | (uAr < 0.0)) & dead))
            lAr[dead] = -np.inf
            uAr[dead] = np.inf
        return rank

    def _compress_task_rows(self, state: _BlockState) -> bool:
        """Replace a scaling LP's equality rows ``[A, −t] z = −r0`` (in the arrays the backend
        sees: reduced ones under frozen rows) by an orthonormal basis of their row space
        (rank-deficient tasks would hand the backend dependent equalities). Returns ``False``
        if the rows are inconsistent."""
        block = state.block
        rows = slice(block.m_hard, block.m_hard + block.m_task)
        A, lA, uA = state.qp[2:5]
        M, rhs = A[rows], lA[rows].copy()
        U, sv, Vt = _svd(M)
        rank = int(np.count_nonzero(sv > max(_ABS_RANK_TOL,
                                             self.compiled.rank_tol * float(sv[0]))))
        c = U[:, :rank].T @ rhs
        if np.linalg.norm(rhs - U[:, :rank] @ c) > 1e-9 * max(1.0, float(np.linalg.norm(rhs))):
            return False
        c /= sv[:rank]  # the rows Vt = Σ⁻¹ Uᵀ M take the right-hand side Σ⁻¹ Uᵀ rhs
        M[:rank] = Vt[:rank]
        M[rank:] = 0.0
        lA[rows][:rank] = c
        uA[rows][:rank] = c
        lA[rows][rank:] = -np.inf
        uA[rows][rank:] = np.inf
        return True

    def _freeze_soft_rows(self, state: _BlockState, slack: np.ndarray) -> None:
        """Later levels keep this level's soft rows at their optimal violation ``w*``:
        ``l + w* <= C x <= u + w*``."""
        block, n = state.block, self.compiled.n
        own = slice(block.m_hard, block.m_hard + block.m_soft)
        dest = slice(block.s_offset, block.s_offset + block.m_soft)
        self._S[dest] = state.A[own, :n]
        self._lS[dest] = state.lA[own] + slack
        self._uS[dest] = state.uA[own] + slack

    def _with_frozen_rows(self, state: _BlockState) -> tuple[np.ndarray, np.ndarray,
                                                            np.ndarray, np.ndarray, np.ndarray]:
        """``(A, lA, uA, lb, ub)`` of the block in ``x``, the levels above's optimum written as
        equality rows (an orthonormal basis of their cost rows, at ``x0``) into the rows the
        compiler keeps for them: what :class:`~wbc.infeasibility.Diagnosis` names a conflict
        with. Only for a failed QP: the tick eliminates these rows instead."""
        A, lA, uA = state.A.copy(), state.lA.copy(), state.uA.copy()
        block = state.block
        if state.eliminates:
            E = self._E[:block.n_frozen_cost] * (state.lb_x != state.ub_x)
            _, sv, Vt = _svd(E)
            rank = int(np.count_nonzero(sv > max(_ABS_RANK_TOL,
                                                 self.compiled.rank_tol * float(sv[0]))))
            rows = slice(block.m_top + block.n_frozen_soft,
                         block.m_top + block.n_frozen_soft + rank)
            A[rows, :self.compiled.n] = Vt[:rank]
            lA[rows] = uA[rows] = Vt[:rank] @ state.x0
        return A, lA, uA, state.lb, state.ub

    def _diagnose(self, state: _BlockState) -> str:
        """Name the culprit of a failure when the data itself is contradictory."""
        n = self.compiled.n
        bad = np.flatnonzero(state.lb[:n] > state.ub[:n])
        if bad.size:
            return f"; bounds have lower > upper at x[{int(bad[0])}]"
        bad = np.flatnonzero(state.lA[:state.block.m_hard] > state.uA[:state.block.m_hard])
        if bad.size:
            return f"; hard constraint row {int(bad[0])} has lower > upper"
        return ""
