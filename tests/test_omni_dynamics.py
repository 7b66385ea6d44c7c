"""OmniDynamics: Coulomb friction solved exactly per step; rolling without slip reproduces the
rigid-body motion and odometry; traction beyond μ f slips; energy and determinism."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import Constant
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc.robots
from wbc.errors import InvalidValueError, ShapeError
from wbc.papers.omni.dynamics import YAW_INERTIA, OmniDynamics, coulomb_forces
from wbc.sim import Simulation

DT = 0.01


@pytest.fixture(scope="module")
def robot():
    return wbc.robots.load("omni4_arm6")


def simulate(robot, tau, seconds=0.5, v0=None, seed=0, **model):
    dynamics = OmniDynamics(**model)
    v = None if v0 is None else np.concatenate([v0, np.zeros(robot.nv - 3)])
    run = Simulation(robot, Constant(tau), DT, [dynamics], command="torque", seed=seed).run(
        seconds=seconds, v0=v)
    return run, dynamics


def min_norm(robot, wrench):
    return np.linalg.pinv(robot.base.jacobian.T) @ np.asarray(wrench, dtype=float)


def kinetic_energy(robot, v, rates, mass=45.0, wheel_inertia=0.02):
    return 0.5 * (mass * (v[0] ** 2 + v[1] ** 2) + YAW_INERTIA * v[2] ** 2
                  + wheel_inertia * np.sum(rates**2))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), loaded=st.lists(st.booleans(), min_size=4, max_size=4))
def test_coulomb_forces_satisfy_coulombs_law(seed, loaded):
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((4, 4))
    A = B @ B.T + 0.1 * np.eye(4)
    s_free = 3.0 * rng.standard_normal(4)
    limit = rng.uniform(0.0, 2.0, 4) * np.asarray(loaded)
    F, slip = coulomb_forces(A, s_free, limit)
    np.testing.assert_allclose(slip, s_free - A @ F, atol=1e-12)
    assert (np.abs(F) <= limit + 1e-9).all()
    inside = np.abs(F) < limit - 1e-9
    np.testing.assert_allclose(slip[inside], 0.0, atol=1e-9)  # sticking wheels do not slide
    on_bound = ~inside & (limit > 0)
    assert (np.sign(F[on_bound]) * slip[on_bound] >= -1e-9).all()  # force opposes the slide
    # the fast path (A⁻¹ given) returns the same solution
    F2, _ = coulomb_forces(A, s_free, limit, np.linalg.inv(A))
    np.testing.assert_allclose(F2, F, atol=1e-9)


def test_small_torques_roll_without_slip(robot):
    force = 10.0  # [N] along the base x axis, far below μ f
    run, _ = simulate(robot, min_norm(robot, [force, 0.0, 0.0]), seconds=0.5, mu=0.5)
    assert run.signals["slip_distance"].max() < 1e-12
    assert run.signals["friction_utilisation"].max() < 1.0
    np.testing.assert_allclose(run.q_est_final, run.q_final, atol=1e-12)  # odometry = truth
    # a rigid body with the wheels' rotor inertia: (m + I_w Σ_i J_ix²) a = f_x
    J = robot.base.jacobian
    acceleration = force / (45.0 + 0.02 * np.sum(J[:, 0] ** 2))
    np.testing.assert_allclose(run.v_final[:3], [acceleration * 0.5, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(run.q_final[0], 0.5 * acceleration * 0.5**2, rtol=1e-9)


def test_traction_beyond_friction_slips_and_saturates(robot):
    tau = min_norm(robot, [250.0, 0.0, 0.0])  # 250 N against μ m g ≈ 221 N in total
    run, dynamics = simulate(robot, tau, seconds=0.3, mu=0.5)
    limit = 0.5 * dynamics.normal_forces(robot, robot.neutral())
    # min-norm splits the force equally: every wheel asks for 250 / (4 cos 45°) ≈ 88 N
    asked = np.abs(tau) / robot.base.radius
    slipping = asked > limit
    assert slipping.any() and not slipping.all()  # the light wheels slip, the heavy one holds
    slid = run.signals["slip_distance"].sum(axis=0)
    assert (slid[slipping] > 1e-3).all()
    np.testing.assert_allclose(run.signals["friction_utilisation"][-1, slipping], 1.0)
    # odometry (the wheels' rotation) runs ahead of the truth
    assert run.q_est_final[0] > run.q_final[0] + 1e-3
    # the ground cannot push harder than friction allows (each wheel's force is at 45° to x)
    assert run.v_final[0] <= 0.3 * np.sqrt(0.5) * limit.sum() / 45.0 + 1e-9


def test_lightest_wheel_slips_first(robot):
    run, dynamics = simulate(robot, min_norm(robot, [60.0, 0.0, 0.0]), seconds=0.2, mu=0.5)
    normal = dynamics.normal_forces(robot, robot.neutral())
    slid = run.signals["slip_distance"].sum(axis=0)
    assert slid.argmax() == normal.argmin() and slid[normal.argmin()] > 0
    np.testing.assert_allclose(run.signals["normal_forces"][0], normal)
    np.testing.assert_allclose(normal.sum(), 45.0 * 9.81)


@pytest.mark.parametrize("v0, rtol", [([0.3, -0.2, 0.0], 1e-9), ([0.3, -0.2, 0.5], 1e-3)])
def test_free_rolling_conserves_energy(robot, v0, rtol):
    """Rolling without slip dissipates nothing: exactly so in translation; while turning, the
    wheels' rotors are re-accelerated by the ground and the semi-implicit step's O(h) error
    shows (about 2e-4 over 1 s)."""
    run, _ = simulate(robot, np.zeros(4), seconds=1.0, v0=np.array(v0), mu=0.5)
    rates = run.signals["wheel_rates"]
    energy = [kinetic_energy(robot, v, w) for v, w in zip(run.v, rates, strict=True)]
    np.testing.assert_allclose(energy, energy[0], rtol=rtol)
    assert run.signals["slip_distance"].max() < 1e-12


def test_work_of_the_torques_becomes_kinetic_energy_or_is_dissipated(robot):
    for force, slips in ((10.0, False), (300.0, True)):
        tau = min_norm(robot, [0.0, force, 0.0])
        run, _ = simulate(robot, tau, seconds=0.4, mu=0.5)
        rates = np.vstack([np.zeros(4), run.signals["wheel_rates"]])
        angle = np.sum(0.5 * (rates[1:] + rates[:-1]) * DT, axis=0)  # rates are linear in t
        work = float(tau @ angle)
        energy = kinetic_energy(robot, run.v_final, rates[-1])
        if slips:
            assert energy < 0.9 * work  # friction dissipates
        else:
            np.testing.assert_allclose(energy, work, rtol=1e-6)


def test_servo_errors_are_seeded(robot):
    tau = min_norm(robot, [20.0, 10.0, 1.0])
    errors = dict(gain_error=[0.05, -0.05, 0.03, -0.03], torque_noise=0.2, mu=0.5)
    a, _ = simulate(robot, tau, seed=3, **errors)
    b, _ = simulate(robot, tau, seed=3, **errors)
    c, _ = simulate(robot, tau, seed=4, **errors)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.signals["wheel_torque"], b.signals["wheel_torque"])
    assert np.abs(a.q_final - c.q_final).max() > 1e-6
    exact, _ = simulate(robot, tau, mu=0.5)
    mean = a.signals["wheel_torque"].mean(axis=0)
    np.testing.assert_allclose(mean, (1 + np.array(errors["gain_error"])) * tau, atol=0.05)
    assert np.abs(exact.q_final - a.q_final).max() > 1e-6


def test_unpowered_wheels_roll_freely(robot):
    tau = np.array([5.0, 5.0, 5.0, 5.0])
    run, _ = simulate(robot, tau, active=[False, True, False, True], mu=0.5)
    np.testing.assert_allclose(run.signals["wheel_torque"][:, [0, 2]], 0.0)
    np.testing.assert_allclose(run.signals["wheel_torque"][:, [1, 3]], 5.0)


def test_radius_error_makes_odometry_drift_without_slip(robot):
    tau = min_norm(robot, [10.0, 0.0, 0.0])
    run, _ = simulate(robot, tau, radius_error=0.01, mu=0.5)
    assert run.signals["slip_distance"].max() < 1e-12
    # a 1 % larger wheel covers 1 % more ground per turn than odometry believes
    np.testing.assert_allclose(run.q_final[0], 1.01 * run.q_est_final[0], rtol=1e-6)


def test_bad_input_is_refused(robot):
    with pytest.raises(InvalidValueError, match="servo"):
        OmniDynamics(servo="velocity")
    with pytest.raises(InvalidValueError, match="substeps"):
        OmniDynamics(substeps=0)
    with pytest.raises(InvalidValueError, match="wheel_inertia"):
        OmniDynamics(wheel_inertia=-1.0)
    with pytest.raises(ShapeError, match="mu"):
        simulate(robot, np.zeros(4), mu=[0.5, 0.5])
    with pytest.raises(InvalidValueError, match="mu"):
        simulate(robot, np.zeros(4), mu=0.0)
    with pytest.raises(ShapeError, match="command"):
        simulate(robot, np.zeros(3))
    with pytest.raises(ShapeError, match="arm_velocity"):
        simulate(robot, np.zeros(4), arm_velocity=lambda t: np.zeros(5))


def test_the_arm_moves_the_load_between_the_wheels(robot):
    pan = np.zeros(6)
    pan[0] = 1.0  # shoulder pan at 1 rad/s: the centre of mass swings around the mount
    run, _ = simulate(robot, np.zeros(4), seconds=0.5, mu=0.5, arm_velocity=lambda t: pan)
    forces = run.signals["normal_forces"]
    np.testing.assert_allclose(forces.sum(axis=1), 45.0 * 9.81)  # the weight is carried
    assert np.abs(forces[-1] - forces[0]).max() > 10.0  # [N]
    # the simulator integrates the mid-tick velocity: the arm starts from rest in the first tick
    np.testing.assert_allclose(run.q_final[3], robot.neutral()[3] + 0.5 - 0.5 * DT, atol=1e-12)
    np.testing.assert_allclose(run.q_est_final, run.q_final, atol=1e-12)  # the arm is exact
