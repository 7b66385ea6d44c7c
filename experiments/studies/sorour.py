"""`wbc study sorour`: Sorour, Cherubini & Fraisse's simulations (§V) rerun on wbc.

Robot ``mpo700_lwr4`` (Neobotix MPO700 + KUKA LWR-IV). Five target poses of the end tip over
65 s (Table II), with Table I's parameters, for three redundancy resolutions:

* ``pinv`` — the whole-body damped pseudo-inverse of eq. 8 (one level, ``ρ``, no mobility);
* ``proposed`` — eq. 9: the ψ-shared task (per-tick mobility on the task's level) and the
  dexterous posture in the null space (exact weighted QP form, docs/DESIGN.md, math note 3);
* ``compensated`` — eq. 9 plus eq. 14: the arm makes up for the base velocity the steering
  controller will not deliver.

The base is simulated through its own controller (:class:`wbc.papers.sorour.steering.
SteerableDrive`): the commanded base twist goes through the ICR steering QP and the drive
controller, and the base moves at the resulting *feasible* twist ``q̇_bf``. The compensated
controller predicts ``q̇_bf`` with its own copy of the same steering controller (same state,
same inputs: the paper's "next sample" prediction).

On MuJoCo (``--plant mujoco``) there is no ``SteerableDrive``: a copy of the same steering
controller (:class:`SteeredJoints`) turns the commanded base twist into the steer and drive
rates of the MPO700's real steer and drive joints (``Simulation(command="joints")``), and the
base moves as its wheels on the floor make it.

The arm has the LWR-IV's joint position and velocity limits (the paper's formulation has none;
:mod:`wbc.papers.sorour.controller`), starts inside them (:func:`within_joint_limits`), its
posture error is wrapped, and eq. 14 is damped (μ = Table I's ρ by default). The runs take the
controllers' path :data:`RUN_PATH`.

Timing (not with ``main_only``): the compensated controller's full tick per backend over 200
states of the daqp run; on daqp the default (fast) controller interleaved tick by tick with
``fused=False`` (:func:`interleaved_timing`: ``timing["daqp"]["ordinary_tick_median_s"]`` and
the largest command difference).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

import wbc
from wbc.papers.sorour import (
    N_BASE,
    PARAMETERS,
    Q_DEX,
    VARIANTS,
    SorourController,
    SteerableController,
    SteerableDrive,
    SteerStep,
)
from wbc.robots import load
from wbc.sim import Simulation
from wbc.solvers import available_backends
from wbc.tasks import RpyPoseTask
from wbc.tasks.rpy_pose import pose_error, rpy_jacobian
from wbc.viz.record import Recording

from .study import (
    DOCUMENTED,
    Claim,
    StudyOptions,
    StudyResult,
    interleaved_timing,
    make_plant,
    plant_timing,
    replay_timing,
    save_figure,
    study_main,
)

# the controller and Table I live in wbc.papers.sorour; their names stay importable from here
# for compatibility
__all__ = ["PARAMETERS", "PARAMETERS_SWEPT", "POSES", "RANDOM_ELEMENTS", "SorourController",
           "SteeredJoints", "main", "run"]

#: the constants a sweep may change (``--param KEY=V``); the keys of :data:`PARAMETERS` where
#: they are Table I's or the steering controller's, so the JSON's ``"parameters"`` show the
#: values used.
PARAMETERS_SWEPT = {
    "compensation_damping": (PARAMETERS["rho"], "μ of eq. 14's damped pseudo-inverse (default "
                             "Table I's ρ: the paper's damped pseudo-inverse) [-]"),
    "daqp_primal_tol": (1e-6, "daqp's primal tolerance in the stack's and eq. 14's QPs "
                        "(default daqp's own; the fused stack caps it, wbc.fused) [-]"),
    "icr_gain": (PARAMETERS["icr_gain"], "λ of the ICR velocity controller, our choice [1/s]"),
    "steer_rate_max": (PARAMETERS["steer_rate_max"],
                       "β̇max, the steer joints' rate limit (an estimate) [rad/s]"),
    "steer_acceleration_max": (PARAMETERS["steer_acceleration_max"],
                               "β̈max, the steer joints' acceleration limit (an estimate) "
                               "[rad/s²]"),
    "Kp": (PARAMETERS["Kp"], "K_p of the drive controller (Table I) [1/s]"),
}


#: half-widths of the uniform re-staging a seed draws (fixed before any seeded run)
START_JITTER = (0.02, math.radians(2.0))  # base start x, y [m]; heading [rad]
POSE_JITTER = (0.02, math.radians(2.0))  # end-tip position per axis [m]; roll/pitch/yaw [rad]

RANDOM_ELEMENTS = (
    "The study is deterministic; a seed re-stages it: the base starts displaced by uniform "
    "±2 cm in x and y and turned by uniform ±2°; the end tip's initial pose (Table II, from "
    "which the arm's start is solved) and each of the five target poses are moved by uniform "
    "±2 cm per axis and ±2° per roll, pitch and yaw angle. Independent streams (numpy "
    "SeedSequence(seed).spawn): start, targets. The pose schedule (start times) is kept.")

#: Table II: initial end-tip pose, then (start time [s], target pose (x, y, z, roll, pitch,
#: yaw)).
INITIAL_POSE = np.array([0.708, 0.004, 1.08, math.pi / 2, 0.0, 0.0])
POSES = ((0.0, (5.0, 1.5, 1.0, 0.0, 0.0, 0.0)),
         (20.0, (5.0, 1.3, 1.0, 0.0, 0.0, 0.0)),
         (25.0, (4.8, 1.3, 1.0, 0.0, 0.0, -math.pi / 2)),
         (35.0, (5.0, 1.5, 1.0, 0.0, 0.0, 0.0)),
         (45.0, (4.0, -0.5, 1.0, math.pi / 2, 0.0, 0.0)))
DURATION = 65.0
#: MPO700 deck outline [m] (the body box of wbc.robots.mpo700: 0.99 × 0.65 m).
DECK = np.array([[0.495, 0.325], [-0.495, 0.325], [-0.495, -0.325], [0.495, -0.325]])
ARM_FRAMES = ("lwr_joint_2", "lwr_joint_4", "lwr_joint_6", "lwr_flange", "ee")
FOOTPRINT_WINDOW = 20.0  # [s]: the travel to the first, far pose
STEADY_WINDOW = 2.0  # [s]: the end of each pose interval
#: a pose counts as reached when ||e_p|| stays within this over the last STEADY_WINDOW of its
#: interval [m, rad] (our choice, fixed before the runs: a fine-manipulation precision, 1 cm /
#: 0.01 rad; r_fm = 0.25 m would make "ψ = 1 where reached" true by eq. 11's definition)
CONVERGED = 0.01
#: times [s] of the footprint snapshots (Fig. 5): the travel to the first pose
SNAPSHOTS = (0.0, 5.0, 10.0, 15.0, 19.975)
#: the runs' path (``fused`` of the controllers): see the README's Sorour section for the check
#: that the fast and ordinary paths give the same claims
RUN_PATH: bool | str = False


def target_at(t: float, poses=POSES) -> np.ndarray:
    """The target pose at time ``t`` [s] of the schedule ``poses`` (default Table II's)."""
    current = poses[0][1]
    for start, pose in poses:
        if t >= start:
            current = pose
    return np.array(current, dtype=float)


def initial_configuration(robot, pose=INITIAL_POSE) -> np.ndarray:
    """A configuration with the end tip at ``pose`` (default Table II's initial pose): the base
    at the origin, the arm solved by the RPY pose task alone (base pinned) from ``q_dex`` — the
    paper does not give its initial joint angles."""
    stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping=0.01,
                      mobility=np.r_[np.zeros(N_BASE), np.ones(robot.nv - N_BASE)])
    stack.add(RpyPoseTask(robot, "ee", 10.0, name="ee"))
    controller = wbc.Controller(robot, stack, dt=0.01, missing_limits="ignore")  # a plain IK
    q = np.concatenate([np.zeros(robot.nq - Q_DEX.size), Q_DEX])
    for _ in range(500):
        q = robot.integrate(q, controller.step(q, ee=pose), 0.01)
    error = np.abs(pose_error(robot.frame_pose(q, "ee"), pose)).max()
    if error > 1e-6:
        raise wbc.WbcError(f"initial configuration: pose error {error:.2e} after 500 steps")
    return q


def staging(seed: int | None) -> tuple[np.ndarray, tuple, np.ndarray]:
    """``(initial end-tip pose, pose schedule, base start offset (x [m], y [m], θ [rad]))``:
    Table II's and the origin for ``seed=None``, else the re-staging of
    :data:`RANDOM_ELEMENTS`."""
    if seed is None:
        return INITIAL_POSE.copy(), POSES, np.zeros(3)
    start_rng, target_rng = (np.random.default_rng(s)
                             for s in np.random.SeedSequence(seed).spawn(2))

    def jitter(rng, pose):
        half = np.repeat(POSE_JITTER, 3)
        return np.asarray(pose, dtype=float) + rng.uniform(-half, half)

    base = start_rng.uniform(-np.repeat(START_JITTER, (2, 1)), np.repeat(START_JITTER, (2, 1)))
    initial = jitter(start_rng, INITIAL_POSE)
    poses = tuple((start, tuple(jitter(target_rng, pose).tolist())) for start, pose in POSES)
    return initial, poses, base


def base_steering(robot, backend: str, options: StudyOptions) -> SteerableController:
    """The MPO700's steering controller with Table I's period and the swept constants (their
    defaults: :func:`wbc.papers.sorour.steering_controller`'s)."""
    def value(key):
        return options.value(key, PARAMETERS_SWEPT)

    return SteerableController(robot.base, dt=PARAMETERS["ts"],
                               steer_rate=value("steer_rate_max"),
                               steer_acceleration=value("steer_acceleration_max"),
                               icr_gain=value("icr_gain"), drive_gain=value("Kp"),
                               backend=backend, fused=RUN_PATH)


class SteeredJoints:
    """The study's controller on the MuJoCo plant's ``"joints"`` command.

    Each tick it runs the whole-body controller, feeds its base twist ``(v_x [m/s], v_y [m/s],
    ω [rad/s])`` to ``steering`` (the paper's ICR steering and drive controller) and commands
    ``[φ̇ (4) [rad/s], β̇ (4) [rad/s], q̇_arm (7) [rad/s]]``: the steering controller's drive and
    steer rates (both in ``robot.base``'s wheel order, the plant's) and the arm's rates.

    The steering controller keeps its own steering angles (those it integrated from its rates:
    the references the plant's steer servos track); it has no input for measured angles. The
    runs record the measured ones (``"steer_angles"``) beside them.

    Attributes:
        controller: the whole-body controller (``step(q, v, ee=target)``).
        steering: the :class:`SteerableController` driving the joints.
        last_step: its :class:`~wbc.papers.sorour.SteerStep` of the last tick.
    """

    def __init__(self, controller, steering: SteerableController) -> None:
        self.controller, self.steering = controller, steering
        self.steering.reset()  # β = 0: the plant starts its steer joints at 0
        self.last_step: SteerStep | None = None

    @property
    def last_solution(self):
        return self.controller.last_solution

    def step(self, q, v=None, ee=None) -> np.ndarray:
        command = self.controller.step(q, v, ee=ee)
        self.last_step = step = self.steering.step(command[:N_BASE])
        return np.concatenate([step.drive_rates, step.steer_rates, command[N_BASE:]])


def within_joint_limits(robot, q: np.ndarray) -> np.ndarray:
    """``q`` with each arm angle moved by whole turns (2π [rad]) into its joint limits where a
    turn brings it there: the same physical pose. The IK start of :func:`initial_configuration`
    (solved without joint limits) has the LWR's joints 1 and 3 at 221° and 212°, beyond their
    ±170°. Raises :class:`wbc.WbcError` if an angle has no turn inside its limits."""
    q = q.copy()
    lower, upper = robot.limits.q_lower, robot.limits.q_upper
    for i in range(N_BASE, robot.nq):
        turned = q[i] + 2.0 * math.pi * np.arange(-2, 3)
        inside = turned[(turned >= lower[i]) & (turned <= upper[i])]
        if not inside.size:
            raise wbc.WbcError(f"start: joint {i} at {q[i]:.3f} rad has no turn within "
                               f"[{lower[i]:.3f}, {upper[i]:.3f}]")
        if not lower[i] <= q[i] <= upper[i]:
            q[i] = inside[np.argmin(np.abs(inside - q[i]))]
    return q


def floor_outline(robot, q) -> tuple[np.ndarray, np.ndarray]:
    """``(deck corners (4, 2), arm points (5, 2))`` [m] on the floor at ``q``: the deck outline
    and the arm's joints 2, 4, 6, flange and end tip."""
    c, s = math.cos(q[2]), math.sin(q[2])
    deck = DECK @ np.array([[c, s], [-s, c]]) + q[:2]
    arm = np.array([robot.frame_pose(q, f)[:2, 3] for f in ARM_FRAMES])
    return deck, arm


def arm_singular_value(robot, q) -> float:
    """Smallest singular value of the arm's columns of the end tip's RPY Jacobian at ``q``
    (the ``J_a`` eq. 14 inverts)."""
    pose = robot.frame_pose(q, "ee")
    J = rpy_jacobian(robot.frame_jacobian(q, "ee"), pose[:3, :3], q[2])
    return float(np.linalg.svd(J[:, N_BASE:], compute_uv=False)[-1])


def footprint_area(robot, q) -> float:
    """Area [m²] of the convex hull of the deck outline and the arm's joints and end tip,
    projected on the floor."""
    return float(ConvexHull(np.vstack(floor_outline(robot, q))).volume)


def simulate(robot, variant: str, backend: str, q0: np.ndarray, seconds: float,
             options: StudyOptions = DOCUMENTED, poses=POSES):
    """One run of ``variant`` from ``q0`` for ``seconds`` [s] towards the schedule ``poses`` on
    the plant of ``options`` (the steering constants from its ``params``)."""
    tolerance = options.value("daqp_primal_tol", PARAMETERS_SWEPT)
    controller = SorourController(
        robot, variant, backend, fused=RUN_PATH,
        compensation_damping=options.value("compensation_damping", PARAMETERS_SWEPT),
        qp_options={"primal_tol": tolerance} if backend == "daqp" else None)
    # its next-sample prediction (eq. 14) must use the base's steering constants
    controller.steering = base_steering(robot, backend, options)

    def errors(tick):
        e = pose_error(tick.robot.frame_pose(tick.q, "ee"), tick.references["ee"])
        return np.array([np.linalg.norm(e[:3]), np.linalg.norm(e)])

    signals = {"errors": errors, "psi": lambda tick: controller.psi,
               # the arm's rates are the command's last entries on both plants' commands
               "arm_rate_max": lambda tick: float(np.abs(tick.command[N_BASE - robot.nv:]).max()),
               "stack_s": lambda tick: controller.tick_parts["stack"],
               "compensation_s": lambda tick: controller.tick_parts["compensation"]}
    # the paper's wheels: each contact beside its steer axis (its inverse actuation model)
    plant = make_plant(robot, options, steer_offset="sideways")
    if plant is None:
        drive = SteerableDrive(base_steering(robot, backend, options))
        sim = Simulation(robot, controller, dt=PARAMETERS["ts"], actuation=[drive],
                         signals=signals)
    else:
        joints = SteeredJoints(controller, base_steering(robot, backend, options))

        def steer_angles(tick):  # measured at the tick's end (signals are read after the step)
            return np.array([plant.data.joint(name).qpos[0] for name in plant.mjcf.steer_joints])

        def last() -> SteerStep:  # the steering controller's tick (signals follow a step)
            assert joints.last_step is not None
            return joints.last_step

        signals.update(
            steer_rate_max=lambda tick: float(np.abs(last().steer_rates).max()),
            steer_acceleration_max=lambda tick: float(np.abs(last().steer_accelerations).max()),
            icr_qp_s=lambda tick: last().qp_s,
            steer_angles=steer_angles,
            steer_reference=lambda tick: last().steering)
        sim = Simulation(robot, joints, dt=PARAMETERS["ts"], command="joints", plant=plant,
                         signals=signals)
    return sim.run(seconds=seconds, q0=q0, references=lambda t: {"ee": target_at(t, poses)})


def series(robot, run) -> dict:
    """The JSON series of one run, with the quantities the claims use (``"arm_rate_max"`` the
    largest commanded arm rate [rad/s] per tick, ``"arm_sigma_min"`` :func:`arm_singular_value`
    at ``"footprint_t"`` (every 0.1 s, as the footprint), ``"arm_q_range"`` each arm joint's
    smallest and largest angle [rad], ``"snapshots"`` the floor outlines at :data:`SNAPSHOTS`);
    on MuJoCo also what only physics gives: per tick the wheels' slip speed [m/s], normal
    forces [N], largest actuator saturation share [-], the odometry error of the base's position
    [m] and heading [rad], and the measured and commanded steering angles [rad]."""
    every = max(1, int(round(0.1 / run.dt)))  # footprint every 0.1 s
    out = run.series(["t", "base_velocity", "tick_s", "steer_rate_max", "arm_rate_max",
                      "steer_acceleration_max", "icr_qp_s", "stack_s", "compensation_s"])
    errors = run.signals["errors"]
    out["ee_error"] = errors[:, 0].tolist()
    out["pose_error_norm"] = errors[:, 1].tolist()
    psi = run.signals["psi"]
    out["psi"] = None if np.isnan(psi).all() else psi.tolist()
    out["base_pose"] = run.q[:, :3].tolist()
    out["dexterity_distance"] = np.linalg.norm(run.q[:, N_BASE:] - Q_DEX, axis=1).tolist()
    out["arm_sigma_min"] = [arm_singular_value(robot, q) for q in run.q[::every]]
    out["arm_q_range"] = [run.q[:, N_BASE:].min(axis=0).tolist(),
                          run.q[:, N_BASE:].max(axis=0).tolist()]
    out["snapshots"] = []
    for t in SNAPSHOTS:
        if t <= run.t[-1]:
            deck, arm = floor_outline(robot, run.q[int(np.argmin(np.abs(run.t - t)))])
            out["snapshots"].append({"t": t, "deck": deck.tolist(), "arm": arm.tolist()})
    out["footprint_t"] = run.t[::every].tolist()
    out["footprint_area"] = [footprint_area(robot, q) for q in run.q[::every]]
    if "plant_step_s" in run.signals:
        out.update(run.series(["wheel_slip", "normal_forces", "plant_step_s", "steer_angles",
                               "steer_reference"]))
        out["saturation_max"] = run.signals["saturation"].max(axis=1).tolist()
        out["odometry_error"] = np.linalg.norm(run.q_est[:, :2] - run.q[:, :2], axis=1).tolist()
        out["odometry_heading_error"] = (run.q_est[:, 2] - run.q[:, 2]).tolist()
    return out


def _intervals(t_end: float):
    """``(k, start, end)`` of the pose intervals within ``[0, t_end]``."""
    ends = [s for s, _ in POSES[1:]] + [DURATION]
    return [(k, s, min(e, t_end)) for k, ((s, _), e) in enumerate(zip(POSES, ends, strict=True))
            if s < t_end]


def per_pose(s: dict, key: str, how: str) -> list[float]:
    """Per pose interval: ``"auc"`` (∫ key dt), ``"steady"``, ``"steady_max"``,
    ``"steady_min"`` (mean, largest, smallest value over its last ``STEADY_WINDOW`` s)."""
    t, y = np.asarray(s["t"]), np.asarray(s[key], dtype=float)
    dt = PARAMETERS["ts"]
    out = []
    for _, start, end in _intervals(t[-1] + dt):
        inside = (t >= start - 1e-9) & (t < end - 1e-9)
        if how == "auc":
            out.append(float(y[inside].sum() * dt))
        else:
            window = y[inside & (t >= end - STEADY_WINDOW - 1e-9)]
            out.append(float(window.mean() if how == "steady" else
                             window.max() if how == "steady_max" else window.min()))
    return out


def claims(runs: dict, parameters: dict = PARAMETERS) -> list[Claim]:
    """The claims from the runs' series (``parameters``: Table I with the swept constants the
    runs used; the steer limits the last two claims check)."""
    pinv, prop, comp = (runs[v] for v in VARIANTS)
    rate, accel = parameters["steer_rate_max"], parameters["steer_acceleration_max"]
    out = []

    def window_mean(s, key, t_max=FOOTPRINT_WINDOW, tkey="t"):
        t, y = np.asarray(s[tkey]), np.asarray(s[key], dtype=float)
        return float(y[t < t_max].mean())

    far = [0, 4] if len(per_pose(pinv, "pose_error_norm", "auc")) == 5 else [0]
    auc = {v: per_pose(runs[v], "pose_error_norm", "auc") for v in VARIANTS}
    faster = all(auc["pinv"][k] < min(auc["proposed"][k], auc["compensated"][k]) for k in far)
    out.append(Claim(
        "pinv_faster_far", "the pseudo-inverse (eq. 8) converges faster on the far poses "
        "(area under ||e_p|| smaller)", "yes (Fig. 6)",
        {v: [round(auc[v][k], 3) for k in far] for v in VARIANTS}, faster,
        f"area under the pose-error norm [m·s, rad·s] over the far poses {[k + 1 for k in far]}"))
    area = {v: window_mean(runs[v], "footprint_area", tkey="footprint_t") for v in VARIANTS}
    out.append(Claim(
        "pinv_larger_footprint", "the pseudo-inverse moves with a larger footprint while "
        "travelling to the first pose", "yes (Fig. 5)", {v: round(a, 3) for v, a in area.items()},
        area["pinv"] > max(area["proposed"], area["compensated"]),
        "footprint = area [m²] of the convex hull of the deck outline and the arm's joints 2, 4, "
        "6, flange and end tip projected on the floor, averaged over the first 20 s"))
    dex = {v: window_mean(runs[v], "dexterity_distance") for v in VARIANTS}
    out.append(Claim(
        "pinv_less_dexterous", "the pseudo-inverse keeps the arm farther from q_dex",
        "yes (Fig. 5)", {v: round(d, 3) for v, d in dex.items()},
        dex["pinv"] > max(dex["proposed"], dex["compensated"]),
        "mean ||q_a − q_dex|| [rad] over the first 20 s"))
    steady = {v: per_pose(runs[v], "pose_error_norm", "steady") for v in VARIANTS[1:]}
    out.append(Claim(
        "compensation_lowers_steady_error", "arm compensation (eq. 14) lowers the steady-state "
        "error at every pose", "significantly smaller (Fig. 7)",
        {v: [float(f"{e:.3g}") for e in steady[v]] for v in steady},
        all(c < p for c, p in zip(steady["compensated"], steady["proposed"], strict=True)),
        f"mean ||e_p|| over the last {STEADY_WINDOW:g} s of each pose interval"))
    out.append(Claim(
        "compensation_lowers_auc", "arm compensation lowers the area under the error curve at "
        "every pose", "yes (Fig. 6 numbers)",
        {v: [round(a, 3) for a in auc[v]] for v in VARIANTS[1:]},
        all(c < p for c, p in zip(auc["compensated"], auc["proposed"], strict=True)),
        "area under ||e_p|| [m·s, rad·s] per pose interval"))
    for v in VARIANTS[1:]:
        worst = per_pose(runs[v], "pose_error_norm", "steady_max")
        lowest_psi = per_pose(runs[v], "psi", "steady_min")
        out.append(Claim(
            f"psi_one_at_convergence_{v}", f"every pose is reached, with only the arm moving "
            f"(ψ = 1) there ({v})", "yes (Fig. 7)",
            {"max_error": [float(f"{e:.3g}") for e in worst], "min_psi": lowest_psi},
            all(e <= CONVERGED for e in worst) and all(p == 1.0 for p in lowest_psi),
            f"per pose over the last {STEADY_WINDOW:g} s of its interval: the largest ||e_p|| "
            f"[m, rad] (reached: <= {CONVERGED:g}, our criterion) and the smallest ψ"))
        t, psi = np.asarray(runs[v]["t"]), np.asarray(runs[v]["psi"])
        inside = (t >= POSES[1][0]) & (t < POSES[3][0])
        if inside.any():
            out.append(Claim(
                f"psi_one_poses_2_3_{v}", f"ψ = 1 throughout the second and third poses ({v})",
                "yes (Fig. 7)", float(np.mean(psi[inside] == 1.0)),
                bool(np.all(psi[inside] == 1.0)), "share of the ticks in [20, 35[ s with ψ = 1"))
    worst_rate = max(max(runs[v]["steer_rate_max"]) for v in VARIANTS)
    out.append(Claim(
        "steer_rate_limit", "steer-rate limits are never exceeded", f"β̇max (ours: {rate} rad/s)",
        round(worst_rate, 6), worst_rate <= rate * (1 + 1e-4),
        "max |β̇| [rad/s] over every tick of the three runs (1e-4 relative: the QP's tolerance)"))
    accels = np.concatenate([runs[v]["steer_acceleration_max"] for v in VARIANTS])
    over = int(np.sum(accels > accel * (1 + 1e-4)))
    out.append(Claim(
        "steer_acceleration_limit", "steer-acceleration limits are never exceeded",
        f"β̈max (ours: {accel} rad/s²)", {"ticks_over": over, "max": round(float(accels.max()), 3)},
        over == 0, "ticks above β̈max: the ICR QP keeps the acceleration cones soft (least "
        "violation) when the four wheels cannot all keep them at once",
        missing="" if over == 0 else "a steering controller that keeps the acceleration cones "
        "when the four wheels' cones share no point (§IV states them as constraints of the "
        "ICR QP, whose two unknowns cannot meet eight of them in general; ours relaxes them)"))
    return out


def timing(robot, states: list, backends, budget_s: float) -> tuple[dict, list[str]]:
    """Full tick (eq. 9 stack + ICR QP + eq. 14 QP) of the compensated controller per backend,
    replayed over ``states`` (``(q, target)`` pairs of the daqp run), at most ``budget_s`` of
    wall time per backend; ``"icr_qp_median_s"``: the steering controller's share
    (``tick_parts["icr_qp"]``; on the fast path the one generated call after the stack). daqp's
    default (fast) controller is timed interleaved with ``fused=False`` (:func:`interleaved_timing`,
    the steering state reset before each pass), which adds ``"ordinary_tick_median_s"``,
    ``"ordinary_tick_p95_s"`` and ``"max_command_difference"``. Returns the timing table and
    the backends that failed."""
    def icr_qp(control: SorourController) -> float:
        return control.tick_parts["icr_qp"]

    others = [backend for backend in backends if backend != "daqp"]
    timings, failures = replay_timing(
        others, lambda backend: SorourController(robot, "compensated", backend), states,
        lambda control, state: control.step(state[0], ee=state[1]), budget_s,
        ("icr_qp_median_s", icr_qp))
    if "daqp" in backends:
        daqp = interleaved_timing(SorourController(robot, "compensated"),
                                  SorourController(robot, "compensated", fused=False),
                                  [(q, None, {"ee": target}) for q, target in states],
                                  budget_s=budget_s, share=icr_qp,
                                  reset=lambda control: control.steering.reset())
        daqp["icr_qp_median_s"] = daqp.pop("qp_median_s")
        timings = {"daqp": daqp, **timings}
    return timings, failures


def figures(runs: dict, out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for ax, v in zip(axes, VARIANTS, strict=True):
        ax.plot(runs[v]["t"], runs[v]["pose_error_norm"], label=v)
        top = max(runs[v]["pose_error_norm"])
        # Fig. 6's numbers: the area under the curve per pose interval
        for (_, start, end), area in zip(_intervals(runs[v]["t"][-1] + PARAMETERS["ts"]),
                                         per_pose(runs[v], "pose_error_norm", "auc"),
                                         strict=True):
            ax.axvline(start, color="0.7", lw=0.8)
            ax.text((start + end) / 2, 0.8 * top, f"{area:.2f}", ha="center", fontsize=8)
        ax.set_ylabel(f"{v}\n||e_p|| [m, rad]")
        ax.set_xlabel("time [s]")
        ax.grid(True)
        ax.legend(loc="upper right")
    fig.suptitle("Pose error norm per variant (numbers: area under the curve per pose "
                 "[m·s, rad·s])")
    names.append(save_figure(fig, out_dir / "sorour_error.png"))
    fig, axes = plt.subplots(2, 3, figsize=(13, 8))
    for ax, v in zip(axes[0], VARIANTS, strict=True):  # Fig. 5: snapshots from above
        for k, snap in enumerate(runs[v]["snapshots"]):
            deck, arm = np.asarray(snap["deck"]), np.asarray(snap["arm"])
            color = plt.get_cmap("viridis")(k / max(1, len(runs[v]["snapshots"]) - 1))
            ax.fill(deck[:, 0], deck[:, 1], color=color, alpha=0.25)
            ax.plot(arm[:, 0], arm[:, 1], "o-", color=color, ms=3,
                    label=f"t = {snap['t']:.0f} s")
        ax.set_aspect("equal")
        ax.set_title(f"{v}: deck and arm from above")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    axes[0][0].legend(fontsize=7)
    end = POSES[3][0]  # the first four poses
    for v in VARIANTS:
        t = np.asarray(runs[v]["footprint_t"])
        axes[1][0].plot(t[t < end], np.asarray(runs[v]["footprint_area"])[t < end], label=v)
        t = np.asarray(runs[v]["t"])
        axes[1][1].plot(t[t < end], np.asarray(runs[v]["dexterity_distance"])[t < end], label=v)
        axes[1][2].semilogy(runs[v]["footprint_t"], runs[v]["arm_sigma_min"], label=v)
    for ax, label in zip(axes[1], ("footprint [m²]", "||q_a − q_dex|| [rad]",
                                   "σ_min of J_a [-]"), strict=True):
        ax.set_xlabel("time [s]")
        ax.set_ylabel(label)
        ax.grid(True)
        ax.legend(fontsize=7)
    fig.suptitle("Footprint and posture (Fig. 5): the travel to the first pose, the first four "
                 "poses, the arm's conditioning")
    names.append(save_figure(fig, out_dir / "sorour_footprint.png"))
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for v in VARIANTS[1:]:
        axes[0].plot(runs[v]["t"], runs[v]["pose_error_norm"], label=v)
        axes[1].plot(runs[v]["t"], runs[v]["psi"], label=v)
    axes[0].set_ylim(0, 0.3)
    axes[0].set_ylabel("||e_p|| [m, rad]")
    axes[0].set_xlabel("time [s]")
    axes[0].legend()
    axes[1].set_ylabel("ψ [-]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend()
    fig.suptitle("Task sharing: pose error and ψ")
    names.append(save_figure(fig, out_dir / "sorour_psi.png"))
    fig, ax = plt.subplots(figsize=(6, 5))
    for v in VARIANTS:
        pose = np.asarray(runs[v]["base_pose"])
        ax.plot(pose[:, 0], pose[:, 1], label=v)
    ax.set_xlabel("base x [m]")
    ax.set_ylabel("base y [m]")
    ax.set_aspect("equal")
    ax.set_title("Base path per variant")
    ax.legend()
    names.append(save_figure(fig, out_dir / "sorour_base_path.png"))
    plt.close("all")
    return names


SUMMARY = """\
**Model.** `mpo700_lwr4`; the arm's initial joint angles are not given: they are solved so that
the end tip starts at Table II's initial pose (base at the origin, from q_dex). Table I's
parameters; the pose task is eq. 12's `λ_p ᵇT_w e_p` on the analytic RPY Jacobian
(`wbc.tasks.RpyPoseTask`, rows `ᵇT_w M_RPY J_w`: an exact first-order loop), ψ from eq. 11
with eq. 10 read as a mobility (erratum: ψ = 1 moves the arm only), the dexterous posture in
the exact weighted null-space form. The arm has the KUKA LWR 4+'s joint limits, which the
paper's formulation lacks (positions ±170° / ±120°, velocities 110–204 °/s:
`wbc.robots.kuka_lwr4`), as hard bounds of every level (position limits approached with gain
0.5) and as the saturation of the compensated command. The IK start has joints 1 and 3 at 221°
and 212°, beyond ±170°: the arm starts a turn lower, at the same pose; the posture error
`q_a − q_dex` is taken within the limits (not wrapped: the wrapped error would drive joints 1
and 3 through their limits). Eq. 14 uses the damped pseudo-inverse with μ = ρ = 0.001 (Table I;
§II: the damped pseudo-inverse "for redundancy resolution in the sequel").

**Base.** The commanded base twist goes through Sorour's steering controller
(`wbc.papers.sorour.steering`): ICR of the twist, direct or complementary route (±X of the
homogeneous ICR), ICR velocity controller (λ = 10 1/s, our choice), next-sample ICR as a QP
with two cone constraints per steer joint (rates hard, accelerations soft), drive controller
(K_p = 2) projected on the next ICR's twist and scaled into the MPO700's twist limits
(0.9 m/s, 0.9 m/s, 1 rad/s), wheel rates by the inverse actuation model. The base moves at that
feasible twist. The base reference q̇_ref(b) of eq. 9 is scaled uniformly into the same limits
before it reaches the base controller and eq. 14 (our decision: at gross motion eq. 12 asks
for up to 1.7 × 5 m/s, and eq. 14 would hand the unreachable remainder to the arm).
β̇max = 1 rad/s and β̈max = 3 rad/s² are estimates (no data
sheet values available offline).

**Claims.** Every number is computed from the runs; footprint and dexterity are defined in the
claims' notes. The paper gives its per-pose areas only in a figure (not in the text): we
compare the variants with each other, not with the paper's numbers.
"""


def arm_summary(runs: dict) -> str:
    """The arm's commanded rates, conditioning and joint range per variant (markdown)."""
    rows = []
    for v in VARIANTS:
        s = runs[v]
        sigma = np.asarray(s["arm_sigma_min"])
        low, high = (np.asarray(b) for b in s["arm_q_range"])
        rows.append(f"| {v} | {max(s['arm_rate_max']):.3g} | {sigma.min():.3g} at "
                    f"{s['footprint_t'][int(np.argmin(sigma))]:.1f} s | "
                    + ", ".join(f"[{a:.2f}, {b:.2f}]" for a, b in zip(low, high, strict=True))
                    + " |")
    return "\n".join([
        "", "**Arm.** Largest commanded arm rate, smallest singular value of J_a (eq. 14's "
        "arm Jacobian, sampled every 0.1 s) and each arm joint's range over the run:", "",
        "| variant | largest arm rate [rad/s] | min σ(J_a) | joint ranges [rad] |",
        "|---|---:|---|---|",
        *rows, ""])


def plant_summary(runs: dict) -> str:
    """What the MuJoCo plant changed, with the numbers of the runs (markdown)."""
    dt = PARAMETERS["ts"]
    rows = []
    for v in VARIANTS:
        s = runs[v]
        slip = np.asarray(s["wheel_slip"])
        angles = np.asarray(s["steer_angles"])
        rates = np.diff(angles, axis=0) / dt
        accelerations = np.abs(np.diff(rates, axis=0)).max() / dt if len(rates) > 1 else 0.0
        tracking = np.abs(angles - np.asarray(s["steer_reference"])).max()
        rows.append(f"| {v} | {1e3 * slip.mean():.1f} | {1e3 * slip.max():.0f} | "
                    f"{1e3 * s['odometry_error'][-1]:.0f} | "
                    f"{math.degrees(abs(s['odometry_heading_error'][-1])):.2f} | "
                    f"{math.degrees(tracking):.2f} | {np.abs(rates).max():.2f} | "
                    f"{accelerations:.1f} | {100 * max(s['saturation_max']):.0f} |")
    return "\n".join([
        "", "**Plant: MuJoCo.** The kinematic plant's `SteerableDrive` is dropped: there the base "
        "moved exactly at the steering controller's feasible twist (the wheels assumed to track "
        "their rates: no servo lag, no slip, exact odometry). Here a copy of the same steering "
        "controller (`SteeredJoints`) sends its steer rates β̇ and drive rates φ̇ to the MPO700's "
        "steer and drive joint servos (integrating velocity servos, 10 Hz, torque-limited), the "
        "base moves as its four wheels on the floor make it, and the controller is given wheel "
        "odometry, while the claims use the true pose. Servo lag, wheel slip and odometry drift "
        "now come from physics. The wheels are the paper's: each contact sits beside its steer "
        "axis by d = 0.045 m (its inverse actuation model r φ̇ = f(β) ξ + d β̇ asks for that "
        "geometry; `MujocoPlant(steer_offset='sideways')`), not behind it as the library's "
        "caster model `wbc.robots.SteerableBase` has them; the steering and drive rates of the "
        "paper's controller are then consistent with the wheels, and slip comes from dynamics "
        "(servo lag, inertia, load transfer), not from a geometric mismatch. "
        "The steering controller keeps its own steering angles (it has no input for measured "
        "ones). Since the claims use the true pose and the controller converges on its "
        "odometry, the odometry drift (slip while turning, above all the heading) shows as "
        "steady pose error, and the position error can stay above r_fm (ψ < 1).", "",
        "| variant | mean slip [mm/s] | max slip [mm/s] | final odometry error [mm] | "
        "final heading error [°] | max steer tracking error [°] | max measured β̇ [rad/s] | "
        "max measured β̈ [rad/s²] | max saturation [%] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|", *rows, ""])


def run(backend: str, out_dir: Path, quick: bool,
        options: StudyOptions = DOCUMENTED) -> StudyResult:
    options.check(PARAMETERS_SWEPT)
    parameters = {**PARAMETERS, **{k: options.value(k, PARAMETERS_SWEPT)
                                   for k in PARAMETERS_SWEPT}}
    robot = load("mpo700_lwr4")
    initial_pose, poses, base_start = staging(options.seed)
    q0 = initial_configuration(robot, initial_pose)
    q0[:3] += base_start
    q0 = within_joint_limits(robot, q0)
    seconds = 10.0 if quick else DURATION
    runs, states, simulated_runs = {}, [], []
    replays: dict[str, Recording] = {}
    for v in VARIANTS:
        simulated = simulate(robot, v, backend, q0, seconds, options, poses)
        simulated_runs.append(simulated)
        runs[v] = series(robot, simulated)
        if options.main_only:
            continue
        replays[f"table_ii/{v}"] = Recording.from_run(
            simulated, target=np.array([target_at(t, poses)[:3] for t in simulated.t]),
            robot="mpo700_lwr4")
        if v == "compensated":
            every = max(1, len(simulated.t) // 200)
            states = [(q, target_at(t, poses)) for q, t in zip(simulated.q[::every],
                                                               simulated.t[::every], strict=True)]
    summary = SUMMARY + arm_summary(runs) + (
        plant_summary(runs) if options.plant == "mujoco" else "")
    timings: dict = {}
    failures: list[str] = []
    names: list[str] = []
    if not options.main_only:
        backends = [backend] if quick else available_backends()
        timings, failures = timing(robot, states, backends, 0.5 if quick else 2.0)
        summary += "\n".join(
            ["", "The steering controller's share (its ICR QP; on daqp's fast path the one "
             "generated call after the stack: steering, ψ and eq. 14), median over the "
             "replayed ticks:", "", "| backend | ICR QP median [µs] |", "|---|---:|"]
            + [f"| {b} | {1e6 * t['icr_qp_median_s']:.1f} |" for b, t in timings.items()])
        if "daqp" in timings:
            t = timings["daqp"]
            summary += (
                f"\n\ndaqp, interleaved over the same states: the default (fast) path "
                f"{1e6 * t['tick_median_s']:.1f} µs median (p95 {1e6 * t['tick_p95_s']:.1f}), "
                f"the ordinary path (`fused=False`) {1e6 * t['ordinary_tick_median_s']:.1f} µs "
                f"(p95 {1e6 * t['ordinary_tick_p95_s']:.1f}): "
                f"{t['tick_median_s'] / t['ordinary_tick_median_s']:.2f}×; commands at most "
                f"{t['max_command_difference']:.1e} apart (each controller carries its "
                "steering state and warm starts through the replay: on a near-tie the fast "
                "path hands over, and the two ordinary daqp solves, warm-started from "
                "different histories, may stop on different vertices within daqp's tolerance — "
                "tests/test_sorour_fast.py compares tick by tick from cold starts). The runs "
                "above use the ordinary path (see the study's docstring).\n")
        names = figures(runs, Path(out_dir))
    return StudyResult(
        name="sorour", claims=claims(runs, parameters), runs={"table_ii": runs},
        timing=timings, figures=names, summary_md=summary, failures=failures,
        parameters={**parameters, "q_dex": Q_DEX.tolist(), "initial_pose": initial_pose.tolist(),
                    "poses": [[s, list(p)] for s, p in poses], "duration_s": seconds,
                    "q0": q0.tolist(), "backend": backend},
        replays=replays, robot="mpo700_lwr4", options=options,
        plant_timing=plant_timing(options, 0.0, simulated_runs))


def main(argv=None) -> int:
    return study_main("sorour", run, argv)


if __name__ == "__main__":
    raise SystemExit(main())
