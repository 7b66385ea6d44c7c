"""Roots of whole-robot URDFs (wbc.robots.whole_body, wbc.robots.floating_base): the free flyer
against pinocchio (poses, Jacobians, drifts, centre of mass, numeric and symbolic) and finite
differences along pinocchio's ``integrate``; posture and joint limits acting on the actuated
joints only; the planar and differential roots of the whole Tiago URDF (wheels recognised,
masses kept, poses equal to the URDF's); continuous joints; clear errors for bad roots and
unmatched wheels; ``urdf_path``; and the humanoid example in closed loop on ``wbc.sim``."""

from __future__ import annotations

import math
import runpy
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import wbc
import wbc.robots
from wbc.robots.fixed_base import FixedBaseRobot, load_panda
from wbc.robots.floating_base import FloatingBaseRobot
from wbc.robots.resources import urdf_path
from wbc.tasks.limits import ConfigurationLimit
from wbc.tasks.linear import LinearTask
from wbc.tasks.posture import PostureTask

SEED = 314
STATES = 20
DT = 0.01
G1 = urdf_path("g1_description/urdf/g1_29dof_rev_1_0.urdf")
TIAGO = urdf_path("tiago_description/robots/tiago_no_hand.urdf")
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def g1():
    return wbc.robots.from_urdf(G1, root="free_flyer", ee_frame="right_rubber_hand")


@pytest.fixture(scope="module")
def reference_g1():
    """The same URDF as pinocchio loads it with a free-flyer root: the referee."""
    model = pin.buildModelFromUrdf(str(G1), pin.JointModelFreeFlyer())
    return model, model.createData()


def random_states(robot, rng, count=STATES):
    out = []
    for _ in range(count):
        q = robot.random_configuration(rng)
        v = rng.uniform(-2.0, 2.0, robot.nv)
        out.append((q, v))
    return out


# ------------------------------------------------------------------------ the free flyer
def test_free_flyer_layout(g1):
    assert isinstance(g1, FloatingBaseRobot) and g1.root == "free_flyer"
    assert (g1.nq, g1.nv, g1.nq_base, g1.nv_base, g1.n_arm) == (36, 35, 7, 6, 29)
    assert g1.configuration_names[:7] == ["x", "y", "z", "qx", "qy", "qz", "qw"]
    assert g1.velocity_names[:6] == ["vx", "vy", "vz", "wx", "wy", "wz"]
    assert g1.joint_names[0] == "left_hip_pitch_joint" and len(g1.joint_names) == 29
    assert np.all(np.isinf(g1.limits.q_lower[:7])) and np.all(np.isinf(g1.limits.v_upper[:6]))
    assert np.all(np.isfinite(g1.limits.q_lower[7:]))  # G1's joints are all bounded
    np.testing.assert_array_equal(g1.neutral()[:7], [0, 0, 0, 0, 0, 0, 1])
    assert g1.has_frame("base") and g1.frame_id("base") == g1.frame_id("pelvis")
    assert g1.urdf_path == str(G1)


def test_free_flyer_equals_pinocchio_numeric_and_symbolic(g1, reference_g1):
    """Pose, Jacobian (world-aligned), drift (classical acceleration at v̇ = 0), centre of mass
    and its Jacobian of three frames at 20 random states, against pinocchio's own functions on
    its own free-flyer model; the symbolic forms too."""
    model, data = reference_g1
    rng = np.random.default_rng(SEED)
    frames = ["ee", "left_ankle_roll_link", "base"]
    symbolic = {f: (g1.symbolic_frame(f), g1.symbolic_drift(f)) for f in frames}
    com_fn, jcom_fn = g1.symbolic_com(), g1.symbolic_com_jacobian()
    worst = 0.0
    for q, v in random_states(g1, rng):
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        pin.computeJointJacobians(model, data)
        pin.updateFramePlacements(model, data)
        for frame in frames:
            fid = model.getFrameId(g1.model.frames[g1.frame_id(frame)].name)
            pose = data.oMf[fid].homogeneous
            J = pin.getFrameJacobian(model, data, fid, LWA)
            drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector
            sym_pose, sym_J = (np.array(x) for x in symbolic[frame][0](q))
            sym_drift = np.array(symbolic[frame][1](q, v)).ravel()
            for ours, theirs in ((g1.frame_pose(q, frame), pose), (sym_pose, pose),
                                 (g1.frame_jacobian(q, frame), J), (sym_J, J),
                                 (g1.frame_drift(q, v, frame), drift), (sym_drift, drift)):
                worst = max(worst, float(np.abs(ours - theirs).max()))
        com = pin.centerOfMass(model, data, q)
        J_com = pin.jacobianCenterOfMass(model, data, q)
        for ours, theirs in ((g1.com(q), com), (np.array(com_fn(q)).ravel(), com),
                             (g1.com_jacobian(q), J_com), (np.array(jcom_fn(q)), J_com)):
            worst = max(worst, float(np.abs(ours - theirs).max()))
    assert worst < 1e-12, worst
    assert g1.mass == pytest.approx(pin.computeTotalMass(model), rel=1e-14)


def test_free_flyer_jacobians_are_derivatives_along_pinocchios_integrate(g1, reference_g1):
    """``J v`` (every reference) and ``J_com v`` against central differences of the pose and
    of the centre of mass along ``pin.integrate(q, ±h v)``; ``robot.integrate`` is it."""
    model, _ = reference_g1
    h = 1e-6
    rng = np.random.default_rng(SEED + 1)
    for q, v in random_states(g1, rng, 5):
        ahead, behind = pin.integrate(model, q, h * v), pin.integrate(model, q, -h * v)
        np.testing.assert_array_equal(g1.integrate(q, v, h), ahead)
        for frame in ("ee", "right_ankle_roll_link", "base"):
            A, B = g1.frame_pose(ahead, frame).copy(), g1.frame_pose(behind, frame).copy()
            twist = np.concatenate([(A[:3, 3] - B[:3, 3]) / (2 * h),
                                    pin.log3(A[:3, :3] @ B[:3, :3].T) / (2 * h)])
            R_base = g1.frame_pose(q, "base")[:3, :3].copy()
            R_frame = g1.frame_pose(q, frame)[:3, :3].copy()
            for reference, R in (("world", np.eye(3)), ("base", R_base), ("local", R_frame)):
                expected = np.concatenate([R.T @ twist[:3], R.T @ twist[3:]])
                J = g1.frame_jacobian(q, frame, reference)
                assert np.abs(J @ v - expected).max() < 1e-7, (frame, reference)
        dcom = (g1.com(ahead) - g1.com(behind)) / (2 * h)
        assert np.abs(g1.com_jacobian(q) @ v - dcom).max() < 1e-7


def test_integrate_and_difference_are_inverse(g1):
    rng = np.random.default_rng(SEED + 2)
    for q, v in random_states(g1, rng, 5):
        q1 = g1.integrate(q, v, 0.3)
        assert abs(np.linalg.norm(q1[3:7]) - 1.0) < 1e-14  # a unit quaternion
        np.testing.assert_allclose(g1.difference(q, q1), 0.3 * v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(g1.integrate(q, g1.difference(q, q1), 1.0), q1, rtol=0,
                                   atol=1e-12)
    panda = load_panda()
    q0, q1 = panda.neutral(), panda.random_configuration(rng)
    np.testing.assert_allclose(panda.difference(q0, q1), q1 - q0, rtol=0, atol=1e-15)
    tiago = wbc.robots.load("tiago_panda")  # scalar root joints: world pose differences
    q0, q1 = tiago.random_configuration(rng), tiago.random_configuration(rng)
    np.testing.assert_allclose(tiago.difference(q0, q1), q1 - q0, rtol=0, atol=1e-15)


def test_velocity_map_is_the_configuration_rate(g1):
    """``S(q) v`` (position rate ``R v``, quaternion rate ``½ quat ⊗ (ω, 0)``, joint rates) is
    the derivative of ``q`` along ``integrate``."""
    rng = np.random.default_rng(SEED + 8)
    h = 1e-6
    for q, v in random_states(g1, rng, 5):
        rate = (g1.integrate(q, v, h) - g1.integrate(q, v, -h)) / (2 * h)
        assert np.abs(g1.velocity_map(q) @ v - rate).max() < 1e-8


def test_random_configurations_of_a_free_flyer(g1):
    rng = np.random.default_rng(SEED + 3)
    samples = np.array([g1.random_configuration(rng, base_range=1.5) for _ in range(300)])
    np.testing.assert_allclose(np.linalg.norm(samples[:, 3:7], axis=1), 1.0, atol=1e-15)
    assert np.all(np.abs(samples[:, :3]) <= 1.5) and np.all(np.ptp(samples[:, :3], 0) > 2.7)
    assert np.all(np.abs(samples[:, 3:7].mean(axis=0)) < 0.1)  # no preferred orientation
    assert np.all(samples[:, 7:] >= g1.limits.q_lower[7:])
    assert np.all(samples[:, 7:] <= g1.limits.q_upper[7:])


def test_posture_and_joint_limits_act_on_the_actuated_joints_only(g1):
    """The posture task alone commands ``gain (q* − q) / dt`` on the joints and nothing on the
    root (the quaternion entries of the target are not compared with a rate); a task pushing
    every velocity up is clipped at the joints' ``ConfigurationLimit`` bounds and leaves the
    root free."""
    rng = np.random.default_rng(SEED + 4)
    q = g1.random_configuration(rng)
    target = g1.random_configuration(rng)  # another root pose and orientation too
    stack = wbc.Stack(wbc.Variables(v=g1.nv), damping=1e-6)
    stack.add(PostureTask(g1, gain=0.5, name="posture"))
    ctrl = wbc.Controller(g1, stack, backend="quadprog", dt=DT, jit=False,
                          missing_limits="ignore")
    v = ctrl.step(q, posture=target)
    np.testing.assert_allclose(v[:6], 0.0, atol=1e-9)
    np.testing.assert_allclose(v[6:], 0.5 * (target[7:] - q[7:]) / DT, rtol=1e-9, atol=1e-9)

    stack = wbc.Stack(wbc.Variables(v=g1.nv), damping=1e-6)
    stack.add(LinearTask(np.eye(g1.nv), np.full(g1.nv, 1e4), name="push"))
    stack.constrain(ConfigurationLimit(g1, gain=0.5, name="limits"))
    ctrl = wbc.Controller(g1, stack, backend="quadprog", dt=DT, jit=False,
                          missing_limits="ignore")
    v = ctrl.step(q)
    upper = 0.5 * (g1.limits.q_upper[7:] - q[7:]) / DT
    np.testing.assert_allclose(v[6:], upper, rtol=1e-9, atol=1e-7)
    np.testing.assert_allclose(v[:6], 1e4, rtol=1e-6)  # the root is not bounded


def test_free_flyer_in_a_compiled_controller(g1):
    """``kinematics="compiled"`` (the free flyer's symbolic forms inlined) commands what the
    numeric kinematics do."""
    from wbc.tasks.frame import FrameTask

    def controller(robot, kinematics):
        stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
        stack.add(FrameTask(robot, "ee", gain=0.5, name="hand"), priority=0)
        stack.add(PostureTask(robot, gain=0.2, weight=1e-2, name="posture"), priority=1)
        return wbc.Controller(robot, stack, backend="quadprog", dt=DT, jit=False,
                              kinematics=kinematics, missing_limits="ignore")

    numeric, compiled = controller(g1, "numeric"), controller(g1.clone(), "compiled")
    rng = np.random.default_rng(SEED + 5)
    q = g1.random_configuration(rng)
    target = g1.frame_pose(g1.random_configuration(rng), "ee")
    for _ in range(3):
        v = numeric.step(q, hand=target)
        np.testing.assert_allclose(compiled.step(q, hand=target), v, rtol=0, atol=1e-9)
        q = g1.integrate(q, v, DT)


# ------------------------------------------------------------------------ planar roots, wheels
def fixed_urdf_pose(model, data, q_joints, frame):
    pin.framesForwardKinematics(model, data, q_joints)
    return data.oMf[model.getFrameId(frame)].homogeneous.copy()


def test_planar_root_of_the_whole_tiago():
    robot = wbc.robots.from_urdf(TIAGO, root="planar", ee_frame="arm_tool_link")
    assert robot.root == "planar" and robot.base.name == "planar"
    assert robot.base.velocity_names == ("vx", "vy", "omega")
    assert robot.wheel_joints == ("wheel_left_joint", "wheel_right_joint")
    assert robot.locked_joints == robot.wheel_joints
    assert not set(robot.wheel_joints) & set(robot.joint_names)
    assert (robot.nq, robot.nv, robot.n_arm) == (13, 13, 10)
    assert np.all(np.isinf(robot.limits.v_upper[:3])) and np.all(np.isinf(robot.limits.a_upper[:3]))
    # the URDF's mass is kept: its root link is the base body, the wheels ride on it
    reference = pin.buildModelFromUrdf(str(TIAGO))
    total = reference.inertias[0].mass + pin.computeTotalMass(reference)
    assert robot.mass == pytest.approx(total, rel=1e-12)
    # poses: the fixed-root URDF's, moved by the planar pose (x, y, θ)
    data = reference.createData()
    rng = np.random.default_rng(SEED + 6)
    for _ in range(5):
        q = robot.random_configuration(rng)
        q_ref = pin.neutral(reference)
        for name, value in zip(robot.joint_names, q[3:], strict=True):
            q_ref[reference.joints[reference.getJointId(name)].idx_q] = value
        base = np.eye(4)
        base[:3, :3] = pin.utils.rpyToMatrix(0.0, 0.0, q[2])
        base[:2, 3] = q[:2]
        for frame in ("arm_tool_link", "head_2_link", "base_link"):
            expected = base @ fixed_urdf_pose(reference, data, q_ref, frame)
            np.testing.assert_allclose(robot.frame_pose(q, frame), expected, rtol=0, atol=1e-12)
        # the holonomic root: body twist coordinates, in the base frame
        v = rng.normal(size=robot.nv)
        twist = robot.frame_velocity(q, v, "base", "base")
        np.testing.assert_allclose(twist[[0, 1, 5]], v[:3], rtol=0, atol=1e-12)


def test_differential_root_of_the_whole_tiago():
    robot = wbc.robots.from_urdf(TIAGO, root="differential", ee_frame="arm_tool_link",
                                 name="tiago_whole")
    assert robot.name == "tiago_whole" and robot.base.velocity_names == ("v", "omega")
    assert robot.wheel_joints == ("wheel_left_joint", "wheel_right_joint")
    assert (robot.nq, robot.nv) == (13, 12)
    np.testing.assert_array_equal(robot.limits.v_upper[:2], wbc.robots.tiago_base().v_max)
    # the base moves as the differential drive: no lateral velocity of the base frame
    rng = np.random.default_rng(SEED + 7)
    q, v = robot.random_configuration(rng), rng.normal(size=robot.nv)
    twist = robot.frame_velocity(q, v, "base", "base")
    np.testing.assert_allclose(twist, [v[0], 0, 0, 0, 0, v[1]], rtol=0, atol=1e-12)
    assert robot.urdf_path == str(TIAGO)


def test_wheels_that_do_not_match_the_base_are_refused():
    with pytest.raises(wbc.InvalidValueError, match=r"root='mecanum' drives 4 wheels.*2 drive "
                                                    r"wheels.*wheel_left_joint"):
        wbc.robots.from_urdf(TIAGO, root="mecanum")
    with pytest.raises(wbc.InvalidValueError, match=r"root='differential' drives 2 wheels.*"
                                                    r"has 0 drive wheels"):
        wbc.robots.from_urdf(G1, root="differential")


def test_a_whole_robot_given_as_an_arm_on_a_base_is_refused_naming_its_wheels():
    # base= puts an arm on a base: the whole Tiago's wheels would become arm joints
    with pytest.raises(wbc.InvalidValueError, match=r"wheel joints \['wheel_left_joint', "
                                                    r"'wheel_right_joint'\].*root='differential'"):
        wbc.robots.from_urdf(TIAGO, base="differential", ee_frame="arm_tool_link")
    locked = wbc.robots.from_urdf(TIAGO, base="differential", ee_frame="arm_tool_link",
                                  locked_joints=["wheel_left_joint", "wheel_right_joint"])
    assert "wheel_left_joint" not in locked.joint_names


def test_continuous_joints_are_accepted():
    """Tiago's wheels (URDF continuous joints) on a fixed root, a continuous double pendulum
    built in one step by FixedBaseRobot and by from_urdf: plain revolute joints, unbounded."""
    tiago = wbc.robots.from_urdf(TIAGO, root="fixed")
    assert tiago.nq == tiago.nv == 12 and tiago.wheel_joints == ()
    wheel = tiago.joint_names.index("wheel_left_joint")
    assert math.isinf(tiago.limits.q_lower[wheel]) and math.isinf(tiago.limits.q_upper[wheel])
    assert not tiago.has_frame("ee")  # no ee_frame given: no alias
    path = urdf_path("double_pendulum_description/urdf/double_pendulum_continuous.urdf")
    model = pin.buildModelFromUrdf(str(path))
    assert model.nq == 2 * model.nv  # (cos, sin) per continuous joint
    for robot in (FixedBaseRobot(model), wbc.robots.from_urdf(path, root="fixed")):
        assert robot.nq == robot.nv == 2
        assert np.all(np.isinf(robot.limits.q_upper))
        q = np.array([0.3, -1.2])
        c = np.cos(q)
        s = np.sin(q)
        reference = pin.neutral(model)
        reference[:] = [c[0], s[0], c[1], s[1]]
        data = model.createData()
        pin.framesForwardKinematics(model, data, reference)
        tip = model.frames[-1].name
        np.testing.assert_allclose(robot.frame_pose(q, tip), data.oMf[len(model.frames) - 1]
                                   .homogeneous, rtol=0, atol=1e-14)


def test_bad_roots_are_clear_errors():
    with pytest.raises(wbc.UnknownNameError, match="unknown root 'nope'.*free_flyer.*mecanum"):
        wbc.robots.from_urdf(G1, root="nope")
    with pytest.raises(wbc.UnknownNameError, match="unknown root 3"):
        wbc.robots.from_urdf(G1, root=3)
    with pytest.raises(wbc.InvalidValueError, match="either root="):
        wbc.robots.from_urdf(G1, root="fixed", base="mecanum")
    with pytest.raises(wbc.InvalidValueError, match="root= needs a URDF path"):
        wbc.robots.from_urdf(wbc.robots.panda(), root="fixed")
    with pytest.raises(wbc.UnknownNameError, match="cannot lock joints"):
        wbc.robots.from_urdf(G1, root="free_flyer", locked_joints=["no_such_joint"])
    with pytest.raises(wbc.UnknownNameError, match="ee_frame 'no_such_frame'"):
        wbc.robots.from_urdf(G1, root="free_flyer", ee_frame="no_such_frame")
    with pytest.raises(wbc.ShapeError, match="home"):
        wbc.robots.from_urdf(G1, root="free_flyer", home=np.zeros(35))
    with pytest.raises(wbc.ModelLoadError):
        wbc.robots.from_urdf("/no/such/robot.urdf", root="free_flyer")
    with pytest.raises(wbc.ShapeError, match="root='free_flyer'"):
        FloatingBaseRobot(load_panda().model)
    model = pin.buildModelFromUrdf(str(G1), pin.JointModelFreeFlyer())
    with pytest.raises(wbc.ShapeError, match="free-floating root"):
        FixedBaseRobot(model)


def test_urdf_path_is_recorded():
    assert load_panda().urdf_path == str(urdf_path("panda_description/urdf/panda.urdf"))
    ur5 = urdf_path("ur_description/urdf/ur5_robot.urdf")
    assert wbc.robots.from_urdf(ur5, base="omni", ee_frame="tool0").urdf_path == str(ur5)
    assert wbc.robots.load("tiago_panda").urdf_path is None  # assembled in code
    locked = wbc.robots.from_urdf(G1, root="free_flyer",
                                  locked_joints=["waist_yaw_joint", "waist_roll_joint"])
    assert locked.locked_joints == ("waist_yaw_joint", "waist_roll_joint")
    assert locked.nv == 33 and "waist_yaw_joint" not in locked.joint_names


# ------------------------------------------------------------------------ the example
def test_humanoid_example_holds_its_feet_and_balance_while_the_hand_tracks():
    main = runpy.run_path(str(EXAMPLES / "humanoid_reach.py"), run_name="example")["main"]
    run = main(["--seconds", "1.0"])
    assert all(status == "solved" for status in run.status) and not any(run.partial)
    assert run.signals["feet_drift"].max() < 1e-6  # [m]
    assert run.signals["com_margin"].min() > 0.05  # [m] inside the support polygon
    error = run.signals["hand_error"]
    assert error[-1] < 0.25 * error[0]
    assert np.all(np.diff(error[:50]) < 0)  # it closes in from the start
    assert run.q.shape == (100, 39) and run.v.shape == (100, 38)
