"""`MobileManipulator.symbolic_frame`: CasADi pose and Jacobian equal to the numeric getters,
in the robot's own velocity coordinates, and controllers with ``kinematics="compiled"``."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wbc
import wbc.robots
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

ROBOTS = wbc.robots.names()
SEED = 20240611
DT = 0.01  # control period [s]


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return wbc.robots.load(request.param)


def configurations(robot, rng: np.random.Generator, count: int) -> list[np.ndarray]:
    """Random configurations with headings far beyond ±π [rad] and, every other one, arm joints
    pushed to within 1e-6 of a position limit (one side per joint, at random)."""
    lower, upper = robot.limits.q_lower[3:], robot.limits.q_upper[3:]
    out = []
    for k in range(count):
        q = robot.random_configuration(rng)
        q[2] += 2.0 * math.pi * rng.integers(-3, 4) + rng.uniform(-1.0, 1.0)
        if k % 2:
            near_upper = rng.random(robot.n_arm) < 0.5
            edge = np.where(near_upper, upper - 1e-6, lower + 1e-6)
            q[3:] = np.where(np.isfinite(edge), edge, q[3:])
        out.append(q)
    assert any(abs(q[2]) > math.pi for q in out)
    return out


def evaluate(function, q) -> tuple[np.ndarray, np.ndarray]:
    pose, J = function(q)
    return np.array(pose), np.array(J)


def pose_rates(robot, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``q̇`` of velocity ``v``, derived here from the base conventions (not from the robot):
    the base coordinates are the body twist ``(v_x, v_y, ω)`` in the base frame (holonomic) or
    ``(v, ω)`` = body twist ``(v, 0, ω)`` (differential drive), so the world pose rates are
    ``ẋ = cos θ v_x − sin θ v_y``, ``ẏ = sin θ v_x + cos θ v_y``, ``θ̇ = ω``; arm rates as is."""
    nb = robot.nv_base
    if nb == 3:
        vx, vy, omega = v[:3]
    else:
        assert robot.base.velocity_names == ("v", "omega")
        (vx, omega), vy = v[:2], 0.0
    c, s = math.cos(q[2]), math.sin(q[2])
    return np.concatenate([[c * vx - s * vy, s * vx + c * vy, omega], v[nb:]])


# ------------------------------------------------------------------------ against pinocchio
def test_symbolic_frame_equals_the_numeric_getters(robot):
    rng = np.random.default_rng(SEED)
    fk = robot.symbolic_frame("ee")
    assert robot.symbolic_frame("ee") is fk  # cached per frame
    assert robot.symbolic_frame(robot.frame_id("ee")) is fk  # ... by index too
    assert fk.size_in(0) == (robot.nq, 1)
    assert fk.size_out(0) == (4, 4) and fk.size_out(1) == (6, robot.nv)
    for q in configurations(robot, rng, 8):
        pose, J = evaluate(fk, q)
        np.testing.assert_allclose(pose, robot.frame_pose(q, "ee"), rtol=0, atol=1e-10)
        np.testing.assert_allclose(J, robot.frame_jacobian(q, "ee", "world"), rtol=0,
                                   atol=1e-10)


def test_symbolic_jacobian_is_the_derivative_of_the_symbolic_pose(robot):
    """``J v`` = world twist of the frame (origin velocity, angular velocity) along ``q̇(v)``,
    by central differences of the symbolic pose."""
    rng = np.random.default_rng(SEED + 2)
    fk, h = robot.symbolic_frame("ee"), 1e-6
    for q in configurations(robot, rng, 4):
        v = rng.uniform(-1.0, 1.0, robot.nv)
        qdot = pose_rates(robot, q, v)
        (T_plus, _), (T_minus, _) = evaluate(fk, q + h * qdot), evaluate(fk, q - h * qdot)
        T, J = evaluate(fk, q)
        linear = (T_plus[:3, 3] - T_minus[:3, 3]) / (2 * h)
        W = (T_plus[:3, :3] - T_minus[:3, :3]) / (2 * h) @ T[:3, :3].T  # Ṙ Rᵀ = [ω]×
        angular = 0.5 * np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])
        np.testing.assert_allclose(J @ v, np.concatenate([linear, angular]), rtol=0,
                                   atol=1e-7)
        # the base columns really are the robot's coordinates, not world pose rates
        if robot.nv_base == 3 and abs(math.sin(q[2])) > 0.1:
            assert not np.allclose(J[:, :3] @ v[:3], J[:, :3] @ qdot[:3], atol=1e-3)


# ------------------------------------------------------------------------ controller
def frame_and_posture_stack(robot) -> wbc.Stack:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="qlim"))
    stack.constrain(VelocityLimit(robot, name="vlim"))
    return stack


@pytest.mark.parametrize("name", ["mpo700_lwr4", "tiago_panda"])  # holonomic, unicycle
def test_compiled_kinematics_give_the_numeric_commands(name):
    robot, twin = wbc.robots.load(name), wbc.robots.load(name)
    numeric = wbc.Controller(robot, frame_and_posture_stack(robot), backend="daqp", dt=DT)
    compiled = wbc.Controller(twin, frame_and_posture_stack(twin), backend="daqp", dt=DT,
                              kinematics="compiled")
    assert not {"pose[ee]", "J[ee]"} & set(compiled.workspace.parameter_names)
    assert set(compiled.model_parameters) == {"dt", "q"}
    calls = []
    twin.update = lambda *args, **kwargs: calls.append(args)  # the tick must not need it
    q = robot.neutral()
    q[2] = 4.0  # heading beyond π [rad]
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += [0.5, -0.3, 0.05]  # out of the arm's reach: the base moves
    for _ in range(40):
        v = numeric.step(q, ee=target)
        assert numeric.last_solution.ok
        np.testing.assert_allclose(compiled.step(q, ee=target), v, rtol=0, atol=1e-8)
        assert compiled.last_solution.ok
        q = robot.integrate(q, v, DT)
    assert np.abs(v[: robot.nv_base]).max() > 1e-3  # the base took part
    assert not calls
