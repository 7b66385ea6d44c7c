"""The omni platform's model facts (torque-redundancy paper): wheel Jacobian (eq. 1) and radius,
the paper's masses and the whole system's centre of mass, the wheels' normal forces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import wbc
import wbc.robots as robots
from wbc.robots import ARM_MASS, PLATFORM_MASS, normal_forces, system_com

BASE = robots.omni4_octagon()
WHEELS = BASE.wheel_positions


# ------------------------------------------------------------------ wheel Jacobian
def test_wheel_jacobian_is_eq1_with_a_01_m_radius():
    """Row i of J is (u_i, p_i × u_i) / r: drive direction u_i tangent at the contact p_i."""
    assert BASE.radius == 0.1  # 20 cm wheels
    for row, p, alpha in zip(BASE.jacobian, WHEELS, BASE.angles, strict=True):
        u = np.array([-math.sin(alpha), math.cos(alpha)])
        np.testing.assert_allclose(row, np.r_[u, p[0] * u[1] - p[1] * u[0]] / 0.1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(WHEELS, axis=1), BASE.distance)
    assert np.all(np.abs(WHEELS) < 0.25)  # on the 500 mm wide platform


def test_wheel_torques_produce_the_platform_force_eq5():
    """f = Jᵀ τ (eq. 5) is virtual work: the power of the torques equals the wrench's."""
    rng = np.random.default_rng(3)
    tau, twist = rng.standard_normal(4), rng.standard_normal(3)
    assert BASE.wrench(tau) @ twist == pytest.approx(tau @ BASE.inverse(twist), rel=1e-12)


# ------------------------------------------------------------------ normal forces
@st.composite
def supports(draw):
    """``(wheel_xy, com_xy, mass)``: the paper's wheels or a random quadrilateral, and a centre
    of mass near the middle (where no wheel lifts)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if draw(st.booleans()):
        wheels = WHEELS
    else:
        angles = np.pi / 4 + np.arange(4) * np.pi / 2 + rng.uniform(-0.3, 0.3, 4)
        wheels = rng.uniform(0.15, 0.4, (4, 1)) * np.column_stack([np.cos(angles),
                                                                    np.sin(angles)])
    com = rng.uniform(-0.03, 0.03, 2)
    return wheels, com, rng.uniform(10.0, 100.0)


@given(supports())
def test_normal_forces_are_in_equilibrium(support):
    wheels, com, mass = support
    f = normal_forces(wheels, com, mass)
    weight = mass * 9.81
    assert f.sum() == pytest.approx(weight, rel=1e-12)
    np.testing.assert_allclose(f @ wheels, weight * com, atol=1e-9 * weight)
    assert np.all(f >= 0)


@given(supports())
def test_normal_forces_are_the_least_norm_solution(support):
    """Against the KKT system of min ||f||² s.t. A f = b, solved explicitly."""
    wheels, com, mass = support
    A = np.vstack([np.ones(4), wheels.T])
    b = mass * 9.81 * np.r_[1.0, com]
    kkt = np.block([[np.eye(4), A.T], [A, np.zeros((3, 3))]])
    expected = np.linalg.solve(kkt, np.r_[np.zeros(4), b])[:4]
    np.testing.assert_allclose(normal_forces(wheels, com, mass), expected, atol=1e-9 * b[0])


def test_symmetric_case_gives_equal_shares():
    np.testing.assert_allclose(normal_forces(WHEELS, [0.0, 0.0], 45.0), 45.0 * 9.81 / 4)
    np.testing.assert_allclose(normal_forces(WHEELS, [0.0, 0.0, 0.7], 45.0, g=10.0), 112.5)


def test_centre_of_mass_towards_a_wheel_loads_it():
    f = normal_forces(WHEELS, 0.05 * WHEELS[0] / np.linalg.norm(WHEELS[0]), 45.0)
    assert f[1] == pytest.approx(f[3])
    assert f[0] > f[1] > f[2]


def test_a_lifting_wheel_is_reported():
    """Beyond the diamond |x| + |y| <= a of the mid-edges, the minimum-norm split would pull
    the opposite wheel down: refused, naming the centre of mass."""
    a = WHEELS[0, 0]
    normal_forces(WHEELS, [0.499 * a, 0.499 * a], 45.0)  # inside: fine
    with pytest.raises(wbc.InvalidValueError, match="com_xy"):
        normal_forces(WHEELS, [0.51 * a, 0.51 * a], 45.0)


@pytest.mark.parametrize("args, error, match", [
    ((np.zeros((4, 3)), [0, 0], 1.0), wbc.ShapeError, "wheel_xy"),
    ((WHEELS[:2], [0, 0], 1.0), wbc.ShapeError, "wheel_xy"),
    ((WHEELS, [0.0], 1.0), wbc.ShapeError, "com_xy"),
    ((WHEELS, [np.nan, 0.0], 1.0), wbc.NonFiniteError, "com_xy"),
    ((WHEELS, [0, 0], 0.0), wbc.InvalidValueError, "mass"),
    ((WHEELS, [0, 0], -3.0), wbc.InvalidValueError, "mass"),
    ((WHEELS, [0, 0], 1.0, 0.0), wbc.InvalidValueError, "g"),
    ((np.c_[np.arange(4.0), np.arange(4.0)], [0, 0], 1.0), wbc.InvalidValueError, "one line"),
])
def test_normal_forces_refuse_bad_input(args, error, match):
    with pytest.raises(error, match=match):
        normal_forces(*args)


# ------------------------------------------------------------------ masses and centre of mass
@pytest.fixture(scope="module")
def robot():
    return robots.load("omni4_arm6")


def test_paper_masses(robot):
    assert (PLATFORM_MASS, ARM_MASS) == (15.0, 30.0)
    assert system_com(robot, robot.neutral())[0] == 45.0


def test_system_com_against_the_whole_body_model(robot):
    """The model's own centre of mass (pinocchio, stand-in masses) gives the arm's centre of
    mass; reweighted to 15 kg + 30 kg it must be system_com's."""
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = robot.random_configuration(rng)
        platform = robot.frame_pose(q, "base") @ np.r_[BASE.com, 1.0]
        arm_mass = robot.mass - BASE.mass
        arm = (robot.mass * robot.com(q) - BASE.mass * platform[:3]) / arm_mass
        expected = (PLATFORM_MASS * platform[:3] + ARM_MASS * arm) / 45.0
        np.testing.assert_allclose(system_com(robot, q)[1], expected, atol=1e-12)


def test_system_com_moves_with_the_arm_and_frames_agree(robot):
    q = robot.neutral()
    _, home = system_com(robot, q, frame="base")
    q[3] += math.pi / 2  # shoulder pan: the arm swings about the vertical
    _, turned = system_com(robot, q, frame="base")
    mount = robot.mount.translation[:2]
    assert np.linalg.norm(turned[:2] - home[:2]) > 0.02
    # a rotation about the mount's vertical axis keeps the distance from it
    assert np.linalg.norm(turned[:2] - mount) == pytest.approx(np.linalg.norm(home[:2] - mount))
    q[:3] = [1.0, -2.0, 0.4]
    _, world = system_com(robot, q)
    c, s = math.cos(0.4), math.sin(0.4)
    np.testing.assert_allclose(world, [1.0 + c * turned[0] - s * turned[1],
                                       -2.0 + s * turned[0] + c * turned[1], turned[2]])


def test_system_com_refuses_bad_input(robot):
    with pytest.raises(wbc.ShapeError, match="q"):
        system_com(robot, np.zeros(3))
    with pytest.raises(wbc.InvalidValueError, match="frame"):
        system_com(robot, robot.neutral(), frame="wheel")
