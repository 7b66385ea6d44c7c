"""wbc.sim.MujocoPlant: the physics plant rolls the bases without slip when driven slowly, its
arm servos track, the omni platform's wheels carry the weight the statics give, a wheel pushed
past μ·f_n slips, one controller object runs on both plants, and the compiled sub-steps give
bitwise the states and signals of the Python loop (which runs where there is no compiler)."""

from __future__ import annotations

import re
from types import MethodType

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="MujocoPlant needs the mujoco package ([mujoco] extra)")

import wbc  # noqa: E402
import wbc.robots  # noqa: E402
from wbc import cbuild  # noqa: E402
from wbc.errors import InvalidValueError, ShapeError, WbcError  # noqa: E402
from wbc.robots.omni import ARM_MASS, PLATFORM_MASS, normal_forces, system_com  # noqa: E402
from wbc.robots.resources import urdf_path  # noqa: E402
from wbc.sim import Simulation, actuation, mjcf, mujoco_substeps  # noqa: E402
from wbc.sim.mujoco_plant import MujocoPlant  # noqa: E402
from wbc.tasks import ConfigurationLimit, FrameTask, VelocityLimit  # noqa: E402

DT = 0.01


class Constant:
    """A controller commanding the same vector every tick."""

    def __init__(self, command) -> None:
        self.command = np.asarray(command, dtype=float)

    def step(self, q, v=None, **references):
        return self.command


def drive(name: str, twist, seconds: float = 2.0, **plant):
    robot = wbc.robots.load(name)
    command = np.zeros(robot.nv)
    command[:len(twist)] = twist
    return robot, Simulation(robot, Constant(command), DT,
                             plant=MujocoPlant(robot, **plant)).run(seconds=seconds)


SLOW = {  # (robot, base velocity coordinates): forward, sideways, turning, for each base
    "steerable": ("mpo700_lwr4", [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.2]]),
    "differential": ("tiago_panda", [[0.1, 0], [0, 0.2], [0.1, 0.1]]),
    "omni": ("omni4_arm6", [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.2]]),
    "mecanum": ("mecanum_gen3", [[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.2]]),
}
CASES = [(base, name, twist) for base, (name, twists) in SLOW.items() for twist in twists]


@pytest.mark.parametrize("base, name, twist", CASES,
                         ids=[f"{c[0]}-{i % 3}" for i, c in enumerate(CASES)])
def test_a_base_driven_slowly_rolls_without_slip(base, name, twist):
    # the twist MuJoCo measures on the base body against the base model's forward kinematics
    # of the wheel joints (odometry), averaged after the first 0.5 s, within 2 %
    robot, run = drive(name, twist)
    true = run.v[50:, :robot.nv_base].mean(axis=0)
    odometry = run.v_est[50:, :robot.nv_base].mean(axis=0)
    assert np.linalg.norm(true - odometry) <= 0.02 * np.linalg.norm(odometry)
    assert np.linalg.norm(odometry - twist) <= 0.05 * np.linalg.norm(twist)  # servos track


@pytest.mark.parametrize("name", ["omni4_arm6", "mpo700_lwr4"])
def test_joint_level_commands_drive_the_wheels_as_the_base_model_says(name):
    # "joints": the controller drives the wheels itself; the wheel (and steer) rates the base
    # model's inverse kinematics gives for a slow forward twist move the base at that twist
    robot = wbc.robots.load(name)
    twist = np.array([0.1, 0.0, 0.0])
    base = robot.base
    if name == "mpo700_lwr4":  # steering at 0 (the plant's start): drive only, no steering
        rates = base.inverse(twist, np.zeros(base.n_wheels))
        wheels, steers = rates.drive_rates, np.zeros(base.n_wheels)
    else:
        wheels, steers = np.asarray(base.jacobian) @ twist, np.zeros(0)
    command = np.concatenate([wheels, steers, np.zeros(robot.n_arm)])
    run = Simulation(robot, Constant(command), DT, command="joints",
                     plant=MujocoPlant(robot)).run(seconds=1.5)
    true = run.v[50:, :3].mean(axis=0)
    assert np.linalg.norm(true - twist) <= 0.02 * np.linalg.norm(twist)
    assert np.abs(run.v[50:, 3:]).max() < 0.01  # the arm holds
    with pytest.raises(ShapeError, match="entries"):
        Simulation(robot, Constant(command[:-1]), DT, command="joints",
                   plant=MujocoPlant(robot)).run(ticks=1)
    panda = wbc.robots.load_panda()
    with pytest.raises(WbcError, match="drive wheels"):
        Simulation(panda, Constant(np.zeros(panda.nv)), DT, command="joints",
                   plant=MujocoPlant(panda)).run(ticks=1)


def test_wheels_beside_their_steer_axes_roll_as_the_papers_model_says():
    # steer_offset="sideways" (Sorour et al.'s wheels): steering on the spot with the drive
    # rate r φ̇ = d β̇ of the paper's inverse actuation model rolls each contact around its
    # steer axis and the base stays put; with the wheels held instead, the contacts stay put
    # and the steer axes (the base) circle them at d β̇
    robot = wbc.robots.load("mpo700_lwr4")
    base = robot.base
    steer_rate = 0.5  # rad/s
    speeds = []
    for drive in (base.offset * steer_rate / base.radius, 0.0):
        command = np.concatenate([np.full(base.n_wheels, drive),
                                  np.full(base.n_wheels, steer_rate), np.zeros(robot.n_arm)])
        run = Simulation(robot, Constant(command), DT, command="joints",
                         plant=MujocoPlant(robot, steer_offset="sideways")).run(seconds=1.0)
        speeds.append(np.linalg.norm(run.v[30:, :2], axis=1).mean())
        assert run.signals["wheel_slip"][30:].max() < 1e-3
        # the wheel odometry of this geometry sees the truth
        assert np.abs(run.v_est[30:, :3] - run.v[30:, :3]).max() < 2e-3
    rolling, held = speeds
    assert rolling < 1e-3 and held == pytest.approx(base.offset * steer_rate, rel=0.05)
    with pytest.raises(WbcError, match="'joints' commands"):
        Simulation(robot, Constant(np.zeros(robot.nv)), DT,
                   plant=MujocoPlant(robot, steer_offset="sideways")).run(ticks=1)
    with pytest.raises(InvalidValueError, match="steer_offset"):
        MujocoPlant(robot, steer_offset="ahead")


def test_a_simulation_that_diverges_raises(tmp_path, monkeypatch):
    # MuJoCo resets a state it finds unstable and only warns: the plant turns that into an
    # error instead of carrying on from the reset state
    monkeypatch.chdir(tmp_path)  # where MuJoCo writes its warning log
    robot = wbc.robots.load("omni4_arm6")
    plant = MujocoPlant(robot)
    plant.reset(robot.neutral(), np.zeros(robot.nv), DT, "velocity")
    plant.model.opt.timestep = 0.5  # far beyond what the contacts and servos integrate
    with pytest.raises(wbc.errors.NonFiniteError, match="diverged"):
        for _ in range(20):
            plant.step(np.zeros(robot.nv))


def test_an_arm_joint_tracks_a_commanded_velocity():
    robot = wbc.robots.load_panda()
    command = np.zeros(robot.nv)
    command[3] = 0.3  # rad/s, the Panda's 4th joint
    q0 = 0.5 * (robot.model.lowerPositionLimit + robot.model.upperPositionLimit)
    q0[3] -= 0.5  # room for the 0.3 rad it travels
    run = Simulation(robot, Constant(command), DT, plant=MujocoPlant(robot)).run(
        seconds=1.0, q0=q0)
    assert np.allclose(run.v[20:, 3], 0.3, rtol=0.01)
    others = np.delete(np.arange(robot.nv), 3)
    assert np.abs(run.v[20:, others]).max() < 0.01
    # the servo integrates the commanded rate: the joint is where the rate puts it
    assert run.q_final[3] - q0[3] == pytest.approx(0.3 * 1.0, abs=0.01)
    assert run.signals["saturation"].max() == 0.0


#: arm configurations (shoulder pan, shoulder lift, elbow) [rad] of the omni robot where the
#: statics are well posed (no wheel under a third of the mean load): folded, out sideways, back
POSES = ((0.0, -1.29, -1.03), (0.8, -1.5708, 1.5708), (-1.0, -2.0, 1.5708))


def omni_pose(robot, pose):
    q = robot.neutral()
    q[3:6] = pose
    return q


@pytest.mark.parametrize("pose", POSES)
def test_the_omni_platform_at_rest_carries_the_statics_normal_forces(pose):
    assert mjcf.PAPER_MASSES["omni4_arm6"] == (PLATFORM_MASS, ARM_MASS)
    robot = wbc.robots.load("omni4_arm6")
    q0 = omni_pose(robot, pose)
    run = Simulation(robot, Constant(np.zeros(robot.nv)), DT,
                     plant=MujocoPlant(robot)).run(seconds=0.3, q0=q0)
    mass, com = system_com(robot, q0, frame="base")
    expected = normal_forces(robot.base.wheel_positions, com, mass)
    assert expected.min() > 0.33 * expected.mean()
    measured = run.signals["normal_forces"][-1]
    assert measured.sum() == pytest.approx(mass * 9.81, rel=1e-3)
    assert run.signals["base_tilt"][-1] < 0.01  # rad: level on its stiff supports
    assert np.allclose(measured, expected, rtol=0.05), (measured, expected)


def test_a_robot_whose_centre_of_mass_leaves_its_wheels_tips():
    # a UR5 stretched out 0.4 m above the omni platform: the centre of mass lies 0.17 m ahead,
    # outside the wheels' support (they touch the floor at ±0.16 m): two wheels lift
    mount = np.eye(4)
    mount[2, 3] = 0.4
    robot = wbc.robots.from_urdf(urdf_path("ur_description/urdf/ur5_robot.urdf"), base="omni",
                                 ee_frame="tool0", mount=mount)
    assert robot.com(robot.neutral())[0] > robot.base.wheel_positions[:, 0].max()
    run = Simulation(robot, Constant(np.zeros(robot.nv)), DT,
                     plant=MujocoPlant(robot)).run(seconds=0.2)
    assert run.signals["base_tilt"][-1] > 0.05
    assert np.sum(run.signals["normal_forces"][-1] == 0.0) == 2


def test_a_wheel_pushed_past_mu_fn_slips():
    # omni platform (arm folded), the same torque on every wheel: it turns in place, on a floor
    # with μ = 0.3. A wheel passes to the ground about 0.7 τ/r (the rest spins the wheel up):
    # 7 N at 1 N m, below every wheel's μ·f_n (18 to 48 N): it rolls; 56 N at 8 N m, above
    # every wheel's: it slips
    robot = wbc.robots.load("omni4_arm6")
    plant = MujocoPlant(robot, mu=0.3)
    q0 = omni_pose(robot, POSES[0])
    slips = {}
    for torque in (1.0, 8.0):
        run = Simulation(robot, Constant(np.full(4, torque)), DT, command="torque",
                         plant=plant).run(seconds=0.2, q0=q0)
        slips[torque] = run.signals["slip_distance"].sum(axis=0)
        assert np.allclose(run.signals["wheel_torque"], torque)  # applied as commanded
        if torque == 8.0:  # contacts that touch are at the friction limit
            touching = run.signals["normal_forces"][1:] > 1.0
            assert np.mean(run.signals["friction_utilisation"][1:][touching] > 0.99) > 0.9
    assert slips[8.0].min() > 0.02  # m, every wheel slid
    assert slips[1.0].max() < 0.05 * slips[8.0].min()


def test_the_same_controller_runs_on_both_plants():
    # a gentle controller (the error's time constant 0.5 s) reaches the target as it believes
    # it is on both plants; on MuJoCo the wheels slip (the first ticks ask the base for
    # 0.33 m/s at once: a wheel saturates) and odometry drifts (measured: 2.4e-2 rad of
    # heading, 15 mm at the hand), so the true error is the drift's and not the controller's
    robot = wbc.robots.load("omni4_arm6")
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.02, name="ee"))
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    controller = wbc.Controller(robot, stack, dt=DT)
    target = robot.frame_pose(robot.neutral(), "ee").copy()
    target[0, 3] += 0.2
    runs = [Simulation(robot, controller, DT, plant=plant).run(
        seconds=3.0, references={"ee": target}) for plant in (None, MujocoPlant(robot))]

    def hand(q):
        return robot.frame_pose(q, "ee")[:3, 3]

    for run in runs:
        assert run.failures == 0
        assert np.linalg.norm(hand(run.q_est_final) - target[:3, 3]) < 2e-3  # as it believes
    kinematic, mujoco = runs
    assert np.linalg.norm(hand(kinematic.q_final) - target[:3, 3]) < 2e-3
    true_error = np.linalg.norm(hand(mujoco.q_final) - target[:3, 3])
    drift = np.linalg.norm(hand(mujoco.q_final) - hand(mujoco.q_est_final))
    assert drift > 1e-3 and abs(true_error - drift) < 2e-3
    assert mujoco.signals["slip_distance"].sum() > 0.01  # m: the wheels slid
    assert "wheel_slip" not in kinematic.signals
    # given the truth instead of odometry, the controller reaches the true target
    truth = Simulation(robot, controller, DT, plant=MujocoPlant(robot, odometry=False)).run(
        seconds=3.0, references={"ee": target})
    assert np.array_equal(truth.q, truth.q_est)
    assert np.linalg.norm(hand(truth.q_final) - target[:3, 3]) < 2e-3


def acceleration_controller(robot, kp=20.0, kd=9.0):
    """The hand to its target and the arm to its home at the acceleration level:
    ``J a + J̇v = kp e − kd J v`` above ``a_arm = −kp (q_arm − q_home) − kd v_arm``."""
    stack = wbc.Stack(wbc.Variables(a=robot.nv), damping=1e-2)
    J = stack.quantity("J[ee]", (6, robot.nv))
    drift = stack.quantity("Jdot_v[ee]", 6)
    pose = stack.quantity("pose[ee]", (4, 4))
    q, v = stack.quantity("q", robot.nq), stack.quantity("v", robot.nv)
    target = stack.parameter("ee.target", (4, 4))
    a = stack.variables["a"]
    wanted = kp * (target[:3, 3] - pose[:3, 3]) - kd * (J[:3, :] @ v)
    stack.add(wbc.Cost(J[:3, :] @ a + drift[:3], wanted, name="ee"))
    home = robot.neutral()[robot.nq - robot.n_arm:]
    arm = slice(robot.nv_base, robot.nv)
    stack.add(wbc.Cost(a[arm], -kp * (q[robot.nq - robot.n_arm:] - home) - kd * v[arm],
                       name="home"), priority=1)
    return wbc.Controller(robot, stack, dt=DT)


@pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")  # limit-free on purpose
@pytest.mark.parametrize("name", ["omni4_arm6", "tiago_panda"])
def test_an_acceleration_level_controller_closes_the_loop_on_mujoco(name):
    # accelerations reach the arm as inverse-dynamics torques and the base through its wheel
    # servos; the loop converges as on the kinematic plant (measured 0.8 and 0.6 mm at 2 s,
    # against 0.16 mm kinematically)
    robot = wbc.robots.load(name)
    controller = acceleration_controller(robot)
    target = robot.frame_pose(robot.neutral(), "ee").copy()
    target[0, 3] += 0.1
    run = Simulation(robot, controller, DT, command="acceleration",
                     plant=MujocoPlant(robot)).run(seconds=2.0, references={"ee": target})
    assert run.failures == 0
    assert np.linalg.norm(robot.frame_pose(run.q_final, "ee")[:3, 3] - target[:3, 3]) < 3e-3


def test_bad_inputs_raise():
    robot = wbc.robots.load("omni4_arm6")
    plant = MujocoPlant(robot)
    with pytest.raises(InvalidValueError, match="multiple"):
        Simulation(robot, Constant(np.zeros(robot.nv)), 0.0125, plant=plant).run(ticks=1)
    with pytest.raises(WbcError, match="actuation"):
        Simulation(robot, Constant(np.zeros(robot.nv)), DT, plant=plant,
                   actuation=[actuation.Lag(0.05)])
    with pytest.raises(WbcError, match="reset"):
        Simulation(robot, Constant(np.zeros(robot.nv)), DT, plant=object())
    with pytest.raises(InvalidValueError, match="mu"):
        MujocoPlant(robot, mu=-1.0)
    with pytest.raises(WbcError, match="reset"):
        MujocoPlant(robot).step(np.zeros(robot.nv))
    with pytest.raises(InvalidValueError, match="odometry"):
        MujocoPlant(robot, odometry=1)
    with pytest.raises(ShapeError, match="masses"):
        MujocoPlant(robot, masses=(15.0, 30.0, 1.0))
    with pytest.raises(ShapeError, match="entries"):
        plant.reset(robot.neutral(), np.zeros(robot.nv), DT)
        plant.step(np.zeros(robot.nv + 1))
    panda = wbc.robots.load_panda()
    with pytest.raises(WbcError, match="wheels"):
        Simulation(panda, Constant(np.zeros(7)), DT, command="torque",
                   plant=MujocoPlant(panda)).run(ticks=1)
    flyer = wbc.robots.from_urdf(urdf_path("ur_description/urdf/ur5_robot.urdf"),
                                 root="free_flyer", ee_frame="tool0")
    with pytest.raises(WbcError, match="free_flyer"):
        MujocoPlant(flyer)


def test_passive_wheels_roll_freely_and_their_commands_are_ignored():
    # the omni paper's two-motor experiment: wheels 0 and 2 without motors; wheels 1 and 3
    # (opposite, driving along one line) move the platform along it and turn it, and the
    # unpowered wheels roll with the motion (turning needs them to), so the odometry of all
    # four encoders still matches the truth
    robot = wbc.robots.load("omni4_arm6")
    J = np.asarray(robot.base.jacobian)
    along = J[1, :2] / np.linalg.norm(J[1, :2])
    twist = np.r_[0.1 * along, 0.2]
    rates = J @ twist
    assert abs(rates[0]) > 0.4  # rad/s: the turning asks wheel 0 to roll

    def run_with(passive_entry):
        command = np.r_[rates, np.zeros(robot.n_arm)]
        command[[0, 2]] = passive_entry
        plant = MujocoPlant(robot, passive_wheels=(0, 2))
        return plant, Simulation(robot, Constant(command), DT, command="joints",
                                 plant=plant).run(seconds=1.5)

    plant, run = run_with(50.0)
    assert plant.model.nu == robot.n_arm + 2  # no actuator on wheels 0 and 2
    assert run.signals["saturation"].shape[1] == robot.n_arm + 2
    assert np.all(run.signals["wheel_torque"][:, [0, 2]] == 0.0)
    true = run.v[50:, :3].mean(axis=0)
    assert np.linalg.norm(true - twist) <= 0.03 * np.linalg.norm(twist)
    odometry = run.v_est[50:, :3].mean(axis=0)
    assert np.linalg.norm(odometry - true) <= 0.03 * np.linalg.norm(true)
    _, same = run_with(0.0)
    assert np.array_equal(same.q, run.q)  # the passive wheels' entries are ignored
    with pytest.raises(InvalidValueError, match="passive_wheels"):
        MujocoPlant(robot, passive_wheels=(4,))


@pytest.mark.parametrize("targets", ["integrated", "present"])
def test_wheel_servo_targets_integrate_or_start_at_the_present_angle(targets):
    # "joints": the drive servos' angle references either integrate the commanded rates or
    # are set each period to the wheel's measured angle + rate × period (eq. 3's increments)
    import mujoco

    robot = wbc.robots.load("omni4_arm6")
    plant = MujocoPlant(robot, wheel_targets=targets)
    plant.reset(robot.neutral(), np.zeros(robot.nv), DT, "joints")
    m, d = plant.model, plant.data
    rates = np.array([1.0, -2.0, 0.5, 3.0])
    adr = [int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"wheel{i}")])
           for i in range(4)]
    act = [int(m.actuator_actadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR,
                                                   f"servo_wheel{i}")]) for i in range(4)]
    for _ in range(3):
        angles, references = d.qpos[adr].copy(), d.act[act].copy()
        plant.step(np.r_[rates, np.zeros(robot.n_arm)])
        start = angles if targets == "present" else references
        assert np.allclose(d.act[act], start + rates * DT, atol=1e-12)
    assert not np.allclose(d.act[act] - d.qpos[adr], 0.0, atol=1e-4)  # the wheels lag
    with pytest.raises(InvalidValueError, match="wheel_targets"):
        MujocoPlant(robot, wheel_targets="absolute")


def test_a_chassis_inertia_short_of_the_triangle_inequality_is_lifted_to_a_physical_one():
    # a thin disc's C = A + B less rim masses can leave A + B < C, which MuJoCo refuses; the two
    # smaller principal moments are raised by half the shortfall each, in the principal axes
    rotation = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    short = rotation @ np.diag([0.10, 0.095, 0.304]) @ rotation.T
    lifted = mjcf._physical(short)
    moments = np.linalg.eigvalsh(lifted)
    assert moments[0] + moments[1] == pytest.approx(moments[2], abs=1e-12)
    assert moments == pytest.approx([0.1495, 0.1545, 0.304])
    assert np.allclose(rotation.T @ lifted @ rotation,
                       np.diag([0.1545, 0.1495, 0.304]))  # the same principal axes
    valid = rotation @ np.diag([0.2, 0.15, 0.3]) @ rotation.T
    assert np.array_equal(mjcf._physical(valid), valid)


def reference_substeps(plant, start, slope):
    """A period's sub-steps as ``MujocoPlant.step`` ran them in Python before the compiled loop
    (the targets of unsteered wheels at once, a steered base's per sub-step): what the compiled
    loop and the Python fallback must reproduce bit for bit."""
    import mujoco

    m, d, h, n = plant.model, plant.data, mjcf.TIMESTEP, plant._substeps
    kind, nb = plant.command, plant.nv_base
    steered = plant.kind == "steerable" and kind in ("velocity", "acceleration")
    drives = None
    if plant.base is not None and kind in ("velocity", "acceleration") and not steered:
        ramp = np.arange(1, n + 1) * h if kind == "acceleration" else np.zeros(n)
        targets = start + np.outer(ramp, slope if kind == "acceleration" else np.zeros(nb))
        drives = targets @ plant._jacobian.T[:, plant._powered]
    tau = np.zeros(m.nv)
    limit, damping = plant.mjcf.arm_torque, m.dof_damping[plant._arm_v]
    qpos_rows, qvel_rows, force_rows = plant._rows
    for k in range(n):
        if drives is not None:
            d.ctrl[plant._wheel_u] = drives[k]
        elif steered:
            target = start + slope * (k + 1) * h if kind == "acceleration" else start
            drive, steer = plant._wheel_rates(target)
            d.ctrl[plant._wheel_u] = drive[plant._powered]
            d.ctrl[plant._steer_u] = steer
        if kind == "acceleration":
            mujoco.mj_step1(m, d)
            d.qacc[:] = plant._qacc  # the commanded accelerations the step assembled
            mujoco.mj_rne(m, d, 1, tau)
            torque = tau[plant._arm_v] + damping * d.qvel[plant._arm_v]
            d.ctrl[plant._arm_u] = np.minimum(np.maximum(torque, -limit), limit)
            mujoco.mj_step2(m, d)
        else:
            mujoco.mj_step(m, d)
        qpos_rows[k] = d.qpos
        qvel_rows[k] = d.qvel
        force_rows[k] = d.qfrc_actuator


def reference_plant(robot, **options) -> MujocoPlant:
    """A plant that runs :func:`reference_substeps` instead of its own loops (when reset
    without the compiled loop: :func:`assert_same_periods`)."""
    plant = MujocoPlant(robot, **options)
    plant._python_substeps = MethodType(reference_substeps, plant)
    return plant


def assert_bitwise(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def assert_same_periods(plant, reference, robot, kind, dt, periods, monkeypatch):
    """``periods`` control periods of random commands (a random walk, large enough to saturate
    joints, slip wheels and tip the omni platform) on ``plant`` and on the
    :func:`reference_plant` from the same start: the same numbers to the bit."""
    rng = np.random.default_rng(0)
    q0 = robot.neutral()
    q0[robot.nq - robot.n_arm:] += rng.uniform(-0.2, 0.2, robot.n_arm)
    start = plant.reset(q0, np.zeros(robot.nv), dt, kind)
    with monkeypatch.context() as patch:
        patch.setattr(mujoco_substeps, "library", lambda: None)  # the reference's Python loop
        for x, y in zip(start, reference.reset(q0, np.zeros(robot.nv), dt, kind), strict=True):
            assert_bitwise(x, y)
    assert not reference.compiled_substeps
    size = {"torque": len(plant._wheel_v) + robot.n_arm,
            "joints": len(plant._wheel_v) + len(plant._steer_v) + robot.n_arm}.get(kind, robot.nv)
    scale = np.full(size, {"velocity": 0.4, "acceleration": 1.0, "torque": 6.0,
                           "joints": 4.0}[kind])  # base velocities, wheel torques or rates
    scale[size - robot.n_arm:] = 30.0 if kind == "acceleration" else 1.0  # the arm's
    command = np.zeros(size)
    clipped = 0.0  # the arm motors' saturation (acceleration commands: torques clipped)
    for _ in range(periods):
        command = 0.8 * command + 0.6 * scale * rng.standard_normal(size)
        a, b = plant.step(command), reference.step(command)
        for x, y in [(a.q, b.q), (a.v, b.v), (a.v_measured, b.v_measured)]:
            assert_bitwise(x, y)
        for field in ("qpos", "qvel", "act", "ctrl", "qacc", "time"):  # MuJoCo state, inputs
            assert_bitwise(getattr(plant.data, field), getattr(reference.data, field))
        assert a.signals.keys() == b.signals.keys()
        for name in a.signals:
            assert_bitwise(a.signals[name], b.signals[name])
        clipped = max(clipped, float(np.max(a.signals["saturation"][:robot.n_arm])))
    assert clipped > 0.0 or kind != "acceleration"


SUBSTEP_CASES = {  # robot -> (plant options, control period [s], command kinds)
    "mecanum_gen3": ({}, 0.02, ("acceleration", "velocity", "torque", "joints")),
    "omni4_arm6": ({"passive_wheels": (0, 2), "wheel_targets": "present"}, DT,
                   ("acceleration", "torque", "joints")),
    "mpo700_lwr4": ({}, DT, ("velocity", "joints", "torque")),
    "tiago_panda": ({}, 0.02, ("acceleration", "velocity")),
    "panda": ({}, DT, ("acceleration", "velocity")),
}


@pytest.mark.parametrize("name", list(SUBSTEP_CASES))
def test_the_compiled_substeps_are_bitwise_the_python_loops(name, monkeypatch):
    # the compiled sub-step loop (wbc.sim.mujoco_substeps) against the Python loop it replaces:
    # the same states, measurements and signals to the bit, period after period, for every
    # command kind and base (the steerable base's velocity commands stay in Python: the wheel
    # targets follow its steering angles)
    robot = wbc.robots.load_panda() if name == "panda" else wbc.robots.load(name)
    options, dt, kinds = SUBSTEP_CASES[name]
    plant, reference = MujocoPlant(robot, **options), reference_plant(robot, **options)
    for kind in kinds:
        assert_same_periods(plant, reference, robot, kind, dt, 30, monkeypatch)
        steered = plant.kind == "steerable" and kind == "velocity"
        assert plant.compiled_substeps == (cbuild.compiler_available() and not steered)


@pytest.fixture
def no_compiler(monkeypatch, tmp_path):
    """No C compiler and an empty library cache (the compiled loop cannot be built)."""
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setenv("WBC_JIT_CACHE", str(tmp_path))
    mujoco_substeps.library.cache_clear()
    yield
    mujoco_substeps.library.cache_clear()


def test_without_a_compiler_the_python_loop_runs_the_same_substeps(no_compiler, monkeypatch):
    assert mujoco_substeps.library() is None
    for name, kind in (("mecanum_gen3", "acceleration"), ("omni4_arm6", "torque")):
        robot = wbc.robots.load(name)
        plant = MujocoPlant(robot)
        assert_same_periods(plant, reference_plant(robot), robot, kind, 0.02, 30, monkeypatch)
        assert not plant.compiled_substeps


@pytest.mark.skipif(not cbuild.compiler_available(), reason="needs a C compiler")
def test_the_compiled_loop_refuses_mujoco_headers_of_another_version(monkeypatch, tmp_path):
    import mujoco

    monkeypatch.setenv("WBC_JIT_CACHE", str(tmp_path))
    monkeypatch.setattr(mujoco, "mj_version", lambda: 1)  # a library older than the headers
    mujoco_substeps.library.cache_clear()
    try:
        assert mujoco_substeps.library() is None
        robot = wbc.robots.load("omni4_arm6")
        plant = MujocoPlant(robot)
        plant.reset(robot.neutral(), np.zeros(robot.nv), DT, "velocity")
        assert not plant.compiled_substeps
        plant.step(np.zeros(robot.nv))
    finally:
        mujoco_substeps.library.cache_clear()


@pytest.mark.skipif(not cbuild.compiler_available(), reason="needs a C compiler")
def test_a_mujoco_error_inside_the_compiled_loop_raises_as_the_bindings_do():
    # mju_error inside the loop exits the process by default: the loop catches it and the plant
    # raises MuJoCo's FatalError with the bindings' message
    import mujoco

    robot = wbc.robots.load("omni4_arm6")
    plant = MujocoPlant(robot)
    plant.reset(robot.neutral(), np.zeros(robot.nv), DT, "velocity")
    assert plant.compiled_substeps
    integrator = plant.model.opt.integrator
    plant.model.opt.integrator = 99  # no such integrator: mj_step raises
    with pytest.raises(mujoco.FatalError) as direct:
        mujoco.mj_step(plant.model, plant.data)
    with pytest.raises(mujoco.FatalError, match=re.escape(str(direct.value))):
        plant.step(np.zeros(robot.nv))
    plant.model.opt.integrator = integrator
    plant.reset(robot.neutral(), np.zeros(robot.nv), DT, "velocity")
    assert np.isfinite(plant.step(np.zeros(robot.nv)).q).all()  # the loop runs on
