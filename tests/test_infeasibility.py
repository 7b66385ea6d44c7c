"""Infeasibility you can act on: a level the backend finds infeasible names the hard constraints
that cannot hold together (an irreducible infeasible subset), in its message and as data
(``Solution.conflict``, ``LevelResult.conflict``). The diagnosis runs when a backend reports
infeasibility, and after any failure of the first QP."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linprog

import wbc
from wbc.infeasibility import ABOVE, infeasible_subset
from wbc.solvers import available_backends
from wbc.tasks import Bounds, LinearConstraint, LinearTask

BACKENDS = available_backends()


def feasible(A, lA, uA, lb, ub, tol=1e-9) -> bool:
    """Whether some x meets the system (HiGHS, independent of the code under test)."""
    finite_u, finite_l = np.isfinite(uA), np.isfinite(lA)
    G = np.vstack([A[finite_u], -A[finite_l]])
    h = np.concatenate([uA[finite_u], -lA[finite_l]]) + tol
    lp = linprog(np.zeros(A.shape[1]), A_ub=G if len(G) else None, b_ub=h if len(h) else None,
                 bounds=list(zip(lb - tol, ub + tol, strict=True)), method="highs")
    return lp.status == 0


def keep(A, lA, uA, lb, ub, subset):
    """The system with only the sides in ``subset`` (others made infinite)."""
    lA2, uA2 = np.full_like(lA, -np.inf), np.full_like(uA, np.inf)
    lb2, ub2 = np.full_like(lb, -np.inf), np.full_like(ub, np.inf)
    for c in subset:
        lower, upper = (lA2, uA2) if c.kind == "row" else (lb2, ub2)
        source_lower, source_upper = (lA, uA) if c.kind == "row" else (lb, ub)
        if c.side == "upper":
            upper[c.index] = source_upper[c.index]
        else:
            lower[c.index] = source_lower[c.index]
    return A, lA2, uA2, lb2, ub2


@given(seed=st.integers(0, 10_000), m=st.integers(1, 6), n=st.integers(1, 5))
def test_the_subset_is_infeasible_and_irreducible(seed, m, n):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, n))
    if m > 1 and rng.random() < 0.3:
        A[-1] = A[0] * rng.uniform(0.5, 2.0)  # dependent rows, as rank-deficient stacks have
    centre = rng.uniform(-1, 1, m)
    lA, uA = centre - rng.uniform(0, 1, m), centre + rng.uniform(0, 1, m)
    lb, ub = -rng.uniform(0.1, 2, n), rng.uniform(0.1, 2, n)
    lA[rng.random(m) < 0.3] = -np.inf
    system = (A, lA, uA, lb, ub)
    subset = infeasible_subset(*system)
    if feasible(*system):
        assert subset == []
        return
    assert subset, "an infeasible system must have a conflict"
    assert not feasible(*keep(*system, subset))
    for i in range(len(subset)):  # irreducible: without any one side it is feasible
        assert feasible(*keep(*system, subset[:i] + subset[i + 1:]))


def test_a_feasible_or_barely_infeasible_system_has_no_conflict():
    A = np.array([[1.0, 1.0]])
    assert infeasible_subset(A, np.array([2.0]), np.array([2.0]), -np.ones(2), np.ones(2)) == []
    # misses by 1e-12: within the tolerance a solver works to, not a conflict of the data
    barely = np.array([2.0 + 1e-12])
    assert infeasible_subset(A, barely, barely, -np.ones(2), np.ones(2)) == []


def conflicting_stack() -> wbc.Stack:
    """A sum of speeds of at least 5.5 that bounds of 1 (base) and 0.5 (arm) cannot reach."""
    x = wbc.Variables(qd_base=3, qd_arm=4)
    stack = wbc.Stack(x, damping=1e-3)
    stack.add(LinearTask(np.eye(7), np.ones(7), name="ee"))
    stack.constrain(Bounds(-1.0, 1.0, name="qd_limits"))
    stack.constrain(Bounds(-0.5, 0.5, name="arm_limits", block="qd_arm"))
    stack.constrain(LinearConstraint(np.ones((1, 7)), [5.5], [6.0], name="sum_speed"))
    stack.constrain(LinearConstraint(np.eye(1, 7, 3), [-2.0], [2.0], name="harmless"))
    return stack


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_infeasible_level_names_its_conflicting_constraints(backend):
    sol = conflicting_stack().solve(backend)
    assert not sol.ok  # infeasible, or (proxqp) its iteration limit: diagnosed all the same
    assert set(sol.conflict) == {"sum_speed", "qd_limits", "arm_limits"}
    assert sol.levels[-1].conflict == sol.conflict
    assert "harmless" not in sol.message
    assert "'sum_speed' (lower side of row 0)" in sol.message
    assert "upper bound of qd_base[0], qd_base[1], qd_base[2]" in sol.message


def test_crossed_bounds_name_their_constraint():
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0, 0], name="t"))
    stack.constrain(Bounds(-1, 1, name="limits"))
    ws = stack.workspace("daqp")
    ws.view("limits.lower")[:, 0] = [-1, 2]  # the unchecked path: set() would refuse it
    sol = ws.solve()
    assert sol.conflict == ("limits",)
    assert "'limits' (upper bound of x[1], lower bound of x[1])" in sol.message


@pytest.mark.parametrize("backend", ["daqp", "quadprog", "clarabel"])
def test_a_lower_level_against_the_levels_above(backend):
    # level 0 puts x0 at 1; a constraint local to level 1 wants x0 <= 0: the optimum above and
    # the local constraint conflict, the bounds take no part
    stack = wbc.Stack(2)
    stack.add(LinearTask(np.eye(1, 2), [1.0], name="first"), priority=0)
    stack.add(LinearTask(np.eye(2), [0.0, 0.0], name="second"), priority=1)
    stack.constrain(LinearConstraint(np.eye(1, 2), [-np.inf], [0.0], name="local"), levels=[1])
    stack.constrain(Bounds(-5, 5, name="limits"))
    sol = stack.solve(backend)
    assert sol.partial and sol.status is wbc.Status.INFEASIBLE
    assert set(sol.conflict) == {"local", ABOVE}
    np.testing.assert_allclose(sol.x[0], 1.0, atol=1e-6)  # the command of the level above


def bounds_against_sum() -> wbc.Stack:
    """Two variables in [-1, 1] whose sum must lie in [3, 4]: "limits" and "sum" conflict."""
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [1.0, 1.0], name="t"))
    stack.constrain(Bounds(-1, 1, name="limits"))
    stack.constrain(LinearConstraint(np.ones((1, 2)), [3.0], [4.0], name="sum"))
    return stack


def test_the_controller_keeps_the_conflict_on_its_last_solution():
    class Point:  # the smallest robot: no kinematics, two velocity coordinates
        nq = nv = 2

    stack = bounds_against_sum()
    ctrl = wbc.Controller(Point(), stack, dt=0.01)
    np.testing.assert_array_equal(ctrl.step(np.zeros(2)), np.zeros(2))  # "hold"
    assert set(ctrl.last_solution.conflict) == {"limits", "sum"}
    with pytest.raises(wbc.InfeasibleError, match="cannot hold together: 'sum'"):
        wbc.Controller(Point(), stack, dt=0.01, fallback="raise").step(np.zeros(2))


def test_the_conflict_is_found_when_first_read_not_on_the_failed_tick(monkeypatch):
    """The LP (and scipy's import) stays off the failed tick; the tick's own arrays are kept, so
    the conflict read after later ticks is still that tick's."""
    from wbc import infeasibility

    calls = []
    real = infeasibility.level_conflict
    monkeypatch.setattr(infeasibility, "level_conflict",
                        lambda *args: calls.append(1) or real(*args))
    stack = bounds_against_sum()
    ws = stack.workspace("daqp")
    failed = ws.solve()
    assert failed.status is wbc.Status.INFEASIBLE and calls == []
    ws.set(**{"sum.lower": [-1.0], "sum.upper": [1.0]})  # the next tick is feasible
    assert ws.solve().ok
    assert set(failed.conflict) == {"limits", "sum"} and calls == [1]
    assert "cannot hold together: 'sum'" in failed.message and calls == [1]  # found once
    assert failed.levels[-1].conflict == failed.conflict


def test_the_message_joins_head_details_and_notes():
    stack = bounds_against_sum()
    solution = stack.workspace("daqp").solve()
    solution.notes.append("fallback 'hold': zero command (hold)")
    details = solution.diagnosis.details
    assert solution.head.startswith("level 0 (tasks: t): infeasible")
    assert details.startswith("hard constraints that cannot hold together")
    assert solution.message == "; ".join([solution.head, details,
                                          "fallback 'hold': zero command (hold)"])
    solved = wbc.Stack(1).add(LinearTask(np.eye(1), [0.5], name="t")).workspace("daqp").solve()
    assert solved.message == "" and solved.conflict == () and solved.diagnosis is None
