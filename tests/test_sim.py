"""wbc.sim: exact actuation reproduces the plain loop; each actuation model has its defining
property; every catalogue robot runs in closed loop under every model."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import Constant

import wbc
import wbc.robots
from wbc.sim import Simulation, actuation, position_error
from wbc.tasks import FrameTask, PostureTask, VelocityLimit

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

DT = 0.01


def velocity_controller(robot):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"), priority=1)
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return wbc.Controller(robot, stack, dt=DT)


def acceleration_controller(robot, kp=20.0, kd=9.0):
    """Position task at the acceleration level: J a + J̇v = kp e − kd J v."""
    stack = wbc.Stack(wbc.Variables(a=robot.nv), damping=1e-2)
    J = stack.quantity("J[ee]", (6, robot.nv))
    drift = stack.quantity("Jdot_v[ee]", 6)
    pose = stack.quantity("pose[ee]", (4, 4))
    v = stack.quantity("v", robot.nv)
    target = stack.parameter("ee.target", (4, 4))
    wanted = kp * (target[:3, 3] - pose[:3, 3]) - kd * (J[:3, :] @ v)
    stack.add(wbc.Cost(J[:3, :] @ stack.variables["a"] + drift[:3], wanted, name="ee"))
    return wbc.Controller(robot, stack, dt=DT)


@pytest.fixture(scope="module")
def omni():
    return wbc.robots.load("omni4_arm6")


def target_of(robot, offset=(0.3, 0.1, 0.05)):
    T = robot.frame_pose(robot.neutral(), "ee").copy()
    T[:3, 3] += offset
    return T


@pytest.mark.parametrize("command", ["velocity", "acceleration"])
def test_exact_actuation_reproduces_the_plain_loop(omni, command):
    make = velocity_controller if command == "velocity" else acceleration_controller
    T = target_of(omni)
    run = Simulation(omni, make(omni), DT, [actuation.Exact()], command=command).run(
        ticks=60, references={"ee": T})
    ctrl, q, v = make(omni), omni.neutral(), np.zeros(omni.nv)
    for k in range(60):
        np.testing.assert_allclose(run.q[k], q, atol=1e-12)
        x = ctrl.step(q, v, ee=T)
        np.testing.assert_allclose(run.command[k], x, atol=1e-12)
        if command == "velocity":
            q, v = omni.integrate(q, x, DT), x
        else:
            v_next = v + DT * x
            q, v = omni.integrate(q, 0.5 * (v + v_next), DT), v_next
    np.testing.assert_allclose(run.q_final, q, atol=1e-12)
    np.testing.assert_array_equal(run.q, run.q_est)
    assert run.status == ["solved"] * 60 and run.tick_s.shape == (60,)


def test_lag_is_a_first_order_step_response(omni):
    tau, command = 0.05, np.r_[0.4, -0.2, 0.1, np.full(omni.nv - 3, 0.3)]
    run = Simulation(omni, Constant(command), DT, [actuation.Lag(tau)]).run(ticks=50)
    expected = 1.0 - np.exp(-(np.arange(50) + 1) * DT / tau)
    np.testing.assert_allclose(run.v, np.outer(expected, command), atol=1e-12)
    np.testing.assert_allclose(run.v, run.v_est[1:].tolist() + [run.v_final], atol=1e-12)


def test_saturation_limits_velocity_and_its_rate(omni):
    rng = np.random.default_rng(0)

    class Random(Constant):
        def step(self, q, v=None, **references):
            return rng.uniform(-3, 3, omni.nv)

    v_max, a_max = 0.8, 2.0
    run = Simulation(omni, Random(0), DT, [actuation.Saturation(v_max, a_max)]).run(ticks=200)
    assert np.abs(run.v).max() <= v_max + 1e-12
    dv = np.diff(np.vstack([np.zeros(omni.nv), run.v]), axis=0)
    assert np.abs(dv).max() <= a_max * DT + 1e-12
    assert np.abs(dv).max() >= a_max * DT - 1e-12  # the limit is reached, not just respected
    # within both limits the command passes unchanged (clip of a feasible value is itself)
    small = Simulation(omni, Constant(np.full(omni.nv, 0.01)), DT,
                       [actuation.Saturation(v_max, a_max)]).run(ticks=3)
    np.testing.assert_allclose(small.v, 0.01)


def test_odometry_error_scales_the_true_base_motion_only(omni):
    command = np.r_[0.2, 0.1, 0.0, np.zeros(omni.nv - 3)]
    run = Simulation(omni, Constant(command), DT,
                     [actuation.OdometryError(scale=0.05, noise=0.0)]).run(ticks=100)
    np.testing.assert_allclose(run.q_est_final[:2], [0.2, 0.1], atol=1e-12)
    np.testing.assert_allclose(run.q_final[:2], 1.05 * np.array([0.2, 0.1]), atol=1e-12)
    noisy = [Simulation(omni, Constant(command), DT, [actuation.OdometryError(0.0, 0.01)],
                        seed=seed).run(ticks=20).q_final for seed in (1, 1, 2)]
    np.testing.assert_array_equal(noisy[0], noisy[1])  # seeded: the same run twice
    assert np.abs(noisy[0] - noisy[2]).max() > 1e-6
    with pytest.raises(wbc.WbcError, match="first"):
        Simulation(omni, Constant(command), DT, [actuation.Lag(0.1), actuation.OdometryError()])


def test_odometry_error_does_not_compound_under_acceleration_commands():
    """The scale acts on the commanded velocity (v_est + a·dt), never on the previous truth:
    a constant acceleration gives a true base velocity (1 + scale) times the estimated one,
    and zero acceleration keeps the base at rest (it grew as 1.03^k before)."""
    robot = wbc.robots.load("mecanum_gen3")
    accelerate = np.r_[0.02, 0.0, 0.0, np.zeros(robot.nv - 3)]
    run = Simulation(robot, Constant(accelerate), 0.02,
                     [actuation.OdometryError(scale=0.05, noise=0.0)],
                     command="acceleration").run(ticks=500)
    np.testing.assert_allclose(run.v[:, 0], 1.05 * (run.v_est[:, 0] + 0.02 * 0.02), rtol=1e-12)
    still = Simulation(robot, Constant(np.zeros(robot.nv)), 0.02,
                       [actuation.OdometryError(0.03, 0.0)], command="acceleration").run(
        ticks=1000)
    assert np.abs(still.v).max() == 0.0


def test_wheel_slip_limits_each_wheel_to_its_friction(omni):
    step = np.r_[0.8, 0.0, 0.0, np.zeros(omni.nv - 3)]  # a velocity step: large traction
    grip = Simulation(omni, Constant(step), DT, [actuation.WheelSlip(mu=50.0)]).run(ticks=5)
    np.testing.assert_allclose(grip.v, np.tile(step, (5, 1)), atol=1e-12)
    assert grip.signals["wheel_slip"].max() < 1e-12
    slip = Simulation(omni, Constant(step), DT, [actuation.WheelSlip(mu=0.3)]).run(ticks=100)
    base = slip.v[:, 0]
    assert base[0] < step[0] and np.all(np.diff(base) >= -1e-12)
    mass = omni.mass
    # with every wheel saturated the acceleration is at most what friction allows
    assert np.diff(np.r_[0.0, base]).max() / DT <= 0.3 * 9.81 * np.sqrt(2) + 1e-9
    assert slip.signals["friction_utilisation"][0].max() > 1.0
    assert slip.signals["wheel_slip"][0].max() > 0.0
    np.testing.assert_allclose(slip.q_est_final[0], 0.8 * 100 * DT)  # odometry believes
    assert slip.q_final[0] < slip.q_est_final[0] and mass > 0


@pytest.mark.parametrize("name", wbc.robots.names())
@pytest.mark.parametrize("model", ["exact", "odometry", "lag", "saturation", "slip"])
def test_every_robot_runs_under_every_actuation_model(name, model):
    robot = wbc.robots.load(name)
    chain = {"exact": [actuation.Exact()],
             "odometry": [actuation.OdometryError(0.03, 0.005)],
             "lag": [actuation.Lag(0.05)],
             "saturation": [actuation.Saturation(0.5, 2.0)],
             "slip": [actuation.WheelSlip(0.8)]}[model]
    T = target_of(robot, (0.4, 0.2, 0.0))
    run = Simulation(robot, velocity_controller(robot), DT, chain,
                     signals={"ee_error": position_error("ee"),
                              "believed": position_error("ee", estimate=True)}).run(
        seconds=1.5, references={"ee": T})
    assert run.q.shape == (150, robot.nq) and run.v.shape == (150, robot.nv)
    assert np.isfinite(run.q).all() and run.failures == 0
    believed, error = run.signals["believed"], run.signals["ee_error"]
    assert believed[-1] < 0.5 * believed[0], f"{name}/{model}: {believed[[0, -1]]}"
    if model in ("odometry", "slip"):  # the truth drifts from the estimate; odometry believes
        assert np.abs(run.q - run.q_est).max() > 1e-4
    else:
        np.testing.assert_array_equal(run.q, run.q_est)
        assert error[-1] < 0.5 * error[0], f"{name}/{model}: {error[[0, -1]]}"
    series = run.series(["t", "base_velocity", "ee_error"])
    assert np.shape(series["base_velocity"]) == (150, robot.nv_base)


def test_bad_input_is_refused(omni):
    ctrl = Constant(np.zeros(omni.nv))
    with pytest.raises(wbc.InvalidValueError):
        Simulation(omni, ctrl, 0.0)
    with pytest.raises(wbc.WbcError, match="step"):
        Simulation(omni, object(), DT)
    sim = Simulation(omni, ctrl, DT)
    with pytest.raises(wbc.WbcError, match="seconds or ticks"):
        sim.run()
    with pytest.raises(wbc.ShapeError):
        sim.run(ticks=2, q0=np.zeros(3))
    with pytest.raises(wbc.NonFiniteError):
        Simulation(omni, Constant(np.full(omni.nv, np.nan)), DT).run(ticks=1)
    with pytest.raises(wbc.ShapeError, match="command_map"):
        Simulation(omni, Constant(np.zeros(omni.nv + 2)), DT).run(ticks=1)
    with pytest.raises(wbc.WbcError, match="v_true"):
        Simulation(omni, ctrl, DT, command="torque").run(ticks=1)
    with pytest.raises(wbc.InvalidValueError):
        Simulation(omni, ctrl, DT, [actuation.Lag(-1.0)]).run(ticks=1)
    with pytest.raises(wbc.WbcError, match="no series"):
        sim.run(ticks=1).series(["nope"])
