"""Bad input to the robot models raises clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import wbc.robots as robots
from wbc.errors import BoundsOrderError, NonFiniteError, ShapeError, UnknownNameError


@pytest.fixture(scope="module", params=["tiago_panda", "mecanum_gen3", "panda"])
def robot(request):
    return robots.load_panda() if request.param == "panda" else robots.load(request.param)


@pytest.mark.parametrize(
    "call",
    [
        lambda r, q: r.update(q),
        lambda r, q: r.frame_pose(q, "ee"),
        lambda r, q: r.frame_jacobian(q, "ee"),
        lambda r, q: r.frame_jacobian_rpy(q, "ee"),
        lambda r, q: r.com(q),
        lambda r, q: r.manipulability(q),
        lambda r, q: r.integrate(q, np.zeros(r.nv), 0.1),
        lambda r, q: r.velocity_map(q),
    ],
)
def test_wrong_configuration_size(robot, call):
    for bad in (np.zeros(robot.nq - 1), np.zeros(robot.nq + 1), np.zeros((robot.nq, 1)), []):
        with pytest.raises(ShapeError, match=rf"\({robot.nq},\)"):
            call(robot, bad)


def test_nan_or_inf_configuration(robot):
    for value in (np.nan, np.inf, -np.inf):
        q = robot.neutral()
        q[4] = value
        with pytest.raises(NonFiniteError, match="NaN"):
            robot.frame_pose(q, "ee")
        with pytest.raises(NonFiniteError):
            robot.frame_jacobian(q, "ee")
        with pytest.raises(NonFiniteError):
            robot.update(q)


def test_nan_configuration_after_a_valid_update_is_still_refused(robot):
    q = robot.neutral()
    robot.update(q)
    bad = q.copy()
    bad[0] = np.nan
    with pytest.raises(NonFiniteError):
        robot.frame_jacobian(bad, "ee")


def test_wrong_or_nan_velocity(robot):
    q = robot.neutral()
    with pytest.raises(ShapeError, match=rf"\({robot.nv},\)"):
        robot.frame_drift(q, np.zeros(robot.nq + 1), "ee")
    with pytest.raises(ShapeError):
        robot.update(q, np.zeros(robot.nv - 1))
    v = np.zeros(robot.nv)
    v[0] = np.nan
    with pytest.raises(NonFiniteError):
        robot.frame_drift(q, v, "ee")
    with pytest.raises(NonFiniteError):
        robot.integrate(q, v, 0.1)


def test_unknown_frame_lists_the_frames(robot):
    q = robot.neutral()
    with pytest.raises(UnknownNameError) as info:
        robot.frame_pose(q, "hand_of_god")
    assert "hand_of_god" in str(info.value) and "'ee'" in str(info.value)
    for getter in (robot.frame_jacobian, robot.frame_jacobian_rpy, robot.manipulability):
        with pytest.raises(UnknownNameError):
            getter(q, "hand_of_god")
    with pytest.raises(UnknownNameError):
        robot.frame_pose(q, 10_000)
    with pytest.raises(UnknownNameError):
        robot.frame_pose(q, -1)


def test_unknown_reference(robot):
    with pytest.raises(UnknownNameError, match="world"):
        robot.frame_jacobian(robot.neutral(), "ee", reference="body")


def test_wrong_out_shape(robot):
    q = robot.neutral()
    with pytest.raises(ShapeError):
        robot.frame_jacobian(q, "ee", out=np.zeros((6, robot.nv + 1)))
    with pytest.raises(ShapeError):
        robot.frame_pose(q, "ee", out=np.zeros((3, 4)))
    with pytest.raises(ShapeError):
        robots.column_major_view(np.zeros(10), 5, (6, 2))


def test_getters_without_state():
    robot = robots.load("omni4_arm6")
    with pytest.raises(RuntimeError, match="update"):
        robot.frame_pose(None, "ee")
    robot.update(robot.neutral())
    with pytest.raises(RuntimeError, match="v"):
        robot.frame_drift(None, None, "ee")


def test_base_input_errors():
    base = robots.mpo700()
    with pytest.raises(ShapeError):
        base.inverse([1.0, 0.0], np.zeros(4))
    with pytest.raises(ShapeError):
        base.inverse([1.0, 0.0, 0.0], np.zeros(3))
    with pytest.raises(NonFiniteError):
        base.inverse([np.nan, 0.0, 0.0], np.zeros(4))
    with pytest.raises(ShapeError):
        robots.tiago_base().inverse([1.0, 0.0, 0.0])
    with pytest.raises(ShapeError):
        robots.mecanum_base().forward(np.zeros(3))
    with pytest.raises(ShapeError):
        robots.omni4_octagon().inverse(np.zeros(4))


def test_construction_errors(tmp_path):
    path = robots.urdf_path("ur_description/urdf/ur5_robot.urdf")
    with pytest.raises(ValueError, match="ee_frame"):
        robots.MobileManipulator(robots.mecanum_base(), path)
    with pytest.raises(UnknownNameError, match="no_such_frame"):
        robots.from_urdf(path, ee_frame="no_such_frame")
    with pytest.raises(ShapeError):
        robots.from_urdf(path, ee_frame="tool0", mount=np.eye(3))
    with pytest.raises(ValueError, match="rotation"):
        robots.from_urdf(path, ee_frame="tool0", mount=np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(UnknownNameError, match="gripper_joint"):
        robots.from_urdf(path, ee_frame="tool0", locked_joints=["gripper_joint"])
    with pytest.raises(TypeError):
        robots.MobileManipulator("mecanum", path, ee_frame="tool0")
    with pytest.raises(UnknownNameError, match="catalogue"):
        robots.load(3)


def test_limits_errors():
    with pytest.raises(BoundsOrderError):
        robots.Limits(np.ones(2), np.zeros(2), -np.ones(1), np.ones(1), -np.ones(1), np.ones(1))
    with pytest.raises(ShapeError):
        robots.Limits(np.zeros(2), np.ones(3), -np.ones(1), np.ones(1), -np.ones(1), np.ones(1))
    limits = robots.load("tiago_panda").limits
    with pytest.raises(ValueError):
        limits.q_lower[0] = 0.0  # read-only arrays
