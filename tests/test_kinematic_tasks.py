"""Kinematic tasks (FrameTask, PostureTask, limits) and the fixed-base robot: compiled errors
against pinocchio, task Jacobians against finite differences, and the QP against pink's."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit
from wbc.tasks.frame import se3_jlog, se3_log, so3_jlog, so3_log

DT = 0.01
RNG_SEED = 7


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def random_q(robot, rng):
    lo, up = robot.limits.q_lower, robot.limits.q_upper
    return lo + (up - lo) * rng.uniform(0.1, 0.9, robot.nq)


def random_rotation(rng, angle):
    axis = rng.standard_normal(3)
    return pin.exp3(axis / np.linalg.norm(axis) * angle)


# ---------------------------------------------------------------------------- Lie helpers
T_SYM, R_SYM = ca.SX.sym("T", 4, 4), ca.SX.sym("R", 3, 3)
LOG6 = ca.Function("log6", [T_SYM], [se3_log(T_SYM)])
JLOG6 = ca.Function("jlog6", [T_SYM], [se3_jlog(T_SYM)])
LOG3 = ca.Function("log3", [R_SYM], [so3_log(R_SYM)])
JLOG3 = ca.Function("jlog3", [R_SYM], [so3_jlog(R_SYM)])


def fd_jlog6(M: pin.SE3, h: float = 1e-6) -> np.ndarray:
    """``d log6(M exp(δ)) / dδ`` by central differences of pinocchio's log."""
    J = np.zeros((6, 6))
    for i in range(6):
        d = np.zeros(6)
        d[i] = h
        J[:, i] = (pin.log6(M * pin.exp6(d)).vector - pin.log6(M * pin.exp6(-d)).vector) / (2 * h)
    return J


@pytest.mark.parametrize("angle", [2.0, 0.7, 0.1, 5.01e-2, 4.99e-2, 1e-3, 1e-5, 1e-9, 0.0])
def test_logs_match_pinocchio_from_large_to_zero_angles(angle):
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(20):
        M = pin.SE3(random_rotation(rng, angle), rng.standard_normal(3))
        H = M.homogeneous
        np.testing.assert_allclose(np.array(LOG6(H)).ravel(), pin.log6(M).vector, atol=1e-12)
        np.testing.assert_allclose(np.array(LOG3(M.rotation)).ravel(), pin.log3(M.rotation),
                                   atol=1e-12)
        # pinocchio's own Jlog6 loses digits around 1e-3 rad; finite differences arbitrate
        np.testing.assert_allclose(np.array(JLOG6(H)), fd_jlog6(M), atol=1e-7)
        np.testing.assert_allclose(np.array(JLOG3(M.rotation)), pin.Jlog3(M.rotation),
                                   atol=1e-8)
        assert np.isfinite(np.array(JLOG6(H))).all()


@pytest.mark.parametrize("gap", [1e-1, 1e-2, 1e-4, 1e-8, 0.0])
def test_logs_near_a_half_turn(gap):
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(20):
        M = pin.SE3(random_rotation(rng, np.pi - gap), rng.standard_normal(3))
        w = np.array(LOG3(M.rotation)).ravel()
        np.testing.assert_allclose(pin.exp3(w), M.rotation, atol=1e-9)  # a valid logarithm
        assert abs(np.linalg.norm(w) - (np.pi - gap)) < 1e-9
        if gap > 0:  # at exactly π the axis sign is arbitrary
            np.testing.assert_allclose(np.array(LOG6(M.homogeneous)).ravel(), pin.log6(M).vector,
                                       atol=1e-9)
            np.testing.assert_allclose(np.array(JLOG6(M.homogeneous)), pin.Jlog6(M),
                                       atol=1e-8)


# ---------------------------------------------------------------------------- helpers
def level_arrays(stack, **values):
    """``(H, g, E, lb, ub)`` of the first level, evaluated at the given parameter values."""
    ws = stack.workspace("quadprog")
    ws.set(**values)
    fn = stack.compile().blocks[0].function
    H, g, _, _, _, lb, ub, ET = (np.array(o) for o in fn(ws.p))
    return H, g.ravel(), ET.T, lb.ravel(), ub.ravel()


def model_values(robot, q, frame="ee"):
    return {f"pose[{frame}]": robot.frame_pose(q, frame).copy(),
            f"J[{frame}]": robot.frame_jacobian(q, frame).copy(), "dt": DT}


def error_of(E, g, weight, gain):
    """The task error behind the cost rows: ``g = −Eᵀ √w (gain/dt) e``."""
    b = -np.linalg.solve(E @ E.T, E @ g)
    return b * DT / (gain * np.sqrt(weight))


def log_error(robot, q, target, frame="ee"):
    M = pin.SE3(robot.frame_pose(q, frame))
    return pin.log6(M.actInv(pin.SE3(target))).vector


# ---------------------------------------------------------------------------- FrameTask
@pytest.mark.parametrize("angle", [0.8, 1e-3, 0.0])
def test_frame_task_error_and_jacobian(robot, angle):
    rng = np.random.default_rng(RNG_SEED)
    gain, weight = 0.7, 2.5
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=gain, weight=weight, name="ee"))
    for _ in range(5):
        q = random_q(robot, rng)
        T = robot.frame_pose(q, "ee").copy()
        target = T.copy()
        target[:3, :3] = T[:3, :3] @ random_rotation(rng, angle)
        target[:3, 3] += 0.2 * rng.standard_normal(3)
        H, g, E, _, _ = level_arrays(stack, **model_values(robot, q), **{"ee.target": target})
        np.testing.assert_allclose(H, E.T @ E + 1e-6 * np.eye(robot.nv), atol=1e-12)
        # the compiled error is pinocchio's log6(T_b⁻¹ T_t)
        np.testing.assert_allclose(error_of(E, g, weight, gain),
                                   log_error(robot, q, target), atol=1e-10)
        # its rate along v is −(task Jacobian) v: central differences of pinocchio's error
        v = rng.standard_normal(robot.nv)
        h = 1e-6
        fd = (log_error(robot, pin.integrate(robot.model, q, h * v), target)
              - log_error(robot, pin.integrate(robot.model, q, -h * v), target)) / (2 * h)
        np.testing.assert_allclose(-E @ v / np.sqrt(weight), fd, atol=1e-6)


def test_frame_task_position_only(robot):
    rng = np.random.default_rng(RNG_SEED)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, weight=[1.0, 2.0, 3.0], position_only=True,
                        name="reach"))
    q = random_q(robot, rng)
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += [0.1, -0.2, 0.05]
    H, g, E, _, _ = level_arrays(stack, **model_values(robot, q), **{"reach.target": target})
    w = np.array([1.0, 2.0, 3.0])
    assert E.shape == (3, robot.nv)
    np.testing.assert_allclose(error_of(E, g, w, 0.5), [0.1, -0.2, 0.05], atol=1e-12)
    v, h = rng.standard_normal(robot.nv), 1e-6
    fd = (robot.frame_pose(q + h * v, "ee")[:3, 3] - robot.frame_pose(q - h * v, "ee")[:3, 3])
    np.testing.assert_allclose(E @ v / np.sqrt(w), fd / (2 * h), atol=1e-7)


def test_frame_task_refuses_unknown_frames_and_bad_weights(robot):
    with pytest.raises(wbc.UnknownNameError, match="panda_hand"):
        FrameTask(robot, "gripper")
    with pytest.raises(wbc.ShapeError):
        FrameTask(robot, "ee", weight=[1.0, 2.0])
    with pytest.raises(wbc.WbcError):
        FrameTask(robot, "ee", gain=-1.0)
    stack = wbc.Stack(wbc.Variables(v=robot.nv + 1))
    with pytest.raises(wbc.ShapeError, match="nv = 7"):
        stack.add(FrameTask(robot, "ee"))


# ---------------------------------------------------------------------------- PostureTask
def test_posture_task_error_and_jacobian(robot):
    rng = np.random.default_rng(RNG_SEED)
    weight = np.linspace(0.5, 2.0, robot.nv)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=0.0, min_norm=False)
    stack.add(PostureTask(robot, gain=0.3, weight=weight, name="posture"))
    q, q_ref = random_q(robot, rng), random_q(robot, rng)
    H, g, E, _, _ = level_arrays(stack, q=q, dt=DT, **{"posture.target": q_ref})
    np.testing.assert_allclose(E, np.diag(np.sqrt(weight)), atol=1e-14)
    np.testing.assert_allclose(error_of(E, g, weight, 0.3),
                               -pin.difference(robot.model, q_ref, q), atol=1e-12)
    v, h = rng.standard_normal(robot.nv), 1e-6
    err = lambda x: pin.difference(robot.model, q_ref, x)  # noqa: E731  (pink's error)
    fd = (err(q + h * v) - err(q - h * v)) / (2 * h)
    np.testing.assert_allclose(E @ v / np.sqrt(weight), fd, atol=1e-8)


def test_posture_default_target_is_neutral(robot):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(PostureTask(robot, name="posture"))
    ws = stack.workspace("quadprog")
    np.testing.assert_allclose(ws.view("posture.target").ravel(), robot.neutral())


def test_posture_and_limits_on_a_mobile_manipulator_act_on_the_arm():
    robots = pytest.importorskip("wbc.robots")
    robot = robots.load("tiago_panda")  # differential drive: nq = nv + 1
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(PostureTask(robot, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=1.0, name="qlim"))
    q = robot.neutral()
    q_ref = q.copy()
    q_ref[:3] = [5.0, -3.0, 1.0]  # base coordinates of the target are ignored
    q_ref[3:] += 0.1
    H, g, E, lb, ub = level_arrays(stack, q=q, dt=DT, **{"posture.target": q_ref})
    n_base = robot.nv - robot.n_arm
    assert E.shape == (robot.n_arm, robot.nv)
    assert not E[:, :n_base].any()
    np.testing.assert_allclose(error_of(E, g, 1.0, 1.0), q_ref[3:] - q[3:], atol=1e-12)
    assert np.isinf(lb[:n_base]).all() and np.isinf(ub[:n_base]).all()
    np.testing.assert_allclose(ub[n_base:], (robot.limits.q_upper[3:] - q[3:]) / DT)


# ---------------------------------------------------------------------------- limits
def test_configuration_and_velocity_limits_are_bounds(robot):
    rng = np.random.default_rng(RNG_SEED)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(PostureTask(robot, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="qlim"))
    stack.constrain(VelocityLimit(robot, name="vlim"))
    block = stack.compile().blocks[0]
    assert block.m_hard == 0  # bounds, not rows of A
    q = random_q(robot, rng)
    q[0] = robot.limits.q_upper[0] - 1e-3  # close to a limit: the position bound binds
    _, _, _, lb, ub = level_arrays(stack, q=q, dt=DT)
    lim = robot.limits
    np.testing.assert_allclose(lb, np.maximum(0.5 * (lim.q_lower - q) / DT, lim.v_lower))
    np.testing.assert_allclose(ub, np.minimum(0.5 * (lim.q_upper - q) / DT, lim.v_upper))
    assert ub[0] == pytest.approx(0.05)
    # one tick at any admissible velocity keeps the configuration within its limits
    for v in (lb, ub):
        assert np.all(q + DT * v <= lim.q_upper + 1e-12)
        assert np.all(q + DT * v >= lim.q_lower - 1e-12)
    with pytest.raises(wbc.WbcError):
        ConfigurationLimit(robot, gain=1.5)


# ---------------------------------------------------------------------------- the robot
def test_fixed_base_robot_jacobians_and_drift_against_finite_differences(robot):
    rng = np.random.default_rng(RNG_SEED)
    q, v, h = random_q(robot, rng), rng.standard_normal(robot.nv), 1e-6
    T = robot.frame_pose(q, "ee")
    Tp, Tm = robot.frame_pose(q + h * v, "ee"), robot.frame_pose(q - h * v, "ee")
    twist = np.concatenate([(Tp[:3, 3] - Tm[:3, 3]) / (2 * h),
                            pin.log3(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * h)])
    J = robot.frame_jacobian(q, "ee", "world")
    np.testing.assert_allclose(J @ v, twist, atol=1e-7)
    np.testing.assert_allclose(robot.frame_jacobian(q, "ee", "base"), J)
    J_local = robot.frame_jacobian(q, "ee", "local")
    R = T[:3, :3]
    np.testing.assert_allclose(J_local, np.vstack([R.T @ J[:3], R.T @ J[3:]]), atol=1e-12)
    drift = robot.frame_drift(q, v, "ee")
    fd = (robot.frame_jacobian(q + h * v, "ee") - robot.frame_jacobian(q - h * v, "ee")) @ v
    np.testing.assert_allclose(drift, fd / (2 * h), atol=1e-6)
    # out= into Fortran-ordered views, after one update
    robot.update(q, v)
    pose_out, J_out, drift_out = (np.zeros((4, 4), order="F"),
                                  np.zeros((6, robot.nv), order="F"), np.zeros(6))
    robot.frame_pose(None, "ee", out=pose_out)
    robot.frame_jacobian(None, "ee", "world", out=J_out)
    robot.frame_drift(None, None, "ee", out=drift_out)
    np.testing.assert_array_equal(pose_out, T)
    np.testing.assert_array_equal(J_out, J)
    np.testing.assert_allclose(drift_out, drift, atol=1e-14)
    with pytest.raises(wbc.UnknownNameError, match="ee"):
        robot.frame_pose(q, "nope")
    with pytest.raises(wbc.UnknownNameError):
        robot.frame_jacobian(q, "ee", "sideways")
    assert robot.nq == robot.nv == 7
    assert np.all(robot.neutral() >= robot.limits.q_lower)


def test_symbolic_frame_kinematics_match_pinocchio(robot):
    rng = np.random.default_rng(RNG_SEED)
    fk = robot.symbolic_frame("ee")
    assert robot.symbolic_frame("panda_hand") is fk  # cached per frame
    for _ in range(10):
        q = random_q(robot, rng)
        pose, J = (np.array(x) for x in fk(q))
        np.testing.assert_allclose(pose, robot.frame_pose(q, "ee"), atol=1e-14)
        np.testing.assert_allclose(J, robot.frame_jacobian(q, "ee"), atol=1e-14)


# ---------------------------------------------------------------------------- against pink
def test_frame_and_posture_qp_equal_pinks_objective(robot):
    pink = pytest.importorskip("pink")
    from pink.tasks import FrameTask as PinkFrameTask
    from pink.tasks import PostureTask as PinkPostureTask

    rng = np.random.default_rng(RNG_SEED)
    cost_p, cost_o, posture_cost, gain, lm = 1.5, 0.5, 1e-2, 0.4, 1.0
    weights = [cost_p ** 2] * 3 + [cost_o ** 2] * 3
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-6)
    stack.add(FrameTask(robot, "ee", gain=gain, weight=weights, lm_damping=lm, name="ee"))
    stack.add(PostureTask(robot, gain=gain, weight=posture_cost ** 2, lm_damping=lm,
                          name="posture"))
    for _ in range(3):
        q, q_ref = random_q(robot, rng), random_q(robot, rng)
        target = robot.frame_pose(q, "ee").copy()
        target[:3, :3] = target[:3, :3] @ random_rotation(rng, 0.6)
        target[:3, 3] += 0.15 * rng.standard_normal(3)
        H, g, _, _, _ = level_arrays(stack, q=q, **model_values(robot, q),
                                     **{"ee.target": target, "posture.target": q_ref})
        conf = pink.Configuration(robot.model, robot.model.createData(), q)
        ft = PinkFrameTask("panda_hand", position_cost=cost_p, orientation_cost=cost_o,
                           gain=gain, lm_damping=lm)
        ft.set_target(pin.SE3(target))
        pt = PinkPostureTask(cost=posture_cost, gain=gain, lm_damping=lm)
        pt.set_target(q_ref)
        H_p, c_p = (sum(x) for x in zip(ft.compute_qp_objective(conf),
                                        pt.compute_qp_objective(conf), strict=True))
        # pink's QP is in Δq = v·dt: same Hessian, gradient scaled by dt
        np.testing.assert_allclose(H - 1e-12 * np.eye(robot.nv), H_p, atol=1e-9)
        np.testing.assert_allclose(g * DT, c_p, atol=1e-9)
