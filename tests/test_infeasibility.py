"""Infeasibility you can act on: a level the backend finds infeasible names the hard constraints
that cannot hold together (an irreducible infeasible subset), in its message and as data
(``Solution.conflict``, ``LevelResult.conflict``). The diagnosis runs when a backend reports
infeasibility, and after any failure of the first QP."""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linprog

import wbc
from wbc.infeasibility import ABOVE, Diagnosis, infeasible_subset
from wbc.solvers import available_backends
from wbc.tasks import Bounds, ConfigurationLimit, LinearConstraint, LinearTask, VelocityLimit

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


def constrain(stack: wbc.Stack, keep, constraints) -> wbc.Stack:
    """``stack`` with the hard ``constraints`` whose names are in ``keep`` (all if ``None``)."""
    for c in constraints:
        if keep is None or c.name in keep:
            stack.constrain(c)
    return stack


def hard_feasible(stack: wbc.Stack, data=None, tol: float = 1e-7) -> bool:
    """Whether the hard rows and bounds of ``stack``'s first QP can hold, with the parameters
    ``data`` written through views (unchecked, so crossed sides get through), by an LP of its
    own (:func:`feasible`), independent of :mod:`wbc.infeasibility`."""
    ws = stack.workspace("daqp")
    for name, value in (data or {}).items():
        if name in ws.compiled.parameters:
            view = ws.view(name)
            view[...] = np.broadcast_to(np.reshape(value, (-1, 1)) if view.shape[1] == 1
                                        else np.asarray(value), view.shape)
    block, n = ws.compiled.blocks[0], ws.compiled.n
    _, _, AT, lA, uA, lb, ub, _ = (np.array(v, dtype=float) for v in block.function(ws.p))
    rows = slice(0, block.m_hard)
    return feasible(AT.T[rows, :n], lA.ravel()[rows], uA.ravel()[rows], lb.ravel(), ub.ravel(),
                    tol)


def assert_irreducible(conflict, build, data=None) -> None:
    """The named constraints ``conflict`` cannot hold together, and without any one of them the
    others can: ``build(names)`` makes the stack with only those hard constraints."""
    assert conflict, "a conflict must be named"
    names = set(conflict)
    assert len(names) == len(conflict)
    assert not hard_feasible(build(names), data), f"{conflict} can hold together"
    for name in names:
        assert hard_feasible(build(names - {name}), data), f"{conflict} without {name!r}"


def conflicting_stack(keep=None) -> wbc.Stack:
    """A sum of speeds of at least 5.5 that bounds of 1 (base) and 0.5 (arm) cannot reach
    (``keep``: the names of the constraints to add, all by default)."""
    x = wbc.Variables(qd_base=3, qd_arm=4)
    stack = wbc.Stack(x, damping=1e-3)
    stack.add(LinearTask(np.eye(7), np.ones(7), name="ee"))
    return constrain(stack, keep, [
        Bounds(-1.0, 1.0, name="qd_limits"),
        Bounds(-0.5, 0.5, name="arm_limits", block="qd_arm"),
        LinearConstraint(np.ones((1, 7)), [5.5], [6.0], name="sum_speed"),
        LinearConstraint(np.eye(1, 7, 3), [-2.0], [2.0], name="harmless")])


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
    # irreducible: x0 = 1 (the optimum above) and x0 <= 0 (local) conflict, each alone holds
    x0, limits = sol.x[0], (-5 * np.ones(2), 5 * np.ones(2))
    both = np.array([[1.0, 0.0], [1.0, 0.0]]), np.array([x0, -np.inf]), np.array([x0, 0.0])
    assert not feasible(*both, *limits)
    assert feasible(both[0][:1], both[1][:1], both[2][:1], *limits)  # without "local"
    assert feasible(both[0][1:], both[1][1:], both[2][1:], *limits)  # without the levels above


def bounds_against_sum(keep=None) -> wbc.Stack:
    """Two variables in [-1, 1] whose sum must lie in [3, 4]: "limits" and "sum" conflict."""
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [1.0, 1.0], name="t"))
    return constrain(stack, keep, [Bounds(-1, 1, name="limits"),
                                   LinearConstraint(np.ones((1, 2)), [3.0], [4.0], name="sum")])


def test_the_controller_keeps_the_conflict_on_its_last_solution():
    class Point:  # the smallest robot: no kinematics, two velocity coordinates
        nq = nv = 2

    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [1.0, 1.0], name="t"))
    stack.constrain(Bounds(-1, 1, name="limits"))
    stack.constrain(LinearConstraint(np.ones((1, 2)), [0.0], [1.0], name="sum"))
    conflicting = {"sum.lower": [3.0], "sum.upper": [4.0]}  # set at run time: no refusal
    ctrl = wbc.Controller(Point(), stack, dt=0.01)
    np.testing.assert_array_equal(ctrl.step(np.zeros(2), **conflicting), np.zeros(2))  # hold
    assert set(ctrl.last_solution.conflict) == {"limits", "sum"}
    with pytest.raises(wbc.InfeasibleError, match="cannot hold together: 'sum'"):
        wbc.Controller(Point(), stack, dt=0.01, fallback="raise").step(np.zeros(2),
                                                                        **conflicting)


@pytest.mark.parametrize("build, names", [
    (bounds_against_sum, ("sum", "limits")),
    (lambda: wbc.Stack(2).add(LinearTask(np.eye(2), [0.0, 0.0], name="t"))
     .constrain(Bounds(2.0, 3.0, name="forward")).constrain(Bounds(-1.0, 1.0, name="backward"))
     .constrain(Bounds(-9.0, 9.0, name="harmless")), ("forward", "backward"))])
def test_constraints_that_conflict_at_any_state_are_refused_when_the_controller_is_built(
        build, names):
    """Contradictory constant bounds and rows (known before the first tick) cannot hold at any
    state: the controller is not built, and the error names an irreducible set of them."""
    class Point:
        nq = nv = 2

    with pytest.raises(wbc.InfeasibleError, match="whatever the state") as refused:
        wbc.Controller(Point(), build(), dt=0.01)
    for name in names:
        assert repr(name) in str(refused.value)
    assert "harmless" not in str(refused.value)


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


# --- the named set is irreducible: drop any one constraint and the rest can hold -------------

def diagnosed(ws: wbc.Workspace) -> tuple[str, ...]:
    """The conflict of the last tick's failed QP — the first: its arrays are in ``x`` — named
    from the tick's parameters ``ws.p`` (so that bounds of several constraints on one variable
    are told apart); the workspace's own diagnosis gets them once it passes ``p`` to
    :class:`~wbc.infeasibility.Diagnosis`."""
    assert len(ws.last_qps()) == 1, "only a failed first QP"
    qps = ws.last_qps()
    _, (_, _, A, lA, uA, lb, ub), _ = qps[-1]
    block = ws.compiled.blocks[len(qps) - 1]
    return Diagnosis(block, A, lA, uA, lb, ub, ws.compiled.variables, p=ws.p).conflict


def readme_stack(keep=None) -> wbc.Stack:
    """The README's example: a total speed of at least 4 that bounds of 0.5 cannot reach."""
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=4), damping=1e-3)
    stack.add(LinearTask(np.eye(7), np.ones(7), name="ee"))
    return constrain(stack, keep, [
        Bounds(-0.5, 0.5, name="qd_limits"),
        LinearConstraint(np.ones((1, 7)), [4.0], [5.0], name="min_total_speed")])


def crossed_stack(keep=None) -> wbc.Stack:
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0, 0], name="t"))
    return constrain(stack, keep, [Bounds(-1, 1, name="limits")])


def box_floor_row(keep=None) -> wbc.Stack:
    """tests/test_fused.py's stack: "box" and "floor" bounds, a hard "row", a soft row."""
    n = 6
    stack = wbc.Stack(n, damping=0.05)
    stack.add(LinearTask(np.ones((3, n)), np.ones(3), name="task"))
    stack.add(LinearConstraint(np.ones((1, n)), [-1.0], [1.0], name="soft"), weight=2.0)
    return constrain(stack, keep, [
        LinearConstraint(np.ones((1, n)), [-1.0], [1.0], name="row"),
        Bounds(-np.ones(n), np.ones(n), name="box"),
        Bounds(-np.inf, np.inf, name="floor")])


class Arm:
    """Robot-like: a 3-dof base then 4 arm joints, |q| <= 1 on the arm, |v| <= 1 [rad/s]."""

    nq = nv = 7
    n_arm = 4
    limits = SimpleNamespace(q_lower=-np.ones(7), q_upper=np.ones(7),
                             v_lower=-np.ones(7), v_upper=np.ones(7))


def arm_stack(keep=None, height_rate: float = 3.5) -> wbc.Stack:
    """Position limits (gain 0.5) and velocity limits on :class:`Arm`, and a "table" row: the
    arm joints' speeds must add up to at least ``height_rate`` [rad/s]."""
    stack = wbc.Stack(wbc.Variables(v=7), damping=1e-3)
    stack.add(LinearTask(np.eye(7), np.zeros(7), name="posture"))
    return constrain(stack, keep, [
        ConfigurationLimit(Arm(), gain=0.5, name="position_limits"),
        VelocityLimit(Arm(), name="velocity_limits"),
        LinearConstraint(np.r_[np.zeros(3), np.ones(4)][None], [height_rate], [np.inf],
                         name="table")])


#: q of the first arm joint near its upper limit: position bound (1 − 0.96) / 0.1 · 0.5 = 0.2
ARM_STATE = {"q": np.r_[np.zeros(3), 0.96, np.zeros(3)], "dt": 0.1}


def contradictory_bounds(keep=None) -> wbc.Stack:
    """Two contradictory bounds on the arm and a third, harmless one on everything."""
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=4), damping=1e-3)
    stack.add(LinearTask(np.eye(7), np.ones(7), name="ee"))
    return constrain(stack, keep, [
        Bounds(0.5, 1.0, name="forward", block="qd_arm"),
        Bounds(-1.0, -0.2, name="backward"),
        Bounds(-2.0, 2.0, name="harmless")])


SUITE_CONFLICTS = {  # every conflict the test suite provokes: (build, data)
    "conflicting_stack": (conflicting_stack, None),
    "bounds_against_sum": (bounds_against_sum, None),
    "readme": (readme_stack, None),
    "crossed_bounds": (crossed_stack, {"limits.lower": [-1.0, 2.0]}),
    "fused_crossed_floor": (box_floor_row, {"floor.lower": [-np.inf, -np.inf, 11.0, -np.inf,
                                                            -np.inf, -np.inf]}),
    "fused_rows": (box_floor_row, {"row.lower": [7.0], "row.upper": [8.0]}),
    "controller_crossed_limits": (partial(arm_stack, height_rate=-np.inf),
                                  {"q": np.r_[np.zeros(3), 1.1, np.zeros(3)], "dt": 0.01}),
}


def failed_workspace(build, data) -> tuple[wbc.Workspace, wbc.Solution]:
    ws = build().workspace("daqp")
    for name, value in (data or {}).items():
        view = ws.view(name)
        view[...] = np.reshape(value, view.shape)
    solution = ws.solve()
    assert not solution.ok
    return ws, solution


@pytest.mark.parametrize("case", SUITE_CONFLICTS)
def test_every_conflict_of_the_suite_is_irreducible(case):
    build, data = SUITE_CONFLICTS[case]
    ws, solution = failed_workspace(build, data)
    conflict = diagnosed(ws)
    assert_irreducible(conflict, build, data)
    assert solution.conflict == conflict  # the workspace's own diagnosis


OVERLAPPING = [
    # the velocity limits alone cannot reach 4.5 (4 × 1): the position limits take no part
    (partial(arm_stack, height_rate=4.5), ARM_STATE, {"table", "velocity_limits"}),
    # 3.5 needs both: 0.2 (position) + 3 × 1 (velocity) = 3.2 < 3.5 <= 4 and <= 0.2 + 3 × 5
    (arm_stack, ARM_STATE, {"table", "position_limits", "velocity_limits"}),
    (contradictory_bounds, None, {"forward", "backward"}),
]


@pytest.mark.parametrize("build, data, expected", OVERLAPPING)
def test_overlapping_bounds_are_told_apart(build, data, expected):
    ws, solution = failed_workspace(build, data)
    conflict = diagnosed(ws)
    assert set(conflict) == expected
    assert_irreducible(conflict, build, data)
    assert solution.conflict == conflict  # the workspace's own diagnosis


def test_the_workspace_tells_overlapping_bounds_apart():
    """``Workspace.solve`` hands its parameters to ``Diagnosis``: its conflicts are the
    irreducible ones above, overlapping bounds told apart."""
    for build, data in [*SUITE_CONFLICTS.values(), *(case[:2] for case in OVERLAPPING)]:
        ws, solution = failed_workspace(build, data)
        assert solution.conflict == diagnosed(ws)


def random_conflict(rng) -> list:
    """Named Bounds (on a block or everything) and linear inequalities on ``a`` (2) and ``b``
    (3) with random, often contradictory, intervals."""
    constraints = []
    for i in range(rng.integers(2, 7)):
        if rng.random() < 0.6:
            block = rng.choice(["a", "b", "all"])
            size = {"a": 2, "b": 3, "all": 5}[block]
            centre, half = rng.uniform(-1, 1, size), rng.uniform(0.05, 1, size)
            lower, upper = centre - half, centre + half
            lower[rng.random(size) < 0.2] = -np.inf
            upper[rng.random(size) < 0.2] = np.inf
            constraints.append(Bounds(lower, upper, name=f"bounds{i}",
                                      block=None if block == "all" else str(block)))
        else:
            m = int(rng.integers(1, 3))
            C = rng.standard_normal((m, 5))
            centre, half = rng.uniform(-3, 3, m), rng.uniform(0.05, 1, m)
            upper = np.where(rng.random(m) < 0.3, np.inf, centre + half)
            constraints.append(LinearConstraint(C, centre - half, upper, name=f"rows{i}"))
    return constraints


def test_random_conflicts_are_irreducible():
    rng = np.random.default_rng(21)
    infeasible = 0
    for _ in range(40):
        constraints = random_conflict(rng)

        def build(keep=None, constraints=constraints):
            stack = wbc.Stack(wbc.Variables(a=2, b=3), damping=1e-3)
            stack.add(LinearTask(np.eye(5), np.ones(5), name="t"))
            return constrain(stack, keep, constraints)

        if hard_feasible(build()):
            continue
        infeasible += 1
        ws, solution = failed_workspace(build, None)
        assert_irreducible(diagnosed(ws), build)
        assert not hard_feasible(build(set(solution.conflict)))
    assert infeasible >= 15
