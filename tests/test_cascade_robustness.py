"""Cascade robustness: a failing lower level keeps the levels above, the levels above are
eliminated (no equality rows, degenerate vertices solved), and a saturating multi-level closed
loop never leaves its bounds."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
import wbc.robots
from wbc.experiments.benchmarks import solver_timing
from wbc.qp import QPResult, Status
from wbc.solvers import make_backend
from wbc.tasks import Bounds, LinearTask


class _Failing:
    """A backend that accepts data and always reports failure."""

    name, profile = "failing", "default"

    def setup(self, H, g, A, lA, uA, lb, ub) -> None:
        self.n, self.m = len(g), len(lA)

    def update(self, H, g, A, lA, uA, lb, ub) -> None:
        pass

    def solve(self, warm_start=None) -> QPResult:
        return QPResult(np.zeros(self.n), Status.NUMERICAL, np.zeros(self.m), np.zeros(self.n),
                        message="refused")


class _RefusesEqualities:
    """daqp, except that any finite equality row (``lA == uA``) is reported infeasible — the
    way solvers miss a point-like feasible set at a vertex."""

    name, profile = "refuses_equalities", "default"

    def __init__(self) -> None:
        self.inner = make_backend("daqp", "tight")
        self.saw = []

    def setup(self, *qp) -> None:
        self.inner.setup(*qp)
        self._check(qp)

    def update(self, *qp) -> None:
        self.inner.update(*qp)
        self._check(qp)

    def _check(self, qp) -> None:
        lA, uA = qp[3], qp[4]
        self.equalities = bool(np.any(np.isfinite(lA) & (lA == uA)))
        self.saw.append(self.equalities)

    def solve(self, warm_start=None) -> QPResult:
        if self.equalities:
            n, m = self.inner.n, self.inner.m
            return QPResult(np.zeros(n), Status.INFEASIBLE, np.zeros(m), np.zeros(n),
                            message="equality rows refused")
        return self.inner.solve(warm_start)


# Measured over TICKS: no partial tick but with proxqp (26) and osqp (87; 3x as many before lower
# levels were warm-started from the level above); without the retry band daqp has 3 and
# qpOASES 7. Some spare for other BLAS builds.
TICKS = 600
MAX_PARTIAL = {"daqp": 1, "qpoases": 1, "quadprog": 1, "clarabel": 1, "proxqp": 60, "osqp": 150}


def _two_level_stack(rng: np.random.Generator) -> tuple[wbc.Stack, np.ndarray, np.ndarray]:
    n = 6
    stack = wbc.Stack(wbc.Variables(x=n))
    J1, J2 = rng.standard_normal((2, n)), rng.standard_normal((3, n))
    stack.add(LinearTask(J1, rng.standard_normal(2), name="first"), priority=0)
    stack.add(LinearTask(J2, rng.standard_normal(3), name="second"), priority=1)
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    return stack, J1, J2


def _backends(*factories):
    """A backend factory handing out ``factories``' products in block order."""
    made = iter(factories)
    return lambda: next(made)()


def test_a_failing_lower_level_keeps_the_levels_above():
    stack, J1, _ = _two_level_stack(np.random.default_rng(0))
    reference = stack.workspace("daqp", "tight").solve()
    ws = stack.workspace(_backends(lambda: make_backend("daqp", "tight"), _Failing,
                                   _Failing))
    solution = ws.solve()
    assert solution.status is Status.NUMERICAL and solution.partial
    assert "level 1" in solution.message and "refused" in solution.message
    np.testing.assert_allclose(solution.x, reference.levels[0].x, atol=1e-9)
    first = ws.compiled  # nothing above the first level: not partial
    ws_first = wbc.Workspace(first, _Failing)
    failed = ws_first.solve()
    assert not failed.partial and np.array_equal(failed.x, np.zeros(6))


def test_lower_levels_see_no_equality_rows():
    """The levels above are eliminated, not frozen as rows: a backend that refuses every
    equality row solves the lower level, and the first level's task rows stay exactly where
    it left them."""
    stack, J1, _ = _two_level_stack(np.random.default_rng(1))
    reference = stack.workspace("quadprog", "tight").solve()
    second = _RefusesEqualities()
    ws = stack.workspace(_backends(lambda: make_backend("daqp", "tight"), lambda: second,
                                   lambda: make_backend("daqp", "tight")))
    solution = ws.solve()
    assert solution.ok, solution.message
    assert second.saw and not any(second.saw)
    level = solution.levels[1]
    assert level.frozen_rank == 2 and level.frozen_band == 0.0
    x1 = solution.levels[0].x
    np.testing.assert_allclose(J1 @ solution.x, J1 @ x1, atol=1e-12)
    np.testing.assert_allclose(solution.x, reference.x, atol=1e-8)


def test_freeze_tol_is_deprecated_and_ignored():
    with pytest.warns(DeprecationWarning, match="freeze_tol is ignored"):
        wbc.Stack(wbc.Variables(x=2), freeze_tol=1e-6)


@pytest.mark.parametrize("backend", ["daqp", "quadprog", "qpoases", "clarabel"])
def test_a_degenerate_vertex_below_a_level_is_solved(backend):
    """Level 0 pushes ``Σx`` far beyond the box: its optimum is the vertex ``(1, 1, 1)``, where
    three bounds are active in the two directions the level leaves — a degenerate vertex, the
    only feasible point of level 1. Every lower level must return it, reported solved."""
    n = 3
    stack = wbc.Stack(wbc.Variables(x=n), damping=0.0)
    stack.add(LinearTask(np.ones((1, n)), [10.0], name="sum"), priority=0)
    stack.add(LinearTask(np.eye(n), [0.3, -0.2, 0.1], name="posture"), priority=1)
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    ws = stack.workspace(backend, "tight")
    for _ in range(3):  # hot starts too
        solution = ws.solve()
        assert solution.ok, solution.message
        np.testing.assert_allclose(solution.x, np.ones(n), atol=1e-7)


@pytest.mark.parametrize("backend", ["daqp", "qpoases", "quadprog", "clarabel", "proxqp", "osqp"])
def test_saturating_three_level_loop_stays_within_bounds(backend, monkeypatch):
    """A target ten times faster than the benchmark's saturates the velocity limits of the
    Tiago base and arm; the three strict levels then meet at vertices of the bounds. Every
    command stays within the bounds and the first level is always solved; a lower level may
    fail (then the command is the levels above it, ``partial``)."""
    monkeypatch.setattr(solver_timing, "CIRCLE_PERIOD", 0.4)
    robot = wbc.robots.load("tiago_panda")
    ctrl = wbc.Controller(robot, solver_timing.build_stack(robot, "three_levels"),
                          backend=backend, dt=solver_timing.DT)
    lower, upper = robot.limits.v_lower, robot.limits.v_upper
    q, v = np.asarray(robot.neutral(), float), np.zeros(robot.nv)
    pose0 = np.array(robot.frame_pose(q, "ee"))
    partial = 0
    for k in range(TICKS):
        T = solver_timing._target(pose0, k * solver_timing.DT)
        v = ctrl.step(q, v, ee=T, ee_pose=T)
        solution = ctrl.last_solution
        assert solution.ok or solution.partial, solution.message
        if solution.partial:
            partial += 1
            assert solution.fallback == "partial"
            np.testing.assert_array_equal(v, solution.levels[-2].x)
        assert np.all(v >= lower - 1e-6) and np.all(v <= upper + 1e-6)
        q = robot.integrate(q, v, solver_timing.DT)
    print(f"{backend}: {partial} partial ticks of {TICKS}")
    assert partial <= MAX_PARTIAL[backend]


def test_a_level_determined_by_the_levels_above_is_not_solved():
    """Level 0 has rank n: level 1's feasible set is level 0's optimum, so no solver runs for
    it (a failing backend there is never called) and its result is that point."""
    rng = np.random.default_rng(3)
    n = 4
    stack = wbc.Stack(wbc.Variables(x=n), damping={0: 0.1})
    stack.add(LinearTask(rng.standard_normal((n, n)), rng.standard_normal(n), name="full"),
              priority=0)
    stack.add(LinearTask(np.eye(n), rng.standard_normal(n), name="posture"), priority=1)
    ws = stack.workspace(_backends(lambda: make_backend("daqp", "tight"), _Failing, _Failing))
    solution = ws.solve()
    assert solution.ok, solution.message
    first, second = solution.levels[0], solution.levels[1]
    assert second.frozen_rank == n and second.iterations == 0
    np.testing.assert_array_equal(second.x, first.x)
    np.testing.assert_array_equal(solution.x, first.x)
    assert [label for label, _, _ in ws.last_qps()] == [first.label]


def test_an_inconsistent_scaled_task_below_a_level_is_reported_not_retried():
    """A scaling level ``J x + d = s t`` with ``d`` and ``t`` such that no ``s`` makes it
    consistent (rank-1 ``J``): the status says so (no solver call, no band retry), and the
    level above is kept."""
    n = 4
    x = wbc.Variables(x=n)
    stack = wbc.Stack(x, damping=0.1)
    stack.add(LinearTask(np.eye(n)[:1], [0.5], name="first"), priority=0)
    J = np.array([[1.0, 1.0, 0.0, 0.0], [2.0, 2.0, 0.0, 0.0]])
    stack.add(wbc.Cost(J @ x["x"] + np.array([1.0, 0.0]), target=np.array([1.0, 2.0]),
                       name="scaled"), priority=1, scaling=True)
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    solution = stack.workspace("daqp").solve()  # first tick: backends not set up yet
    assert solution.status is Status.INFEASIBLE and solution.partial
    assert "inconsistent" in solution.message and "level 1" in solution.message
    assert solution.x[0] == pytest.approx(0.5 / (1 + 0.1 ** 2), abs=1e-9)  # damped level 0


@pytest.mark.parametrize("backend, profile, warns", [
    ("osqp", "default", True), ("osqp", "tight", True), ("proxqp", "default", True),
    ("qpoases", "default", True), ("clarabel", "default", True), ("daqp", "default", False),
    ("quadprog", "default", False), ("clarabel", "tight", False)])
def test_a_backend_measured_inexact_on_cascades_warns_with_the_measurement(backend, profile,
                                                                           warns):
    import warnings

    from wbc.solvers.registry import CASCADE_CAVEATS

    stack, _, _ = _two_level_stack(np.random.default_rng(3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stack.workspace(backend, profile)
        single = wbc.Stack(wbc.Variables(x=6), damping=1e-3)
        single.add(LinearTask(np.eye(6), np.zeros(6), name="only"))
        single.workspace(backend, profile)  # one QP: nothing to warn about
    messages = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    if warns:
        assert len(messages) == 1 and CASCADE_CAVEATS[(backend, profile)] in messages[0]
    else:
        assert not messages
