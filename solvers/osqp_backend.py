"""OSQP (ADMM, sparse) behind the :class:`wbc.qp.Backend` contract.

OSQP has one constraint form, ``l <= A x <= u``: the bounds become identity rows appended to
``A`` (:class:`~wbc.solvers.forms.StackedConstraints`). ``setup`` once with the dense pattern of
``triu(H)`` and of ``[A; I]`` as CSC (zeros kept as structural entries), then every tick
``update(q, l, u, Px, Ax)`` with the value vectors of that unchanged pattern. OSQP warm-starts
from its previous iterate (``warm_starting``); a primal guess given to :meth:`solve` replaces the
primal part; after a failed solve the iterate is reset to zero. ``±inf`` (clipped to
``OSQP_INFTY`` by the wrapper) and singular or zero Hessians are handled natively; ``y = [rows;
bounds]`` already follows the sign convention of :mod:`wbc.qp`.

Profiles: ``default`` (eps 1e-5, no polishing) is sized for control ticks; ``tight`` (eps 1e-10,
polishing, up to 200 000 iterations) reaches ≈1e-14 on the tests, polishing making it exact once
the active set is identified. Quirks (OSQP 1.1): with polishing on it prints "Polishing not
needed ..." through Python's ``sys.stdout`` whatever ``verbose`` says (captured and counted
then, see :class:`~wbc.solvers.base.ConsoleCapture`); ADMM stalls around 1e-3 on some random
vertex LPs (8 of 20 in the tests) whatever rho, sigma or scaling: use an active-set backend for
LPs. The Python wrapper adds about 25 µs per tick (it clips ``l``/``u`` and builds an info
namespace on every call).
Degenerate problems (optimum at a vertex with zero multipliers, as in the levels after a
task-scaling LP) converge only like the square root of the tolerance: 1e-6 to 1e-4 off in the SNS
cascades of ``tests/test_equivalence.py``; active-set backends (daqp, qpoases, quadprog) are exact
there.
"""

from __future__ import annotations

import numpy as np

from wbc.qp import QPResult, Status

from .base import (
    BackendBase,
    ConsoleCapture,
    clock,
    empty_failure,
    empty_sides,
    failure,
    import_solver,
)
from .forms import StackedConstraints, UpperTriangle

_STATUS = {  # "solved inaccurate" (tolerances missed by up to 10x) is a failure
    "OSQP_SOLVED": Status.SOLVED,
    "OSQP_PRIMAL_INFEASIBLE": Status.INFEASIBLE,
    "OSQP_PRIMAL_INFEASIBLE_INACCURATE": Status.INFEASIBLE,
    "OSQP_MAX_ITER_REACHED": Status.MAX_ITER,
    "OSQP_TIME_LIMIT_REACHED": Status.MAX_ITER,
}


class OsqpBackend(BackendBase):
    """OSQP, kept alive between ticks. See the module docstring."""

    name = "osqp"
    package = "osqp"
    PROFILES = {
        "default": {"eps_abs": 1e-5, "eps_rel": 1e-5, "polishing": False, "max_iter": 4000},
        "tight": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polishing": True, "max_iter": 200_000,
                  "eps_prim_inf": 1e-8, "eps_dual_inf": 1e-8},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        self._osqp = import_solver("osqp", self.name)
        # OSQP prints "Polishing not needed ..." whatever its verbosity
        if self.options.get("polishing"):
            self._console = ConsoleCapture()

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        n, m = self._n, self._m
        self._triu = UpperTriangle(n)
        self._P = np.empty(self._triu.nnz)
        self._stack = StackedConstraints(n, m)
        self._pattern, self._index = self._stack.pattern(np.arange(m + n))
        self._A = np.empty(self._pattern.nnz)
        self._load(H, A, lA, uA, lb, ub)
        t0 = clock()
        self._solver = self._osqp.OSQP()
        self._solver.setup(  # with empty sides (see _load) OSQP is set up on u = max(l, u)
            self._triu.matrix(self._P), g, self._pattern.matrix(self._A),
            self._stack.l, np.maximum(self._stack.l, self._stack.u), verbose=False,
            **self.options,
        )
        self.library_time += clock() - t0
        self._status = {int(code): _STATUS.get(code.name, Status.NUMERICAL)
                        for code in self._osqp.SolverStatus}

    def _load(self, H, A, lA, uA, lb, ub) -> None:
        self._triu.gather(H, self._P)
        self._stack.load(A, lA, uA, lb, ub)
        self._stack.gather(self._index, self._A)
        # OSQP refuses data with a lower side above its upper one: setup raises, and update
        # prints an error, returns None and keeps the previous data, which solve() then solves
        # as if nothing were wrong. An upper side of -inf it takes for -1e30 and "solves".
        self._empty = empty_sides(self._stack.l, self._stack.u)

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._load(H, A, lA, uA, lb, ub)
        if not self._empty:
            t0 = clock()
            self._solver.update(q=g, l=self._stack.l, u=self._stack.u, Px=self._P, Ax=self._A)
            self.library_time += clock() - t0

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        if self._empty:
            return empty_failure(self.name, n, m)
        t0 = clock()
        if warm_start is not None:
            self._solver.warm_start(x=np.asarray(warm_start, dtype=float))
        result = self._solver.solve(raise_error=False)
        self.library_time += clock() - t0
        info = result.info
        status = self._status.get(info.status_val, Status.NUMERICAL)
        if status is not Status.SOLVED:
            self._solver.warm_start(x=np.zeros(n), y=np.zeros(m + n))
            return failure(n, m, status, f"osqp: {info.status}", info.iter)
        y = result.y
        return QPResult(x=result.x.copy(), status=Status.SOLVED, y=y[:m].copy(),
                        z=y[m:].copy(), iterations=info.iter)
