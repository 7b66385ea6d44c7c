"""Any solver of `qpsolvers` through its stateless ``solve_problem``: the fallback adapter for
solvers without a native one, and the "cold call" baseline of the solver benchmarks.

Registered as ``"qpsolvers:<solver>"``. Nothing persists between ticks but copies of the data
(and the last solution, used as the default initial guess): every solve builds a
``qpsolvers.Problem`` — equalities (``lA == uA``) as ``A x = b``, the finite sides of the other
rows as ``G x <= h``, bounds as ``lb``/``ub`` — and calls ``solve_problem``, so its cost includes
each solver's setup. The bounds are passed even when all infinite (qpsolvers accepts ``±inf``):
without any constraint qpsolvers hands a clarabel problem to its own least-squares solve, which
fails its 1e-8 residual check on small curvatures. qpsolvers'
multipliers (``y`` equalities, ``z`` inequalities, ``z_box`` bounds) use the sign convention of
:mod:`wbc.qp`. qpsolvers does not say why a solve failed: a failure is ``NUMERICAL`` with the
solver's warning or exception as the message. What the solver prints through Python's
``sys.stdout`` (OSQP's "Polishing not needed ...") is captured and counted (≈1 µs per call).

Options are the solver's own keyword settings (``SOLVER_PROFILES`` holds the profiles of the
solvers tested here; others get empty profiles), plus ``proximal`` (``True``/``False``; by default
``True`` for solvers that need a positive-definite Hessian, i.e. quadprog) and the ``prox_*``
settings of :class:`~wbc.solvers.proximal.ProximalPoint` for those.
Accuracy on the tests (``tight``): as the native adapters of the same solvers, except that
ProxQP's functional API, which qpsolvers calls, cannot set the infeasibility tolerances: feasible
LPs are then often declared infeasible (11 of 20 random vertex LPs).
"""

from __future__ import annotations

import warnings

import numpy as np

from wbc.qp import QPResult, Status

from . import proximal
from .base import (
    BackendBase,
    ConsoleCapture,
    clock,
    failure,
    import_solver,
    package_version,
)
from .forms import OneSidedRows

SOLVER_PROFILES: dict[str, dict[str, dict]] = {
    "clarabel": {
        "default": {},
        "tight": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10,
                  "tol_ktratio": 1e-8, "max_iter": 500},
    },
    "daqp": {"default": {}, "tight": {"primal_tol": 1e-10, "eta_prox": 1e-10}},
    "osqp": {
        "default": {"eps_abs": 1e-5, "eps_rel": 1e-5, "polishing": False},
        "tight": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polishing": True, "max_iter": 200_000,
                  "eps_prim_inf": 1e-8, "eps_dual_inf": 1e-8},
    },
    "proxqp": {
        "default": {"eps_abs": 1e-6, "eps_rel": 0.0},
        "tight": {"eps_abs": 1e-10, "eps_rel": 0.0, "check_duality_gap": True,
                  "eps_duality_gap_abs": 1e-9, "eps_duality_gap_rel": 0.0, "max_iter": 100_000},
    },
    "quadprog": {"default": {}, "tight": {"prox_tol": 1e-10, "prox_max_iter": 500}},
}
"""qpsolvers keyword settings per solver and profile."""

NEEDS_POSITIVE_DEFINITE = frozenset({"quadprog"})
#: the distribution of a qpsolvers solver, where it differs from the solver's name (for versions)
SOLVER_PACKAGES = {"proxqp": "proxsuite", "piqp": "piqp", "highs": "highspy", "qpoases":
                   "qpoases", "hpipm": "hpipm_python", "kvxopt": "kvxopt", "cvxopt": "cvxopt",
                   "gurobi": "gurobipy", "mosek": "Mosek", "scs": "scs", "ecos": "ecos"}
"""Solvers that refuse singular Hessians: their ``proximal`` option defaults to ``True``."""


class _NoSolution(Exception):
    """qpsolvers returned without a solution."""


class QpsolversBackend(BackendBase):
    """One solver of qpsolvers, called cold every tick. See the module docstring.

    Args:
        solver: a name in ``qpsolvers.available_solvers``.
        profile: ``"default"`` or ``"tight"``.
        **options: the solver's settings, ``proximal`` and ``prox_*``; they override the
            profile's.
    """

    def __init__(self, solver: str, profile: str = "default", **options):
        self.solver = solver
        self.name = f"qpsolvers:{solver}"
        self.PROFILES = SOLVER_PROFILES.get(solver, {"default": {}, "tight": {}})
        self.package = "qpsolvers"
        super().__init__(profile, **options)
        self._qpsolvers = import_solver("qpsolvers", self.name)
        settings = dict(self.options)
        use_proximal = settings.pop("proximal", solver in NEEDS_POSITIVE_DEFINITE)
        self._proximal = proximal.ProximalPoint.from_options(settings) if use_proximal else None
        self._settings = {k: v for k, v in settings.items() if k not in proximal.OPTION_NAMES}
        self._console = ConsoleCapture()  # e.g. OSQP's "Polishing not needed ..."

    def settings(self) -> dict:
        """As :meth:`BackendBase.settings`, with the solver qpsolvers calls and its version."""
        return {**super().settings(), "solver": self.solver,
                "solver_version": package_version(SOLVER_PACKAGES.get(self.solver, self.solver))}

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        self._x = np.zeros(self._n)
        self._update(H, g, A, lA, uA, lb, ub)

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._data = [np.array(a, dtype=float) for a in (H, g, A, lA, uA, lb, ub)]

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        H, g, A, lA, uA, lb, ub = self._data
        rows = OneSidedRows(lA, uA)
        G_all, h_all = rows.matrix(A), rows.rhs(lA, uA)
        k = rows.n_eq
        constraints = {
            "A": G_all[:k] if k else None, "b": h_all[:k] if k else None,
            "G": G_all[k:] if rows.n_ineq else None, "h": h_all[k:] if rows.n_ineq else None,
            "lb": lb, "ub": ub,
        }
        x0 = self._x if warm_start is None else np.asarray(warm_start, dtype=float)

        def solve(H_, g_):
            problem = self._qpsolvers.Problem(H_, g_, **constraints)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                t0 = clock()  # qpsolvers' conversions are inside: it is the library here
                solution = self._qpsolvers.solve_problem(
                    problem, solver=self.solver, initvals=x0, **self._settings
                )
                self.library_time += clock() - t0
            if not solution.found or solution.x is None:
                words = "; ".join(str(w.message) for w in caught) or "no solution found"
                raise _NoSolution(words)
            return solution.x, solution

        try:
            if self._proximal is None or proximal.is_positive_definite(H):
                x, solution = solve(H, g)
                iterations = -1
            else:
                x, solution, iterations, converged = self._proximal.run(solve, H, g, x0)
                if not converged:
                    return failure(n, m, Status.MAX_ITER, "proximal iterations did not converge",
                                   iterations)
        except (TypeError, AttributeError):  # a setting the solver rejects: not a failure of
            raise  # this problem (BackendBase makes it a BackendError naming the backend)
        except Exception as exc:  # any solver's failure, reported as a status
            return failure(n, m, Status.NUMERICAL, f"{self.name}: {exc}")
        self._x = x
        lam = np.concatenate([_vector(solution.y, k), _vector(solution.z, rows.n_ineq)])
        return QPResult(x=np.asarray(x, dtype=float), status=Status.SOLVED,
                        y=rows.multipliers(lam), z=_vector(solution.z_box, n),
                        iterations=iterations)


def _vector(value, size: int) -> np.ndarray:
    """A multiplier vector of qpsolvers (None or empty when absent) as ``size`` floats."""
    if value is None or np.size(value) != size:
        return np.zeros(size)
    return np.asarray(value, dtype=float)
