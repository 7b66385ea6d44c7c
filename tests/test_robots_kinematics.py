"""Whole-body kinematics of the catalogue robots against finite differences.

Every Jacobian is checked column by column against central differences of the frame pose along
the configuration path ``q̇ = S(q) v``, where ``S`` is rebuilt here from the documented velocity
conventions (base velocity coordinates in the base frame), not taken from the robot.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import wbc.robots as robots
from wbc.robots import column_major_view

EPS = 1e-6
RTOL = 1e-6
N_CONFIGS = 4


def _close(actual, expected, rtol=RTOL, atol=1e-8):
    actual, expected = np.asarray(actual), np.asarray(expected)
    scale = max(1.0, float(np.max(np.abs(expected))))
    err = float(np.max(np.abs(actual - expected)))
    assert err <= rtol * scale + atol, f"max error {err:.3e} (scale {scale:.3e})"


def path_direction(robot, q, v):
    """``q̇`` for the velocity ``v`` from the documented conventions."""
    c, s = math.cos(q[2]), math.sin(q[2])
    nb = robot.nv_base
    if nb == 3:
        vx, vy, omega = v[:3]
    else:  # differential drive: (v, ω)
        (vx, omega), vy = v[:2], 0.0
    return np.concatenate([[c * vx - s * vy, s * vx + c * vy, omega], v[nb:]])


def fd_twist(robot, q, v, frame):
    """Central difference of the world pose: [origin velocity; angular velocity], world axes."""
    d = path_direction(robot, q, v)
    plus = robot.frame_pose(q + EPS * d, frame).copy()
    minus = robot.frame_pose(q - EPS * d, frame).copy()
    linear = (plus[:3, 3] - minus[:3, 3]) / (2 * EPS)
    angular = pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * EPS)
    return np.concatenate([linear, angular])


def fd_jacobian(robot, q, frame):
    return np.column_stack([fd_twist(robot, q, e, frame) for e in np.eye(robot.nv)])


def yaw_transpose(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def mid_arm_frame(robot):
    """A body frame in the middle of the arm (its Jacobian has zero columns at the end)."""
    joint = 4 + robot.n_arm // 2  # whole-model joint index (3 base joints + universe)
    for frame in robot.model.frames:
        if frame.parentJoint == joint and frame.type == pin.FrameType.BODY:
            return frame.name
    raise AssertionError("no body frame found")


@pytest.fixture(scope="module", params=robots.names())
def robot(request):
    return robots.load(request.param)


@pytest.fixture
def configs(robot):
    rng = np.random.default_rng(12345)
    return [robot.random_configuration(rng) for _ in range(N_CONFIGS)]


def test_world_jacobian_matches_finite_differences(robot, configs):
    for q in configs:
        for frame in ("ee", "base", "mount", mid_arm_frame(robot)):
            _close(robot.frame_jacobian(q, frame), fd_jacobian(robot, q, frame))


def test_base_axes_jacobian_matches_rotated_finite_differences(robot, configs):
    for q in configs:
        for frame in ("ee", "base", mid_arm_frame(robot)):
            jac_fd = fd_jacobian(robot, q, frame)
            rt = yaw_transpose(q[2])
            expected = np.vstack([rt @ jac_fd[:3], rt @ jac_fd[3:]])
            _close(robot.frame_jacobian(q, frame, reference="base"), expected)


def test_base_axes_arm_columns_are_the_arm_jacobian_in_the_base_frame(robot, configs):
    """Arm columns of the base-axes Jacobian = derivative of the pose relative to the base."""

    def relative(q):
        base = robot.frame_pose(q, "base").copy()
        ee = robot.frame_pose(q, "ee").copy()
        return np.linalg.inv(base) @ ee

    nb = robot.nv_base
    for q in configs:
        jac = robot.frame_jacobian(q, "ee", reference="base")
        for k in range(robot.n_arm):
            dq = np.zeros(robot.nq)
            dq[3 + k] = EPS
            plus, minus = relative(q + dq), relative(q - dq)
            linear = (plus[:3, 3] - minus[:3, 3]) / (2 * EPS)
            angular = pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * EPS)
            _close(jac[:, nb + k], np.concatenate([linear, angular]))


def test_base_jacobian_is_the_base_models_twist_matrix(robot, configs):
    for q in configs:
        offset = robot.frame_position(q, "ee") - robot.frame_position(q, "base")
        expected = robot.base.twist_matrix(q[2], offset)
        _close(robot.base_jacobian(q, "ee"), expected, atol=1e-12)
        _close(robot.arm_jacobian(q, "ee"), robot.frame_jacobian(q, "ee")[:, robot.nv_base :])


def test_base_frame_twist_is_the_base_velocity(robot, configs):
    """In base axes, the base frame's twist is the body twist of the base coordinates."""
    rows = np.zeros((6, robot.nv_base))
    rows[[0, 1, 5]] = robot.base.body_map
    for q in configs:
        _close(robot.frame_jacobian(q, "base", "base")[:, : robot.nv_base], rows, atol=1e-12)
        _close(robot.frame_jacobian(q, "base", "base")[:, robot.nv_base :], 0.0, atol=1e-12)


def _wrap(angle):
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


def test_local_jacobian_matches_finite_differences_in_frame_axes(robot, configs):
    for q in configs:
        for frame in ("ee", mid_arm_frame(robot)):
            jac_fd = fd_jacobian(robot, q, frame)
            rt = robot.frame_pose(q, frame)[:3, :3].T
            expected = np.vstack([rt @ jac_fd[:3], rt @ jac_fd[3:]])
            _close(robot.frame_jacobian(q, frame, reference="local"), expected)


def test_rpy_jacobian_matches_finite_differences_of_rpy(robot, configs):
    rng = np.random.default_rng(7)
    checked = 0
    for q in configs + [robot.random_configuration(rng) for _ in range(8)]:
        if abs(robot.frame_rpy(q, "ee")[1]) > 1.3:  # away from the pitch singularity
            continue
        jac = robot.frame_jacobian_rpy(q, "ee").copy()
        columns = []
        for e in np.eye(robot.nv):
            d = path_direction(robot, q, e)
            plus = robot.frame_pose(q + EPS * d, "ee").copy()
            minus = robot.frame_pose(q - EPS * d, "ee").copy()
            d_rpy = _wrap(pin.rpy.matrixToRpy(plus[:3, :3]) - pin.rpy.matrixToRpy(minus[:3, :3]))
            columns.append(np.concatenate([(plus[:3, 3] - minus[:3, 3]), d_rpy]) / (2 * EPS))
        _close(jac, np.column_stack(columns), rtol=1e-5)
        checked += 1
        if checked == N_CONFIGS:
            break
    assert checked >= 2


def test_drift_matches_finite_differences_of_jacobian(robot, configs):
    rng = np.random.default_rng(3)
    for q in configs:
        v = rng.normal(size=robot.nv)
        d = path_direction(robot, q, v)
        for frame in ("ee", "base", mid_arm_frame(robot)):
            for reference in ("world", "base", "local"):
                plus = robot.frame_jacobian(q + EPS * d, frame, reference) @ v
                minus = robot.frame_jacobian(q - EPS * d, frame, reference) @ v
                drift = robot.frame_drift(q, v, frame, reference)
                _close(drift, (plus - minus) / (2 * EPS), rtol=1e-5)


def test_frame_velocity_is_jacobian_times_v(robot, configs):
    rng = np.random.default_rng(4)
    for q in configs:
        v = rng.normal(size=robot.nv)
        for reference in ("world", "base", "local"):
            _close(
                robot.frame_velocity(q, v, "ee", reference),
                robot.frame_jacobian(q, "ee", reference) @ v,
            )


def test_centre_of_mass_and_its_jacobian(robot, configs):
    for q in configs:
        jac = robot.com_jacobian(q).copy()
        columns = []
        for e in np.eye(robot.nv):
            d = path_direction(robot, q, e)
            columns.append((robot.com(q + EPS * d) - robot.com(q - EPS * d)) / (2 * EPS))
        _close(jac, np.column_stack(columns))


def test_centre_of_mass_composes_base_and_arm(robot, configs):
    """Whole-system CoM = mass-weighted mean of the base body's and the fixed-base arm's."""
    arm_model = robot.arm.model
    arm_data = arm_model.createData()
    base = robot.base
    for q in configs:
        world_base = pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, q[2]), np.array([q[0], q[1], 0.0]))
        pin.forwardKinematics(arm_model, arm_data, q[3:])
        # every body, including the fixed root link attached to the arm's universe
        masses = [inertia.mass for inertia in arm_model.inertias]
        points = [
            arm_data.oMi[j].act(arm_model.inertias[j].lever) for j in range(arm_model.njoints)
        ]
        arm_mass = sum(masses)
        arm_com_local = sum(m * p for m, p in zip(masses, points, strict=True)) / arm_mass
        arm_com = (world_base * robot.mount).act(arm_com_local)
        base_com = world_base.act(np.asarray(base.com))
        expected = (arm_mass * arm_com + base.mass * base_com) / (arm_mass + base.mass)
        _close(robot.com(q), expected, atol=1e-12)
        assert robot.mass == pytest.approx(arm_mass + base.mass)


def test_manipulability_gradient_matches_finite_differences(robot, configs):
    for q in configs:
        gradient = robot.manipulability_gradient(q).copy()
        expected = []
        for k in range(robot.n_arm):
            dq = np.zeros(robot.nq)
            dq[3 + k] = EPS
            expected.append(
                (robot.manipulability(q + dq) - robot.manipulability(q - dq)) / (2 * EPS)
            )
        _close(gradient, expected, rtol=1e-5)


def test_manipulability_is_det_of_arm_jacobian_and_base_invariant(robot, configs):
    for q in configs:
        arm = robot.frame_jacobian(q, "ee")[:, robot.nv_base :]
        value = robot.manipulability(q)
        assert value == pytest.approx(np.linalg.det(arm @ arm.T), rel=1e-9, abs=1e-15)
        moved = q.copy()
        moved[:3] += [0.7, -0.3, 1.1]
        assert robot.manipulability(moved) == pytest.approx(value, rel=1e-9, abs=1e-15)


def test_jacobian_derivatives_used_by_the_gradient(robot, configs):
    q = configs[0]
    robot.update(q)
    _, d_jac = robot._arm_jacobian_and_derivatives("ee")
    for k in range(robot.n_arm):
        dq = np.zeros(robot.nq)
        dq[3 + k] = EPS
        plus = robot.frame_jacobian(q + dq, "ee")[:, robot.nv_base :]
        minus = robot.frame_jacobian(q - dq, "ee")[:, robot.nv_base :]
        _close(d_jac[k], (plus - minus) / (2 * EPS), rtol=1e-5)


def test_integrate_matches_fine_rk4(robot, configs):
    rng = np.random.default_rng(5)
    for q in configs[:2]:
        v = rng.normal(size=robot.nv)
        dt, steps = 0.7, 400
        h = dt / steps
        x = q.copy()
        for _ in range(steps):
            k1 = path_direction(robot, x, v)
            k2 = path_direction(robot, x + 0.5 * h * k1, v)
            k3 = path_direction(robot, x + 0.5 * h * k2, v)
            k4 = path_direction(robot, x + h * k3, v)
            x = x + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
        _close(robot.integrate(q, v, dt), x, atol=1e-10)


def test_velocity_map(robot, configs):
    for q in configs:
        s = robot.velocity_map(q)
        assert s.shape == (robot.nq, robot.nv)
        for e in np.eye(robot.nv):
            _close(s @ e, path_direction(robot, q, e), atol=1e-15)


def test_getters_write_into_a_column_major_parameter_buffer(robot, configs):
    q = configs[0]
    v = np.linspace(-1.0, 1.0, robot.nv)
    buffer = np.zeros(7 + 6 * robot.nv + 6 + 16)
    jac_view = column_major_view(buffer, 7, (6, robot.nv))
    drift_view = column_major_view(buffer, 7 + 6 * robot.nv, (6,))
    pose_view = column_major_view(buffer, 13 + 6 * robot.nv, (4, 4))
    robot.update(q, v)
    robot.frame_jacobian(None, "ee", out=jac_view)
    robot.frame_drift(None, None, "ee", out=drift_view)
    robot.frame_pose(None, "ee", out=pose_view)
    jac = robot.frame_jacobian(q, "ee")
    assert np.array_equal(buffer[7 : 7 + 6 * robot.nv], jac.flatten(order="F"))
    assert np.array_equal(
        buffer[7 + 6 * robot.nv : 13 + 6 * robot.nv], robot.frame_drift(q, v, "ee")
    )
    assert np.array_equal(buffer[13 + 6 * robot.nv :], robot.frame_pose(q, "ee").flatten(order="F"))
    assert np.all(buffer[:7] == 0.0)


def test_update_cache_follows_the_configuration(robot, configs):
    q1, q2 = configs[0], configs[1]
    pose1 = robot.frame_pose(q1, "ee").copy()
    pose2 = robot.frame_pose(q2, "ee").copy()
    robot.update(q1)
    assert np.array_equal(robot.frame_pose(None, "ee"), pose1)
    q_mut = q1.copy()
    robot.update(q_mut)
    q_mut[:] = q2  # mutating the caller's array must not fool the cache
    assert np.array_equal(robot.frame_pose(q_mut, "ee"), pose2)
    assert np.array_equal(robot.frame_pose(q1.tolist(), "ee"), pose1)


def test_clone_has_independent_buffers(robot, configs):
    other = robot.clone()
    robot.update(configs[0])
    other.update(configs[1])
    assert np.array_equal(robot.frame_pose(None, "ee"), robot.frame_pose(configs[0], "ee"))
    assert not np.allclose(robot.frame_pose(None, "ee"), other.frame_pose(None, "ee"))
