"""quadprog (Goldfarb–Idnani dual active set) behind the :class:`wbc.qp.Backend` contract.

quadprog is stateless and needs a strictly positive-definite Hessian: every solve passes the
finite sides of the constraints (bounds included, as rows; :class:`~wbc.solvers.forms.OneSidedRows`,
cached while the pattern of finite sides holds) and, when ``H`` is not numerically positive
definite (a Cholesky pivot below ``1e-12 max(diag H)``), runs proximal-point iterations
(:mod:`wbc.solvers.proximal`) instead of a single solve. The warm start (or else the previous
solution) is the proximal starting point; it has no effect on a positive-definite problem.

quadprog has no feasibility tolerance: when the active constraints are linearly dependent — in
the cascade, frozen rows of an earlier level through a vertex of the bounds, so the feasible set
is a point up to roundoff — it reports "constraints are inconsistent". The adapter then retries
once with every finite side relaxed by ``feas_tol * max(1, |side|)`` (equalities become narrow
two-sided rows); only if that fails too is the problem reported INFEASIBLE.

Multipliers: quadprog solves ``min 1/2 x'Gx - a'x`` s.t. ``C'x >= b`` with ``G x - a = C lam``,
``lam >= 0``; with ``C = -G_rows'`` (rows ``G_rows x <= h``) ``lam`` is exactly the multiplier of
those rows, mapped back by :meth:`~wbc.solvers.forms.OneSidedRows.multipliers`.

Options (profiles ``default`` and ``tight``): ``feas_tol``, and ``prox_mu``, ``prox_tol``,
``prox_max_iter`` of :class:`~wbc.solvers.proximal.ProximalPoint`.
Accuracy on the tests (``tight``): ≈1e-14 on positive-definite QPs, ≈1e-11 with a singular
Hessian or an LP.
"""

from __future__ import annotations

import numpy as np

from wbc.qp import QPResult, Status

from . import proximal
from .base import BackendBase, check_option_names, failure, import_solver
from .forms import OneSidedRows, StackedConstraints


class _NotConverged(Exception):
    """The proximal iterations hit their limit."""


class QuadprogBackend(BackendBase):
    """quadprog, with proximal iterations for singular Hessians. See the module docstring."""

    name = "quadprog"
    PROFILES = {
        "default": {"feas_tol": 1e-10, "prox_mu": 1e-3, "prox_tol": 1e-8, "prox_max_iter": 100},
        "tight": {"feas_tol": 1e-10, "prox_mu": 1e-3, "prox_tol": 1e-10, "prox_max_iter": 500},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        check_option_names(self.name, self.options, ("feas_tol", *proximal.OPTION_NAMES))
        self._quadprog = import_solver("quadprog", self.name)
        self._proximal = proximal.ProximalPoint.from_options(self.options)
        self._feas_tol = self.options.get("feas_tol", 1e-10)

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H = np.empty((self.n, self.n))
        self._g = np.empty(self.n)
        self._stack = StackedConstraints(self.n, self.m)
        self._x = np.zeros(self.n)
        self._update(H, g, A, lA, uA, lb, ub)
        self._rows = OneSidedRows(self._stack.l, self._stack.u)

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H[...] = H
        self._g[...] = g
        self._stack.load(A, lA, uA, lb, ub)

    def _solve(self, warm_start) -> QPResult:
        n, m = self.n, self.m
        l, u = self._stack.l, self._stack.u
        if not self._rows.same_pattern(l, u):
            self._rows = OneSidedRows(l, u)
        x0 = self._x if warm_start is None else np.asarray(warm_start, dtype=float)
        try:
            try:
                x, lam, iterations = self._attempt(self._rows, l, u, x0)
                rows = self._rows
            except ValueError as exc:
                if "inconsistent" not in str(exc):
                    raise
                l = l - self._feas_tol * np.maximum(1.0, np.abs(l))
                u = u + self._feas_tol * np.maximum(1.0, np.abs(u))
                rows = OneSidedRows(l, u)
                x, lam, iterations = self._attempt(rows, l, u, x0)
        except ValueError as exc:  # quadprog's only failure signal
            status = Status.INFEASIBLE if "inconsistent" in str(exc) else Status.NUMERICAL
            return failure(n, m, status, f"quadprog: {exc}")
        except _NotConverged as exc:
            return failure(n, m, Status.MAX_ITER, str(exc), exc.args[1])
        self._x = x
        multipliers = rows.multipliers(lam)
        return QPResult(x=x, status=Status.SOLVED, y=multipliers[:m], z=multipliers[m:],
                        iterations=int(iterations))

    def _attempt(self, rows: OneSidedRows, l, u, x0) -> tuple[np.ndarray, np.ndarray, int]:
        """``(x, lam, iterations)`` with the one-sided ``rows`` of sides ``l``, ``u``; raises
        quadprog's ``ValueError`` or :class:`_NotConverged`."""
        if len(rows.source):
            C, b = -rows.matrix(self._stack.C).T, -rows.rhs(l, u)
        else:  # quadprog wants None, not an empty matrix
            C = b = None

        def solve(H, g):
            x, _, _, iterations, lam, _ = self._quadprog.solve_qp(H, -g, C, b, rows.n_eq)
            return x, (lam[:len(rows.source)], iterations[0])

        if proximal.is_positive_definite(self._H):
            x, (lam, iterations) = solve(self._H, self._g)
            return x, lam, iterations
        x, (lam, _), iterations, converged = self._proximal.run(solve, self._H, self._g, x0)
        if not converged:
            raise _NotConverged("proximal iterations did not converge", iterations)
        return x, lam, iterations
