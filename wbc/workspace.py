"""`Workspace`: the mutable half of a compiled stack (parameter vector, buffers, live solvers).

A :class:`~wbc.compiler.CompiledStack` is immutable and can be shared; each workspace owns the
parameter vector ``p``, one set of preallocated QP arrays per block, the CasADi evaluation
buffers that write into them, and one persistent backend per block. The tick is::

    for each block (level, scaling LP, min-norm):   # a loop over levels, never over tasks
        evaluate its compiled function into its arrays         (≈ 1–3 µs)
        append frozen rows of earlier levels (numpy)
        if they leave a single point: that is the level's answer, no solve
        backend.update(...); backend.solve(warm start: its last solution, with the level
                                             above's x in place of its own)
        on failure under exact frozen rows: once more within a 1e-7 band
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from scipy.linalg import get_lapack_funcs

from .checks import check_bounds_order, checked_array
from .compiler import SCALING_LP, CompiledStack, QPBlock
from .errors import UnknownNameError, WbcError
from .infeasibility import Diagnosis
from .qp import Backend, QPResult, Status
from .solution import LevelResult, Solution, Timings

BackendSpec = str | Callable[[], Backend]

_ABS_RANK_TOL = 1e-12
try:  # the ufunc behind np.clip: one call, where np.clip's Python wrappers cost 4x more
    from numpy._core.umath import clip as _clip  # type: ignore[attr-defined]
except ImportError:  # numpy < 2
    from numpy.core.umath import clip as _clip  # type: ignore[no-redef]

_GESDD, _GEQP3, _ORGQR = get_lapack_funcs(("gesdd", "geqp3", "orgqr"), dtype=np.float64)
_RETRY_BAND = 1e-7  # relative half-width of the frozen rows when the exact solve failed
_INCONSISTENT = ("the task's equations are inconsistent (target outside the range of its "
                 "Jacobian): no scale s > 0 can hold them")


def _svd(M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thin SVD ``(U, s, Vt)`` by calling LAPACK directly: for the few-row matrices of a tick
    numpy's wrapper costs more than the factorisation."""
    U, s, Vt, info = _GESDD(M, compute_uv=1, full_matrices=0)
    if info != 0:  # did not converge: let numpy raise or retry its way
        return np.linalg.svd(M, full_matrices=False)
    return U, s, Vt


def _row_basis(M: np.ndarray, rank_tol: float) -> tuple[int, np.ndarray]:
    """``(r, Q)``: the rank of ``M`` and, in the first ``r`` columns of ``Q``, an orthonormal
    basis of its row space, by QR with column pivoting of ``Mᵀ`` (LAPACK geqp3 + orgqr: half
    the time of an SVD for a tick's few rows). The rank counts the pivots ``|R_ii|`` above
    ``rank_tol·|R_00|`` (and an absolute floor)."""
    qr, _, tau, _, _ = _GEQP3(M.T)
    pivots = qr.diagonal().tolist()  # few: Python beats numpy's per-call cost here
    tol = max(_ABS_RANK_TOL, rank_tol * abs(pivots[0]))
    rank = sum(abs(pivot) > tol for pivot in pivots)
    Q, _, _ = _ORGQR(qr[:, :tau.shape[0]], tau)
    return rank, Q


def make_backend(spec: BackendSpec, profile: str, **options) -> Backend:
    """A fresh backend from a registered name (see :func:`wbc.solvers.make_backend`) or from a
    zero-argument factory."""
    if isinstance(spec, str):
        from wbc.solvers import make_backend as from_registry

        return from_registry(spec, profile=profile, **options)
    if callable(spec):
        return spec()
    raise WbcError(f"backend must be a name or a factory, got {type(spec).__name__}")


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
        # Views of the rows the cascade appends each tick (fixed places, made once).
        soft = slice(top, top + block.n_frozen_soft)
        eq = slice(soft.stop, soft.stop + block.m_frozen_eq)
        self.soft_rows, self.soft_lA, self.soft_uA = self.A[soft, :n], self.lA[soft], self.uA[soft]
        self.eq_rows, self.eq_lA, self.eq_uA = self.A[eq, :n], self.lA[eq], self.uA[eq]
        self.frozen_rank = 0  # frozen equality rows in use; the rest are inert (0, ±inf)
        self.lb_x, self.ub_x = self.lb[:n], self.ub[:n]
        self.qp = (self.H, self.g, self.A, self.lA, self.uA, self.lb, self.ub)
        self.has_frozen_rows = bool(block.n_frozen_cost or block.n_frozen_soft)
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
            rank = (self._append_frozen_rows(state, x)  # type: ignore[arg-type]
                    if state.has_frozen_rows else 0)
            if rank < 0:  # the levels above leave one point, x: nothing to solve
                assembly += clock() - t0
                levels.append(LevelResult(block.label, Status.SOLVED,
                                          x.copy(), -rank, 0))  # type: ignore[union-attr]
                continue
            consistent = block.kind != SCALING_LP or self._compress_task_rows(state)
            t1 = clock()
            if not consistent:
                result = QPResult(np.zeros(block.n_z), Status.INFEASIBLE, np.zeros(block.m_total),
                                  np.zeros(block.n_z), message=_INCONSISTENT)
            elif state.ready:
                state.backend.update(*state.qp)
                warm = state.warm
                if warm is not None and x is not None:
                    # the level above's optimum is feasible here, and often near-optimal
                    warm = warm.copy()
                    warm[:n] = x
                result = state.backend.solve(warm)
            else:
                state.backend.setup(*state.qp)
                state.ready = True
                result = state.backend.solve(None)
            if (result.status is not Status.SOLVED and consistent and rank
                    and not self.compiled.freeze_tol):
                # Exact frozen rows through a vertex of the bounds leave a single feasible point,
                # which solvers can miss by their last digit: retry within a thin band.
                band = _RETRY_BAND
                self._widen_frozen_rows(state, rank, band)
                state.backend.update(*state.qp)
                result = state.backend.solve(None)
            else:
                band = self.compiled.freeze_tol if rank else 0.0
            t2 = clock()
            state.result = result
            solved.append(state)
            assembly += t1 - t0
            solving += t2 - t1
            if result.status is not Status.SOLVED:
                state.warm = None
                status = result.status
                # Which hard constraints conflict (one LP, found when first read): when the
                # backend says infeasible, or when the first QP failed (the command is then a
                # fallback; some backends stop at their iteration limit on an infeasible
                # problem).
                diagnosis = (Diagnosis(block, *state.qp[2:], self.compiled.variables)
                             if status is Status.INFEASIBLE or x is None else None)
                message = f"{block.label}: {result.status.value}" + (
                    f" ({result.message})" if result.message else "") + self._diagnose(state)
                levels.append(LevelResult(block.label, result.status, np.zeros(n), rank,
                                          result.iterations, result.message, band, diagnosis))
                break
            z = result.x
            if self.warm_start:
                state.warm = z
            if block.kind == SCALING_LP:
                s = min(max(float(z[n]), 0.0), 1.0)
                scales[block.priority] = s  # type: ignore[index]  # a level's: not None
                self.p[block.scale_index] = s
                level_x = z[:n].copy()
            else:
                # Exactly within the bounds: solvers meet them only to their tolerance (daqp
                # ~1e-11, osqp ~1e-5), and commands and the rows frozen at x must not leave them.
                x = level_x = _clip(z[:n], state.lb_x, state.ub_x)
                if x_above is not None:
                    x_above[:] = x
                if block.m_soft:
                    self._freeze_soft_rows(state, z[n:])
            levels.append(LevelResult(block.label, result.status, level_x, rank,
                                      result.iterations, "", band))
        partial = x is not None and status is not Status.SOLVED
        return Solution(np.zeros(n) if x is None else x, status, levels,
                        self.compiled.variables, scales, Timings(0.0, assembly, solving), message,
                        partial, diagnosis=levels[-1].diagnosis if levels else None)

    def _append_frozen_rows(self, state: _BlockState, x: np.ndarray) -> int:
        """Write earlier levels' frozen rows below the block's own rows; return the rank of the
        frozen cost rows, negated when with the fixed variables it determines every variable
        of the block (which has no slack then): the level's feasible set is the point x."""
        block = state.block
        if block.n_frozen_soft:
            state.soft_rows[...] = self._S[:block.n_frozen_soft]
            state.soft_lA[...] = self._lS[:block.n_frozen_soft]
            state.soft_uA[...] = self._uS[:block.n_frozen_soft]
        if not block.n_frozen_cost:
            return 0
        # Keep A_j x = A_j x_j* for every earlier level j, as an orthonormal basis of the
        # stacked rows' row space: backends never see dependent equalities. Variables fixed by
        # their bounds (lb == ub, e.g. pinned by a zero mobility) are left out of the rows, or
        # the rows would repeat those bounds.
        E = self._E[:block.n_frozen_cost]
        fixed = state.lb_x == state.ub_x
        n_fixed = int(np.count_nonzero(fixed))
        if n_fixed:
            E = E * ~fixed
        rank, Q = _row_basis(E, self.compiled.rank_tol)
        basis = Q[:, :rank].T
        rows, lA, uA = state.eq_rows, state.eq_lA, state.eq_uA
        rows[:rank] = basis
        if rank < state.frozen_rank:  # rows beyond the rank become inert again
            rows[rank:state.frozen_rank] = 0.0
            lA[rank:state.frozen_rank] = -np.inf
            uA[rank:state.frozen_rank] = np.inf
        state.frozen_rank = rank
        # x is within the bounds (see solve): rows frozen at a point outside them would leave
        # later levels a feasible set a solver can judge empty.
        rhs = basis @ x
        lA[:rank] = rhs
        uA[:rank] = rhs
        if self.compiled.freeze_tol:
            self._widen_frozen_rows(state, rank, self.compiled.freeze_tol)
        if rank + n_fixed == block.n_z and np.array_equal(x[fixed], state.lb_x[fixed]):
            # x itself meets every row kept and the variables this level fixes (a level-local
            # pin may fix one that x moved)
            return -rank
        return rank

    @staticmethod
    def _widen_frozen_rows(state: _BlockState, rank: int, tol: float) -> None:
        """Turn the ``rank`` frozen equalities ``a x = c`` into ``|a x − c| <= tol·(1 + |c|)``."""
        c = state.eq_lA[:rank].copy()
        band = tol * (1.0 + np.abs(c))
        state.eq_lA[:rank] = c - band
        state.eq_uA[:rank] = c + band

    def _compress_task_rows(self, state: _BlockState) -> bool:
        """Replace a scaling LP's equality rows ``[A, −t] z = −r0`` by an orthonormal basis of
        their row space (rank-deficient tasks would hand the backend dependent equalities).
        Returns ``False`` if the rows are inconsistent."""
        block = state.block
        rows = slice(block.m_hard, block.m_hard + block.m_task)
        M, rhs = state.A[rows], state.lA[rows]
        U, sv, Vt = _svd(M)
        rank = int(np.count_nonzero(sv > max(_ABS_RANK_TOL,
                                             self.compiled.rank_tol * float(sv[0]))))
        c = U[:, :rank].T @ rhs
        if np.linalg.norm(rhs - U[:, :rank] @ c) > 1e-9 * max(1.0, float(np.linalg.norm(rhs))):
            return False
        c /= sv[:rank]  # the rows Vt = Σ⁻¹ Uᵀ M take the right-hand side Σ⁻¹ Uᵀ rhs
        M[:rank] = Vt[:rank]
        M[rank:] = 0.0
        state.lA[rows][:rank] = c
        state.uA[rows][:rank] = c
        state.lA[rows][rank:] = -np.inf
        state.uA[rows][rank:] = np.inf
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
