"""MuJoCo as the plant of :class:`~wbc.sim.Simulation`: real physics under the controller.

::

    from wbc.sim import MujocoPlant, Simulation
    sim = Simulation(robot, controller, dt=0.01, plant=MujocoPlant(robot))
    run = sim.run(seconds=5.0, references=...)
    run.signals["wheel_slip"], run.signals["saturation"], run.signals["normal_forces"]

The model is :func:`wbc.sim.mjcf.build_mjcf`'s (links with pinocchio's inertias, real wheels —
with passive rollers for omni and mecanum bases — on a floor with friction; every parameter and
where it comes from is in that module's docstring). Needs the ``mujoco`` package (the
``[mujoco]`` extra).

The plant interface (what :class:`~wbc.sim.Simulation` calls; any object with these two methods
is a plant):

* ``reset(q0, v0, dt, command) -> (q, v)``: build the model for the command kind, put the robot
  in ``q0`` (settled on its wheels at rest for ``settle_s``, then given ``v0``) and return the
  true state it starts from;
* ``step(command) -> PlantStep``: advance one control period of ``dt`` (``dt / TIMESTEP``
  physics sub-steps with the command held) and return the true ``q``, ``v`` at its end, what the
  encoders measured over it (``v_measured``) and the tick's signals. The sub-steps run in
  compiled C where a C compiler and MuJoCo's headers are at hand
  (:mod:`wbc.sim.mujoco_substeps`; the same MuJoCo calls, bitwise the same states), else in
  Python.

Coordinates are wbc's: ``q = [x, y, θ, q_arm]`` (θ unwrapped, the base frame's pose on the
floor) and ``v`` = the base's own velocity coordinates in the base frame (``(v_x, v_y, ω)``, or
``(v, ω)`` for the differential drive) then the arm's joint rates. The true twist is the base
body's, measured by MuJoCo; the measured one (unless ``odometry=False``: then the controller
is given the truth) is **wheel odometry**: the base model's forward
kinematics of the wheel joints' angle increments over the period (the steerable base's also of
its steering angles), as on the robot; the arm's is its joints' increments.

Commands (``Simulation(command=...)``):

* ``"velocity"``: ``(nv,)`` velocities; the arm's go to its joint velocity servos, the base's
  through the base model's inverse kinematics to the wheel (and steer) servos;
* ``"acceleration"``: ``(nv,)`` accelerations; arm joints get inverse-dynamics torques each
  sub-step (MuJoCo's recursive Newton–Euler at the current state with the commanded arm and
  base accelerations: the base's acceleration's reaction on the arm is fed forward; wheels,
  rollers and springs taken unaccelerated), clipped to their limits; the base's acceleration
  is integrated into the wheels' velocity targets;
* ``"torque"``: ``(n_wheels,)`` drive wheel torques [N m] (the base model's wheel order),
  applied directly (omni force control), optionally followed by ``(n_arm,)`` arm joint
  velocities for the arm's servos (default: the arm holds its pose);
* ``"joints"`` (wheeled bases): ``(n_wheels + n_steer + n_arm,)`` joint rates [rad/s] — the
  drive wheels' (the base model's wheel order), the steer joints' (steerable base), then the
  arm's — each to its integrating servo, for a controller that drives the wheels itself (a
  steering controller's steer and drive rates; wheel angle increments divided by the period:
  the servo integrates the rate into its angle reference, so it tracks the angles). With
  ``wheel_targets="present"`` each drive servo's angle reference is set at the period's start
  to the wheel's measured angle plus its entry times the period, and held over the period: a
  wheel servo given the target "present angle + Δθ" each period (``OmniDynamics``'
  ``servo="angle"``); with the default ``"integrated"`` the references integrate the rates
  (absolute angle trajectories).

``passive_wheels``: those drive wheels have no actuator and roll freely (an unpowered motor);
their entries in a ``"torque"`` or ``"joints"`` command are ignored, and for ``"velocity"`` and
``"acceleration"`` commands the base's inverse kinematics still drives only the others.

Recorded per tick (``run.signals``): ``"wheel_slip"`` (n_wheels,) [m/s] — the mean slip speed
at each wheel's contact over the tick (rim speed ``r φ̇`` against the contact's speed along the
wheel's driven direction from the true base twist; for steered wheels also across it);
``"slip_distance"`` (n_wheels,) [m] — how far each contact slid in the tick; ``"lateral_slip"``
[m/s] (differential drive) — the base's sideways speed, which its kinematics forbid;
``"normal_forces"`` (n_wheels,) [N] and ``"friction_utilisation"`` (n_wheels,) — the wheel
contacts' normal force and the largest ``|f_t| / (μ f_n)`` of their contacts at the tick's end;
``"base_tilt"`` [rad] — the base's
tilt from the vertical at the tick's end (a robot whose centre of mass leaves its wheels'
support tips over: the wheels lift, ``normal_forces`` drop to 0);
``"wheel_torque"`` (n_wheels,) [N m] — the drive torques the wheels' actuators produced, mean
over the tick (0 for a passive wheel); ``"saturation"`` (n_actuated,) — the fraction of
sub-steps each actuated joint (arm joints, then powered drive wheels, then steer joints) was at
its torque limit.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import all_finite, checked_flag, checked_number, checked_vector
from ..errors import InvalidValueError, NonFiniteError, ShapeError, WbcError
from . import mjcf, mujoco_substeps

__all__ = ["MujocoPlant", "PlantStep"]


@dataclass
class PlantStep:
    """What a plant reports after one control period.

    Attributes:
        q: true configuration at the period's end, ``(nq,)``.
        v: true velocity at the period's end, ``(nv,)``.
        v_measured: the mean velocity the encoders (wheel odometry) measured over the period.
        signals: ``name -> float | array`` recorded in ``run.signals``.
        q_measured: the configuration the controller is given next, when the plant measures it
            itself (``None``: the simulator integrates ``v_measured`` from its estimate).
    """

    q: np.ndarray
    v: np.ndarray
    v_measured: np.ndarray
    signals: dict = field(default_factory=dict)
    q_measured: np.ndarray | None = None


def _import_mujoco():
    try:
        import mujoco
    except ImportError:  # pragma: no cover - depends on the environment
        raise WbcError("MujocoPlant needs the mujoco package: pip install 'wbc[mujoco]'") \
            from None
    return mujoco


class MujocoPlant:
    """A wbc robot simulated by MuJoCo (see the module docstring).

    Args:
        robot: the wbc robot (fixed base, or a differential, steerable, omni or mecanum base).
        mu: wheel-floor friction coefficient (default :data:`wbc.sim.mjcf.DEFAULT_MU`).
        masses: ``(platform, arm)`` masses [kg] (default: the paper's for ``"omni4_arm6"``,
            else the model's; see :func:`wbc.sim.mjcf.build_mjcf`).
        base_height: height [m] of the base frame above the floor (default per base kind).
        settle_s: time [s] the robot settles on its wheels at rest in :meth:`reset`.
        odometry: the controller's estimate comes from the wheel and joint encoders (default);
            ``False``: it is the true state (as from motion capture), ``q_measured = q`` and
            ``v_measured = v``.
        passive_wheels: indices (the base model's wheel order) of drive wheels without an
            actuator, rolling freely (default none; see the module docstring).
        wheel_targets: ``"integrated"`` (default) or ``"present"``: where the drive servos'
            angle references start each period under ``"joints"`` commands (module docstring).
        steer_offset: a steered wheel ``"trailing"`` its steer axis (default, the base model's
            caster) or ``"sideways"`` beside it (Sorour et al.'s model; see
            :data:`wbc.sim.mjcf.STEER_OFFSETS`). The base model's inverse kinematics is a
            caster's, so ``"sideways"`` takes ``"joints"`` commands only (a steering controller
            choosing the angles).

    Attributes:
        model, data: MuJoCo's ``MjModel`` / ``MjData`` after :meth:`reset`.
        mjcf: the :class:`~wbc.sim.mjcf.MjcfModel` they were built from.
        compiled_substeps: whether :meth:`step` runs its physics sub-steps in compiled C
            (:mod:`wbc.sim.mujoco_substeps`: bitwise the same states, ≈ 1–5 µs less per
            1 ms sub-step) rather than in Python (no C compiler or MuJoCo headers, or a
            steered base's velocity or acceleration commands); set by :meth:`reset`.
    """

    def __init__(self, robot, *, mu: float = mjcf.DEFAULT_MU, masses=None,
                 base_height: float | None = None, settle_s: float = 0.3,
                 odometry: bool = True, passive_wheels=(),
                 wheel_targets: str = "integrated", steer_offset: str = "trailing") -> None:
        self._mujoco = _import_mujoco()
        self.kind = mjcf.base_kind(robot)
        self.settle_s = checked_number(settle_s, "settle_s [s]")
        self.odometry = checked_flag(odometry, "odometry")
        mu = checked_number(mu, "mu", strict=True)
        if base_height is not None:
            base_height = checked_number(base_height, "base_height [m]", low=None)
        if masses is not None:
            masses = tuple(checked_number(m, "masses [kg]", strict=True) for m in masses)
            if len(masses) != 2:
                raise ShapeError(f"masses must be (platform, arm) [kg], got {len(masses)} "
                                 "numbers")
        if wheel_targets not in ("integrated", "present"):
            raise InvalidValueError(f"wheel_targets must be 'integrated' or 'present', got "
                                    f"{wheel_targets!r}")
        self.wheel_targets = wheel_targets
        description = mjcf.build_mjcf(robot, "velocity", mu, masses=masses,
                                      base_height=base_height, passive_wheels=passive_wheels,
                                      steer_offset=steer_offset)  # checks
        self.passive_wheels = description.passive_wheels
        self.steer_offset = steer_offset
        self.robot = robot
        self.mu, self.masses, self.base_height = mu, masses, base_height
        self.nq, self.nv = int(robot.nq), int(robot.nv)
        self.nv_base = int(getattr(robot, "nv_base", 0))
        self.base: Any = getattr(robot, "base", None) if self.kind != "fixed" else None
        # an unsteered base's wheel rates = J · base velocity coordinates (its model's matrix;
        # empty for a steered or fixed base, which have none)
        self._jacobian = (np.asarray(robot.base.jacobian, dtype=float)
                          if self.kind in ("differential", "omni", "mecanum")
                          else np.zeros((0, 0)))
        self._built: dict[str, tuple] = {}
        self._substeps = 0
        self._theta = self._theta_wrapped = 0.0  # base heading [rad]: unwrapped, MuJoCo's
        self.model: Any = None  # mujoco.MjModel once reset
        self.data: Any = None  # mujoco.MjData once reset
        self.mjcf: Any = None  # mjcf.MjcfModel once reset
        self.command: str | None = None
        self.compiled_substeps = False

    # ------------------------------------------------------------------ set-up
    def _build(self, command: str) -> None:
        if command not in self._built:
            description = mjcf.build_mjcf(self.robot, command, self.mu, masses=self.masses,
                                          base_height=self.base_height,
                                          passive_wheels=self.passive_wheels,
                                          steer_offset=self.steer_offset)
            model = self._mujoco.MjModel.from_xml_string(description.xml)
            self._built[command] = (description, model, self._mujoco.MjData(model))
        self.mjcf, self.model, self.data = self._built[command]
        self.command = command
        m, desc, mj = self.model, self.mjcf, self._mujoco

        def joint(name):
            return mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, name)

        arm = [joint(n) for n in desc.arm_joints]
        self._arm_q = np.array([m.jnt_qposadr[j] for j in arm], dtype=int)
        self._arm_v = np.array([m.jnt_dofadr[j] for j in arm], dtype=int)
        wheels = [joint(n) for n in desc.wheel_joints]
        steers = [joint(n) for n in desc.steer_joints]
        self._wheel_q = np.array([m.jnt_qposadr[j] for j in wheels], dtype=int)
        self._wheel_v = np.array([m.jnt_dofadr[j] for j in wheels], dtype=int)
        self._steer_q = np.array([m.jnt_qposadr[j] for j in steers], dtype=int)
        self._steer_v = np.array([m.jnt_dofadr[j] for j in steers], dtype=int)

        def actuator(name):
            return mj.mj_name2id(m, mj.mjtObj.mjOBJ_ACTUATOR, name)

        prefix = "motor_" if command == "acceleration" else "servo_"
        self._arm_u = np.array([actuator(prefix + n) for n in desc.arm_joints], dtype=int)
        prefix = "motor_" if command == "torque" else "servo_"
        self._powered = np.array([i not in desc.passive_wheels for i in range(len(wheels))],
                                 dtype=bool)
        self._wheel_u = np.array([actuator(prefix + n) for n, powered
                                  in zip(desc.wheel_joints, self._powered, strict=True)
                                  if powered], dtype=int)
        self._steer_u = np.array([actuator("servo_" + n) for n in desc.steer_joints], dtype=int)
        self._act = {int(u): int(m.actuator_actadr[u]) for u in range(m.nu)
                     if m.actuator_actadr[u] >= 0}
        # the drive servos' angle references (activations) and their wheels' angles (none for
        # torque motors)
        servos = [(self._act[int(u)], int(adr)) for u, adr
                  in zip(self._wheel_u, self._wheel_q[self._powered], strict=True)
                  if int(u) in self._act]
        self._wheel_act = np.array([a for a, _ in servos], dtype=int)
        self._wheel_act_q = np.array([adr for _, adr in servos], dtype=int)
        # saturation: every actuated joint's dof and its torque limit
        self._sat_v = np.concatenate([self._arm_v, self._wheel_v[self._powered],
                                      self._steer_v])
        limits = np.concatenate([desc.arm_torque, np.full(len(self._wheel_u) + len(steers),
                                                          desc.wheel_torque)])
        self._sat_limit = limits * (1.0 - 1e-6)
        # contacts: geom -> wheel index (−1 for none)
        body_wheel = np.full(m.nbody, -1, dtype=int)
        for i, name in enumerate(desc.wheel_bodies):
            body_wheel[mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, name)] = i
        for b in range(m.nbody):  # rollers belong to their wheel
            if body_wheel[b] < 0 and body_wheel[m.body_parentid[b]] >= 0:
                body_wheel[b] = body_wheel[m.body_parentid[b]]
        self._geom_wheel = body_wheel[m.geom_bodyid]
        self._substeps = 0
        self._force = np.zeros(6)
        self._arm_v_fast, self._arm_u_fast, self._wheel_u_fast = (
            _contiguous(self._arm_v), _contiguous(self._arm_u), _contiguous(self._wheel_u))
        self._hips = (np.asarray(self.base.hips, dtype=float) if self.kind == "steerable"
                      else np.zeros((0, 2)))
        # MuJoCo's counts of the warnings it gives when it resets an unstable simulation
        self._unstable = np.array([int(getattr(mj.mjtWarning, name)) for name in
                                   ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC",
                                    "mjWARN_BADCTRL")])

    # ------------------------------------------------------------------ state maps
    def _yaw(self) -> float:
        w, x, y, z = self.data.qpos[3:7].tolist()
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    def _twist(self) -> np.ndarray:
        """True body twist ``(v_x, v_y, ω)`` of the base frame, base (yaw) axes."""
        d = self.data
        c, s = math.cos(self._theta_wrapped), math.sin(self._theta_wrapped)
        vx, vy, _, rx, ry, rz = d.qvel[0:6].tolist()  # linear (world), angular (body) velocity
        w, x, y, z = d.qpos[3:7].tolist()
        # world z component of the body-frame angular velocity: third row of R(quat)
        row = (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))
        omega = row[0] * rx + row[1] * ry + row[2] * rz
        return np.array([c * vx + s * vy, -s * vx + c * vy, omega])

    def _read(self) -> tuple[np.ndarray, np.ndarray]:
        q, v = np.empty(self.nq), np.empty(self.nv)
        d = self.data
        nb = self.nv_base
        if self.base is not None:
            yaw = self._yaw()
            self._theta += math.remainder(yaw - self._theta_wrapped, 2.0 * math.pi)
            self._theta_wrapped = yaw
            q[0], q[1], q[2] = d.qpos[0], d.qpos[1], self._theta
            twist = self._twist()
            v[:nb] = twist[[0, 2]] if nb == 2 else twist
            q[3:] = d.qpos[self._arm_q]
        else:
            q[:] = d.qpos[self._arm_q]
        v[nb:] = d.qvel[self._arm_v]
        return q, v

    def _wheel_rates(self, base_velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drive (and steer) rates [rad/s] for base velocity coordinates (base model's IK)."""
        if self.kind == "steerable":
            steering = self.data.qpos[self._steer_q]
            rates = self.base.inverse(base_velocity, steering)
            return rates.drive_rates, rates.steer_rates
        return self._jacobian @ base_velocity, np.zeros(0)

    # ------------------------------------------------------------------ the interface
    def reset(self, q0, v0, dt: float, command: str = "velocity"):
        """Build the model for ``command``, settle the robot at ``q0`` and give it ``v0``;
        return the true ``(q, v)`` it starts from (see the module docstring)."""
        dt = float(dt)
        substeps = round(dt / mjcf.TIMESTEP)
        if substeps < 1 or abs(substeps * mjcf.TIMESTEP - dt) > 1e-9 * dt:
            raise InvalidValueError(f"MujocoPlant: dt = {dt} s must be a multiple of the physics "
                                    f"step {mjcf.TIMESTEP} s")
        if command in ("torque", "joints") and self.base is None:
            raise WbcError(f"MujocoPlant: {command} commands drive wheels; this robot has none")
        if self.steer_offset == "sideways" and self.kind == "steerable" and command != "joints":
            raise WbcError("MujocoPlant: wheels beside their steer axes (steer_offset="
                           "'sideways') need 'joints' commands: the base model's inverse "
                           "kinematics is a trailing caster's")
        q0 = checked_vector(q0, self.nq, "q0", broadcast=False)
        v0 = checked_vector(v0, self.nv, "v0", broadcast=False)
        self._build(command)
        mj, m, d = self._mujoco, self.model, self.data
        mj.mj_resetData(m, d)
        mj.mj_forward(m, d)
        self._substeps, self._dt = substeps, dt
        self._rows = (np.empty((substeps, m.nq)), np.empty((substeps, m.nv)),
                      np.empty((substeps, m.nv)))
        self._prepare_substeps()
        self._place(q0)
        self._theta = self._theta_wrapped = float(q0[2]) if self.base is not None else 0.0
        self._hold_q = q0[self.nq - len(self._arm_q):].copy()
        self._hold()
        for _ in range(round(self.settle_s / mjcf.TIMESTEP)):
            self._settle_control()
            mj.mj_step(m, d)
        # back to the asked pose (the settling moved it by micrometres), keeping the height,
        # tilt and contacts it settled to, then the asked velocity
        self._place(q0, keep_height=True)
        d.qvel[:] = 0.0
        if self.base is not None:
            nb = self.nv_base
            twist = np.asarray(self.base.body_map, dtype=float) @ v0[:nb]
            c, s = math.cos(q0[2]), math.sin(q0[2])
            d.qvel[0:2] = (c * twist[0] - s * twist[1], s * twist[0] + c * twist[1])
            d.qvel[5] = twist[2]
            drive, steer = self._wheel_rates(v0[:nb])
            d.qvel[self._wheel_v] = drive
            d.qvel[self._steer_v] = steer
        d.qvel[self._arm_v] = v0[self.nv_base:]
        self._hold()
        mj.mj_forward(m, d)
        q, v = self._read()
        self._v_base_target = v[:self.nv_base].copy()
        return q, v

    def _place(self, q0: np.ndarray, keep_height: bool = False) -> None:
        d = self.data
        if self.base is not None:
            if keep_height:
                w, x, y, z = d.qpos[3:7]
                yaw = self._yaw()
                # remove the settled yaw, keep roll and pitch, then turn to θ0
                half = -0.5 * yaw
                r = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
                tilt = _quat_mul(r, np.array([w, x, y, z]))
            else:
                d.qpos[2] = self.mjcf.base_height
                tilt = np.array([1.0, 0.0, 0.0, 0.0])
                d.qpos[self._steer_q] = 0.0
            half = 0.5 * q0[2]
            d.qpos[3:7] = _quat_mul(np.array([math.cos(half), 0.0, 0.0, math.sin(half)]), tilt)
            d.qpos[0:2] = q0[0:2]
            d.qpos[self._arm_q] = q0[3:]
            self._theta = self._theta_wrapped = float(q0[2])
        else:
            d.qpos[self._arm_q] = q0

    def _hold(self) -> None:
        """Servo references at the present joint positions (intvelocity activations)."""
        d, m = self.data, self.model
        for u, adr in self._act.items():
            d.act[adr] = d.qpos[m.jnt_qposadr[m.actuator_trnid[u, 0]]]
        d.ctrl[:] = 0.0

    def _settle_control(self) -> None:
        if self.command != "acceleration":  # servos hold at zero rates, gravity fed forward
            self.data.qfrc_applied[self._arm_v] = self.data.qfrc_bias[self._arm_v]
            return
        # torque motors on the arm: hold it against gravity and drift (a stiff PD + bias)
        d, m = self.data, self.model
        self._mujoco.mj_forward(m, d)
        bias = d.qfrc_bias[self._arm_v]
        inertia = np.maximum(np.array([m.dof_M0[i] for i in self._arm_v]), 1e-3)
        omega = 2.0 * math.pi * mjcf.SERVO_BANDWIDTH_HZ
        error = self._hold_q - d.qpos[self._arm_q]
        d.ctrl[self._arm_u] = bias + inertia * (omega**2 * error
                                                - 2.0 * omega * d.qvel[self._arm_v])

    def _prepare_substeps(self) -> None:
        """The sub-step loop's buffers for this reset's command, and the compiled loop's
        arguments when it runs the periods (:mod:`wbc.sim.mujoco_substeps`)."""
        m, kind, n = self.model, self.command, self._substeps
        accelerate = kind == "acceleration"
        # a steered base's wheel targets follow its steering angles: set per sub-step in Python
        self._steered = self.kind == "steerable" and kind in ("velocity", "acceleration")
        unsteered = self.base is not None and kind in ("velocity", "acceleration") \
            and not self._steered
        self._drives = np.empty((n, len(self._wheel_u))) if unsteered else None
        # the powered wheels' rates = base velocity coordinates · this
        self._wheel_jacobian = (self._jacobian.T[:, self._powered] if unsteered
                                else np.zeros((0, 0)))
        # the velocity targets' ramp over the period: the integrated commanded acceleration
        self._ramp = np.arange(1, n + 1) * mjcf.TIMESTEP if accelerate else np.zeros(n)
        self._qacc = np.zeros(m.nv)
        self._tau = np.zeros(m.nv)
        self._damping = np.zeros(len(self._arm_v))
        self._limit = np.ascontiguousarray(self.mjcf.arm_torque, dtype=float)
        compiled = None if self._steered else mujoco_substeps.library()
        self.compiled_substeps = compiled is not None
        if compiled is None:
            return
        self._compiled = compiled
        # the arrays the library reads and writes through raw pointers: kept alive here
        self._compiled_index = tuple(np.ascontiguousarray(i, dtype=np.intc) for i
                                     in (self._wheel_u, self._arm_v, self._arm_u))
        self._compiled_error = ctypes.create_string_buffer(1024)
        wheel_u, arm_v, arm_u = self._compiled_index
        drives, qacc = self._drives, self._qacc

        def address(array):
            return None if array is None else array.ctypes.data

        self._compiled_arguments = (
            m._address, self.data._address, n,
            0 if drives is None else len(wheel_u), address(wheel_u), address(drives),
            address(qacc) if accelerate else None, address(self._tau),
            len(arm_v) if accelerate else 0, address(arm_v), address(arm_u),
            address(self._damping), address(self._limit),
            *(address(rows) for rows in self._rows),
            ctypes.addressof(self._compiled_error), len(self._compiled_error))

    def _python_substeps(self, start: np.ndarray, slope: np.ndarray) -> None:
        """The period's sub-steps in Python: the compiled loop's twin (the same MuJoCo calls in
        the same order; see :mod:`wbc.sim.mujoco_substeps`), and the only loop for a steered
        base's velocity or acceleration commands (``start``, ``slope``: the base's velocity
        target at the period's start and its rate, for the wheels' inverse kinematics)."""
        mj, m, d = self._mujoco, self.model, self.data
        h = mjcf.TIMESTEP
        accelerate = self.command == "acceleration"
        drives, qacc, tau = self._drives, self._qacc, self._tau
        damping, limit = self._damping, self._limit
        qpos_rows, qvel_rows, force_rows = self._rows
        # MuJoCo's arrays bound once (each attribute read makes a new view) and the index
        # arrays as slices where contiguous: the loop below runs 1000 times a simulated second
        qpos, qvel, ctrl, d_qacc, qfrc = d.qpos, d.qvel, d.ctrl, d.qacc, d.qfrc_actuator
        arm_v, arm_u, wheel_u = self._arm_v_fast, self._arm_u_fast, self._wheel_u_fast
        for k in range(self._substeps):
            if drives is not None:
                ctrl[wheel_u] = drives[k]
            elif self._steered:
                target = start + slope * (k + 1) * h if accelerate else start
                drive, steer = self._wheel_rates(target)
                ctrl[wheel_u] = drive[self._powered]
                ctrl[self._steer_u] = steer
            if accelerate:
                mj.mj_step1(m, d)
                d_qacc[:] = qacc
                mj.mj_rne(m, d, 1, tau)
                torque = tau[arm_v] + damping * qvel[arm_v]
                ctrl[arm_u] = np.minimum(np.maximum(torque, -limit, out=torque), limit,
                                         out=torque)
                mj.mj_step2(m, d)
            else:
                mj.mj_step(m, d)
            # recorded per sub-step, evaluated after the period (vectorised)
            qpos_rows[k] = qpos
            qvel_rows[k] = qvel
            force_rows[k] = qfrc

    def step(self, command) -> PlantStep:
        """Advance one control period under ``command`` (see the module docstring)."""
        if self._substeps == 0:
            raise WbcError("MujocoPlant.step: call reset(q0, v0, dt, command) first")
        mj, m, d = self._mujoco, self.model, self.data
        command = np.asarray(command, dtype=float).reshape(-1)
        if not all_finite(command):
            raise NonFiniteError("MujocoPlant: the command contains NaN or inf")
        nb, kind = self.nv_base, str(self.command)  # set by reset
        n_wheels = len(self._wheel_v)
        sizes = {"torque": (n_wheels, n_wheels + len(self._arm_v)),
                 "joints": (n_wheels + len(self._steer_v) + len(self._arm_v),)}.get(kind,
                                                                                  (self.nv,))
        if command.shape[0] not in sizes:
            raise ShapeError(f"MujocoPlant: a {kind} command must have "
                             f"{' or '.join(map(str, sizes))} entries, got {command.shape[0]}")
        h = mjcf.TIMESTEP
        warned = d.warning.number[self._unstable].sum()
        arm_q0 = d.qpos[self._arm_q].copy()
        wheel_q0 = d.qpos[self._wheel_q].copy()
        steer_q0 = d.qpos[self._steer_q].copy()
        if kind != "acceleration":
            # the arm servos' gravity and Coriolis feedforward (joint torques), held over the
            # period
            d.qfrc_applied[self._arm_v] = d.qfrc_bias[self._arm_v]
        # the base's velocity target at the period's start and its rate over the period (none
        # for torque and joints commands)
        start = slope = np.zeros(nb)
        if kind == "velocity":
            d.ctrl[self._arm_u] = command[nb:]
            start, slope = command[:nb], np.zeros(nb)
        elif kind == "acceleration":
            start, slope = self._v_base_target, command[:nb]
            # the arm's and the base's commanded accelerations (wheels, rollers and springs
            # taken unaccelerated), for the arm's inverse dynamics
            qacc = self._qacc
            qacc[:] = 0.0
            qacc[self._arm_v] = command[nb:]
            if self.base is not None:
                qacc[:6] = self._base_acceleration(command[:nb])
            np.take(m.dof_damping, self._arm_v, out=self._damping)
        elif kind == "joints":
            n_drive_steer = n_wheels + len(self._steer_v)
            d.ctrl[self._wheel_u] = command[:n_wheels][self._powered]
            d.ctrl[self._steer_u] = command[n_wheels:n_drive_steer]
            d.ctrl[self._arm_u] = command[n_drive_steer:]
            if self.wheel_targets == "present":  # targets: where the wheels are + Δθ, held
                d.act[self._wheel_act] = (d.qpos[self._wheel_act_q]
                                          + d.ctrl[self._wheel_u] * self._dt)
                d.ctrl[self._wheel_u] = 0.0
        else:
            d.ctrl[self._wheel_u] = command[:n_wheels][self._powered]
            d.ctrl[self._arm_u] = command[n_wheels:] if command.size > n_wheels else 0.0
        if self._drives is not None:  # the unsteered wheels' servo targets, all at once
            np.matmul(start + self._ramp[:, None] * slope, self._wheel_jacobian,
                      out=self._drives)
        if self.compiled_substeps:
            if self._compiled(*self._compiled_arguments):
                raise mj.FatalError(self._compiled_error.value.decode())
        else:
            self._python_substeps(start, slope)
        qpos_rows, qvel_rows, force_rows = self._rows
        n = self._substeps
        # the means below as sums / n: numpy's mean without its Python overhead, the same
        # numbers (the same arrays summed in the same order)
        saturated = (np.abs(force_rows.take(self._sat_v, axis=1)) >= self._sat_limit).sum(
            axis=0) / n
        if not all_finite(d.qpos) or d.warning.number[self._unstable].sum() > warned:
            raise NonFiniteError(f"MujocoPlant: the simulation diverged at t = {d.time:.4g} s "
                                 "(MuJoCo found NaN, inf or huge values in its state and reset "
                                 "it)")
        if kind == "acceleration":
            self._v_base_target = start + command[:nb] * self._dt
        q, v = self._read()
        dt = self._dt
        v_meas = np.empty(self.nv)
        v_meas[nb:] = (d.qpos[self._arm_q] - arm_q0) / dt
        signals: dict = {"saturation": saturated}
        if self.base is not None:
            rates = (d.qpos[self._wheel_q] - wheel_q0) / dt
            if self.kind == "steerable":
                steering = d.qpos[self._steer_q]
                v_meas[:nb] = self._steered_odometry(rates, 0.5 * (steering + steer_q0),
                                                     (steering - steer_q0) / dt)
            else:
                v_meas[:nb] = self.base.forward(rates)
            if kind == "velocity":
                self._v_base_target = command[:nb].copy()
            slips, lateral = self._slips(qpos_rows, qvel_rows)
            signals["wheel_torque"] = np.add.reduce(force_rows[:, self._wheel_v], axis=0) / n
            slip_sum = np.add.reduce(slips, axis=0)
            signals["wheel_slip"] = slip_sum / n
            signals["slip_distance"] = slip_sum * h
            if self.kind == "differential":
                signals["lateral_slip"] = float(np.add.reduce(lateral) / n)
            normal, utilisation = self._contacts(n_wheels)
            signals["normal_forces"] = normal
            signals["friction_utilisation"] = utilisation
            w, x, y, z = d.qpos[3:7].tolist()  # the base's tilt: its z axis from the vertical
            signals["base_tilt"] = math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y))))
        if not self.odometry:
            return PlantStep(q, v, v.copy(), signals, q_measured=q.copy())
        return PlantStep(q, v, v_meas, signals)

    def _steered_odometry(self, drive_rates: np.ndarray, steering: np.ndarray,
                          steer_rates: np.ndarray) -> np.ndarray:
        """Base twist ``(v_x, v_y, ω)`` from the steered wheels' encoders: least squares over
        each wheel's rolling and no-slip rows for its geometry (:meth:`_slip`'s, zero slip)."""
        c, s = np.cos(steering), np.sin(steering)
        hx, hy = self._hips[:, 0], self._hips[:, 1]
        d, r = self.mjcf.offset, float(self.base.radius)
        rolling = np.column_stack([c, s, hx * s - hy * c])
        lateral = np.column_stack([-s, c, hx * c + hy * s])
        if self.steer_offset == "trailing":  # across: n·v_h − (ω + β̇) d = 0
            lateral[:, 2] -= d
            rhs = np.concatenate([r * drive_rates, d * steer_rates])
        else:  # along: e·v_h + (ω + β̇) d = r φ̇
            rolling[:, 2] += d
            rhs = np.concatenate([r * drive_rates - d * steer_rates, np.zeros_like(steering)])
        return np.linalg.lstsq(np.vstack([rolling, lateral]), rhs, rcond=None)[0]

    def _base_acceleration(self, acceleration: np.ndarray) -> np.ndarray:
        """The free joint's acceleration (world linear, body angular) of a commanded base
        acceleration in the base's own coordinates (its frame; turning about the vertical),
        with the centripetal term of the present motion."""
        a = np.asarray(self.base.body_map, dtype=float) @ acceleration  # (a_x, a_y, α)
        yaw = self._yaw()
        c, s = math.cos(yaw), math.sin(yaw)
        omega = self._twist()[2]
        vx, vy = self.data.qvel[0], self.data.qvel[1]
        return np.array([c * a[0] - s * a[1] - omega * vy, s * a[0] + c * a[1] + omega * vx,
                         0.0, 0.0, 0.0, a[2]])

    def _slips(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per sub-step (the rows of MuJoCo's ``qpos`` and ``qvel``) and wheel the slip speed
        [m/s] at the contact, ``(n, n_wheels)``, and the base's lateral speed [m/s], ``(n,)``."""
        w, x, y, z = qpos[:, 3], qpos[:, 4], qpos[:, 5], qpos[:, 6]
        yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        c, s = np.cos(yaw), np.sin(yaw)
        vx = c * qvel[:, 0] + s * qvel[:, 1]
        vy = -s * qvel[:, 0] + c * qvel[:, 1]
        # world z component of the body-frame angular velocity: third row of R(quat)
        omega = ((2.0 * (x * z - w * y)) * qvel[:, 3] + (2.0 * (y * z + w * x)) * qvel[:, 4]
                 + (1.0 - 2.0 * (x * x + y * y)) * qvel[:, 5])
        r = float(self.base.radius)
        rates = qvel[:, self._wheel_v]
        if self.kind == "steerable":
            # the contact's slip from the wheel's own geometry: e the rolling direction, n the
            # axle's; the hip moves at v_h; a trailing contact (h − d e) also moves across by
            # −(ω + β̇) d, a sideways one (h − d n) along by +(ω + β̇) d
            beta = qpos[:, self._steer_q]
            cb, sb = np.cos(beta), np.sin(beta)
            hips = self._hips
            hx = vx[:, None] - omega[:, None] * hips[:, 1]
            hy = vy[:, None] + omega[:, None] * hips[:, 0]
            turn = (omega[:, None] + qvel[:, self._steer_v]) * self.mjcf.offset
            along = cb * hx + sb * hy - r * rates
            across = -sb * hx + cb * hy
            if self.steer_offset == "trailing":
                across = across - turn
            else:
                along = along + turn
            return np.hypot(along, across), np.zeros(len(qpos))
        J = self._jacobian
        coordinates = (np.column_stack([vx, omega]) if self.nv_base == 2
                       else np.column_stack([vx, vy, omega]))
        return np.abs(r * (coordinates @ J.T - rates)), np.abs(vy)

    def _contacts(self, n_wheels: int) -> tuple[np.ndarray, np.ndarray]:
        mj, m, d = self._mujoco, self.model, self.data
        normal = np.zeros(n_wheels)
        utilisation = np.zeros(n_wheels)
        force = self._force
        wheels = self._geom_wheel[d.contact.geom].max(axis=1)  # each contact's (−1: none)
        for i, wheel in enumerate(wheels.tolist()):
            if wheel < 0:
                continue
            mj.mj_contactForce(m, d, i, force)
            normal_force, f1, f2 = force[:3].tolist()
            normal[wheel] += normal_force
            if normal_force > 0:
                share = math.hypot(f1, f2) / (self.mu * normal_force)
                utilisation[wheel] = max(utilisation[wheel], share)
        return normal, utilisation


def _contiguous(index: np.ndarray):
    """``index`` as a slice when its entries are consecutive (faster to read and write through),
    else itself."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (w, x, y, z)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
