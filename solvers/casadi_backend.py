"""CasADi's ``conic`` plugins (qpOASES and others) behind the :class:`wbc.qp.Backend` contract.

``casadi.conic(name, plugin, {"h": dense(n, n), "a": dense(m, n)}, options)`` is created once per
structure, and evaluated through a ``Function.buffer()`` bound to preallocated column-major
numpy arrays: no ``DM`` conversion on the hot path (about 80 µs saved per call). CasADi's form is
that of :mod:`wbc.qp` itself (``lba <= A x <= uba``, ``lbx <= x <= ubx``, ``±inf`` accepted), and
its multipliers ``lam_a``, ``lam_x`` follow the same sign convention. The inputs ``x0``,
``lam_x0``, ``lam_a0`` receive the previous solution (or the primal guess given to
:meth:`solve`); plugins that warm-start from them do so, and qpOASES instead hot-starts from its
own previous active set, kept in the buffer's memory; a failed warm call is retried once from a
fresh buffer. Failure detection: the conic is created
with ``error_on_fail=True``, so that a failed call raises (the buffer's return code is 0 even when
the solver failed), and only then are CasADi's stats read (reading them costs about 9 µs, so
``iterations`` is -1 on success). After a failed solve a fresh buffer (hence
a fresh solver memory) is made, so that no plugin hot-starts from a broken state.

Plugins and their profiles (``PLUGIN_PROFILES``):

- ``qpoases`` (registered as ``"qpoases"``, also ``"casadi:qpoases"``): dense online active set,
  with ``hessian_type="semidef"`` and ``enableRegularisation`` for singular and zero Hessians
  (see the comment in ``PLUGIN_PROFILES``).
- ``osqp``: see ``PLUGIN_PROFILES`` and the accuracy noted there.

Plugins left out after testing (CasADi 3.8): ``proxqp`` rebuilds its solver on every call, cannot
set ProxQP's infeasibility tolerances (false "primal infeasible" on LPs) and maps ``lam_a`` wrongly
when equalities and inequalities are mixed; ``qrqp`` hits its iteration limit, or returns a wrong
point flagged as solved, on small random QPs with infinite bounds; ``daqp`` fails on singular
Hessians (no proximal setting); ``hpipm`` refuses a dense ``A`` (it wants OCP structure);
``highs`` is off by up to 1e-4 on unconstrained cascade levels with small damping (stationarity
residual 8e-5 whatever its feasibility tolerances) and, with ``qp_regularization_value`` below
1e-10, fails ("Not Set") on some singular ones.

Quirks: with no constraint row (``m = 0``) CasADi runs qpOASES' bound-only ``QProblemB``, which
with one variable returns the unconstrained minimiser, bounds ignored, flagged as solved; so the
conic always gets at least one row (an inert one when ``m = 0``). qpOASES prints its banner
whenever a solver memory is created (silenced here: it goes through Python's ``sys.stdout``).
CasADi's qpOASES option ``enableDriftCorrection`` actually sets ``enableRegularisation`` (a CasADi
bug), so it is not used.

Console output: qpOASES prints its errors ("ERROR: Division by zero", "Failed to setup
auxiliary QP for initialised homotopy", ...) through CasADi, which forwards them to Python's
``sys.stdout``, on failed calls (often ones the retries then solve). ``printLevel="none"`` does
not keep them quiet: qpOASES' message handler is global, and destroying any qpOASES solver (a
restart after a failure, a dropped backend) makes every instance's errors visible again until
the next one is created. So every solve of a CasADi plugin is captured at the Python level
(≈1 µs per call, :class:`~wbc.solvers.base.ConsoleCapture`) and its lines counted, in the
result's ``message`` and in ``console_lines``. CasADi's OSQP prints "Polishing not needed ..."
from C, when ``polishing`` is on (not in the profiles): then file descriptors 1 and 2 are
captured as well (≈14 µs per call).
"""

from __future__ import annotations

import numpy as np

from wbc.errors import BackendUnavailableError
from wbc.qp import QPResult, Status

from .base import (
    BackendBase,
    ConsoleCapture,
    clock,
    empty_failure,
    empty_sides,
    failure,
    import_solver,
    silenced,
)

PLUGIN_PROFILES: dict[str, dict[str, dict]] = {
    # Without enableRegularisation qpOASES runs out of working-set recalculations on a singular
    # Hessian with no constraint rows (a level of an undamped cascade); with it, its own Hessian
    # detection ("unknown") fails on an identity Hessian ("Initialisation failed"), hence
    # "semidef"; its default epsRegularisation (~2e-13) is too small for small rank-1 Hessians
    # (again out of recalculations), hence 1e-10 with two refinement steps. Its default
    # terminationTolerance is already accurate (≈1e-14 on the tests); 1e-12 breaks degenerate
    # levels (a point-sized feasible set reads "infeasible"), so tight = default.
    "qpoases": {
        profile: {"printLevel": "none", "hessian_type": "semidef", "enableRegularisation": True,
                  "epsRegularisation": 1e-10, "numRegularisationSteps": 2}
        for profile in ("default", "tight")
    },
    # OSQP 1.0 bundled with CasADi. Its polishing prints "Polishing not needed ..." from C (kept
    # off the terminal only by capturing file descriptors, ≈14 µs per call), so tight does
    # without: ≈1e-8 on the tests.
    "osqp": {
        "default": {"osqp": {"verbose": False, "eps_abs": 1e-5, "eps_rel": 1e-5}},
        "tight": {"osqp": {"verbose": False, "eps_abs": 1e-10, "eps_rel": 1e-10,
                           "max_iter": 200_000}},
    },
}
"""Options per plugin and profile, passed to ``casadi.conic`` (with ``error_on_fail=True``)."""

#: Options of one more cold attempt after a failed solve (per plugin). qpOASES' default
#: initial guess failed every tick ("Division by zero" in its TQ factorisation) on a cascade
#: level whose Hessian covers only some variables below frozen rows (the base reference of
#: ``wbc study petric``); with every bound initially inactive it solves them. Not the first
#: attempt: that guess fails on vertex LPs the default one solves.
RETRY_OPTIONS: dict[str, dict] = {"qpoases": {"initialStatusBounds": "inactive"}}

_INPUTS = ("h", "g", "a", "lba", "uba", "lbx", "ubx", "x0", "lam_x0", "lam_a0")
_OUTPUTS = ("x", "cost", "lam_a", "lam_x")
_STATUS = {
    "SOLVER_RET_INFEASIBLE": Status.INFEASIBLE,
    "SOLVER_RET_LIMITED": Status.MAX_ITER,
}


def _failure_status(stats: dict) -> Status:
    """Status of a failed call. CasADi's unified status is often ``SOLVER_RET_UNKNOWN`` (qpOASES,
    OSQP and HiGHS on an infeasible QP, for instance), so the plugin's own words decide then."""
    if stats.get("unified_return_status") in _STATUS:
        return _STATUS[stats["unified_return_status"]]
    words = str(stats.get("return_status", "")).lower()
    if "infeasib" in words:
        return Status.INFEASIBLE
    if "iteration" in words or "maximum" in words:
        return Status.MAX_ITER
    return Status.NUMERICAL


class CasadiConicBackend(BackendBase):
    """A CasADi ``conic`` plugin, evaluated through a preallocated buffer.

    Args:
        plugin: CasADi conic plugin name (``"qpoases"``, ``"osqp"``, ...).
        profile: ``"default"`` or ``"tight"`` (see ``PLUGIN_PROFILES``).
        name: backend name; ``"casadi:<plugin>"`` unless given.
        **options: ``casadi.conic`` options overriding the profile's (top-level keys).
    """

    def __init__(self, plugin: str = "qpoases", profile: str = "default",
                 name: str | None = None, **options):
        self.plugin = plugin
        self.name = name or f"casadi:{plugin}"
        self.PROFILES = PLUGIN_PROFILES.get(plugin, {"default": {}, "tight": {}})
        self.package = "casadi"  # the plugin (qpOASES, OSQP) ships inside CasADi
        super().__init__(profile, **options)
        self._casadi = import_solver("casadi", self.name)
        with silenced():
            if not self._casadi.has_conic(plugin):
                raise BackendUnavailableError(
                    f"QP backend {self.name!r}: CasADi has no loadable conic plugin {plugin!r}"
                )
        # CasADi forwards its plugins' output to Python; its OSQP polishes with C's printf
        polishing = plugin == "osqp" and self.options.get("osqp", {}).get("polishing", False)
        self._console = ConsoleCapture(fd=bool(polishing))

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        n, m = self._n, self._m
        rows = max(m, 1)  # an inert row when m = 0: see the module docstring
        casadi = self._casadi
        self._structure = {"h": casadi.Sparsity.dense(n, n),
                           "a": casadi.Sparsity.dense(rows, n)}
        self._new_function()
        self._inputs = {
            "h": np.empty((n, n), order="F"), "g": np.empty(n),
            "a": np.zeros((rows, n), order="F"), "lba": np.full(rows, -np.inf),
            "uba": np.full(rows, np.inf), "lbx": np.empty(n), "ubx": np.empty(n),
            "x0": np.zeros(n), "lam_x0": np.zeros(n), "lam_a0": np.zeros(rows),
        }
        self._outputs = {"x": np.zeros(n), "cost": np.zeros(1), "lam_a": np.zeros(rows),
                         "lam_x": np.zeros(n)}
        self._update(H, g, A, lA, uA, lb, ub)
        self._bind()

    def _new_function(self) -> None:
        """A new conic function: a solver with no memory of earlier solves."""
        self._function = self._conic(self.options)

    def _conic(self, options: dict):
        with silenced():
            return self._casadi.conic("wbc_qp", self.plugin, self._structure,
                                      {**options, "error_on_fail": True})

    def _bind(self) -> None:
        """A new buffer bound to the numpy arrays (for qpOASES not a cold start: its hot-start
        state lives in the function, see :meth:`_restart`)."""
        self._buffer, self._evaluate = self._bound(self._function)
        self._fresh = True

    def _bound(self, function):
        """``(buffer, evaluate)`` of ``function`` on the numpy arrays, started cold."""
        for name in ("x0", "lam_x0", "lam_a0"):
            self._inputs[name][...] = 0.0
        with silenced():
            buffer, evaluate = function.buffer()
        for name in _INPUTS:
            view = self._inputs[name].reshape(-1, order="F")
            buffer.set_arg(function.index_in(name), memoryview(view))
        for name in _OUTPUTS:
            buffer.set_res(function.index_out(name), memoryview(self._outputs[name]))
        return buffer, evaluate

    def _retry_cold(self) -> bool:
        """One more cold attempt with the plugin's :data:`RETRY_OPTIONS` (a new function each
        time: qpOASES keeps its hot-start state there); whether it solved. Failed ticks only."""
        options = RETRY_OPTIONS.get(self.plugin)
        if options is None:
            return False
        buffer, evaluate = self._bound(self._conic({**self.options, **options}))
        t0 = clock()
        try:
            evaluate()
        except RuntimeError:
            return False
        finally:
            self.library_time += clock() - t0
        return True

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        arrays, m = self._inputs, self._m
        arrays["h"][...] = H
        arrays["g"][...] = g
        # A constant objective (H = 0, g = 0: an empty or all-zero undamped level) makes every
        # feasible point optimal, yet qpOASES reports it unbounded (found by wbc fuzz). The
        # identity Hessian picks the minimum-norm feasible point, an optimum of the original;
        # its multipliers are then those of the original's zero objective: 0.
        self._constant = not (H.any() or g.any())
        if self._constant:
            arrays["h"][...] = np.eye(self._n)
        arrays["a"][:m] = A
        arrays["lba"][:m] = lA
        arrays["uba"][:m] = uA
        arrays["lbx"][...] = lb
        arrays["ubx"][...] = ub
        # CasADi's conic asserts nonempty sides and raises; that is an infeasible problem
        self._empty = empty_sides(lA, uA) or empty_sides(lb, ub)

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        if self._empty:
            return empty_failure(self.name, n, m)
        inputs, outputs = self._inputs, self._outputs
        if warm_start is not None:
            inputs["x0"][...] = warm_start
        try:
            self._evaluate_once()
        except RuntimeError:  # error_on_fail: the plugin did not report success
            stats = self._buffer.stats()
            self._restart()
            if not self._retry_cold():
                status = _failure_status(stats)
                message = f"{self.name}: {stats.get('return_status', status.value)}"
                return failure(n, m, status, message, stats.get("iter_count", -1))
        inputs["x0"][...] = outputs["x"]
        inputs["lam_x0"][...] = outputs["lam_x"]
        inputs["lam_a0"][...] = outputs["lam_a"]
        if self._constant:
            return QPResult(x=outputs["x"].copy(), status=Status.SOLVED, y=np.zeros(m),
                            z=np.zeros(n))
        return QPResult(x=outputs["x"].copy(), status=Status.SOLVED,
                        y=outputs["lam_a"][:m].copy(), z=outputs["lam_x"].copy())

    def _evaluate_once(self) -> None:
        """Evaluate; a failure of a warm (hot-started) call is retried once from a fresh buffer,
        since the warm state itself may be what failed (qpOASES: "Failed to setup auxiliary QP
        for initialized homotopy" after a large change of the data)."""
        t0 = clock()
        try:
            self._evaluate()
        except RuntimeError:
            if self._fresh:
                raise
            self._restart()
            self._evaluate()
        finally:
            self._fresh = False
            self.library_time += clock() - t0

    def _restart(self) -> None:
        """Forget every earlier solve. A new buffer is not enough: qpOASES keeps its hot-start
        state with the function, and after a failed solve refuses every later one ("Unable to
        perform homotopy as previous QP is not solved"), so the function is made anew (about a
        millisecond, on failed ticks only)."""
        self._new_function()
        self._bind()
