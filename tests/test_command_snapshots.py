"""A command you can keep: every tick's command (and ``last_solution``) is an array no later
tick writes, on every backend and on both paths; ``out=`` is the zero-copy opt-in."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.solvers import available_backends
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

DT = 0.01
TICKS = 15
PATHS = [("daqp", True)] + [(name, False) for name in available_backends()]


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def controller(robot, backend: str, fused: bool, levels: int) -> wbc.Controller:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=2.0, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=1.0, weight=1e-2, name="posture"),
              priority=levels - 1)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    ctrl = wbc.Controller(robot, stack, backend, dt=DT, fused=fused)
    assert ctrl.fused is fused
    return ctrl


@pytest.mark.parametrize("levels", [1, 2])
@pytest.mark.parametrize("backend, fused", PATHS,
                         ids=[f"{b}-{'fused' if f else 'ordinary'}" for b, f in PATHS])
def test_kept_commands_stay_what_each_tick_returned(robot, backend, fused, levels):
    ctrl = controller(robot, backend, fused, levels)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += [0.3, -0.2, 0.1]  # moving for every tick: every command differs
    kept, values, solutions, xs = [], [], [], []
    for _ in range(TICKS):
        command = ctrl.step(q, ee=target)
        kept.append(command)
        values.append(command.copy())
        assert ctrl.last_command is command
        solutions.append(ctrl.last_solution)
        xs.append(ctrl.last_solution.x.copy())
        q = robot.integrate(q, command, DT)
    for command, value, solution, x in zip(kept, values, solutions, xs, strict=True):
        np.testing.assert_array_equal(command, value)
        np.testing.assert_array_equal(solution.x, x)
    assert len({command.tobytes() for command in kept}) == TICKS
    assert len({id(command) for command in kept}) == TICKS


@pytest.mark.parametrize("fused", [True, False])
def test_out_receives_the_command(robot, fused):
    ctrl = controller(robot, "daqp", fused, 1)
    reference = controller(robot, "daqp", fused, 1)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[0, 3] += 0.2
    buffer = np.full(robot.nv, np.nan)
    assert ctrl.step(q, out=buffer, ee=target) is buffer
    assert ctrl.last_command is buffer
    np.testing.assert_array_equal(buffer, reference.step(q, ee=target))


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros((7, 1)), np.zeros(7, dtype=np.float32),
                                 [0.0] * 7])
def test_a_bad_out_is_refused_before_anything_is_written(robot, bad):
    ctrl = controller(robot, "daqp", True, 1)
    ctrl.set_references(ee=robot.frame_pose(robot.neutral(), "ee"))
    before = ctrl.workspace.p.copy()
    with pytest.raises(wbc.ShapeError, match="out must be"):
        ctrl.step(robot.neutral() + 0.1, out=bad)
    np.testing.assert_array_equal(ctrl.workspace.p, before)


def test_the_fused_solution_is_copied_once_when_read(robot):
    ctrl = controller(robot, "daqp", True, 1)
    q = robot.neutral()
    ctrl.step(q, ee=robot.frame_pose(q, "ee"))
    first = ctrl.last_solution
    assert first is ctrl.last_solution  # the same snapshot until the next tick
    x = first.x.copy()
    ctrl.step(q + 0.1)
    assert ctrl.last_solution is not first
    np.testing.assert_array_equal(first.x, x)
