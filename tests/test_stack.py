"""Generality of stacks (accelerations, torques, inequalities) and clear errors on bad input."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from helpers import assert_kkt, random_matrix
from scipy.optimize import minimize

import wbc
from wbc.solvers import available_backends
from wbc.solvers import reference as ref
from wbc.tasks import Bounds, LinearConstraint, LinearTask

BACKENDS = available_backends()


# ----------------------------------------------------------------------------- generality
@pytest.mark.parametrize("backend", BACKENDS)
def test_acceleration_stack_with_drift(backend):
    """Decision = joint accelerations; the task J q̈ + J̇q̇ = ẍ_d, with active bounds."""
    rng = np.random.default_rng(1)
    n, m = 9, 6
    J, drift, xdd = random_matrix(rng, m, n), rng.standard_normal(m), rng.standard_normal(m)
    x = wbc.Variables(qdd_base=3, qdd_arm=6)
    stack = wbc.Stack(x)
    Jp, dp = stack.parameter("J", (m, n), J), stack.parameter("Jdot_qdot", m, drift)
    stack.add(wbc.Cost(Jp @ x.symbol + dp, target=xdd, name="ee_acceleration"))
    ws = stack.workspace(backend, "tight")
    sol = ws.solve()
    np.testing.assert_allclose(sol.x, ref.pinv(J) @ (xdd - drift), atol=1e-7)
    # Tighten one bound below the unconstrained answer: it must become active and stay exact.
    limit = 0.5 * np.abs(sol.x).max()
    stack.constrain(Bounds(-limit, limit, name="qdd_limits"))
    ws = stack.workspace(backend, "tight")
    sol = ws.solve()
    assert sol.ok, sol.message
    assert np.abs(sol.x).max() <= limit + 1e-8
    assert np.isclose(np.abs(sol.x).max(), limit, atol=1e-7)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
def test_wheel_torque_distribution(backend):
    """Decision = 4 wheel torques; hard Jᵀτ = f (planar wrench) and a weighted cost on τ."""
    rng = np.random.default_rng(2)
    Jt = rng.standard_normal((3, 4))  # maps wheel torques to the platform wrench (fx, fy, mz)
    f = rng.standard_normal(3)
    w = np.array([1.0, 2.0, 0.5, 4.0])
    stack = wbc.Stack(wbc.Variables(tau=4))
    stack.add(LinearTask(np.eye(4), np.zeros(4), weight=w, name="effort"))
    stack.constrain(LinearConstraint(Jt, f, f, name="wrench"))
    ws = stack.workspace(backend, "tight")
    sol = ws.solve()
    assert sol.ok, sol.message
    Winv = np.diag(1 / w)
    expected = Winv @ Jt.T @ np.linalg.solve(Jt @ Winv @ Jt.T, f)  # weighted min-norm
    np.testing.assert_allclose(sol.x, expected, atol=1e-7)
    np.testing.assert_allclose(Jt @ sol.x, f, atol=1e-8)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_variables_with_linear_inequalities_only(backend):
    """Projection of a point onto a polygon {C x <= d}: an inequality-only stack."""
    C = np.array([[1.0, 1.0], [-1.0, 2.0], [0.0, -1.0]])
    d = np.array([1.0, 2.0, 0.5])
    target = np.array([2.0, 1.5])
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), target, name="point"))
    stack.constrain(LinearConstraint(C, -np.inf, d, name="polygon"))
    ws = stack.workspace(backend, "tight")
    sol = ws.solve()
    assert sol.ok, sol.message
    expected = minimize(lambda x: np.sum((x - target) ** 2), np.zeros(2), method="SLSQP",
                        constraints={"type": "ineq", "fun": lambda x: d - C @ x},
                        options={"ftol": 1e-14}).x
    np.testing.assert_allclose(sol.x, expected, atol=1e-6)
    assert np.all(C @ sol.x <= d + 1e-8)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
def test_soft_inequality_level_freezes_its_slack(backend):
    """Level 0: 1 <= x_i <= 2 (soft, feasible); level 1 pulls x far: it must stay in the box.
    A conflicting soft level keeps its minimal violation for the levels below."""
    stack = wbc.Stack(2)
    stack.add(LinearConstraint(np.eye(2), [1, 1], [2, 2], name="box"), priority=0)
    stack.add(LinearTask(np.array([[1.0, 1.0]]), [10.0], name="sum"), priority=1)
    sol = stack.solve(backend, "tight")
    np.testing.assert_allclose(sol.x, [2.0, 2.0], atol=1e-6)
    # x0 >= 3 and x0 <= 1 cannot both hold: the violation is split evenly and then frozen.
    stack = wbc.Stack(1)
    stack.add(LinearConstraint(np.array([[1.0], [1.0]]), [3.0, -np.inf], [np.inf, 1.0],
                               name="conflict"), priority=0)
    stack.add(LinearTask(np.eye(1), [0.0], name="pull"), priority=1)
    sol = stack.solve(backend, "tight")
    np.testing.assert_allclose(sol.x, [2.0], atol=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_workspace_update_changes_answer_without_recompiling(backend):
    rng = np.random.default_rng(3)
    stack = wbc.Stack(5, damping=0.1).add(LinearTask(np.eye(3, 5), np.ones(3), name="t"))
    ws = stack.workspace(backend, "tight")
    for _ in range(3):
        J, v = random_matrix(rng, 3, 5), rng.standard_normal(3)
        ws.set(**{"t.A": J, "t.b": v})
        np.testing.assert_allclose(ws.solve().x, ref.damped_pinv(J, 0.1) @ v, atol=1e-7)


# ----------------------------------------------------------------------------- bad input
def test_wrong_shapes_are_named():
    stack = wbc.Stack(4)
    with pytest.raises(wbc.ShapeError, match="task 'ee'.*3 columns.*4 entries"):
        stack.add(LinearTask(np.ones((2, 3)), np.ones(2), name="ee"))
    with pytest.raises(wbc.ShapeError, match="b of task 'ee'"):
        LinearTask(np.ones((2, 4)), np.ones(3), name="ee")
    stack.add(LinearTask(np.ones((2, 4)), np.ones(2), name="ee"))
    ws = stack.workspace("daqp")
    with pytest.raises(wbc.ShapeError, match="parameter 'ee.A' expects shape"):
        ws.set(**{"ee.A": np.ones((3, 4))})
    with pytest.raises(wbc.UnknownNameError, match="unknown parameter 'nope'.*ee.A"):
        ws.set(nope=1.0)
    with pytest.raises(wbc.ShapeError, match="block 'arm'"):
        wbc.Stack(wbc.Variables(base=3, arm=2)).add(
            LinearTask(np.ones((1, 3)), [0.0], name="t", block="arm"))


def test_nan_and_inf_coefficients_are_refused():
    with pytest.raises(wbc.NonFiniteError, match="A of task 'ee'"):
        LinearTask(np.array([[np.nan, 1.0]]), [0.0], name="ee")
    with pytest.raises(wbc.NonFiniteError, match="b of task 'ee'"):
        LinearTask(np.eye(2), [np.inf, 0.0], name="ee")
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0.0, 0.0], name="ee"))
    stack.constrain(Bounds(-1, 1, name="limits"))
    ws = stack.workspace("daqp")
    with pytest.raises(wbc.NonFiniteError, match="parameter 'ee.b'"):
        ws.set(**{"ee.b": [np.nan, 0.0]})
    with pytest.raises(wbc.NonFiniteError, match="parameter 'limits.lower'"):
        ws.set(**{"limits.lower": [np.nan, 0.0]})
    ws.set(**{"limits.lower": [-np.inf, -np.inf]})  # inf is a legal bound
    assert ws.solve().ok


def test_non_affine_task_is_refused_with_its_name():
    x = wbc.Variables(q=2)
    stack = wbc.Stack(x).add(wbc.Cost(x["q"] ** 2, name="squared"))
    with pytest.raises(wbc.NonAffineError, match="task 'squared' is not affine"):
        stack.compile()
    stack = wbc.Stack(x).add(wbc.Cost(x["q"], target=ca.sin(x["q"]), name="moving_target"))
    with pytest.raises(wbc.NonAffineError, match="target of task 'moving_target'"):
        stack.compile()
    stack = wbc.Stack(x).add(wbc.Cost(x["q"], name="t"))
    stack.constrain(wbc.Inequality(x["q"][0] * x["q"][1], 0, 1, name="product"))
    with pytest.raises(wbc.NonAffineError, match="constraint 'product'"):
        stack.compile()


def test_undeclared_symbols_are_reported():
    x = wbc.Variables(q=2)
    stray = ca.SX.sym("stray", 2)
    stack = wbc.Stack(x).add(wbc.Cost(x["q"] - stray, name="t"))
    with pytest.raises(wbc.WbcError, match="stack.parameter"):
        stack.compile()


def test_unknown_backend_lists_the_available_ones():
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0, 0], name="t"))
    with pytest.raises(wbc.BackendUnavailableError) as err:
        stack.workspace("no_such_solver")
    for name in BACKENDS:
        assert name in str(err.value)


def test_lower_above_upper():
    with pytest.raises(wbc.BoundsOrderError, match="bounds 'limits'.*index 1"):
        Bounds([0, 1], [1, 0], name="limits")
    with pytest.raises(wbc.BoundsOrderError, match="constraint 'c'"):
        LinearConstraint(np.eye(2), [0, 2], [1, 1], name="c")
    # workspace.set refuses crossed bounds; data written through a view (the unchecked path)
    # or computed from parameters reach the solve, which reports them as a status.
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0, 0], name="t"))
    stack.constrain(Bounds(-1, 1, name="limits"))
    ws = stack.workspace("daqp")
    with pytest.raises(wbc.BoundsOrderError, match="'limits'.lower/.upper"):
        ws.set(**{"limits.lower": [-1, 2]})
    ws.view("limits.lower")[:, 0] = [-1, 2]
    sol = ws.solve()
    assert sol.status is wbc.Status.INFEASIBLE
    assert "lower > upper at x[1]" in sol.message
    assert np.isfinite(sol.x).all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_infeasible_constraints_give_a_status_naming_the_level(backend):
    stack = wbc.Stack(2)
    stack.add(LinearTask(np.eye(2), [0, 0], name="track"), priority=0)
    stack.add(LinearTask(np.eye(2), [1, 1], name="posture"), priority=1)
    stack.constrain(LinearConstraint(np.array([[1.0, 1.0], [1.0, 1.0]]), [2.0, -np.inf],
                                     [np.inf, 1.0], name="contradiction"))
    sol = stack.solve(backend)
    assert not sol.ok
    assert sol.status in (wbc.Status.INFEASIBLE, wbc.Status.NUMERICAL, wbc.Status.MAX_ITER)
    assert "level 0 (tasks: track)" in sol.message
    assert np.isfinite(sol.x).all()


def test_bad_stack_arguments():
    with pytest.raises(wbc.InvalidValueError, match="damping"):
        wbc.Stack(2, damping=-1.0)
    with pytest.raises(wbc.InvalidValueError, match="positive semi-definite"):
        wbc.Stack(2, mobility=np.array([1.0, -1.0]))
    with pytest.raises(wbc.ShapeError, match="positive integer size"):
        wbc.Variables(q=0)
    stack = wbc.Stack(2).add(LinearTask(np.eye(2), [0, 0], name="t"))
    with pytest.raises(wbc.WbcError, match="already in the stack"):
        stack.add(LinearTask(np.eye(2), [0, 0], name="t"))
    with pytest.raises(wbc.WbcError, match="no task"):
        wbc.Stack(2).compile()
    with pytest.raises(wbc.WbcError, match="bounds are hard"):
        wbc.Stack(2).add(Bounds(-1, 1, name="b"))


def test_editing_a_stack_a_controller_was_built_from_is_refused():
    """The controller compiled a snapshot: an edit afterwards would silently not reach it."""
    class Point:  # the smallest robot: no kinematics, two velocity coordinates
        nq = nv = 2

    stack = wbc.Stack(2, damping=1e-3).add(LinearTask(np.eye(2), [1.0, 0.0], name="t"))
    stack.add(LinearTask(np.eye(2), [0.0, 0.0], name="before"), priority=1)  # still editable
    wbc.Controller(Point(), stack, dt=0.01)
    for edit in (lambda: stack.add(LinearTask(np.eye(2), [0.0, 1.0], name="late")),
                 lambda: stack.constrain(Bounds(-1.0, 1.0, name="late_bounds")),
                 lambda: stack.parameter("late_parameter", 2),
                 lambda: stack.set_mobility(np.ones(2))):
        with pytest.raises(wbc.WbcError, match="compiled into a wbc.Controller"):
            edit()
    wbc.Controller(Point(), stack, dt=0.01)  # more controllers from the finished stack: fine
