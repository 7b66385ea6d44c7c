"""Clarabel (interior point, conic) behind the :class:`wbc.qp.Backend` contract.

Clarabel's form is ``A x + s = b`` with ``s`` in a product of cones: the finite sides of all
constraints (bounds as rows, :class:`~wbc.solvers.forms.OneSidedRows`) become a zero cone for
the equalities and a nonnegative cone for the one-sided rows, so ``±inf`` sides and inert rows
are simply absent. The solver is built once per *structure* — which rows are equalities and which
sides are finite — and updated in place (``solver.update(P=, q=, A=, b=)``, Clarabel 0.11, with
``presolve_enable=False`` so that updates stay allowed) while that structure holds; a change of
structure rebuilds it. An interior-point method has no warm start: the primal guess is ignored.
Singular and zero Hessians are native. Multipliers: ``z >= 0`` of ``G x <= h`` mapped back by
:meth:`OneSidedRows.multipliers`; ``AlmostSolved`` counts as solved (reduced tolerances), with
the solver's status in ``info``.

Profiles: ``default`` is Clarabel's (tolerances 1e-8, ≈1e-8 on the tests); ``tight`` (1e-10,
and 1e-8 for an AlmostSolved answer) reaches ≈1e-9 on the tests.
Degenerate problems (optimum at a vertex with zero multipliers, as in the levels after a
task-scaling LP) converge only like the square root of the tolerance: 1e-6 to 1e-4 off in the SNS
cascades of ``tests/test_equivalence.py``; active-set backends (daqp, qpoases, quadprog) are exact
there.
"""

from __future__ import annotations

import numpy as np

from wbc.qp import QPResult, Status

from .base import BackendBase, check_option_names, clock, failure, import_solver
from .forms import OneSidedRows, StackedConstraints, UpperTriangle

_STATUS = {
    "Solved": Status.SOLVED,
    "AlmostSolved": Status.SOLVED,
    "PrimalInfeasible": Status.INFEASIBLE,
    "AlmostPrimalInfeasible": Status.INFEASIBLE,
    "MaxIterations": Status.MAX_ITER,
    "MaxTime": Status.MAX_ITER,
}


class ClarabelBackend(BackendBase):
    """Clarabel, updated in place while the constraint structure holds. See the module
    docstring."""

    name = "clarabel"
    package = "clarabel"
    PROFILES = {
        "default": {},
        # Tighter than 1e-10 fails (InsufficientProgress) on degenerate cascade levels whose
        # feasible set is a point; reduced_* bound what an AlmostSolved answer may miss by.
        "tight": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10,
                  "tol_ktratio": 1e-8, "reduced_tol_gap_abs": 1e-8, "reduced_tol_gap_rel": 1e-8,
                  "reduced_tol_feas": 1e-8, "reduced_tol_ktratio": 1e-6, "max_iter": 500},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        self._clarabel = import_solver("clarabel", self.name)
        self._settings = self._clarabel.DefaultSettings()
        known = [k for k in dir(self._settings) if not k.startswith("_")]
        check_option_names(self.name, self.options, known)
        self._settings.verbose = False
        self._settings.presolve_enable = False  # in-place updates need it off
        for key, value in self.options.items():
            setattr(self._settings, key, value)

    def _library_defaults(self) -> dict:
        # the settings object it solves with (verbose and presolve set by the adapter)
        settings = self._settings
        return {k: getattr(settings, k) for k in dir(settings) if not k.startswith("_")
                and isinstance(getattr(settings, k), (bool, int, float, str))}

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        n, m = self._n, self._m
        self._triu = UpperTriangle(n)
        self._P = np.empty(self._triu.nnz)
        self._g = np.empty(n)
        self._stack = StackedConstraints(n, m)
        self._load(H, g, A, lA, uA, lb, ub)
        self._build()

    def _load(self, H, g, A, lA, uA, lb, ub) -> None:
        self._triu.gather(H, self._P)
        self._g[...] = g
        self._stack.load(A, lA, uA, lb, ub)

    def _build(self) -> None:
        """A new solver for the structure of the loaded constraints."""
        clarabel, stack = self._clarabel, self._stack
        self._rows = OneSidedRows(stack.l, stack.u)
        pattern, self._index = stack.pattern(self._rows.source)
        self._sign = self._rows.sign[pattern.rows]
        self._G = np.empty(pattern.nnz)
        self._gather_G()
        cones = [cone(size) for cone, size in ((clarabel.ZeroConeT, self._rows.n_eq),
                                               (clarabel.NonnegativeConeT, self._rows.n_ineq))
                 if size]
        t0 = clock()
        self._solver = clarabel.DefaultSolver(
            self._triu.matrix(self._P), self._g, pattern.matrix(self._G),
            self._rows.rhs(stack.l, stack.u), cones, self._settings,
        )
        self.library_time += clock() - t0

    def _gather_G(self) -> None:
        self._stack.gather(self._index, self._G)
        self._G *= self._sign

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._load(H, g, A, lA, uA, lb, ub)
        stack = self._stack
        if not self._rows.same_pattern(stack.l, stack.u):
            self._build()
            return
        self._gather_G()
        t0 = clock()
        self._solver.update(P=self._P, q=self._g, A=self._G, b=self._rows.rhs(stack.l, stack.u))
        self.library_time += clock() - t0

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        t0 = clock()
        solution = self._solver.solve()
        self.library_time += clock() - t0
        words = str(solution.status)
        status = _STATUS.get(words, Status.NUMERICAL)
        if status is not Status.SOLVED:
            return failure(n, m, status, f"clarabel: {words}", solution.iterations)
        multipliers = self._rows.multipliers(np.asarray(solution.z))
        return QPResult(x=np.asarray(solution.x), status=status, y=multipliers[:m],
                        z=multipliers[m:], iterations=solution.iterations)
