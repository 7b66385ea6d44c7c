"""AMP's fast path (``amp_controller(fused="auto")``: the tick in generated C where the task is
not saturated, :mod:`wbc.papers.xing.fast`) against its ordinary path (``fused=False``):
commands, task scale, statuses and fallbacks, on the study's recorded states and on random
states of the mecanum Gen3; and the zonotope test against an LP. Equality and behaviour only;
speed is measured by ``wbc study xing`` (``timing["daqp"]``), never asserted here."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import linprog

import wbc.robots as robots
from wbc.cbuild import compiler_available
from wbc.errors import WbcError
from wbc.experiments.studies import xing as study
from wbc.experiments.studies.study import DOCUMENTED
from wbc.papers.xing import POSE, POSITION, amp_controller
from wbc.papers.xing.fast import FAST_QP_LABEL, full_rank, zonotope_interior
from wbc.qp import Status

pytestmark = pytest.mark.skipif(not compiler_available(), reason="needs a C compiler")

TOL = 1e-6  # the project's equality tolerance for a fast path
# jit=False: the ordinary paths on CasADi's virtual machine, the same evaluation on every
# controller here (bitwise comparisons below), and no JIT builds; the fast tick is C anyway


@pytest.fixture(scope="module")
def robot():
    return robots.load("mecanum_gen3")


def _pair(robot, setup=POSITION):
    fast = amp_controller(robot, setup, jit=False)
    ordinary = amp_controller(robot, setup, jit=False, fused=False)
    assert fast.fused and fast.fused_reason is None and not ordinary.fused
    return fast, ordinary


@pytest.fixture(scope="module")
def recorded(robot):
    """Every tick's ``(setup, q, v, references)`` of the quick study's closed loops on the
    position task (the circles, the singularity runs without avoidance and without the
    tertiary objective; the timing run is the larger circle's start)."""
    start = study.staging(robot, None)
    pose = robot.frame_pose(start.q0, "ee")
    small, large = (study.circle(pose[:3, 3].copy(), radius, pose[:3, :3].copy())
                    for radius in (0.10, 0.25))
    runs = ((POSITION, small, 8.0), (POSITION, large, 8.0),
            (replace(POSITION, sigma_thr=0.0, gamma1=0.0, gamma2=0.0), large, 4.0),
            (replace(POSITION, gamma1=0.0, gamma2=0.0), large, 4.0))
    out = []
    for setup, references, seconds in runs:
        _, run = study.simulate(robot, amp_controller(robot, setup, jit=False), references,
                                seconds, setup, start, DOCUMENTED, record=False)
        out.append((setup, [(q, v, references(t))
                            for q, v, t in zip(run.q_est, run.v_est, run.t, strict=True)]))
    return out


def test_recorded_states(robot, recorded):
    """The fast path answers every recorded tick (none saturates), as the ordinary path."""
    ticks = 0
    for setup, states in recorded:
        fast, ordinary = _pair(robot, setup)
        for q, v, references in states:
            a, b = fast.step(q, v, **references), ordinary.step(q, v, **references)
            sa, sb = fast.last_solution, ordinary.last_solution
            assert sa.status is sb.status is Status.SOLVED
            np.testing.assert_allclose(a, b, rtol=0.0, atol=TOL)
            assert sa.scale == 1.0 and abs(sb.scale - 1.0) <= TOL
        assert fast.workspace.fallback_solves == 0
        ticks += len(states)
    assert ticks == 1200


def test_random_states(robot):
    """1000 random states of the study's sampler (a third with saturating demands): where the
    fast path answers, the ordinary path's command and scale; where it does not (the task
    saturated), the ordinary path's own answer — bitwise that of an ordinary controller that
    saw the same ticks (a saturated tick's answer depends on the active sets daqp keeps from
    the ticks before, see :mod:`wbc.papers.xing.fast`). Statuses equal throughout."""
    fast, ordinary = _pair(robot)
    shadow = amp_controller(robot, POSITION, jit=False, fused=False)  # the fallbacks' history
    rng = np.random.default_rng(0)
    answered = handed = saturated = 0
    for _ in range(1000):
        q, v, references = study.random_state(rng, robot)
        before = fast.workspace.fallback_solves
        a, b = fast.step(q, v, **references), ordinary.step(q, v, **references)
        sa, sb = fast.last_solution, ordinary.last_solution
        assert (sa.status, sa.fallback) == (sb.status, sb.fallback)
        if fast.workspace.fallback_solves == before:
            answered += 1
            np.testing.assert_allclose(a, b, rtol=0.0, atol=TOL)
            assert sa.scale == 1.0 and abs(sb.scale - 1.0) <= TOL
        else:
            handed += 1
            c = shadow.step(q, v, **references)
            sc = shadow.last_solution
            np.testing.assert_array_equal(a, c)
            assert (sa.status, sa.fallback, sa.scale) == (sc.status, sc.fallback, sc.scale)
            saturated += sb.scale < 1.0
    # seed 0: 696 answered; 304 handed over, 293 of them saturated
    assert answered > 600 and handed > 250 and saturated > 250
    assert fast.workspace.skipped_solves == 0  # no back-off: every tick tries the fast call


def test_fast_tick_solution(robot):
    """A fast tick's solution: every level solved at the command, ``s = 1``, and the one QP
    the generated daqp solved, whose solution meets its rows and bounds."""
    fast, _ = _pair(robot)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee")
    target[:3, 3] += [0.02, -0.01, 0.01]
    x = fast.step(q, 0.1 * robot.limits.v_upper, target=target)
    assert fast.workspace.fallback_solves == 0
    solution = fast.last_solution
    assert [level.status for level in solution.levels] == [Status.SOLVED] * 4
    assert all(np.array_equal(level.x, x) for level in solution.levels)
    assert solution.scales == {0: 1.0}
    [(label, (H, g, A, lA, uA, lb, ub), result)] = fast.last_qps()
    assert label == FAST_QP_LABEL and np.array_equal(lA, uA)
    np.testing.assert_allclose(A @ result.x, lA, atol=1e-9)
    assert np.all(result.x >= lb - 1e-9) and np.all(result.x <= ub + 1e-9)
    np.testing.assert_allclose(np.clip(result.x, lb, ub), x, rtol=0.0, atol=0.0)


def test_infeasible_tick_is_named(robot):
    """A joint beyond its velocity limit crosses its acceleration bounds (eqs. 6–8): the fast
    path hands the tick over, and it is refused and named as on the ordinary path."""
    fast, ordinary = _pair(robot)
    q0 = robot.neutral()
    target = robot.frame_pose(q0, "ee")
    v = np.zeros(robot.nv)
    v[4] = 1.9  # above the joint's 1.75 rad/s
    for controller in (fast, ordinary):
        controller.step(q0, np.zeros(robot.nv), target=target)
        controller.step(q0, v, target=target)
    sa, sb = fast.last_solution, ordinary.last_solution
    assert fast.workspace.fallback_solves == 1
    assert sa.status is sb.status is Status.INFEASIBLE
    assert sa.fallback == sb.fallback == "decelerate"
    assert sa.message == sb.message and sa.levels[-1].conflict == ("limits",)
    np.testing.assert_allclose(fast.last_command, ordinary.last_command, rtol=0.0, atol=TOL)


def test_where_the_fast_path_does_not_apply(robot):
    pose = amp_controller(robot, POSE, jit=False)
    assert not pose.fused and "6 rows" in pose.fused_reason
    with pytest.raises(WbcError, match="6 rows"):
        amp_controller(robot, POSE, jit=False, fused=True)
    other = amp_controller(robot, POSITION, "quadprog", jit=False)
    assert not other.fused and "quadprog" in other.fused_reason


def _inside_by_lp(G, lower, upper, y) -> float:
    """The largest ``s`` with ``c + s (y − c)`` in the zonotope (``c`` its centre): > 1 inside,
    < 1 outside (scipy's HiGHS)."""
    k = G.shape[1]
    centre = G @ (lower + upper) / 2
    # variables [x (k), s]: maximise s, G x − s (y − c) = c
    result = linprog(np.r_[np.zeros(k), -1.0], A_eq=np.c_[G, centre - y], b_eq=centre,
                     bounds=[*zip(lower, upper, strict=True), (0.0, None)], method="highs")
    assert result.status == 0
    return result.x[-1]


def test_zonotope_interior_against_an_lp():
    """``zonotope_interior`` (facets from pairs of generators) decides what an LP decides, on
    random zonotopes with a zero generator and two opposite ones (as the mecanum Gen3's)."""
    G, y = ca.SX.sym("G", 3, 7), ca.SX.sym("y", 3)
    lower, upper, margin = ca.SX.sym("lower", 7), ca.SX.sym("upper", 7), ca.SX.sym("margin")
    inside = ca.Function("inside", [G, lower, upper, y, margin],
                         [zonotope_interior(G, lower, upper, y, margin)])
    rng = np.random.default_rng(5)
    seen = {True: 0, False: 0}
    for _ in range(300):
        g = rng.normal(size=(3, 7))
        g[:, 6] = 0.0
        g[:, 3] = -g[:, 2]
        lo, hi = -rng.uniform(0.1, 2.0, 7), rng.uniform(0.1, 2.0, 7)
        point = g @ rng.uniform(lo, hi) * rng.uniform(0.5, 2.0)
        s = _inside_by_lp(g, lo, hi, point)
        if abs(s - 1.0) < 1e-6:  # on the boundary: either answer
            continue
        assert bool(inside(g, lo, hi, point, 0.0)) == (s > 1.0)
        seen[s > 1.0] += 1
    assert min(seen.values()) > 50
    # the margin: a point inside by less than it is refused
    g = np.eye(3, 7)
    lo, hi = -np.ones(7), np.ones(7)
    assert bool(inside(g, lo, hi, np.array([0.9, 0.0, 0.0]), 0.05))
    assert not bool(inside(g, lo, hi, np.array([0.9, 0.0, 0.0]), 0.2))


def test_full_rank():
    J = ca.SX.sym("J", 3, 5)
    rank = ca.Function("rank", [J], [full_rank(J)])
    rng = np.random.default_rng(2)
    well = rng.normal(size=(3, 5))
    flat = well.copy()
    flat[2] = flat[0] + flat[1]  # rank 2
    assert bool(rank(well)) and not bool(rank(flat))
