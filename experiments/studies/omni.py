"""``wbc study omni``: the omni platform's slip experiments (torque-redundancy paper, §4), rerun
in simulation with position control and with force control under three torque distributions.

Plant: ``"omni4_arm6"`` driven through :class:`wbc.papers.omni.dynamics.OmniDynamics` — a
planar rigid body of 45 kg (the paper's 15 kg platform + 30 kg arm), wheel rotors, per-wheel
Coulomb friction with normal forces from the whole system's centre of mass, servo gain errors,
torque noise and wheel radius errors (values in :data:`PARAMETERS`). The arm swings its
shoulder during every run, so its centre of mass — and with it the load on each wheel — moves.

Scenarios (the paper's §4): ``"y"`` — 40 cm along the world y axis; ``"diagonal"`` — along the
line x = y up to x = y = 40 cm (56.6 cm). The platform starts at heading 45° so that, as in the
paper, the y motion needs only two wheels (wheels 1 and 3 roll along y, wheels 0 and 2 along
x) and the diagonal needs all four (the paper's Fig. 5 is not in its text; this is the wheel
layout its "just two motors were used" implies for our wheel placement).

Regimes (:data:`REGIMES`, fixed before the runs): ``"paper_speed"`` — the paper's experiments,
"at a constant speed": a trapezoid of 0.1 m/s with 0.25 m/s² ramps (2 cm each: constant speed
over 90 % of the way; the paper gives no speed, this is our estimate of a slow laboratory run);
the position-control anchors are measured there. ``"binding"`` — the study's main regime, twice
as fast with the same ramp length (0.2 m/s, 1 m/s²; ``--param speed_m_s`` /
``acceleration_m_s2``), where the lightly loaded wheels reach their friction limit, without
which no distribution matters. Runs of the binding regime are keyed by the scenario (``"y"``,
``"diagonal"``), those of the paper's by ``"<scenario>_paper_speed"``.

Methods: ``"position"`` — eqs. 3–4, wheel angle increments from the odometry pose tracked by
the wheels' PID servos; ``"position_reference"`` — the other reading of eq. 3's "present
position" (the previous reference: absolute wheel angle trajectories, no pose feedback; see
:class:`wbc.robots.OmniPositionControl`); in ``"y"`` both power only the two motors the motion
needs, the others roll freely, as in the paper's first experiment; ``"min_norm"``,
``"proportional"``, ``"minmax"`` — eq. 6 force control whose platform force is distributed
over the four wheels by the distribution's QP stack (:class:`wbc.tasks.TorqueDistribution`) on
the chosen backend, with the statics' normal forces; ``"proportional_ratios"`` — the other
reconstruction of eq. 12's H (the closed form, ``criterion="ratios"``: the friction
utilisations most nearly equal, the maximising root of a quadratic equation in α; see
:mod:`wbc.papers.omni.closed_form`); ``"proportional_load_transfer"`` — the proportional
QP fed normal forces that include the load transfer of the commanded acceleration
(``OmniForceControl(com_height=...)``) for a centre-of-mass height the controller believes
``1 + com_height_error`` times the true one (−20 %: our estimate of how well the height of an
assembled robot's centre of mass is known without weighing it; low, the direction in which the
controller under-predicts the transfer) — the controller-model mismatch of the MuJoCo runs.

On MuJoCo (``--plant mujoco``, :class:`wbc.sim.MujocoPlant` with the floor's friction μ) the same
controllers drive the physics model's wheels with their 12 passive rollers each:
OmniDynamics is dropped — slip, normal forces and odometry error come from the rollers' real
contacts. Force control commands the wheel torques (``command="torque"``) followed by the arm's
swing rates; the servo gain errors and torque noise are kept as a perturbation of those
commanded torques (:class:`_TorqueCommand`); the wheel radius errors have no counterpart (the
model's wheels have the nominal radius). Position control commands wheel rates
(``command="joints"``: Δθ / dt) to the plant's own wheel servos, which replace eq. 4's PID —
their angle references restart at the wheels' present angles each period for ``"position"``
(``wheel_targets="present"``: eq. 3's increments from the present angle) and integrate into
absolute angle trajectories for ``"position_reference"``; in ``"y"`` wheels 0 and 2 have no
actuator (``passive_wheels``) and roll freely. No servo errors there (the servo is the plant's).

Per scenario and method the runs hold ``"t"`` [s], ``"base_velocity"`` (N, 3) [m/s, m/s, rad/s]
(true body twist), ``"ee_error"`` [m] — here the platform's true position error to its target
(this robot's study is about the platform, not the end effector) —, ``"odometry_error"`` [m]
(true position minus odometry), ``"slip"`` (N, 4) [m] — each wheel's cumulative slip distance —,
``"friction_utilisation"`` (N, 4) (the contact forces', peak per tick),
``"planned_utilisation"`` (N, 4) (force control: the commanded torques' ``|τ_i| / (μ f_i r)``),
``"normal_forces"`` (N, 4) [N] (the plant's), ``"wheel_torque"`` (N, 4) [N m], ``"base_pose"`` and
``"odometry_pose"`` (N, 3); on MuJoCo also ``"wheel_saturation"`` (N, 4) (the fraction of each
tick a powered wheel's motor was at its torque limit) and ``"base_tilt"`` (N,) [rad].

Criteria (fixed from the paper's statements before the results; :func:`claims`): a numeric
anchor of the paper holds when ours has its sign and lies within a factor
:data:`ANCHOR_FACTOR` of it; an anchor the model cannot reach, for want of the mechanism behind
it, is classified "not reproducible with this model" (``holds`` false, the mechanism missing in
the note, :data:`MISSING_MECHANISM`). One distribution positions (or localises) better than
another when its final error is smaller by at least :data:`RESOLUTION_M` (1 mm: the paper
quotes positions to 0.1 cm); slip comparisons are strict beyond :data:`SLIP_ROUND_OFF_M`
(1 µm; the paper measures no slip).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

import wbc.robots as robots
from wbc.papers.omni import OmniDynamics, OmniForceControl, OmniPositionControl, TorqueDistribution
from wbc.papers.omni import closed_form as ref
from wbc.robots.omni import OmniBase
from wbc.sim import Simulation
from wbc.solvers import available_backends
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

__all__ = ["METHODS", "PARAMETERS", "PARAMETERS_SWEPT", "RANDOM_ELEMENTS", "SCENARIOS", "main",
           "run", "simulate"]

#: every value the study chose (the paper gives none of them except the masses and geometry).
PARAMETERS: dict[str, Any] = {
    "dt_s": 0.01,  # control period; the servos run at 1 ms inside (10 sub-steps)
    "substeps": 10,
    "mu": 0.3,  # wheel-floor friction coefficient (hard omni rollers on a smooth floor)
    "speed_m_s": 0.2,  # cruise speed of the binding regime's trapezoid
    "acceleration_m_s2": 1.0,  # its acceleration / deceleration
    "settle_s": 0.8,  # time after the reference stops
    "heading_rad": math.pi / 4,
    "gain_error": [0.05, -0.05, 0.03, -0.03],  # servo torque gain errors per wheel
    "torque_noise_Nm": 0.1,  # servo torque noise (σ), per tick and wheel
    "radius_error": [0.005, -0.005, 0.003, -0.003],  # real wheel radius / nominal − 1
    "arm_pan_rad": [-math.pi / 4, math.pi / 4],  # shoulder pan swept over each run
    "paper_speed_m_s": 0.1,  # the paper's "constant speed" (an estimate; see REGIMES)
    "paper_acceleration_m_s2": 0.25,  # its ramps: 2 cm each, as the binding regime's
    "com_height_error": -0.2,  # the load-transfer controller's height belief, relative error
    "seed": 1,
    "sweep_mu": [0.2, 0.5],  # friction coefficients of the robustness sweep (full runs only)
}
#: the constants ``--param`` may change: ``KEY -> (default, description [unit])``.
PARAMETERS_SWEPT = {
    "mu": (PARAMETERS["mu"], "wheel-floor friction coefficient, of the floor and of the "
           "distributions [-]"),
    "acceleration_m_s2": (PARAMETERS["acceleration_m_s2"], "acceleration and deceleration of "
                          "the binding regime's trapezoidal reference [m/s²]"),
    "speed_m_s": (PARAMETERS["speed_m_s"], "cruise speed of the binding regime's trapezoidal "
                  "reference [m/s]"),
    "torque_noise_Nm": (PARAMETERS["torque_noise_Nm"], "servo torque noise σ per tick and wheel "
                        "[N m]"),
    "com_height_error": (PARAMETERS["com_height_error"], "relative error of the centre-of-mass "
                         "height the load-transfer controller believes (−1: the statics) [-]"),
}
#: what one ``--seed`` draws (the documented run: the fixed values of :data:`PARAMETERS`).
RANDOM_ELEMENTS = (
    "the servos' torque gain errors, uniform in ±5 % per wheel (the documented run's largest); "
    "the wheel radius errors, uniform in ±0.5 % per wheel (kinematic plant only: MuJoCo's wheels "
    "have the nominal radius); the seed of the per-tick torque noise (σ = torque_noise_Nm). One "
    "draw per study run, shared by all its runs (the robot's servos and wheels do not change "
    "between experiments). On MuJoCo the gain errors and the noise perturb the force "
    "controllers' commanded torques; position control there runs on the plant's own servos, "
    "without them.")
#: scenario -> (unit direction in the world, distance [m]); the paper's Fig. 6 and Fig. 7.
SCENARIOS = {"y": (np.array([0.0, 1.0]), 0.40),
             "diagonal": (np.array([1.0, 1.0]) / math.sqrt(2.0), 0.40 * math.sqrt(2.0))}
#: method -> (eq. 3's present position, the servo mode) for position control.
POSITION_CONTROL = {"position": ("odometry", "angle"),
                    "position_reference": ("reference", "angle_target")}
#: the distributions' QP stacks (statics' normal forces)
DISTRIBUTIONS = ("min_norm", "proportional", "minmax")
#: the other reconstruction of eq. 12's H (closed form) and the load-transfer controller
RATIOS, LOAD_TRANSFER = "proportional_ratios", "proportional_load_transfer"
#: the force-control methods compared per regime (each claim's values, per distribution)
COMPARED = ("min_norm", "proportional", RATIOS, "minmax")
#: regime -> (the parameters of its speed and acceleration, the methods run in it)
REGIMES = {"binding": (("speed_m_s", "acceleration_m_s2"), (*COMPARED, LOAD_TRANSFER)),
           "paper_speed": (("paper_speed_m_s", "paper_acceleration_m_s2"),
                           (*POSITION_CONTROL, *COMPARED))}
METHODS = (*POSITION_CONTROL, *COMPARED, LOAD_TRANSFER)
#: a numeric anchor holds when ours lies within this factor of the paper's (same sign)
ANCHOR_FACTOR = 2.0
#: the paper's resolution of a position [m] (it quotes 37.7 cm and 8.8 cm): a smaller
#: difference between two final errors does not count as one being better
RESOLUTION_M = 0.001
#: slip distances [m] closer than this are equal (round-off: runs that never slip differ by
#: 1e-10 m)
SLIP_ROUND_OFF_M = 1e-6
#: what the model lacks to reach each anchor (fixed before the runs; the claim's note when it
#: does not hold)
MISSING_MECHANISM = {
    "two_wheel_shortfall": (
        "a sustained slip (or elastic creep) of the two driven wheels at constant speed that "
        "leaves the platform behind its odometry — e.g. the rollers' creep under the traction "
        "that drags the unpowered wheels' rollers; our contacts have no rolling resistance and "
        "no creep, the driven wheels stick at constant speed, and the only systematic errors "
        "are the ramps' slip and the ±0.5 % radius errors (kinematic plant)"),
    "four_wheel_error": (
        "what turns the servos' mutual errors into centimetres of slip on a real floor — an "
        "uneven floor (a wheel's load changing as it rolls, the slip risk the paper names), "
        "compliant rollers and their hand-over; our flat floor and rigid (or stiff) contacts "
        "let the servos absorb their errors (±5 % gain, noise, ±0.5 % radii) with millimetres "
        "of slip"),
}


def trapezoid(distance: float, speed: float, acceleration: float):
    """``s(t) -> (position [m], velocity [m/s], acceleration [m/s²])`` of a trapezoidal
    velocity profile over ``distance``, and its duration [s]."""
    ramp = speed / acceleration
    cruise = distance / speed - ramp
    duration = 2.0 * ramp + cruise

    def profile(t: float):
        if t < ramp:
            return 0.5 * acceleration * t * t, acceleration * t, acceleration
        if t < ramp + cruise:
            return 0.5 * acceleration * ramp**2 + speed * (t - ramp), speed, 0.0
        if t < duration:
            left = duration - t
            return distance - 0.5 * acceleration * left**2, acceleration * left, -acceleration
        return distance, 0.0, 0.0

    return profile, duration


def arm_swing(seconds: float, pan: tuple[float, float]):
    """The arm's joint velocities [rad/s]: the shoulder pan moves from ``pan[0]`` to ``pan[1]``
    with a half-cosine profile over ``seconds``; the other joints hold."""
    sweep = pan[1] - pan[0]

    def velocity(t: float) -> np.ndarray:
        rates = np.zeros(6)
        if t < seconds:
            rates[0] = 0.5 * sweep * math.pi / seconds * math.sin(math.pi * t / seconds)
        return rates

    return velocity


def setup(options: StudyOptions) -> dict:
    """The run's parameters: :data:`PARAMETERS` with the ``--param`` overrides and, for a seed,
    the random elements drawn from it (:data:`RANDOM_ELEMENTS`; independent streams per
    element)."""
    p = {**PARAMETERS, **{key: options.value(key, PARAMETERS_SWEPT) for key in options.params}}
    if options.seed is not None:
        gains, radii, noise = (np.random.default_rng(stream) for stream
                               in np.random.SeedSequence(options.seed).spawn(3))
        gain_bound = max(abs(e) for e in PARAMETERS["gain_error"])
        radius_bound = max(abs(e) for e in PARAMETERS["radius_error"])
        p["gain_error"] = gains.uniform(-gain_bound, gain_bound, 4).tolist()
        p["radius_error"] = radii.uniform(-radius_bound, radius_bound, 4).tolist()
        p["seed"] = int(noise.integers(2**31))
    return p


def regime_parameters(p: dict, regime: str) -> dict:
    """``p`` with the trapezoid's speed and acceleration of ``regime`` (:data:`REGIMES`)."""
    (speed, acceleration), _ = REGIMES[regime]
    return {**p, "speed_m_s": p[speed], "acceleration_m_s2": p[acceleration]}


def run_key(scenario: str, regime: str) -> str:
    """The key of a scenario's runs in ``regime``: the scenario for the binding regime, else
    ``"<scenario>_<regime>"``."""
    return scenario if regime == "binding" else f"{scenario}_{regime}"


def com_height(robot, q) -> float:
    """The true height [m] of the whole system's centre of mass above the floor in ``q``
    (:func:`wbc.robots.system_com`, the base frame on the floor; MuJoCo's model agrees within
    0.1 %)."""
    return float(robots.system_com(robot, q, frame="base")[1][2])


def start_configuration(robot, p: dict) -> np.ndarray:
    """Every run's start: at the origin, heading ``p["heading_rad"]``, the shoulder pan at the
    start of its sweep, the other arm joints neutral."""
    q0 = robot.neutral()
    q0[2], q0[3] = p["heading_rad"], p["arm_pan_rad"][0]
    return q0


def unpowered_wheels(scenario: str, method: str) -> tuple[int, ...]:
    """The wheels whose motors are off: the paper's first experiment (position control along y)
    powers only the two motors the motion needs."""
    return (0, 2) if scenario == "y" and method in POSITION_CONTROL else ()


def simulate(robot, scenario: str, method: str, backend: str = "daqp", substeps: int = 10,
             p: dict | None = None, options: StudyOptions = DOCUMENTED):
    """One run of ``method`` on ``scenario`` with the parameters ``p`` (default
    :data:`PARAMETERS`) on ``options.plant``: ``(run, references, controller)`` (a force
    controller records its torques, wrench and normal forces per tick, :class:`_Recording`)."""
    p = PARAMETERS if p is None else p
    direction, distance = SCENARIOS[scenario]
    profile, duration = trapezoid(distance, p["speed_m_s"], p["acceleration_m_s2"])
    seconds = duration + p["settle_s"]
    heading = p["heading_rad"]

    dx, dy = direction

    def references(t: float) -> dict:
        s, ds, dds = profile(t)
        return {"target": np.array([dx * s, dy * s, heading]),
                "velocity": np.array([dx * ds, dy * ds, 0.0]),
                "acceleration": np.array([dx * dds, dy * dds, 0.0])}

    arm = arm_swing(seconds, p["arm_pan_rad"])
    q0 = start_configuration(robot, p)
    controller: OmniPositionControl | _Recording
    unpowered = unpowered_wheels(scenario, method)
    position = method in POSITION_CONTROL
    if position:
        present, servo = POSITION_CONTROL[method]
        controller = OmniPositionControl(robot, present)
    elif method == RATIOS:
        controller = _Recording(OmniForceControl(robot, "proportional", p["mu"],
                                                 criterion="ratios"))
    else:
        height = (None if method != LOAD_TRANSFER
                  else (1.0 + p["com_height_error"]) * com_height(robot, q0))
        controller = _Recording(OmniForceControl(
            robot, mu=p["mu"], com_height=height, distribution=TorqueDistribution(
                robot.base.jacobian, qp_method(method), p["mu"], backend=backend)))
    if options.plant == "kinematic":
        dynamics = OmniDynamics(
            servo=servo if position else "torque", gain_error=p["gain_error"],
            torque_noise=p["torque_noise_Nm"], radius_error=p["radius_error"], mu=p["mu"],
            substeps=substeps, arm_velocity=arm,
            active=[i not in unpowered for i in range(4)] if unpowered else None)
        sim = Simulation(robot, controller, p["dt_s"], [dynamics], command="torque",
                         seed=p["seed"])
        return sim.run(seconds=seconds, q0=q0, references=references), references, controller
    # physics: the arm's swing rates follow the wheels' command; the servos for "position"
    # start each period from the wheels' present angles (eq. 3's increments)
    mujoco: _JointCommand | _TorqueCommand
    if isinstance(controller, OmniPositionControl):
        mujoco = _JointCommand(controller, p["dt_s"], absolute=present == "reference")
    else:
        mujoco = _TorqueCommand(controller, p["gain_error"], p["torque_noise_Nm"], p["seed"])
    plant = make_plant(robot, options, mu=p["mu"], passive_wheels=unpowered,
                       wheel_targets="present" if method == "position" else "integrated")
    sim = Simulation(robot, mujoco, p["dt_s"], command="joints" if position else "torque",
                     plant=plant)
    simulated = sim.run(seconds=seconds, q0=q0,
                        references=lambda t: {**references(t), "arm_velocity": arm(t)})
    return simulated, references, controller


def qp_method(method: str) -> str:
    """The distribution stack a force-control method solves (``"proportional_load_transfer"``:
    the proportional one)."""
    return "proportional" if method == LOAD_TRANSFER else method


def series(run, references, unpowered: tuple[int, ...] = ()) -> dict:
    """The JSON series of one run (module docstring); ``unpowered``: the wheels without a motor
    (MuJoCo's saturation signal has no column for them)."""
    physics = {}
    if "saturation" in run.signals:  # MuJoCo: arm joints, then the powered wheels
        powered = [i for i in range(4) if i not in unpowered]
        saturation = np.zeros((len(run.t), 4))
        saturation[:, powered] = run.signals["saturation"][:, -len(powered):]
        physics = {"wheel_saturation": saturation, "base_tilt": run.signals["base_tilt"]}
    targets = np.array([references(t)["target"][:2] for t in run.t])
    return {"t": run.t, "base_velocity": run.base_velocity,
            "ee_error": np.linalg.norm(run.q[:, :2] - targets, axis=1),
            "odometry_error": np.linalg.norm(run.q[:, :2] - run.q_est[:, :2], axis=1),
            "slip": np.cumsum(run.signals["slip_distance"], axis=0),
            "friction_utilisation": run.signals["friction_utilisation"],
            "normal_forces": run.signals["normal_forces"],
            "wheel_torque": run.signals["wheel_torque"],
            "base_pose": run.q[:, :3], "odometry_pose": run.q_est[:, :3],
            "final_true_position": run.q_final[:2], "final_odometry_position": run.q_est_final[:2],
            "status": run.status, "tick_s": run.tick_s, **physics}


def summary_numbers(s: dict, scenario: str) -> dict:
    """Per run: final odometry error [m], final distance to the goal [m], distances travelled
    along the scenario's direction [m], slip per wheel [m], peak friction utilisation per
    wheel; for force control also the distribution's planned peak utilisation, the number of
    ticks it planned above 1 and the RMS difference [N] between the normal forces it was given
    and the plant's (``s["_raw"]``)."""
    direction, distance = SCENARIOS[scenario]
    true = np.asarray(s["final_true_position"])
    odometry = np.asarray(s["final_odometry_position"])
    planned = {}
    if "planned_utilisation" in s:
        worst = np.asarray(s["planned_utilisation"]).max(axis=1)
        planned = {"planned_peak_utilisation": float(worst.max()),
                   "ticks_planned_over_1": int(np.sum(worst > 1.0)),
                   # the normal forces distributed with against the plant's
                   "belief_rms_N": float(np.sqrt(np.mean((np.asarray(s["_raw"]["forces"])
                                                         - np.asarray(s["normal_forces"])) ** 2)))}
    return {**planned, "final_odometry_error_m": float(np.linalg.norm(true - odometry)),
            "goal_error_m": float(np.linalg.norm(true - distance * direction)),
            "true_travel_m": float(true @ direction),
            "odometry_travel_m": float(odometry @ direction),
            "slip_per_wheel_m": np.asarray(s["slip"])[-1].tolist(),
            "total_slip_m": float(np.asarray(s["slip"])[-1].sum()),
            "peak_utilisation": np.asarray(s["friction_utilisation"]).max(axis=0).tolist()}


def qp_versus_closed_form(runs: dict, mu: float) -> float:
    """Largest ``|τ_QP − τ_closed form|`` [N m] over every tick of the QP distributions' runs:
    the torques the stack commanded against :func:`wbc.solvers.reference.torque_distribution`
    fed the same wrench, normal forces and friction coefficient ``mu``."""
    worst = 0.0
    for methods in runs.values():
        for method, s in methods.items():
            if "_raw" not in s or method == RATIOS:  # the ratios runs are the closed form
                continue
            raw = s["_raw"]
            for tau, wrench, forces in zip(raw["command"], raw["wrench"], raw["forces"],
                                           strict=True):
                closed = ref.torque_distribution(raw["J"], wrench, forces, mu,
                                                 qp_method(method))
                worst = max(worst, float(np.abs(tau - closed).max()))
    return worst


class _Recording:
    """Wraps a force controller to record the torques [N m] it commanded, its wrench and the
    normal forces of every tick."""

    def __init__(self, controller: OmniForceControl) -> None:
        self.controller = controller
        self.torques: list[np.ndarray] = []
        self.wrench: list[np.ndarray] = []
        self.forces: list[np.ndarray] = []

    @property
    def last_solution(self):
        return self.controller.last_solution

    def step(self, q, v, **references):
        tau = np.asarray(self.controller.step(q, v, **references), dtype=float)
        self.torques.append(tau.copy())
        self.wrench.append(self.controller.last_wrench.copy())
        self.forces.append(self.controller.last_normal_forces.copy())
        return tau


class _TorqueCommand:
    """MuJoCo's torque command from a force controller: the wheel torques as the servos produce
    them, ``(1 + gain_error_i) τ_i + σ ε_i`` (OmniDynamics' servo errors: ``ε ~ N(0, 1)`` per
    tick and wheel from ``seed``'s generator), then the arm's swing rates [rad/s] (the
    reference ``arm_velocity``)."""

    def __init__(self, controller: _Recording, gain_error, torque_noise: float,
                 seed: int) -> None:
        self.controller = controller
        self.gain = 1.0 + np.asarray(gain_error, dtype=float)
        self.torque_noise = float(torque_noise)
        self.rng = np.random.default_rng(seed)

    @property
    def last_solution(self):
        return self.controller.last_solution

    def step(self, q, v, arm_velocity, **references):
        tau = self.controller.step(q, v, **references)
        noise = self.torque_noise * self.rng.standard_normal(tau.size)
        return np.concatenate([self.gain * tau + noise, arm_velocity])


class _JointCommand:
    """MuJoCo's joints command from eq. 3's wheel angle commands: wheel rates [rad/s] — the
    increments Δθ over the period (``absolute=False``: the plant's servos start each period at
    the wheels' present angles), or the steps of the absolute angle targets (``absolute=True``:
    the servos integrate them into the targets) —, then the arm's swing rates."""

    def __init__(self, controller: OmniPositionControl, dt: float, absolute: bool) -> None:
        self.controller, self.dt, self.absolute = controller, float(dt), absolute
        self.targets = np.zeros(4)  # the last absolute wheel angle targets [rad]

    last_solution = None

    def step(self, q, v, arm_velocity, **references):
        command = np.asarray(self.controller.step(q, v, **references), dtype=float)
        if self.absolute:
            command, self.targets = command - self.targets, command
        return np.concatenate([command / self.dt, arm_velocity])


def timing(robot, states: list, backends, budget_s: float,
           mu: float = PARAMETERS["mu"]) -> tuple[dict, list[str]]:
    """Force-control tick (eq. 6 + the proportional distribution's QP, friction coefficient
    ``mu``) per backend, replayed on ``states`` (``(q, v, references)`` of the daqp runs), at
    most ``budget_s`` per backend; ``"qp_median_s"``: the distribution's share (assembly + QP
    solve). Each backend's controller is the default one (the fast path,
    :class:`OmniForceControl`'s ``fused``); daqp's is timed interleaved with the ordinary path
    (:func:`interleaved_timing`), which adds ``"ordinary_tick_median_s"`` and
    ``"ordinary_tick_p95_s"``."""
    def controller(backend, fused="auto"):
        distribution = TorqueDistribution(robot.base.jacobian, "proportional", mu,
                                          backend=backend, fused=fused)
        return OmniForceControl(robot, mu=mu, distribution=distribution, fused=fused)

    others = [backend for backend in backends if backend != "daqp"]
    timings, failures = replay_timing(others, controller, states, _tick, budget_s,
                                      ("qp_median_s", _qp_seconds))
    if "daqp" in backends:
        timings = {"daqp": interleaved_timing(controller("daqp"), controller("daqp", False),
                                              states, budget_s=budget_s, share=_qp_seconds),
                   **timings}
    return timings, failures


def _tick(control: OmniForceControl, state: tuple) -> None:
    """One force-control tick on a recorded ``(q, v, references)``."""
    control.step(state[0], state[1], **state[2])


def _qp_seconds(control: OmniForceControl) -> float:
    """The last tick's distribution share [s] (assembly + QP solve)."""
    return control.last_solution.timings.total


#: the paper's two position-control results: (distance [m], the true end [m] or the final error
#: [m]) — 37.7 cm reached of 40 cm along y, 8.8 cm of error after 56.6 cm along x = y
PAPER_TWO_WHEELS = (0.40, 0.377)
PAPER_FOUR_WHEELS = (0.40 * math.sqrt(2.0), 0.088)


def _anchor(claim_id: str, statement: str, paper: str, ours: dict, ratio: float,
            criterion: str) -> Claim:
    """A claim on one of the paper's numbers: holds when ``ratio`` (ours over the paper's, the
    sign included) lies within :data:`ANCHOR_FACTOR`; otherwise classified "not reproducible
    with this model", with the mechanism the model lacks (:data:`MISSING_MECHANISM`)."""
    held = 1.0 / ANCHOR_FACTOR <= ratio <= ANCHOR_FACTOR
    note = (f"{criterion}; holds within a factor {ANCHOR_FACTOR:g} of the paper's, same sign "
            f"(ours / paper = {ratio:.2f})")
    missing = "" if held else MISSING_MECHANISM[claim_id.removesuffix("_reference")]
    return Claim(claim_id, statement, paper, ours, held, note, missing)


def _position_claims(numbers: dict, method: str, suffix: str, reading: str) -> list[Claim]:
    """The paper's two position-control experiments at its speed, for one reading of eq. 3."""
    two = numbers[run_key("y", "paper_speed")][method]
    four = numbers[run_key("diagonal", "paper_speed")][method]
    distance, reached = PAPER_TWO_WHEELS
    shortfall = two["odometry_travel_m"] - two["true_travel_m"]  # along y
    two_rel = two["final_odometry_error_m"] / SCENARIOS["y"][1]
    four_rel = four["final_odometry_error_m"] / SCENARIOS["diagonal"][1]
    paper_four_rel = PAPER_FOUR_WHEELS[1] / PAPER_FOUR_WHEELS[0]
    return [
        _anchor(f"two_wheel_shortfall{suffix}",
                f"two motors, 40 cm along y at the paper's speed (position control, {reading}): "
                "the platform really travels less than odometry reports, by the paper's amount",
                f"{100 * reached:.1f} cm reached where odometry reports 40 cm: "
                f"{100 * (distance - reached):.1f} cm "
                f"({100 * (distance - reached) / distance:.1f} %) short",
                {"true_cm": round(100 * two["true_travel_m"], 2),
                 "odometry_cm": round(100 * two["odometry_travel_m"], 2),
                 "shortfall_cm": round(100 * shortfall, 2),
                 "shortfall_pct": round(100 * shortfall / distance, 2),
                 "goal_offset_cm": round(100 * (two["true_travel_m"] - distance), 2)},
                shortfall / (distance - reached),
                "final travel along y, odometry minus true (the shortfall); goal_offset: true "
                "minus the 40 cm goal (the paper's: −2.3 cm)"),
        _anchor(f"four_wheel_error{suffix}",
                f"four motors, x = y to 40 cm at the paper's speed (position control, {reading}): "
                "odometry error after 56.6 cm",
                f"{100 * PAPER_FOUR_WHEELS[1]:.1f} cm ({100 * paper_four_rel:.1f} %)",
                {"error_cm": round(100 * four["final_odometry_error_m"], 2),
                 "error_pct": round(100 * four_rel, 2)},
                four_rel / paper_four_rel, "final |p_true − p_odometry|"),
        Claim(f"four_wheels_worse_than_two{suffix}",
              f"with four motors mutual servo errors cause slip ({reading}, the paper's speed): "
              "the relative odometry error is larger than with two",
              f"{100 * paper_four_rel:.1f} % vs {100 * (distance - reached) / distance:.1f} %",
              {"four_pct": round(100 * four_rel, 2), "two_pct": round(100 * two_rel, 2)},
              four_rel > two_rel, "final odometry error over the distance travelled; the model "
              "has the mechanism the paper supposes (the servos' mutual errors), so a failure "
              "is a result, not a missing mechanism"),
    ]


#: the comparisons between distributions: claim word -> (summary key, what the better one
#: does, the paper's statement it tests, whether the resolution applies)
COMPARISONS = {
    "less_slip": ("total_slip_m", "slips less than",
                  "proposed 'to avoid the slippage of wheels' (§3.2; not measured)", False),
    "goal_error": ("goal_error_m", "stops nearer its goal than",
                   "'bad effect of wheel slippages ... on positioning accuracy can be decreased' "
                   "(§3.1; not measured)", True),
    "odometry_error": ("final_odometry_error_m", "ends with a smaller odometry error than",
                       "slip spoils odometry, 'very critical for localization' (§3.1); §4 "
                       "measures odometry against a camera (not for the distributions)", True),
}
#: short names of the compared methods in the claims' values
SHORT = {"min_norm": "min_norm", "proportional": "proportional", RATIOS: "ratios",
         "minmax": "minmax", LOAD_TRANSFER: "load_transfer"}


def _better(per_method: dict, method: str, against: str, comparison: str) -> bool:
    """``method`` beats ``against`` on ``comparison`` (:data:`COMPARISONS`): less slip by more
    than :data:`SLIP_ROUND_OFF_M`, or a final error smaller by at least :data:`RESOLUTION_M`."""
    key, _, _, resolved = COMPARISONS[comparison]
    margin = per_method[against][key] - per_method[method][key]
    return margin >= RESOLUTION_M if resolved else margin > SLIP_ROUND_OFF_M


def _values(per_method: dict, methods, comparison: str) -> dict:
    """``"<method>_mm"`` -> the comparison's quantity [mm] per method."""
    key = COMPARISONS[comparison][0]
    return {f"{SHORT[m]}_mm": round(1e3 * per_method[m][key], 3) for m in methods}


def _comparison_note(comparison: str) -> str:
    """What a comparison claim measures and its criterion, for its note."""
    key, _, _, resolved = COMPARISONS[comparison]
    what = {"total_slip_m": "total slip distance of the four wheels over the run",
            "goal_error_m": "final |p_true − p_goal|",
            "final_odometry_error_m": "final |p_true − p_odometry|"}[key]
    return what + (f"; better by at least {1e3 * RESOLUTION_M:g} mm (the paper's resolution)"
                   if resolved else f"; less by more than {1e6 * SLIP_ROUND_OFF_M:g} µm "
                   "(round-off)")


#: the regimes in the claims' statements
REGIME_WORDS = {"binding": "where friction binds", "paper_speed": "at the paper's speed"}


def _distribution_claims(numbers: dict) -> list[Claim]:
    """Per regime, scenario and comparison: the proportional distribution against the minimum
    norm, with every compared distribution's value (ids end with the runs' key,
    :func:`run_key`)."""
    out = []
    for regime in ("paper_speed", "binding"):
        for scenario in SCENARIOS:
            key = run_key(scenario, regime)
            n = numbers[key]
            for comparison, (_, verb, paper, _) in COMPARISONS.items():
                out.append(Claim(
                    f"proportional_{comparison}_{key}",
                    f"{scenario}, {REGIME_WORDS[regime]}: the proportional distribution {verb} "
                    "the minimum norm", paper, _values(n, COMPARED, comparison),
                    _better(n, "proportional", "min_norm", comparison),
                    _comparison_note(comparison) + " (ratios: the other reconstruction of "
                    "H; minmax: beyond the paper)"))
    return out


def _load_transfer_claims(numbers: dict, heights: tuple[float, float]) -> list[Claim]:
    """The proportional distribution fed the load transfer of a mismatched centre-of-mass
    height (``heights``: believed, true [m]) against the minimum norm, binding regime."""
    believed, true = heights
    error = 100 * (believed / true - 1.0)
    out = []
    for scenario in SCENARIOS:
        n = numbers[scenario]
        for comparison, (_, verb, paper, _) in COMPARISONS.items():
            out.append(Claim(
                f"load_transfer_{comparison}_{scenario}",
                f"{scenario}, where friction binds, the controller modelling load transfer with "
                f"its centre of mass {abs(error):.0f} % {'low' if error < 0 else 'high'} "
                f"({believed:.2f} m believed, {true:.2f} m true): the proportional distribution "
                f"still {verb} the minimum norm", paper,
                _values(n, ("min_norm", "proportional", LOAD_TRANSFER), comparison),
                _better(n, LOAD_TRANSFER, "min_norm", comparison),
                _comparison_note(comparison) + " (proportional: the statics' forces, as the "
                "paper; the kinematic plant has no load transfer, so there the model predicts a "
                "transfer that does not happen)"))
    return out


def _reconstruction_claim(numbers: dict) -> Claim:
    """Do the proportional claims' verdicts survive the other reconstruction of H?"""
    differ, total = [], 0
    for regime in REGIMES:
        for scenario in SCENARIOS:
            n = numbers[run_key(scenario, regime)]
            for comparison in COMPARISONS:
                total += 1
                if (_better(n, "proportional", "min_norm", comparison)
                        != _better(n, RATIOS, "min_norm", comparison)):
                    differ.append(f"{comparison}/{run_key(scenario, regime)}")
    return Claim("h_reconstruction_immaterial",
                 "the proportional claims do not depend on the reconstruction of eq. 12's H "
                 "(least squared utilisations, or the most nearly equal utilisations — the "
                 "maximising root of a quadratic equation in α): the same verdicts against "
                 "min-norm",
                 "H lost from the text; 'solving a quadratic equation in α'",
                 {"same_verdicts": total - len(differ), "comparisons": total,
                  "differ": ", ".join(differ) or "none"},
                 not differ, "each proportional_* comparison of both regimes recomputed with "
                 "the ratios runs")


def _no_slip_claim(numbers: dict) -> Claim:
    """§3.1: with eq. 7 (force control) slippage does not occur despite torque errors."""
    runs = {f"{SHORT[m]}/{scenario}": numbers[run_key(scenario, "paper_speed")][m]
            for scenario in SCENARIOS for m in COMPARED}
    worst = max(runs, key=lambda name: runs[name]["total_slip_m"])
    diagonal = numbers[run_key("diagonal", "paper_speed")]
    return Claim("force_control_no_slip_paper_speed",
                 "at the paper's speed, force control (eq. 7, any distribution) does not slip "
                 "although the servos have torque errors",
                 "'slippage does not occur even if the wheels have torque errors' (§3.1)",
                 {"largest_mm": round(1e3 * runs[worst]["total_slip_m"], 3),
                  "largest_run": worst,
                  "its_planned_peak_utilisation": round(runs[worst]["planned_peak_utilisation"],
                                                        3),
                  "largest_least_squares_readings_mm": round(1e3 * max(
                      m["total_slip_m"] for name, m in runs.items()
                      if not name.startswith(SHORT[RATIOS])), 3),
                  "position_four_wheels_mm": round(1e3 * diagonal["position"]["total_slip_m"], 3),
                  "position_reference_four_wheels_mm": round(
                      1e3 * diagonal["position_reference"]["total_slip_m"], 3)},
                 runs[worst]["total_slip_m"] < RESOLUTION_M,
                 f"largest total slip of the force-control runs (both scenarios); holds below "
                 f"{1e3 * RESOLUTION_M:g} mm. A run that planned a utilisation above 1 slips by "
                 "its own plan, not by torque errors; largest_least_squares_readings: min-norm, "
                 "proportional and minmax alone (the ratios reading left out); the four-wheel "
                 "position-control runs for contrast")


def sweep(robot, backend: str, substeps: int, p: dict = PARAMETERS,
          options: StudyOptions = DOCUMENTED) -> dict:
    """``scenario -> μ -> distribution -> total slip [m]`` over ``p["sweep_mu"]`` (the floor's
    and the distributions' μ; the rest of ``p`` and the plant as in the main runs): does the
    ranking of the distributions depend on the floor?"""
    out: dict[str, dict] = {}
    for scenario in SCENARIOS:
        out[scenario] = {}
        for mu in p["sweep_mu"]:
            out[scenario][mu] = {}
            for method in DISTRIBUTIONS:
                simulated = simulate(robot, scenario, method, backend, substeps,
                                     {**p, "mu": mu}, options)[0]
                out[scenario][mu][method] = float(simulated.signals["slip_distance"].sum())
    return out


def _ranking_claims(numbers: dict, swept: dict, mu: float) -> list[Claim]:
    """The two slip rankings over the main runs (friction coefficient ``mu``) and the μ
    sweep."""
    cases = {f"{scenario}, mu={mu}": {m: numbers[scenario][m]["total_slip_m"]
                                                    for m in DISTRIBUTIONS}
             for scenario in SCENARIOS}
    cases.update({f"{scenario}, mu={mu}": slip for scenario, per_mu in swept.items()
                  for mu, slip in per_mu.items()})
    note = ("total slip of the four wheels per case (scenario, μ)"
            + ("" if swept else "; --quick: the μ sweep was not run"))
    out = []
    for claim_id, statement, better, worse, allowance in (
            ("proportional_less_slip_sweep", "proportional slips less than the minimum norm",
             "proportional", "min_norm", 0.0),
            ("minmax_at_most_proportional_sweep", "minmax slips at most as much as "
             "proportional", "minmax", "proportional", 1e-6)):
        held = [case for case, slip in cases.items() if slip[better] < slip[worse] + allowance]
        out.append(Claim(
            claim_id, f"{statement} across the floor's friction coefficient", "—",
            {"cases_held": len(held), "cases": len(cases),
             "slip_mm": {case: f"{1e3 * slip[better]:.2f} vs {1e3 * slip[worse]:.2f}"
                         for case, slip in cases.items()}},
            len(held) == len(cases), f"{note}; slip_mm: '{better} vs {worse}' [mm]"))
    return out


def claims(numbers: dict, runs: dict, qp_gap: float, swept: dict | None, mu: float,
           heights: tuple[float, float]) -> list[Claim]:
    """The claims table; ``swept``: :func:`sweep`'s result (``None``: main runs only, the
    ``*_sweep`` claims left out); ``heights``: the load-transfer controller's believed and the
    true centre-of-mass height [m]."""
    out = (_position_claims(numbers, "position", "", "present position from odometry")
           + _position_claims(numbers, "position_reference", "_reference",
                              "present position = previous reference"))
    forces = np.vstack([np.asarray(m["normal_forces"]) for s in runs.values()
                        for m in s.values()])
    lifted = int(np.sum(forces <= 0.0))  # wheel-ticks off the floor (MuJoCo's contacts)
    ratio = float(forces.max() / forces.min()) if not lifted else math.inf
    # infinity has no JSON form: a lifted wheel is reported by its count of ticks
    ours = ({"max_over_min": round(ratio, 1)} if not lifted else
            {"max_over_min": "inf", "max_N": round(float(forces.max()), 1),
             "wheel_ticks_off_the_floor": lifted})
    out.append(Claim("unequal_normal_forces",
                     "the arm's motion makes the wheels' normal forces unequal (premise)",
                     "unequal (no numbers)", ours, ratio > 2.0,
                     "largest over smallest normal force over all ticks of all runs"
                     + ("; inf: a wheel left the floor (its contacts carried nothing): the "
                        "centre of mass's height moves load between the wheels under "
                        "acceleration, which the statics neglect" if lifted else "")))
    out.append(_no_slip_claim(numbers))
    out += _distribution_claims(numbers)
    for scenario in SCENARIOS:
        n = numbers[scenario]
        out.append(Claim(
            f"minmax_at_most_proportional_{scenario}",
            f"{scenario}, where friction binds: minmax slips at most as much as the proportional "
            "distribution", "beyond the paper",
            {"minmax_mm": round(1e3 * n["minmax"]["total_slip_m"], 3),
             "proportional_mm": round(1e3 * n["proportional"]["total_slip_m"], 3)},
            n["minmax"]["total_slip_m"] <= n["proportional"]["total_slip_m"] + SLIP_ROUND_OFF_M,
            "total slip distance (1 µm round-off allowance). Minmax minimises the planned "
            "utilisation, not the slip distance: on "
            f"{n['minmax']['ticks_planned_over_1']} ticks of its run even its optimum was "
            f"above 1 (peak {n['minmax']['planned_peak_utilisation']:.3f}: no distribution "
            "avoids slip there), and servo errors, noise and the wheels' rotor inertia act "
            "after the distribution"))
    out += _load_transfer_claims(numbers, heights)
    out.append(_reconstruction_claim(numbers))
    if swept is not None:
        out += _ranking_claims(numbers, swept, mu)
    out.append(Claim("qp_equals_closed_form",
                     "the distribution stacks' torques equal the closed forms on every tick",
                     "—", {"max_abs_diff_Nm": qp_gap}, qp_gap <= 1e-6,
                     "largest |τ_QP − τ_closed| over all ticks of the QP distributions' runs"))
    return out


def figures(runs: dict, numbers: dict, out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    fig, axes = plt.subplots(len(REGIMES), len(SCENARIOS), figsize=(11, 10))
    for row, regime in zip(axes, ("paper_speed", "binding"), strict=True):
        for ax, scenario in zip(row, SCENARIOS, strict=True):
            for method, s in runs[run_key(scenario, regime)].items():
                true, odo = np.asarray(s["base_pose"]), np.asarray(s["odometry_pose"])
                line, = ax.plot(true[:, 0], true[:, 1], label=f"{method} (true)")
                ax.plot(odo[:, 0], odo[:, 1], "--", color=line.get_color(),
                        label=f"{method} (odometry)")
            ax.set_xlabel("x [m]")
            ax.set_ylabel("y [m]")
            ax.set_title(f"{scenario}, {REGIME_WORDS[regime]}: platform path")
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=6)
    names.append(save_figure(fig, out_dir / "omni_paths.png"))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, scenario in zip(axes, SCENARIOS, strict=True):
        per_method = numbers[scenario]
        width = 0.8 / len(per_method)
        for k, (method, n) in enumerate(per_method.items()):
            offset = (k - 0.5 * (len(per_method) - 1)) * width
            ax.bar(np.arange(4) + offset, 1e3 * np.asarray(n["slip_per_wheel_m"]), width,
                   label=method)
        ax.set_xticks(range(4))
        ax.set_xlabel("wheel")
        ax.set_ylabel("slip distance [mm]")
        ax.set_title(f"{scenario}, {REGIME_WORDS['binding']}: total slip per wheel")
        ax.legend(fontsize=7)
    names.append(save_figure(fig, out_dir / "omni_slip.png"))
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    s = runs["diagonal"]["proportional"]
    axes[0].plot(s["t"], s["normal_forces"], label=[f"wheel {i}" for i in range(4)])
    axes[0].set_ylabel("normal force [N]")
    axes[0].set_xlabel("time [s]")
    axes[0].legend(fontsize=8)
    for method in (*DISTRIBUTIONS, LOAD_TRANSFER):
        m = runs["diagonal"][method]
        axes[1].plot(m["t"], np.asarray(m["friction_utilisation"]).max(axis=1), label=method)
    axes[1].set_ylabel("largest friction utilisation [-]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=8)
    fig.suptitle("diagonal: the arm's swing moves the load; utilisation per distribution")
    names.append(save_figure(fig, out_dir / "omni_utilisation.png"))
    fig, axes = plt.subplots(len(COMPARISONS), 1, figsize=(10, 9), sharex=True)
    keys = [run_key(scenario, regime) for regime in ("paper_speed", "binding")
            for scenario in SCENARIOS]
    methods = (*COMPARED, LOAD_TRANSFER)
    width = 0.8 / len(methods)
    for ax, (key, *_) in zip(axes, COMPARISONS.values(), strict=True):
        for k, method in enumerate(methods):
            values = [1e3 * numbers[case][method][key] if method in numbers[case] else np.nan
                      for case in keys]
            ax.bar(np.arange(len(keys)) + (k - 0.5 * (len(methods) - 1)) * width, values, width,
                   label=method)
        ax.set_ylabel({"total_slip_m": "total slip [mm]", "goal_error_m": "goal error [mm]",
                       "final_odometry_error_m": "odometry error [mm]"}[key])
        ax.set_xlabel("scenario and regime")
        ax.legend(fontsize=7)
    axes[-1].set_xticks(range(len(keys)), keys)
    fig.suptitle("per distribution: slip, final distance to the goal, final odometry error")
    names.append(save_figure(fig, out_dir / "omni_accuracy.png"))
    plt.close("all")
    return names


SUMMARY = """\
**Plant.** `omni4_arm6` in `wbc.papers.omni.dynamics.OmniDynamics`: 45 kg planar rigid body
(yaw inertia 2 kg m², our estimate), wheel rotors of 0.02 kg m² (estimate: the gear is not
given), Coulomb friction μ = 0.3 per wheel (our choice: the paper gives no floor), normal forces
from the whole system's centre of mass (`wbc.robots.system_com`: the paper's 15 kg + 30 kg, the
arm's mass distributed like the UR10 stand-in's links) by the minimum-norm (equal-stiffness)
split — no load transfer (the centre of mass's height plays no part), and the statics'
controller knows these forces exactly. Servo errors: torque gain errors of +5, −5, +3, −3 % and
torque noise σ = 0.1 N m; wheel radius errors +0.5, −0.5, +0.3, −0.3 %. 1 ms sub-steps (the
paper's servo period), 10 ms control ticks.

**Motion.** Trapezoidal references in two regimes, fixed before the runs: the paper's
experiments "at a constant speed" — 0.1 m/s with 0.25 m/s² ramps (2 cm each: constant speed
over 90 % of the way; the paper gives no speed, this is our estimate) — and the binding regime,
twice as fast with the same ramp length (0.2 m/s, 1 m/s²), where the lightly loaded wheels
reach their friction limit, without which no distribution matters; 0.8 s settling. Position
control runs at the paper's speed (its anchors), force control in both. The arm's shoulder pans
from −45° to +45° with a half-cosine profile over each run: the centre of mass (0.39 m above the
floor) moves from about (0.10, 0) to (0, 0.10) m in the platform frame and the normal forces
range between about 12 and 210 N. Heading 45°: the y motion needs two wheels (the paper's
first experiment: the other two motors unpowered), the diagonal all four.

**Controllers.** Position control: eq. 3 with D = I (wheel-side angles), the servo PID of eq. 4
(k_p = 22.5 N m/rad, k_v = 4.5 N m s/rad, k_i = 50 N m/(rad s), our choice) on each wheel's own
encoder. Eq. 3's "present position" is ambiguous; both readings run: `position` — the odometry
pose, the servo target being the wheel's angle at the tick's start + Δθ; `position_reference`
— the previous reference, the increments summed into absolute wheel angle trajectories that
each servo tracks (no pose feedback; the servos' integrals fight each other's radius and gain
errors). Force control: eq. 6 with M = diag(45, 45, 2), k_p = M·16 s⁻²,
k_v = M·8 s⁻¹ (our choice), world frame, then the distribution's QP on the chosen backend;
normal forces from the measured arm joints. Eq. 12's H is lost from the text; two readings run:
`proportional` — the least squared friction utilisations (a linear equation in α), and
`proportional_ratios` — the utilisations most nearly equal, the squared cosine between |u| and
(1, …, 1): the maximising root of a quadratic equation in α, as the paper says, but scale-free,
so it squeezes the wheels against each other to equalise them
(`wbc.papers.omni.closed_form`). `proportional_load_transfer` adds to the statics' forces the
load transfer of the commanded acceleration for a centre of mass the controller believes
{height_words} ({believed:.2f} m against {true:.2f} m; our estimate, fixed before the runs, of
how well the height is known without weighing the assembled robot).

**Timing.** A force-control tick is eq. 6, the whole system's centre of mass, the normal
forces and the distribution's QP. By default (the fast path, `OmniForceControl(fused="auto")`)
the first three are one generated C call writing into the distribution's parameters, and on
daqp the QP is one more (`TorqueDistribution(fused="auto")`, `wbc.fused`); the ordinary path
(`fused=False` for both) computes them in numpy and pinocchio (`wbc.robots.system_com`) around
the Python daqp backend. daqp's tick is timed interleaved with the ordinary path's over the
same recorded states (`ordinary_tick_median_s` in the JSON); the other backends run the fast
model stage around their QP. The last table gives the QP's share (`qp_median_s`).

**Robustness.** The distributions' slip ranking is rerun with μ = 0.2 and 0.5 (full runs
only; the `*_sweep` claims), so that it does not rest on the one friction coefficient chosen;
`wbc sweep omni --param acceleration_m_s2=2` moves the binding regime.

**Reading the claims.** Criteria fixed from the paper's statements before the results: the
paper's numbers hold within a factor 2, with their sign; an anchor the model cannot reach for
want of the mechanism behind it does not hold and its note classifies it "not reproducible
with this model", naming that mechanism; one distribution positions or localises better than
another when its final error is smaller by at least 1 mm (the paper quotes positions to
0.1 cm); slip comparisons are strict beyond 1 µm of round-off. The paper reports two
position-control experiments and proposes the proportional distribution without measuring it.
Our model reproduces the mechanism (slip where the traction asked of a wheel exceeds μ fᵢ;
odometry then disagrees with the truth), not the paper's magnitudes, which came from a real
floor and real rollers. "Planned" utilisation is the commanded torques' |τᵢ|/(μ fᵢ r); the
contact forces differ from τᵢ/r by the rotors' inertia and the servo errors. "Belief error" is
the RMS difference between the normal forces the controller distributed with and the plant's.
"""


MUJOCO_SUMMARY = """\
**Plant: MuJoCo** (`--plant mujoco`). `omni4_arm6` as `wbc.sim.MujocoPlant(robot, mu=μ)`: the
paper's 15 kg platform (wheels included) and 30 kg arm as rigid bodies, four omni wheels with
12 passive rollers each on a floor whose friction coefficient is the study's μ (the number the
distributions use), 1 ms physics steps, wheel odometry from the wheel encoders. Dropped with
`OmniDynamics`: its planar rigid body (yaw inertia 2 kg m²; MuJoCo's comes from the bodies), its
per-wheel Coulomb model with the statics' normal forces (MuJoCo's come from the contacts and
also move with the centre of mass's height under acceleration, which the statics neglect), the
wheel radius errors (no counterpart: the model's wheels have the nominal radius) and, for
position control, eq. 4's PID with its gain errors and noise: the plant's own wheel servos
(10 Hz, `wbc.sim.mjcf`) take the wheel rates (`command="joints"`), `position` setting each
servo's target to the wheel's present angle + Δθ every period as `OmniDynamics`' servo does,
`position_reference` integrating them into absolute angle trajectories (the Controllers
paragraph's PID is the kinematic plant's); in `y` wheels 0 and 2
have no actuator and roll freely. Kept, decided before the runs: the servo gain errors and the
torque noise (the kinematic plant's values and noise stream) as a perturbation of the force
controllers' commanded torques (a controller-side wrapper). The arm follows its swing on its
joint servos, so its reaction now moves the platform. Slip, friction utilisation (the
contacts' at each tick's end), normal forces and odometry error come from the rollers'
contacts; `wheel_saturation` and `base_tilt` are recorded per run.

**What physics changes.** (1) Load transfer: the centre of mass stands 0.39 m above the floor,
so the ramps move load between the wheels; the lightly loaded wheel (12–25 N in the statics)
carries nothing on some ticks ({lifted} wheel-ticks off the floor over the main runs). The
statics' distributions plan with forces that are off by {static_rms:.1f} N RMS (binding
regime, mean over their runs); the load-transfer controller's, with its height
{height_words}, by {transfer_rms:.1f} N. (2) No mutual servo errors in position
control (identical, exact servos, nominal radii): the position-control odometry errors stay in
millimetres. (3) Minmax equalises the planned utilisation with the statics' forces, which
raises the torque of the lightly loaded wheel — the one the ramps unload. (4) Momentum: in `y`
with two motors nothing holds the platform along the unpowered wheels' direction, and the arm's
swing pushes it {drift:.1f} cm sideways (`position`, the paper's speed; the system's centre of
mass stays put, the platform moves against the arm's). (5) The rollers' soft contacts creep:
every run slips a little (millimetres at the paper's speed).

"""


def run(backend: str, out_dir: Path, quick: bool,
        options: StudyOptions = DOCUMENTED) -> StudyResult:
    options.check(PARAMETERS_SWEPT)
    p = setup(options)
    robot = robots.load("omni4_arm6")
    substeps = 5 if quick else PARAMETERS["substeps"]
    base = robot.base
    assert isinstance(base, OmniBase)  # the catalogue's omni4_arm6
    runs: dict[str, dict] = {}
    numbers: dict[str, dict] = {}
    states: list = []
    replays: dict[str, Recording] = {}
    main_runs = []
    for regime, (_, methods) in REGIMES.items():
        pr = regime_parameters(p, regime)
        for scenario in SCENARIOS:
            key = run_key(scenario, regime)
            runs[key], numbers[key] = {}, {}
            for method in methods:
                simulated, references, controller = simulate(robot, scenario, method, backend,
                                                             substeps, pr, options)
                main_runs.append(simulated)
                s = series(simulated, references, unpowered_wheels(scenario, method))
                if not options.main_only:
                    replays[f"{key}/{method}"] = Recording.from_run(
                        simulated, robot="omni4_arm6",
                        target=np.array([references(t)["target"][:2] for t in simulated.t]))
                if method not in POSITION_CONTROL:
                    s["_raw"] = {"command": controller.torques, "J": base.jacobian,
                                 "wrench": controller.wrench, "forces": controller.forces}
                    # what the distribution planned: |τ_i| / (μ f_i r) of the commanded torques
                    s["planned_utilisation"] = np.array([
                        ref.friction_utilisation(tau, forces, base.radius, p["mu"])
                        for tau, forces in zip(controller.torques, controller.forces,
                                               strict=True)])
                    if regime == "binding" and method == "proportional":
                        states += [(q, v, references(t)) for q, v, t in zip(
                            simulated.q_est[::4], simulated.v_est[::4], simulated.t[::4],
                            strict=True)]
                runs[key][method] = s
                numbers[key][method] = summary_numbers(s, scenario)
    gap = qp_versus_closed_form(runs, p["mu"])
    swept = None if options.main_only else {} if quick else sweep(robot, backend, substeps, p,
                                                                    options)
    for methods_runs in runs.values():
        for s in methods_runs.values():
            s.pop("_raw", None)
    timings: dict = {}
    failures: list[str] = []
    if not options.main_only:
        backends = [backend] if quick else available_backends()
        timings, failures = timing(robot, states, backends, 0.3 if quick else 1.0, p["mu"])
    true_height = com_height(robot, start_configuration(robot, p))
    heights = ((1.0 + p["com_height_error"]) * true_height, true_height)
    table = ["", "| runs | method | total slip [mm] | goal error [mm] | odometry error [mm] | "
             "peak utilisation | planned peak | ticks planned > 1 | belief error [N] |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for key, per_method in numbers.items():
        for method, n in per_method.items():
            planned = (f"{n['planned_peak_utilisation']:.2f} | {n['ticks_planned_over_1']} | "
                       f"{n['belief_rms_N']:.1f}" if "planned_peak_utilisation" in n
                       else "— | — | —")
            table.append(f"| {key} | {method} | {1e3 * n['total_slip_m']:.2f} | "
                         f"{1e3 * n['goal_error_m']:.2f} | "
                         f"{1e3 * n['final_odometry_error_m']:.2f} | "
                         f"{max(n['peak_utilisation']):.2f} | {planned} |")
    qp_table = ["", "The distribution's QP alone (median over the replayed ticks):", "",
                "| backend | QP median [µs] |", "|---|---:|"]
    qp_table += [f"| {b} | {1e6 * t['qp_median_s']:.0f} |" for b, t in timings.items()]
    if "daqp" in timings:
        t = timings["daqp"]
        qp_table += ["", f"daqp, interleaved over the same states: the default (fast) path "
                     f"{1e6 * t['tick_median_s']:.1f} µs median (p95 "
                     f"{1e6 * t['tick_p95_s']:.1f}), the ordinary path "
                     f"{1e6 * t['ordinary_tick_median_s']:.1f} µs (p95 "
                     f"{1e6 * t['ordinary_tick_p95_s']:.1f}): "
                     f"{t['tick_median_s'] / t['ordinary_tick_median_s']:.2f}×."]
    parameters = {**p, "substeps": substeps, "backend": backend,
                  "com_height_m": {"true": heights[1], "believed": heights[0]},
                  "scenarios": {k: {"direction": d.tolist(), "distance_m": s}
                                for k, (d, s) in SCENARIOS.items()}}
    words = {"height_words": f"{abs(100 * p['com_height_error']):.0f} % "
                             f"{'low' if p['com_height_error'] < 0 else 'high'}",
             "believed": heights[0], "true": heights[1]}
    summary = SUMMARY.format(**words)
    if options.plant == "mujoco":
        parameters["mujoco"] = {"mu": p["mu"], "passive_wheels_y_position": [0, 2],
                                "servo_errors_on": "force control's commanded torques",
                                "wheel_servos": "the plant's (position control)"}
        y = runs[run_key("y", "paper_speed")]["position"]  # its motion across y (world x)
        lifted = sum(int(np.sum(np.asarray(m["normal_forces"]) <= 0.0))
                     for methods in runs.values() for m in methods.values())
        belief = {method: np.mean([numbers[scenario][method]["belief_rms_N"]
                                   for scenario in SCENARIOS])
                  for method in ("proportional", LOAD_TRANSFER)}
        summary = (MUJOCO_SUMMARY.format(lifted=lifted,
                                         drift=100 * abs(y["final_true_position"][0]),
                                         static_rms=belief["proportional"],
                                         transfer_rms=belief[LOAD_TRANSFER], **words)
                   # the kinematic plant's paragraphs but its first (plant) and last (reading)
                   + "\n\n".join(summary.split("\n\n")[1:-1]) + "\n")
    figures_saved = [] if options.main_only else figures(runs, numbers, Path(out_dir))
    return StudyResult(name="omni", claims=claims(numbers, runs, gap, swept, p["mu"], heights),
                       runs={k: {m: {**s, "summary": numbers[k][m]} for m, s in v.items()}
                             for k, v in runs.items()},
                       timing=timings, figures=figures_saved,
                       summary_md=summary + "\n".join(table + qp_table), parameters=parameters,
                       failures=failures, replays=replays, robot="omni4_arm6", options=options,
                       plant_timing=plant_timing(options, 0.0, main_runs))


def main(argv=None) -> int:
    return study_main("omni", run, argv)
