"""Wheel kinematics of the four base models."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.errors import InvalidValueError
from wbc.robots import (
    DifferentialDriveBase,
    MecanumBase,
    OmniBase,
    SteerableBase,
    mecanum_base,
    mpo700,
    omni4_octagon,
    tiago_base,
)

EPS = 1e-6
_BODY = {"mass": 10.0, "com": [0.0, 0.0, 0.0], "inertia": np.eye(3), "v_max": [1.0, 1.0, 1.0],
         "a_max": [1.0, 1.0, 1.0]}


def random_twists(rng, n=20, scale=(1.0, 1.0, 1.5)):
    return [rng.normal(size=3) * np.asarray(scale) for _ in range(n)]


def rotation(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


# ---------------------------------------------------------------------- forward ∘ inverse
@pytest.mark.parametrize("factory", [omni4_octagon, mecanum_base])
def test_holonomic_wheel_kinematics_forward_inverse_identity(factory):
    base = factory()
    rng = np.random.default_rng(0)
    for twist in random_twists(rng):
        np.testing.assert_allclose(base.forward(base.inverse(twist)), twist, rtol=0, atol=1e-12)


def test_differential_forward_inverse_identity():
    base = tiago_base()
    rng = np.random.default_rng(1)
    for _ in range(20):
        command = rng.normal(size=2)
        np.testing.assert_allclose(base.forward(base.inverse(command)), command, atol=1e-12)
        rates = rng.normal(size=2) * 5
        np.testing.assert_allclose(base.inverse(base.forward(rates)), rates, atol=1e-12)


def test_steerable_forward_inverse_identity():
    base = mpo700()
    rng = np.random.default_rng(2)
    for twist in random_twists(rng):
        steering = rng.uniform(-math.pi, math.pi, base.n_wheels)
        steer_rates, drive_rates = base.inverse(twist, steering)
        np.testing.assert_allclose(
            base.forward(drive_rates, steering, steer_rates), twist, atol=1e-12
        )


# ---------------------------------------------------------------------- steerable base
def test_mpo700_parameters_are_sorour_table_one():
    base = mpo700()
    assert base.radius == 0.09
    assert base.offset == 0.045
    assert sorted(map(tuple, np.abs(base.hips))) == [(0.24, 0.19)] * 4
    assert {tuple(np.sign(h)) for h in base.hips} == {(1, 1), (1, -1), (-1, 1), (-1, -1)}
    assert base.velocity_names == ("vx", "vy", "omega")


def _contact_point_world(base, pose, steering, i):
    x, y, theta = pose
    beta = steering[i]
    local = base.hips[i] - base.offset * np.array([math.cos(beta), math.sin(beta)])
    return np.array([x, y]) + rotation(theta) @ local


def test_steerable_wheel_rates_satisfy_no_slip_in_the_world():
    """Move the base with the twist and steer at β̇: each contact point, differentiated
    numerically in the world, moves along its wheel's rolling direction at r_w φ̇."""
    base = mpo700()
    rng = np.random.default_rng(3)
    for twist in random_twists(rng, n=10):
        pose = np.array([rng.normal(), rng.normal(), rng.uniform(-math.pi, math.pi)])
        steering = rng.uniform(-math.pi, math.pi, base.n_wheels)
        steer_rates, drive_rates = base.inverse(twist, steering)
        pose_rate = np.concatenate([rotation(pose[2]) @ twist[:2], [twist[2]]])
        for i in range(base.n_wheels):
            plus = _contact_point_world(
                base, pose + EPS * pose_rate, steering + EPS * steer_rates, i
            )
            minus = _contact_point_world(
                base, pose - EPS * pose_rate, steering - EPS * steer_rates, i
            )
            velocity = (plus - minus) / (2 * EPS)
            heading = pose[2] + steering[i]
            rolling = np.array([math.cos(heading), math.sin(heading)])
            lateral = np.array([-math.sin(heading), math.cos(heading)])
            assert abs(velocity @ lateral) < 1e-8
            assert velocity @ rolling == pytest.approx(base.radius * drive_rates[i], abs=1e-8)
        contact = base.contact_velocities(twist, steering, steer_rates)
        expected = (
            base.radius
            * drive_rates[:, None]
            * np.column_stack([np.cos(steering), np.sin(steering)])
        )
        np.testing.assert_allclose(contact, expected, atol=1e-12)


def test_steering_for_twist_needs_no_steering_and_matches_the_icr():
    base = mpo700()
    rng = np.random.default_rng(4)
    checked = 0
    for twist in random_twists(rng, n=40):
        hips_v = np.column_stack(
            [twist[0] - twist[2] * base.hips[:, 1], twist[1] + twist[2] * base.hips[:, 0]]
        )
        if np.min(np.linalg.norm(hips_v, axis=1)) < 2 * base.offset * abs(twist[2]):
            continue  # a hip too close to the ICR: no steady steering angle
        steering = base.steering_for_twist(twist)
        steer_rates, drive_rates = base.inverse(twist, steering)
        np.testing.assert_allclose(steer_rates, 0.0, atol=1e-12)
        assert np.all(drive_rates * base.radius > -1e-12)  # forward solution rolls forwards
        icr_twist = SteerableBase.icr_of_twist(twist, homogeneous=True)
        icr_steer = base.icr_of_steering(steering, homogeneous=True)
        assert (
            min(np.linalg.norm(icr_twist - icr_steer), np.linalg.norm(icr_twist + icr_steer)) < 1e-9
        )
        # the nearest solution to a given configuration also needs no steering
        current = steering + rng.uniform(-3.0, 3.0, base.n_wheels)
        near = base.steering_for_twist(twist, current)
        assert np.all(np.abs(near - current) <= math.pi + 1e-12)
        np.testing.assert_allclose(base.inverse(twist, near).steer_rates, 0.0, atol=1e-12)
        # and so do the angles computed from the ICR alone
        from_icr = base.steering_for_icr(icr_twist)
        np.testing.assert_allclose(base.inverse(twist, from_icr).steer_rates, 0.0, atol=1e-12)
        checked += 1
    assert checked > 10


def test_icr_of_twist_is_the_point_at_rest():
    rng = np.random.default_rng(5)
    for twist in random_twists(rng):
        p = SteerableBase.icr_of_twist(twist)
        velocity = twist[:2] + twist[2] * np.array([-p[1], p[0]])
        np.testing.assert_allclose(velocity, 0.0, atol=1e-12)
    assert np.all(np.isinf(SteerableBase.icr_of_twist([1.0, 0.5, 0.0])))
    np.testing.assert_allclose(
        SteerableBase.icr_of_twist([1.0, 0.0, 0.0], homogeneous=True), [0, 1, 0]
    )
    with pytest.raises(ValueError):
        SteerableBase.icr_of_twist([0.0, 0.0, 0.0])


def test_icr_of_parallel_steering_is_at_infinity():
    base = mpo700()
    steering = np.full(base.n_wheels, 0.3)
    icr = base.icr_of_steering(steering, homogeneous=True)
    assert abs(icr[2]) < 1e-12
    assert np.all(np.isinf(base.icr_of_steering(steering)))


# ---------------------------------------------------------------------- differential drive
def test_differential_drive_wheels_and_constraint():
    base = tiago_base()
    assert base.nv == 2 and not base.holonomic
    rng = np.random.default_rng(6)
    for _ in range(10):
        v, omega = rng.normal(size=2)
        left, right = base.inverse([v, omega])
        half = base.separation / 2
        # rigid-body speed of each wheel's contact point along x
        assert base.radius * left == pytest.approx(v - omega * half)
        assert base.radius * right == pytest.approx(v + omega * half)
        theta = rng.uniform(-math.pi, math.pi)
        a = base.constraint_matrix(theta)
        assert a.shape == (1, 3)
        np.testing.assert_allclose(a @ base.pose_rate_matrix(theta), 0.0, atol=1e-12)
        # the constraint forbids lateral motion
        assert abs(a @ np.array([-math.sin(theta), math.cos(theta), 0.0])) == pytest.approx(1.0)


def test_tiago_base_values_come_from_the_urdf():
    import xml.etree.ElementTree as ET

    from wbc.robots import urdf_path

    root = ET.parse(urdf_path("tiago_description/robots/tiago.urdf")).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}  # not transmissions
    left_y = float(joints["wheel_left_joint"].find("origin").get("xyz").split()[1])
    right_y = float(joints["wheel_right_joint"].find("origin").get("xyz").split()[1])
    height = float(joints["base_footprint_joint"].find("origin").get("xyz").split()[2])
    base = tiago_base()
    assert base.separation == pytest.approx(left_y - right_y)
    assert base.radius == pytest.approx(height)


# ---------------------------------------------------------------------- omni base
def test_omni_jacobian_from_rigid_body_velocities():
    base = omni4_octagon()
    assert base.radius == pytest.approx(0.1)  # 0.2 m wheels
    assert base.mass == 15.0
    assert base.distance < 0.25  # inside the 500 mm wide platform
    rng = np.random.default_rng(7)
    for twist in random_twists(rng):
        rates = base.inverse(twist)
        for i, alpha in enumerate(base.angles):
            p = base.distance * np.array([math.cos(alpha), math.sin(alpha)])
            contact = twist[:2] + twist[2] * np.array([-p[1], p[0]])
            drive = np.array([-math.sin(alpha), math.cos(alpha)])
            assert base.radius * rates[i] == pytest.approx(contact @ drive, abs=1e-12)
    # Δθ = J Δx for small displacements; one-dimensional torque redundancy
    assert base.jacobian.shape == (4, 3)
    assert np.linalg.matrix_rank(base.jacobian) == 3
    torques = np.linalg.svd(base.jacobian.T)[2][-1]
    np.testing.assert_allclose(base.wrench(torques), 0.0, atol=1e-12)


# ---------------------------------------------------------------------- mecanum base
def test_mecanum_slip_is_along_the_free_rollers():
    """Contact velocity minus the wheel's rolling velocity must lie along the free direction
    of the bottom roller (±45°, an X pattern seen from above)."""
    base = mecanum_base()
    free = {0: (1.0, 1.0), 1: (1.0, -1.0), 2: (1.0, -1.0), 3: (1.0, 1.0)}  # FL, FR, RL, RR
    rng = np.random.default_rng(8)
    for twist in random_twists(rng):
        rates = base.inverse(twist)
        for i, p in enumerate(base.wheel_positions):
            contact = twist[:2] + twist[2] * np.array([-p[1], p[0]])
            slip = contact - np.array([base.radius * rates[i], 0.0])
            direction = np.array(free[i]) / math.sqrt(2.0)
            assert abs(slip @ np.array([-direction[1], direction[0]])) < 1e-12


def test_mecanum_is_xing_eq16():
    base = MecanumBase(
        0.05, 0.3, 0.2, mass=1.0, com=[0, 0, 0], inertia=np.eye(3), v_max=[1, 1, 1], a_max=[1, 1, 1]
    )
    k = 0.5
    expected = np.array([[1, -1, -k], [1, 1, k], [1, 1, -k], [1, -1, k]]) / 0.05
    np.testing.assert_allclose(base.jacobian, expected)


# ---------------------------------------------------------------------- shared planar maps
@pytest.mark.parametrize("factory", [mpo700, tiago_base, omni4_octagon, mecanum_base])
def test_integrate_pose_is_exact(factory):
    base = factory()
    rng = np.random.default_rng(9)
    for _ in range(5):
        command = rng.normal(size=base.nv)
        pose = np.array([0.3, -0.2, rng.uniform(-3, 3)])
        dt, steps = 1.3, 2000
        x = pose.copy()
        h = dt / steps
        for _ in range(steps):  # RK4 of ṗ = H(θ) v_b
            k1 = base.pose_rate_matrix(x[2]) @ command
            k2 = base.pose_rate_matrix(x[2] + 0.5 * h * k1[2]) @ command
            k3 = base.pose_rate_matrix(x[2] + 0.5 * h * k2[2]) @ command
            k4 = base.pose_rate_matrix(x[2] + h * k3[2]) @ command
            x = x + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
        np.testing.assert_allclose(base.integrate_pose(pose, command, dt), x, atol=1e-10)
    np.testing.assert_allclose(
        base.integrate_pose([1.0, 2.0, 0.5], np.zeros(base.nv), 3.0), [1.0, 2.0, 0.5]
    )


@pytest.mark.parametrize("factory", [mpo700, tiago_base, omni4_octagon, mecanum_base])
def test_pose_rate_drift_is_the_derivative_of_h(factory):
    base = factory()
    rng = np.random.default_rng(10)
    command = rng.normal(size=base.nv)
    theta = 0.4
    omega = (base.body_map @ command)[2]
    expected = (
        base.pose_rate_matrix(theta + EPS * omega) @ command
        - base.pose_rate_matrix(theta - EPS * omega) @ command
    ) / (2 * EPS)
    np.testing.assert_allclose(base.pose_rate_drift(theta, command), expected, atol=1e-8)
    assert base.constraint_matrix(theta).shape == (3 - base.nv, 3)


@pytest.mark.parametrize("make, lengths", [
    (lambda **k: DifferentialDriveBase(**k, **{**_BODY, "v_max": [1.0, 1.0], "a_max": [1.0, 1.0]}),
     {"separation": 0.4, "radius": 0.1}),
    (lambda **k: MecanumBase(**k, **_BODY),
     {"radius": 0.076, "half_wheelbase": 0.25, "half_track": 0.2}),
    (lambda **k: OmniBase([0.0, 2.0, 4.0], **k, **_BODY), {"distance": 0.2, "radius": 0.05}),
    (lambda **k: SteerableBase([[0.3, 0.2], [-0.3, -0.2]], **k, **_BODY),
     {"offset": 0.02, "radius": 0.09}),
])
def test_base_geometry_must_be_positive(make, lengths):
    make(**lengths)  # valid
    for name in lengths:
        for bad in (0.0, -0.1):
            with pytest.raises(InvalidValueError, match=rf"{name} = {bad}"):
                make(**{**lengths, name: bad})
