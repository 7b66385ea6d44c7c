"""ProxQP (proxsuite, dense backend, augmented Lagrangian) behind the :class:`wbc.qp.Backend`
contract.

One ``proxqp.dense.QP(n, 0, m, box_constraints=True)``: every row of ``A`` goes to ProxQP's
two-sided ``l <= C x <= u`` (equalities as ``l == u``, so the split never changes the structure)
and the bounds to its native box. ``init`` once, ``update`` every tick (the preconditioner of the
first data is kept: ``update_preconditioner=False``). ``±inf`` and singular or zero Hessians are
handled natively; multipliers ``z = [rows; box]`` follow the sign convention of :mod:`wbc.qp`.

Warm start, and why it is guarded. Each tick first tries ``WARM_START_WITH_PREVIOUS_RESULT``
(previous primal-dual point *and* proximal parameters), capped at ``warm_max_iter`` iterations:
on slowly varying data it needs 2–14 iterations where a cold start needs ~20. After a large change
of the data, though, ProxQP 0.8 often runs to its iteration limit, and sometimes reports
``PROXQP_SOLVED`` with small primal and dual residuals but multipliers on inactive or absent sides
(a wrong ``x``; about 5 % of random jumps): its stopping test bounds the primal and dual
residuals (unscaled, checked) but not complementarity. The warm answer is therefore accepted only
if it is solved and its complementarity gap
(:meth:`~wbc.solvers.forms.StackedConstraints.complementarity_gap`, ≈5 µs) is below
``10 (eps_abs + eps_rel)``.
Otherwise the tick is solved by a *new* model (``init`` + ``EQUALITY_CONSTRAINED_INITIAL_GUESS``):
once in that state, ProxQP's own cold starts (``EQUALITY_CONSTRAINED_INITIAL_GUESS``,
``NO_INITIAL_GUESS``, ``COLD_START_WITH_PREVIOUS_RESULT`` on the same model) return the same kind
of wrong answer, and ``cleanup()`` makes the next solve hang. The model is also rebuilt after a
failed solve. A primal guess given to :meth:`solve` is not used: ProxQP 0.8's ``WARM_START`` with
box constraints runs to the iteration limit once the model has been solved before.

Other quirks (ProxQP 0.8): ``WARM_START_WITH_PREVIOUS_RESULT`` before any solve segfaults; with the
default infeasibility tolerances (``eps_primal_inf = eps_dual_inf = 1e-4``) some feasible LPs are
declared primal infeasible, so both profiles use ``1e-9``.
Profiles: ``default`` (``eps_abs = 1e-6``, at most 300 outer × 100 inner iterations, so a
tick is bounded: < 1 s on the fuzz campaign's worst scaling) is sized for control ticks;
``tight`` (``eps_abs = 1e-10`` with ProxQP's duality-gap test, without which answers with
``eps_abs = 1e-10`` missed complementarity by 2e-7) reaches ≈3e-10 on the tests.
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
    check_option_names,
    clock,
    empty_failure,
    empty_sides,
    failure,
    import_solver,
)
from .forms import StackedConstraints


class ProxqpBackend(BackendBase):
    """ProxQP dense, kept alive between ticks. See the module docstring.

    Options: ProxQP settings (``eps_abs``, ``max_iter``, ...) and ``warm_max_iter``, the
    iteration cap of the warm attempt.
    """

    name = "proxqp"
    package = "proxsuite"
    PROFILES = {
        # max_iter / max_iter_in bound a tick: ProxQP's own (10⁴ outer × 1500 inner) let one
        # badly scaled level (H up to 1e13, found by wbc fuzz) iterate for 48 s; 300 × 100
        # stops it in ≈ 0.4 s, and a control tick needs ~20 outer iterations cold.
        "default": {"eps_abs": 1e-6, "eps_rel": 0.0, "eps_primal_inf": 1e-9,
                    "eps_dual_inf": 1e-9, "max_iter": 300, "max_iter_in": 100,
                    "warm_max_iter": 100},
        # eps_abs below 1e-10 fails (max_iter, "infeasible") on degenerate cascade levels whose
        # feasible set is a point; the duality-gap test is what makes 1e-10 accurate.
        "tight": {"eps_abs": 1e-10, "eps_rel": 0.0, "check_duality_gap": True,
                  "eps_duality_gap_abs": 1e-9, "eps_duality_gap_rel": 0.0,
                  "eps_primal_inf": 1e-9, "eps_dual_inf": 1e-9, "max_iter": 100_000,
                  "warm_max_iter": 100},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        self._proxqp = import_solver("proxsuite", self.name).proxqp
        self._settings = dict(self.options)
        self._warm_max_iter = self._settings.pop("warm_max_iter", 100)
        known = [k for k in dir(self._proxqp.Settings()) if not k.startswith("_")]
        check_option_names(self.name, self._settings, known)
        output = self._proxqp.QPSolverOutput
        self._status = {
            output.PROXQP_SOLVED: Status.SOLVED,
            output.PROXQP_MAX_ITER_REACHED: Status.MAX_ITER,
            output.PROXQP_PRIMAL_INFEASIBLE: Status.INFEASIBLE,
            output.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: Status.INFEASIBLE,
            output.PROXQP_DUAL_INFEASIBLE: Status.NUMERICAL,  # unbounded
        }

    def _library_defaults(self) -> dict:
        defaults = self._proxqp.Settings()
        return {k: getattr(defaults, k) for k in dir(defaults) if not k.startswith("_")
                and isinstance(getattr(defaults, k), (bool, int, float))}

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        n, m = self._n, self._m
        self._H = np.empty((n, n))
        self._g = np.empty(n)
        self._stack = StackedConstraints(n, m)  # the data, for rebuilds and the guard
        self._load(H, g, A, lA, uA, lb, ub)
        self._build()

    def _load(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H[...] = H
        self._g[...] = g
        self._stack.load(A, lA, uA, lb, ub)
        # ProxQP does not check the sides: with lower > upper it "solves" outside them
        self._empty = empty_sides(self._stack.l, self._stack.u)

    def _build(self) -> None:
        """A new model on the loaded data (the next solve starts cold)."""
        n, m, stack = self._n, self._m, self._stack
        self._qp = self._proxqp.dense.QP(n, 0, m, True)
        settings = self._qp.settings
        settings.verbose = False
        for key, value in self._settings.items():
            setattr(settings, key, value)
        self._max_iter = settings.max_iter
        self._guard = 10.0 * (settings.eps_abs + settings.eps_rel)
        t0 = clock()
        self._qp.init(self._H, self._g, None, None, stack.C[:m], stack.l[:m], stack.u[:m],
                      stack.l[m:], stack.u[m:])
        self.library_time += clock() - t0
        self._fresh = True

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._load(H, g, A, lA, uA, lb, ub)
        t0 = clock()
        self._qp.update(H=H, g=g, C=A, l=lA, u=uA, l_box=lb, u_box=ub)
        self.library_time += clock() - t0

    def _run(self, initial_guess, max_iter: int) -> Status:
        settings = self._qp.settings
        settings.initial_guess = initial_guess
        settings.max_iter = max_iter
        t0 = clock()
        self._qp.solve()
        self.library_time += clock() - t0
        return self._status.get(self._qp.results.info.status, Status.NUMERICAL)

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        if self._empty:
            return empty_failure(self.name, n, m)
        guess = self._proxqp.InitialGuess
        if not self._fresh:
            status = self._run(guess.WARM_START_WITH_PREVIOUS_RESULT,
                               min(self._warm_max_iter, self._max_iter))
            results = self._qp.results
            if (status is not Status.SOLVED
                    or self._stack.complementarity_gap(results.x, results.z) > self._guard):
                self._build()
        if self._fresh:
            status = self._run(guess.EQUALITY_CONSTRAINED_INITIAL_GUESS, self._max_iter)
            self._fresh = False
        results = self._qp.results
        info = results.info
        if status is not Status.SOLVED:
            message, iterations = f"proxqp: {info.status.name}", info.iter
            self._build()
            return failure(n, m, status, message, iterations)
        return QPResult(x=results.x.copy(), status=status, y=results.z[:m].copy(),
                        z=results.z[m:].copy(), iterations=info.iter)
