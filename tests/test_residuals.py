"""A task that is not achieved is visible: ``solution.residuals[name]`` is what each task still
asks at the solution, in its own units, on both paths, kept with the solution it belongs to."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.tasks import Bounds, ConfigurationLimit, FrameTask, LinearTask, VelocityLimit

DT = 0.01
GAIN = 1.0


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def reach(robot, fused: bool) -> wbc.Controller:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=GAIN, position_only=True, name="ee"))
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return wbc.Controller(robot, stack, dt=DT, fused=fused)


@pytest.mark.parametrize("fused", [True, False])
def test_an_unreachable_target_shows_in_the_residual(robot, fused):
    """A target 2.6 m high: the loop stalls with every QP solved, and the residual of "ee" is
    the error the command leaves, ``e − dt/gain · J v`` (m): about the error itself once the
    arm has stretched as far as it goes."""
    ctrl = reach(robot, fused)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] = [0.3, 0.0, 2.6]
    for _ in range(400):
        q = robot.integrate(q, ctrl.step(q, ee=target), DT)
    ctrl.step(q, ee=target)
    solution = ctrl.last_solution
    assert solution.ok and solution.message == ""
    error = target[:3, 3] - robot.frame_pose(q, "ee")[:3, 3]
    assert np.linalg.norm(error) > 1.0
    J = robot.frame_jacobian(q, "ee")[:3]
    np.testing.assert_allclose(solution.residuals["ee"], error - DT / GAIN * J @ solution.x,
                               atol=1e-9)
    assert np.linalg.norm(solution.residuals["ee"]) == pytest.approx(np.linalg.norm(error),
                                                                       rel=0.05)


@pytest.mark.parametrize("fused", [True, False])
def test_a_reachable_target_leaves_no_residual(robot, fused):
    ctrl = reach(robot, fused)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[0, 3] += 0.01
    ctrl.step(q, ee=target)
    np.testing.assert_allclose(ctrl.last_solution.residuals["ee"], 0.0, atol=1e-6)


def test_the_residuals_stay_with_their_solution(robot):
    """The fused solution read after a tick keeps that tick's residuals, whatever the next
    references and ticks write."""
    ctrl = reach(robot, True)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[0, 3] += 0.5
    ctrl.step(q, ee=target)
    solution = ctrl.last_solution
    expected = solution.residuals["ee"].copy()
    ctrl.set_references(ee=robot.frame_pose(q, "ee"))
    ctrl.step(q)
    np.testing.assert_array_equal(solution.residuals["ee"], expected)
    live = ctrl.last_solution  # read before set_references moves the target
    ctrl.set_references(ee=target)
    np.testing.assert_allclose(live.residuals["ee"], 0.0, atol=1e-9)


def test_residuals_of_costs_soft_inequalities_and_scaled_tasks():
    """Three kinds of rows: a cost (``A x − b``), a soft inequality (signed violation) and a
    scaling level's task at its unscaled target (a scale below 1 shows)."""
    stack = wbc.Stack(2, damping=0.0)
    stack.add(LinearTask(np.eye(2), [3.0, 0.5], name="far"), priority=0, scaling=True)
    stack.add(wbc.Inequality(stack.variables.symbol[:1], -np.inf, -2.0, name="soft"),
              priority=1)
    stack.constrain(Bounds(-1.0, 1.0, name="box"))
    solution = stack.solve("quadprog")
    assert solution.ok, solution.message
    x = solution.x
    np.testing.assert_allclose(solution.residuals["far"], x - [3.0, 0.5], atol=1e-9)
    assert solution.scale < 1.0
    np.testing.assert_allclose(solution.residuals["soft"], [min(x[0] + 2.0, 0.0)
                                                            + max(x[0] + 2.0, 0.0)], atol=1e-9)
    assert solution.residuals["soft"][0] > 0.9  # x[0] >= -1 cannot reach <= -2
