"""Actuation models: how a commanded velocity becomes the robot's real motion.

Each tick the simulator hands an :class:`ActuationState` through the chain of models given to
:class:`~wbc.sim.Simulation`, in order. ``state.v_true`` (the velocity the robot really moves
with) and ``state.v_measured`` (what its encoders and odometry report, from which the
controller's estimate is integrated) both start as ``state.v_command``, the velocity asked for
(for acceleration commands the truth starts from its own velocity, ``v + a·dt``); each model
rewrites them. Models may record per-tick numbers in ``state.signals`` (they become
``run.signals``).

=====================  ==================================================================
model                  effect
=====================  ==================================================================
:class:`Exact`         none (the default when no model is given)
:class:`Lag`           first-order actuator lag with time constant τ
:class:`Saturation`    velocity and acceleration (rate) limits
:class:`OdometryError` the base moves with a scale error and noise; odometry believes the
                       command, so the estimated base pose drifts from the true one
:class:`WheelSlip`     per-wheel traction limited to μ·f_normal: a wheel asked for more
                       slips, the base accelerates less than commanded, odometry (wheel
                       encoders) believes the command
=====================  ==================================================================

Order matters and follows the physics: e.g. ``[OdometryError(...), Lag(...), Saturation(...),
WheelSlip(...)]``. :class:`OdometryError` changes what the command means on the ground (the
wheel-to-ground ratio), so it comes first — the simulator refuses it elsewhere: after a model
that works from the previous true velocity (a lag, the slip dynamics) its scale would compound
from tick to tick. A model of your own subclasses :class:`Actuation`.

``joints`` selects velocity coordinates: ``"base"`` (the base's, ``robot.nv_base`` first
entries), ``"arm"`` (the rest), ``None`` (all), or an index array / slice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InvalidValueError, ShapeError, WbcError

__all__ = ["Actuation", "ActuationState", "Exact", "Lag", "OdometryError", "Saturation",
           "WheelSlip"]


@dataclass
class ActuationState:
    """One tick as the actuation models see it (arrays of the robot's ``nv`` unless noted).

    Attributes:
        dt: period [s]; t: tick start [s]; rng: the run's seeded ``numpy`` generator.
        robot: the robot model.
        command: the controller's raw command.
        q, v: true configuration and velocity at the tick's start.
        q_est, v_est: the controller's estimate at the tick's start.
        v_command: the velocity asked for (``None`` for raw commands such as torques).
        v_true: the velocity the robot moves with (set by the models).
        v_measured: what encoders and odometry report (set by the models).
        signals: per-tick numbers to record, ``name -> float | array``.
    """

    dt: float
    t: float
    rng: np.random.Generator
    robot: Any
    command: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_est: np.ndarray
    v_est: np.ndarray
    v_command: Any  # np.ndarray, or None for raw commands
    v_true: Any = None  # np.ndarray once set (None only until a raw command is turned into one)
    v_measured: Any = None
    signals: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.v_command is not None:
            self.v_true = self.v_command.copy()
            self.v_measured = self.v_command.copy()


class Actuation:
    """Base class of the actuation models: override :meth:`apply` (and :meth:`reset` if the
    model keeps state between ticks)."""

    def reset(self, robot, dt: float) -> None:
        """Called once at the start of every run (robot and period known)."""

    def apply(self, state: ActuationState) -> None:
        """Rewrite ``state.v_true`` / ``state.v_measured`` for this tick."""
        raise NotImplementedError

    @staticmethod
    def _require_velocity(state: ActuationState, what: str) -> None:
        if state.v_true is None:
            raise WbcError(f"{what} acts on velocities: put a model that turns the raw "
                           "command into a velocity before it")


def _indices(joints, robot) -> np.ndarray:
    nv = int(robot.nv)
    nb = int(getattr(robot, "nv_base", 0))
    if joints is None:
        return np.arange(nv)
    if isinstance(joints, str):
        if joints == "base":
            if nb == 0:
                raise WbcError("joints='base': the robot has no base velocity coordinates")
            return np.arange(nb)
        if joints == "arm":
            return np.arange(nb, nv)
        raise InvalidValueError(f"joints must be 'base', 'arm', None, indices or a slice, got "
                                f"{joints!r}")
    return np.arange(nv)[joints]


def _per_joint(value, size: int, what: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (size,)).copy()
    if np.isnan(arr).any() or (arr < 0).any():
        raise InvalidValueError(f"{what} must be >= 0 (inf for none), got {value!r}")
    return arr


class Exact(Actuation):
    """The robot moves exactly as commanded and measures it exactly."""

    def apply(self, state: ActuationState) -> None:
        self._require_velocity(state, "Exact")


class Lag(Actuation):
    """First-order actuator lag: ``τ v̇ = v_cmd − v`` on the selected joints, integrated exactly
    over a tick (``v ← v + (1 − e^{−dt/τ}) (v_cmd − v)``). Encoders see the lagged motion.

    Args:
        tau: time constant(s) τ [s] (> 0; scalar or one per selected joint).
        joints: see the module docstring (default: all).
    """

    def __init__(self, tau, joints=None) -> None:
        self.tau, self.joints = tau, joints

    def reset(self, robot, dt: float) -> None:
        self._idx = _indices(self.joints, robot)
        tau = np.broadcast_to(np.asarray(self.tau, dtype=float), self._idx.shape)
        if not (np.isfinite(tau).all() and (tau > 0).all()):
            raise InvalidValueError(f"Lag: tau must be finite and > 0 [s], got {self.tau!r}")
        self._gain = 1.0 - np.exp(-dt / tau)

    def apply(self, state: ActuationState) -> None:
        self._require_velocity(state, "Lag")
        i, k = self._idx, self._gain
        state.v_true[i] = state.v[i] + k * (state.v_true[i] - state.v[i])
        state.v_measured[i] = state.v_est[i] + k * (state.v_measured[i] - state.v_est[i])


class Saturation(Actuation):
    """Velocity and acceleration limits of the actuators: the velocity change over a tick is
    clipped to ``±acceleration·dt``, then the velocity to ``±velocity`` (rate limit, then
    saturation: the projection onto both intervals, docs/DESIGN.md, math note 5).

    Args:
        velocity: limits [m/s or rad/s] (scalar or one per selected joint; ``inf`` for none).
        acceleration: limits [m/s² or rad/s²] (likewise).
        joints: see the module docstring (default: all).
    """

    def __init__(self, velocity=np.inf, acceleration=np.inf, joints=None) -> None:
        self.velocity, self.acceleration, self.joints = velocity, acceleration, joints

    def reset(self, robot, dt: float) -> None:
        self._idx = _indices(self.joints, robot)
        self._v_max = _per_joint(self.velocity, self._idx.size, "Saturation velocity")
        self._dv_max = _per_joint(self.acceleration, self._idx.size,
                                  "Saturation acceleration") * dt

    def apply(self, state: ActuationState) -> None:
        self._require_velocity(state, "Saturation")
        i = self._idx
        for target, previous in ((state.v_true, state.v), (state.v_measured, state.v_est)):
            rate_limited = np.clip(target[i], previous[i] - self._dv_max,
                                   previous[i] + self._dv_max)
            target[i] = np.clip(rate_limited, -self._v_max, self._v_max)


class OdometryError(Actuation):
    """The base does not move exactly as commanded, and its odometry does not notice.

    True base velocity: ``(1 + scale) ⊙ v_cmd + noise ⊙ N(0, 1)`` on the selected coordinates
    (the first model of the chain: see the module docstring)
    (each tick an independent draw from the run's seeded generator); the measured velocity —
    what wheel odometry reports, and what the controller's pose estimate integrates — stays
    the commanded one. The estimated base pose therefore drifts from the true one, as on a
    real wheeled base (slippage, wheel radius errors); an arm tracking a world target from the
    estimate then misses it by the drift.

    Args:
        scale: relative scale error(s) [-] (scalar or one per selected coordinate), e.g. 0.03.
        noise: standard deviation(s) of the additive noise [m/s, rad/s].
        joints: default ``"base"``.
    """

    def __init__(self, scale=0.03, noise=0.005, joints="base") -> None:
        self.scale, self.noise, self.joints = scale, noise, joints

    def reset(self, robot, dt: float) -> None:
        self._idx = _indices(self.joints, robot)
        self._scale = np.broadcast_to(np.asarray(self.scale, dtype=float), self._idx.shape)
        self._noise = _per_joint(self.noise, self._idx.size, "OdometryError noise")
        if not np.isfinite(self._scale).all() or (self._scale <= -1).any():
            raise InvalidValueError(f"OdometryError: scale must be finite and > -1, got "
                                    f"{self.scale!r}")

    def apply(self, state: ActuationState) -> None:
        self._require_velocity(state, "OdometryError")
        i = self._idx
        draw = state.rng.standard_normal(i.size)
        # from the command, never from the previous true velocity: the error must not compound
        state.v_true[i] = (1.0 + self._scale) * state.v_command[i] + self._noise * draw


class WheelSlip(Actuation):
    """Wheels whose traction is limited by friction: ``|f_i| <= μ·N_i`` per wheel.

    Model (planar, rigid base, base velocity coordinates ``v_b`` with body map ``B``): the
    commanded change of ``v_b`` over the tick needs the generalised force
    ``F = M_b (v_cmd − v)/dt`` with ``M_b = Bᵀ diag(m, m, I_z) B``; the wheels must supply it
    as traction forces ``f`` along their driving directions, ``F = r Jᵀ f`` with the wheel
    Jacobian ``J`` (wheel rates = ``J v_b``) and wheel radius ``r``; the minimum-norm
    ``f = (r Jᵀ)⁺ F`` is what equal wheel servos produce. Each ``f_i`` is clipped to
    ``±μ N_i``; the base then accelerates with what the clipped forces give,
    ``v_true = v + M_b⁻¹ r Jᵀ f_clipped dt``. The wheels turn as commanded (their servos
    follow the command; the difference is slip), so the encoders and odometry report the
    commanded velocity. Recorded signals: ``"wheel_slip"`` — per wheel ``|r θ̇_cmd − r θ̇_true|``
    [m/s], the slip speed at the contact — and ``"friction_utilisation"`` — ``|f_i|/(μ N_i)``
    before clipping.

    Args:
        mu: friction coefficient(s) μ [-] (scalar or one per wheel).
        normal_forces: ``N_i`` [N]: an array, or ``fn(robot, q) -> (n_wheels,)`` evaluated each
            tick at the true configuration (e.g. from the centre of mass); default: the robot's
            weight shared equally.
        mass: moving mass ``m`` [kg] (default ``robot.mass``).
        yaw_inertia: ``I_z`` [kg m²] (default: the base body's, scaled by total/base mass).
        g: gravity [m/s²].

    Needs ``robot.base`` with a wheel ``radius`` and either a constant wheel Jacobian
    ``jacobian`` (omni, mecanum, differential drive) or, for a steerable base, its rolling
    no-slip rows: the wheels are taken steered for the commanded twist
    (``steering_for_twist``) and ``J = P(β)/r`` (``no_slip_matrices``) maps the twist to the
    drive rates — traction along the rolling directions is limited, the lateral forces that
    keep steered wheels from side-slipping are assumed available (an approximation: their
    share of the friction cone is ignored).
    """

    def __init__(self, mu, normal_forces=None, mass: float | None = None,
                 yaw_inertia: float | None = None, g: float = 9.81) -> None:
        self.mu, self.normal_forces, self.mass = mu, normal_forces, mass
        self.yaw_inertia, self.g = yaw_inertia, g

    def reset(self, robot, dt: float) -> None:
        base: Any = getattr(robot, "base", None)
        J = getattr(base, "jacobian", None)
        steered = J is None and hasattr(base, "steering_for_twist")
        if (J is None and not steered) or not hasattr(base, "radius"):
            raise WbcError(f"WheelSlip needs robot.base.radius and a wheel Jacobian "
                           f"(robot.base.jacobian, or a steerable base); {type(base).__name__} "
                           "has none")
        self._base, self._steered, self._r = base, steered, float(base.radius)
        if steered:
            J = base.no_slip_matrices(np.zeros(base.n_wheels))[0] / self._r
        self._J = np.asarray(J, dtype=float)
        n_wheels, nb = self._J.shape
        if nb != int(robot.nv_base):
            raise ShapeError(f"WheelSlip: wheel Jacobian has {nb} columns, the base has "
                             f"{robot.nv_base} velocity coordinates")
        mass = float(robot.mass if self.mass is None else self.mass)
        if self.yaw_inertia is None:
            yaw = float(base.inertia[2, 2]) * mass / float(base.mass)
        else:
            yaw = float(self.yaw_inertia)
        if not (mass > 0 and yaw > 0 and math.isfinite(mass) and math.isfinite(yaw)):
            raise InvalidValueError(f"WheelSlip: mass and yaw inertia must be > 0, got {mass}, "
                                    f"{yaw}")
        B = np.array(base.body_map, dtype=float)
        self._M = B.T @ np.diag([mass, mass, yaw]) @ B
        self._M_inv = np.linalg.inv(self._M)
        self._mu = _per_joint(self.mu, n_wheels, "WheelSlip mu")
        self._dt, self._nb, self._mass = dt, nb, mass
        if self.normal_forces is None:
            self._normal = np.full(n_wheels, mass * self.g / n_wheels)
        elif not callable(self.normal_forces):
            self._normal = _per_joint(self.normal_forces, n_wheels, "WheelSlip normal_forces")

    def apply(self, state: ActuationState) -> None:
        self._require_velocity(state, "WheelSlip")
        nb = self._nb
        normal = (self._normal if not callable(self.normal_forces) else
                  _per_joint(self.normal_forces(state.robot, state.q), self._mu.size,
                             "WheelSlip normal_forces"))
        limit = self._mu * normal
        J = self._J
        if self._steered and np.any(state.v_true[:nb]):
            steering = self._base.steering_for_twist(state.v_true[:nb])
            J = self._base.no_slip_matrices(steering)[0] / self._r
        force_map = self._r * J.T  # base force F = force_map @ f for traction forces f
        wanted = self._M @ (state.v_true[:nb] - state.v[:nb]) / self._dt
        forces = np.linalg.pinv(force_map) @ wanted
        state.signals["friction_utilisation"] = np.abs(forces) / np.maximum(limit, 1e-300)
        clipped = np.clip(forces, -limit, limit)
        achieved = state.v[:nb] + self._M_inv @ (force_map @ clipped) * self._dt
        state.signals["wheel_slip"] = np.abs(self._r * J @ (state.v_true[:nb] - achieved))
        state.v_true[:nb] = achieved
