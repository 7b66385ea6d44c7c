"""The catalogue, the arms' published parameters, the papers' reference values and user URDFs."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import wbc.robots as robots
from wbc.errors import UnknownNameError
from wbc.robots import resources

EXPECTED_SIZES = {  # name: (nq, nv, n_arm, base velocity coordinates)
    "mpo700_lwr4": (10, 10, 7, ("vx", "vy", "omega")),
    "tiago_panda": (10, 9, 7, ("v", "omega")),
    "omni4_arm6": (9, 9, 6, ("vx", "vy", "omega")),
    "mecanum_gen3": (10, 10, 7, ("vx", "vy", "omega")),
}


def test_names_lists_the_catalogue():
    assert robots.names() == list(EXPECTED_SIZES)


def test_unknown_robot_lists_the_catalogue():
    with pytest.raises(UnknownNameError) as info:
        robots.load("pr2")
    message = str(info.value)
    assert "pr2" in message
    for name in EXPECTED_SIZES:
        assert name in message
    assert isinstance(info.value, KeyError)


@pytest.mark.parametrize("name", list(EXPECTED_SIZES))
def test_layout_limits_and_frames(name):
    robot = robots.load(name)
    nq, nv, n_arm, base_names = EXPECTED_SIZES[name]
    assert (robot.nq, robot.nv, robot.n_arm) == (nq, nv, n_arm)
    assert tuple(robot.base.velocity_names) == base_names
    assert robot.velocity_names[: len(base_names)] == list(base_names)
    assert robot.configuration_names[:3] == ["x", "y", "theta"]
    limits = robot.limits
    assert limits.q_lower.shape == limits.q_upper.shape == (nq,)
    for array in (limits.v_lower, limits.v_upper, limits.a_lower, limits.a_upper):
        assert array.shape == (nv,)
    assert np.all(np.isinf(limits.q_lower[:3])) and np.all(np.isinf(limits.q_upper[:3]))
    assert np.all(limits.v_lower < 0) and np.all(limits.v_upper > 0)
    assert np.all(limits.a_lower < 0) and np.all(limits.a_upper > 0)
    q = robot.neutral()
    assert q.shape == (nq,)
    assert np.all(q >= limits.q_lower) and np.all(q <= limits.q_upper)
    for frame in ("ee", "base", "mount"):
        assert frame in robot.frame_names
    rng = np.random.default_rng(0)
    sample = robot.random_configuration(rng)
    assert np.all(sample >= limits.q_lower) and np.all(sample <= limits.q_upper)
    # the base frame is at the base pose
    q[:3] = [1.0, -2.0, 0.5]
    pose = robot.frame_pose(q, "base")
    np.testing.assert_allclose(pose[:2, 3], [1.0, -2.0])
    np.testing.assert_allclose(pose[:3, :3], pin.utils.rpyToMatrix(0.0, 0.0, 0.5), atol=1e-15)
    # the mount frame is the mounting transform; "ee" is the arm's end-effector frame
    np.testing.assert_allclose(
        pose @ robot.mount.homogeneous, robot.frame_pose(q, "mount"), atol=1e-12
    )
    np.testing.assert_array_equal(
        robot.frame_pose(q, "ee"), robot.frame_pose(q, robot.arm.ee_frame)
    )


def test_loads_are_independent():
    a, b = robots.load("mecanum_gen3"), robots.load("mecanum_gen3")
    assert a.data is not b.data


# ---------------------------------------------------------------------- paper values
def test_mecanum_gen3_start_position_of_xing():
    robot = robots.load("mecanum_gen3")
    q0 = np.array([0, 0, 0, 0, math.pi / 6, 0, math.pi / 2, 0, -math.pi / 6, 0])
    np.testing.assert_allclose(robot.neutral(), q0)
    position = robot.frame_position(q0, "ee")
    assert np.linalg.norm(position - [0.65, -0.0246, 0.4921]) < 0.01


def _kinova_classic_dh(q):
    """Kinova Gen3 user guide, classic DH (d [m], θ offsets π on joints 2–7, base twist π)."""

    def dh(alpha, d, theta):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        return np.array(
            [[ct, -ca * st, sa * st, 0], [st, ca * ct, -sa * ct, 0], [0, sa, ca, d], [0, 0, 0, 1]]
        )

    table = [
        (math.pi, 0.0, 0.0),
        (math.pi / 2, -(0.1564 + 0.1284), q[0]),
        (math.pi / 2, -(0.0054 + 0.0064), q[1] + math.pi),
        (math.pi / 2, -(0.2104 + 0.2104), q[2] + math.pi),
        (math.pi / 2, -(0.0064 + 0.0064), q[3] + math.pi),
        (math.pi / 2, -(0.2084 + 0.1059), q[4] + math.pi),
        (math.pi / 2, 0.0, q[5] + math.pi),
        (math.pi, -(0.1059 + 0.0615), q[6] + math.pi),
    ]
    transform = np.eye(4)
    for alpha, d, theta in table:
        transform = transform @ dh(alpha, d, theta)
    return transform


def test_kinova_gen3_agrees_with_the_user_guide_dh_table():
    arm = robots.kinova_gen3()
    data = arm.model.createData()
    frame = arm.model.getFrameId(arm.ee_frame)
    rng = np.random.default_rng(1)
    for _ in range(10):
        q = rng.uniform(-math.pi, math.pi, 7)
        pin.framesForwardKinematics(arm.model, data, q)
        expected = _kinova_classic_dh(q)
        np.testing.assert_allclose(data.oMf[frame].translation, expected[:3, 3], atol=5e-4)
        np.testing.assert_allclose(data.oMf[frame].rotation, expected[:3, :3], atol=1e-12)
    assert sum(i.mass for i in arm.model.inertias) == pytest.approx(8.19, abs=0.01)


def test_kuka_lwr4_agrees_with_its_modified_dh_table():
    def mdh(alpha, d, theta):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        return np.array(
            [
                [ct, -st, 0, 0],
                [st * ca, ct * ca, -sa, -sa * d],
                [st * sa, ct * sa, ca, ca * d],
                [0, 0, 0, 1],
            ]
        )

    alphas = [0, math.pi / 2, -math.pi / 2, -math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2]
    ds = [0.31, 0, 0.40, 0, 0.39, 0, 0]
    arm = robots.kuka_lwr4()
    data = arm.model.createData()
    frame = arm.model.getFrameId(arm.ee_frame)
    rng = np.random.default_rng(2)
    for _ in range(10):
        q = rng.uniform(arm.q_lower, arm.q_upper)
        transform = np.eye(4)
        for alpha, d, theta in zip(alphas, ds, q, strict=True):
            transform = transform @ mdh(alpha, d, theta)
        transform = transform @ np.array(
            [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.078], [0, 0, 0, 1]]
        )
        pin.framesForwardKinematics(arm.model, data, q)
        np.testing.assert_allclose(data.oMf[frame].homogeneous, transform, atol=1e-12)
    pin.framesForwardKinematics(arm.model, data, np.zeros(7))
    assert data.oMf[frame].translation[2] == pytest.approx(0.31 + 0.40 + 0.39 + 0.078)
    assert sum(i.mass for i in arm.model.inertias) == pytest.approx(16.0)


def test_tiago_panda_reduced_point_and_segment_lengths():
    """l0 0.333, l1 = |(0.0825, 0.316)| ≈ 0.327, l2 = |(0.088, 0.384)| ≈ 0.394 (the paper
    prints l1 ≈ 0.328: docs/DESIGN.md, section "Petrič & Žlajpah")."""
    robot = robots.load("tiago_panda")
    reduced = robots.ReducedPanda(robot)
    l0, l1, l2 = reduced.lengths
    assert abs(l0 - 0.333) < 1e-3
    assert abs(l1 - 0.327) < 1e-3
    assert abs(l2 - 0.394) < 1e-3
    design = (0.333, 0.327, 0.394)
    gamma1 = math.atan2(0.0825, 0.316)
    gamma2 = math.atan2(0.0825, 0.384)
    mount = robot.mount.translation
    rng = np.random.default_rng(3)
    arm = robot.arm
    for _ in range(20):
        q = robot.random_configuration(rng)
        q[5] = 0.0  # q3 = 0: the reduced arm is planar
        q1, q2, q4 = q[3], q[4], q[6]
        radial = design[1] * math.sin(q2 + gamma1) + design[2] * math.sin(q2 - q4 - gamma2)
        height = (
            design[0] + design[1] * math.cos(q2 + gamma1) + design[2] * math.cos(q2 - q4 - gamma2)
        )
        expected = mount + np.array([radial * math.cos(q1), radial * math.sin(q1), height])
        assert np.linalg.norm(reduced.point(q, frame="base") - expected) < 1e-3
        # in the world: the base pose applied
        world = robot.frame_pose(q, "base") @ np.append(expected, 1.0)
        assert np.linalg.norm(reduced.point(q) - world[:3]) < 1e-3
    for _ in range(10):  # any q3: the segments keep their lengths
        q = robot.random_configuration(rng)
        shoulder, elbow, point = reduced.shoulder(q), reduced.elbow(q), reduced.point(q)
        assert np.linalg.norm(elbow - shoulder) == pytest.approx(l1, abs=1e-12)
        assert np.linalg.norm(point - elbow) == pytest.approx(l2, abs=1e-12)
        base_shoulder = reduced.shoulder(q, frame="base")
        np.testing.assert_allclose(base_shoulder, mount + [0, 0, l0], atol=1e-12)
    assert arm.name == "panda"


def test_omni_arm_is_about_30_kg_and_platform_15_kg():
    robot = robots.load("omni4_arm6")
    arm_mass = sum(i.mass for i in robot.arm.model.inertias)
    assert 27.0 < arm_mass < 34.0
    assert robot.base.mass == 15.0
    assert robot.mass == pytest.approx(arm_mass + 15.0)


# ---------------------------------------------------------------------- user URDFs
@pytest.mark.parametrize("base", ["steerable", "differential", "omni", "mecanum"])
def test_user_urdf_on_each_base(base):
    path = robots.urdf_path("ur_description/urdf/ur5_robot.urdf")
    mount = np.eye(4)
    mount[:3, 3] = [0.1, -0.05, 0.4]
    mount[:3, :3] = pin.utils.rpyToMatrix(0.0, 0.0, 0.3)
    robot = robots.from_urdf(path, base=base, ee_frame="tool0", mount=mount, name="my_ur5")
    assert robot.name == "my_ur5"
    assert robot.n_arm == 6 and robot.nq == 9 and robot.nv == robot.base.nv + 6
    # pose = base pose ∘ mount ∘ UR5 forward kinematics, computed on the bare URDF
    arm_model = pin.buildModelFromUrdf(str(path))
    arm_data = arm_model.createData()
    rng = np.random.default_rng(4)
    q = robot.random_configuration(rng)
    pin.framesForwardKinematics(arm_model, arm_data, q[3:])
    base_pose = np.eye(4)
    base_pose[:3, :3] = pin.utils.rpyToMatrix(0.0, 0.0, q[2])
    base_pose[:2, 3] = q[:2]
    expected = base_pose @ mount @ arm_data.oMf[arm_model.getFrameId("tool0")].homogeneous
    np.testing.assert_allclose(robot.frame_pose(q, "ee"), expected, atol=1e-12)
    # the UR5's own "base" frame does not shadow the mobile base's
    assert "arm_base" in robot.frame_names
    np.testing.assert_allclose(robot.frame_pose(q, "base"), base_pose, atol=1e-12)


def test_user_arm_as_model_or_path_on_a_base_object():
    path = robots.urdf_path("panda_description/urdf/panda.urdf")
    with_fingers = robots.MobileManipulator(robots.mecanum_base(), path, ee_frame="panda_hand_tcp")
    assert with_fingers.n_arm == 9  # fingers kept as prismatic joints
    model = pin.buildModelFromUrdf(str(path))
    from_model = robots.MobileManipulator(robots.omni4_octagon(), model, ee_frame="panda_link8")
    assert from_model.n_arm == 9
    panda_on_omni = robots.from_urdf(
        path,
        base="omni",
        ee_frame="panda_link8",
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )
    assert panda_on_omni.n_arm == 7
    arm = robots.panda()
    custom = robots.MobileManipulator(robots.mpo700(), arm, ee_frame="panda_hand_tcp")
    q = custom.neutral()
    hand = custom.frame_pose(q, "panda_hand_tcp")
    np.testing.assert_allclose(custom.frame_pose(q, "ee"), hand)


TWO_LINK_URDF = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="root"><inertial><mass value="1.0"/><origin xyz="0 0 0.05"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="upper"><inertial><mass value="2.0"/><origin xyz="0 0 0.2"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="lower"><inertial><mass value="1.0"/><origin xyz="0.15 0 0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip"/>
  <joint name="yaw" type="continuous"><parent link="root"/><child link="upper"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit effort="10" velocity="2.0"/></joint>
  <joint name="pitch" type="revolute"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit effort="10" velocity="3.0" lower="-1.5" upper="1.5"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="lower"/><child link="tip"/>
    <origin xyz="0.3 0 0"/></joint>
</robot>
"""


def test_user_urdf_with_a_continuous_joint(tmp_path):
    path = tmp_path / "two_link.urdf"
    path.write_text(TWO_LINK_URDF)
    robot = robots.from_urdf(path, base="mecanum", ee_frame="tip")
    assert (robot.nq, robot.nv, robot.n_arm) == (5, 5, 2)
    np.testing.assert_array_equal(robot.limits.q_lower[3:], [-np.inf, -1.5])
    np.testing.assert_array_equal(robot.limits.v_upper[3:], [2.0, 3.0])
    assert np.all(np.isinf(robot.limits.a_upper[3:]))
    q = np.array([0.0, 0.0, 0.0, math.pi / 2, 0.0])
    np.testing.assert_allclose(robot.frame_position(q, "ee"), [0.0, 0.3, 0.5], atol=1e-12)
    assert robot.mass == pytest.approx(40.0 + 4.0)


# ---------------------------------------------------------------------- resources
def test_example_robot_data_is_found_offline():
    folder = resources.robots_dir()
    assert (folder / "panda_description" / "urdf" / "panda.urdf").is_file()
    with pytest.raises(FileNotFoundError, match="no_such_robot"):
        robots.urdf_path("no_such_robot/robot.urdf")


def test_example_robot_data_environment_override(tmp_path, monkeypatch):
    monkeypatch.setenv("EXAMPLE_ROBOT_DATA_MODEL_DIR", str(tmp_path))
    resources.robots_dir.cache_clear()
    try:
        assert resources.robots_dir() == tmp_path
    finally:
        monkeypatch.delenv("EXAMPLE_ROBOT_DATA_MODEL_DIR")
        resources.robots_dir.cache_clear()
    assert resources.robots_dir() != tmp_path


def test_base_names_and_make_base():
    for name in robots.base_names():
        assert isinstance(robots.make_base(name), robots.PlanarBase)
    with pytest.raises(UnknownNameError, match="mecanum"):
        robots.make_base("hovercraft")
