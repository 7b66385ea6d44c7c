"""The omni platform's controllers: eq. 3's wheel angle increments, eq. 6's force law and its
distribution (closed forms and the QP stacks on every backend), in closed loop with
OmniDynamics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc.robots
from wbc.errors import InvalidValueError, ShapeError, WbcError
from wbc.papers.omni import TorqueDistribution
from wbc.papers.omni import closed_form as ref
from wbc.papers.omni.control import OmniForceControl, OmniPositionControl, platform_error
from wbc.papers.omni.dynamics import OmniDynamics
from wbc.sim import Simulation
from wbc.solvers import available_backends

DT = 0.01
MU = 0.5


@pytest.fixture(scope="module")
def robot():
    return wbc.robots.load("omni4_arm6")


def rotation(phi):
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


finite = st.floats(-1.0, 1.0)


@settings(max_examples=30, deadline=None)
@given(pose=st.tuples(finite, finite, st.floats(-3.1, 3.1)),
       target=st.tuples(finite, finite, st.floats(-3.1, 3.1)))
def test_position_control_is_eq_3_in_the_platform_frame(robot, pose, target):
    q = robot.neutral()
    q[:3] = pose
    command = OmniPositionControl(robot).step(q, target=np.array(target))
    error = platform_error(q, target)
    displacement = np.r_[rotation(pose[2]).T @ error[:2], error[2]]
    np.testing.assert_allclose(command, robot.base.jacobian @ displacement, atol=1e-12)
    assert -math.pi < error[2] <= math.pi


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_reference_reading_sums_the_reference_increments(robot, seed):
    """present="reference": x(t) = x_d(t − dt), so at constant heading the wheel angle targets
    telescope to J Rᵀ (x_d(t) − x(0))."""
    rng = np.random.default_rng(seed)
    q = robot.neutral()
    q[:3] = rng.uniform(-1, 1, 3)
    controller = OmniPositionControl(robot, present="reference")
    for _ in range(5):
        target = np.r_[q[:2] + rng.uniform(-0.5, 0.5, 2), q[2]]
        command = controller.step(q, target=target)  # q (the measurement) is not fed back
    displacement = np.r_[rotation(q[2]).T @ (target[:2] - q[:2]), 0.0]
    np.testing.assert_allclose(command, robot.base.jacobian @ displacement, atol=1e-12)


def test_heading_error_is_wrapped(robot):
    q = robot.neutral()
    q[2] = -math.pi + 0.01
    np.testing.assert_allclose(platform_error(q, [0.0, 0.0, math.pi - 0.01]), [0, 0, -0.02],
                               atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), method=st.sampled_from(ref.DISTRIBUTION_METHODS))
def test_force_control_is_eq_6_distributed(robot, seed, method):
    rng = np.random.default_rng(seed)
    q = robot.neutral()
    q[:3] = rng.uniform(-1, 1, 3)
    q[3] = rng.uniform(-math.pi / 4, math.pi / 4)  # the arm swings: the load moves
    v = np.r_[rng.uniform(-0.3, 0.3, 3), np.zeros(6)]
    refs = {name: rng.uniform(-1, 1, 3) for name in ("target", "velocity", "acceleration")}
    controller = OmniForceControl(robot, method=method, mu=MU)
    tau = controller.step(q, v, **refs)
    M = np.array([45.0, 45.0, 2.0])
    world_velocity = np.r_[rotation(q[2]) @ v[:2], v[2]]
    world = (M * refs["acceleration"] + M * 8.0 * (refs["velocity"] - world_velocity)
             + M * 16.0 * platform_error(q, refs["target"]))
    f_d = np.r_[rotation(q[2]).T @ world[:2], world[2]]
    np.testing.assert_allclose(controller.last_wrench, f_d, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(robot.base.jacobian.T @ tau, f_d, rtol=1e-9, atol=1e-9)  # eq. 5
    mass, com = wbc.robots.system_com(robot, q, frame="base")
    forces = wbc.robots.normal_forces(robot.base.wheel_positions, com[:2], mass)
    np.testing.assert_allclose(controller.last_normal_forces, forces)
    np.testing.assert_allclose(tau, ref.torque_distribution(robot.base.jacobian, f_d, forces,
                                                            MU, method), atol=1e-12)


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("method", ["proportional", "minmax"])
def test_force_control_on_a_backend_equals_the_closed_form(robot, backend, method):
    rng = np.random.default_rng(7)
    stack = OmniForceControl(robot, mu=MU, distribution=TorqueDistribution(
        robot.base.jacobian, method, MU, backend=backend, profile="tight"))
    closed = OmniForceControl(robot, method=method, mu=MU)
    for _ in range(5):
        q = robot.neutral()
        q[:3], q[3] = rng.uniform(-1, 1, 3), rng.uniform(-math.pi / 4, math.pi / 4)
        v = np.r_[rng.uniform(-0.3, 0.3, 3), np.zeros(6)]
        refs = {"target": rng.uniform(-1, 1, 3), "velocity": rng.uniform(-1, 1, 3)}
        expected = closed.step(q, v, **refs)
        np.testing.assert_allclose(stack.step(q, v, **refs), expected,
                                   atol=1e-7 * (1 + np.abs(expected).max()))
        assert stack.last_solution.status.value == "solved"


def test_position_control_reaches_a_target_through_the_wheel_servos(robot):
    goal = np.array([0.05, -0.03, 0.1])
    run = Simulation(robot, OmniPositionControl(robot), DT,
                     [OmniDynamics(mu=MU, servo="angle")], command="torque").run(
        seconds=5.0, references=lambda t: {"target": min(t / 2.0, 1.0) * goal})
    assert run.signals["slip_distance"].sum() < 1e-9  # a gentle ramp: the wheels roll
    np.testing.assert_allclose(run.q_est_final, run.q_final, atol=1e-9)
    np.testing.assert_allclose(run.q_final[:3], goal, atol=1e-3)


def test_wheel_angle_trajectories_reach_the_target(robot):
    goal = np.array([0.05, -0.03, 0.0])
    run = Simulation(robot, OmniPositionControl(robot, present="reference"), DT,
                     [OmniDynamics(mu=MU, servo="angle_target")], command="torque").run(
        seconds=5.0, references=lambda t: {"target": min(t / 2.0, 1.0) * goal})
    assert run.signals["slip_distance"].sum() < 1e-9
    np.testing.assert_allclose(run.q_final[:3], goal, atol=1e-3)


def test_a_position_step_makes_the_wheels_slip_and_odometry_drift(robot):
    goal = np.array([0.05, -0.03, 0.1])
    run = Simulation(robot, OmniPositionControl(robot), DT,
                     [OmniDynamics(mu=MU, servo="angle")], command="torque").run(
        seconds=3.0, references={"target": goal})
    assert run.signals["slip_distance"].sum() > 1e-3
    np.testing.assert_allclose(run.q_est_final[:3], goal, atol=1e-3)  # what the servos see
    assert np.abs(run.q_final[:3] - goal).max() > 5e-3  # where the platform really is


def test_force_control_tracks_a_slow_reference_without_slip(robot):
    def references(t):
        s = min(t, 2.0)  # 0.05 m/s along x for 2 s, then hold
        return {"target": [0.05 * s, 0.0, 0.0], "velocity": [0.05 * (t < 2.0), 0.0, 0.0]}

    run = Simulation(robot, OmniForceControl(robot, method="proportional", mu=MU), DT,
                     [OmniDynamics(mu=MU)], command="torque").run(seconds=3.0,
                                                                  references=references)
    np.testing.assert_allclose(run.q_final[:3], [0.1, 0.0, 0.0], atol=2e-3)
    assert run.signals["slip_distance"].sum() < 1e-9


def test_missing_or_malformed_references_are_refused(robot):
    q, v = robot.neutral(), np.zeros(robot.nv)
    with pytest.raises(WbcError, match="target"):
        OmniPositionControl(robot).step(q, v)
    with pytest.raises(WbcError, match="target"):
        OmniForceControl(robot).step(q, v)
    with pytest.raises(ShapeError, match="velocity"):
        OmniForceControl(robot).step(q, v, target=np.zeros(3), velocity=np.zeros(2))
    with pytest.raises(InvalidValueError, match="present"):
        OmniPositionControl(robot, present="camera")
    with pytest.raises(InvalidValueError, match="method"):
        OmniForceControl(robot, method="equal")
    with pytest.raises(ShapeError, match="kp"):
        OmniForceControl(robot, kp=[1.0, 2.0])
