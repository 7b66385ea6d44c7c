"""Rigid-body dynamics of the omni platform with Coulomb friction at the wheels (a ``wbc.sim``
actuation model for torque or wheel-angle commands).

:class:`OmniDynamics` replaces the kinematic actuation chain for the four-omni-wheel platform
of the torque-redundancy paper (``"omni4_arm6"``): the controller commands wheel torques
(``Simulation(..., command="torque")``) — or, with ``servo="angle"`` / ``"angle_target"``,
wheel angle commands that the wheels' own PID servos (the paper's eq. 4) turn into torques —
and the model
integrates

* the **platform**, a planar rigid body of mass ``m`` (45 kg: the paper's 15 kg platform and
  30 kg arm) and yaw inertia ``I_z``, in body coordinates ``v = (v_x, v_y, ω)``::

      m (v̇_x − ω v_y) = F_x,   m (v̇_y + ω v_x) = F_y,   I_z ω̇ = M_z,   (F_x, F_y, M_z) = Gᵀ F

  with ``G = r J`` (row ``i``: wheel ``i``'s driving direction ``u_i`` and lever ``L``) and
  ``F_i`` [N] the ground's tangential force on wheel ``i`` (the rollers leave the radial
  direction free);
* the **wheels**, each a rotor of inertia ``I_w`` (wheel, gear and motor reflected to the
  wheel axis): ``I_w θ̈_i = τ_i − r_i F_i``;
* **Coulomb friction** at each contact: ``|F_i| ≤ μ_i f_i`` with ``f_i`` the wheel's normal
  force (:func:`wbc.robots.normal_forces` at the whole system's centre of mass,
  :func:`wbc.robots.system_com`, which moves with the arm). A wheel sticks (its rim speed
  ``r_i θ̇_i`` equals its contact point's speed ``(G v)_i``) while the force that takes is
  within the cone; otherwise it slips and its force saturates at ``±μ_i f_i`` in the direction
  of the slip.

Time stepping: each control tick is cut into ``substeps`` sub-steps of ``h = dt / substeps``
(the servo controllers' 1 ms period for ``dt = 10 ms``). A sub-step is semi-implicit: the
torques are held, the contact forces are the ones that make the next slip velocities
``s⁺ = s_free − A F`` (``A = h (R² / I_w + G M⁻¹ Gᵀ)``, ``R = diag(r_i)``) consistent with
Coulomb's law — the box-constrained QP ``min ½ Fᵀ A F − s_freeᵀ F, |F_i| ≤ μ_i f_i``, whose
optimality conditions are exactly "stick inside the cone, slip (with ``sign s⁺_i = sign F_i``)
on its boundary" (the standard velocity-level time-stepping of friction, maximal dissipation).
It is solved exactly by a small active-set loop (:func:`coulomb_forces`). The normal forces
are evaluated once per tick at the tick's configuration (the arm moves slowly); the inertial
coupling of the centre of mass's offset from the platform centre and the arm's own dynamics
are neglected (the arm only shifts the load between the wheels).

What the encoders see: the wheels' own rotation. Odometry is ``v_measured = J⁺ θ̇`` with the
nominal wheel radius — exact while every wheel sticks and the radii are nominal; a slipping
wheel (or a wheel whose real radius differs, ``radius_error``) makes it differ from the truth.

Servo errors (documented, seeded): each wheel produces ``(1 + gain_error_i) τ_i + σ ε`` with a
fixed relative gain error per wheel and a torque noise ``ε ~ N(0, 1)`` drawn each tick from the
run's generator (held over the tick).

Recorded signals (per tick): ``"slip_distance"`` (4,) [m] — ``∫ |s_i| dt`` over the tick, the
distance each contact slid; ``"friction_utilisation"`` (4,) — the tick's peak of
``|F_i| / (μ_i f_i)`` (1 while slipping); ``"wheel_torque"`` (4,) [N m] — the tick's mean
torque actually produced; ``"normal_forces"`` (4,) [N]; ``"wheel_rates"`` (4,) [rad/s] at the
tick's end.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from wbc.checks import checked_vector
from wbc.errors import InvalidValueError, ShapeError, WbcError
from wbc.robots.omni import normal_forces, system_com
from wbc.sim.actuation import Actuation, ActuationState

from . import dynamics_c

__all__ = ["OmniDynamics", "coulomb_forces"]

#: default yaw inertia [kg m²] of platform + arm about the platform centre: the platform as a
#: 15 kg cylinder of radius 0.26 m (½ m r² ≈ 0.5) plus the 30 kg arm with a radius of gyration
#: of about 0.2 m about the centre (≈ 1.2); rounded up for the arm links' own inertia.
YAW_INERTIA = 2.0
#: default rotor inertia of one wheel [kg m²] reflected to the wheel axis (wheel, gear, motor):
#: the paper gives neither the gear ratio nor the motor; a geared DC servo of this size puts
#: its rotor inertia, multiplied by the squared reduction, in this range.
WHEEL_INERTIA = 0.02
#: default gains of the wheel servos' PID (eq. 4), wheel side: k_p [N m/rad], k_v
#: [N m s/rad], k_i [N m/(rad s)] — a platform mode near 10 rad/s, about critically damped.
SERVO_GAINS = (22.5, 4.5, 50.0)


def coulomb_forces(A, s_free, limit, A_inv=None) -> tuple[np.ndarray, np.ndarray]:
    """Contact forces of one time step under Coulomb friction, and the next slip velocities.

    Solves the box-constrained QP ``min ½ Fᵀ A F − s_freeᵀ F`` s.t. ``|F_i| ≤ limit_i`` by an
    active-set loop (a wheel over its limit is put on the bound, a bound wheel whose slip does
    not point its way is released); its optimality conditions with ``s⁺ = s_free − A F`` are
    Coulomb's law: ``s⁺_i = 0`` inside, ``sign s⁺_i = sign F_i`` on the bound.

    Args:
        A: (n, n) symmetric positive definite, ``∂s⁺/∂(−F)`` [m/s per N].
        s_free: (n,) slip velocities without contact forces [m/s].
        limit: (n,) friction limits ``μ_i f_i`` [N], ≥ 0.
        A_inv: ``A⁻¹`` if known (the common all-stick case then costs one product).

    Returns:
        ``(F [N], s⁺ [m/s])``.
    """
    if A_inv is not None:
        F = A_inv @ s_free
        if (np.abs(F) <= limit).all():
            return F, s_free - A @ F
    n = s_free.size
    bound = limit <= 0.0  # an unloaded wheel transmits nothing
    sign = np.zeros(n)
    force_tol = 1e-12 * (1.0 + limit.max())
    slip_tol = 1e-12 * (1.0 + np.abs(s_free).max())
    for _ in range(8 * n):
        F = np.where(bound, sign * limit, 0.0)
        free = ~bound
        if free.any():
            F[free] = np.linalg.solve(A[free][:, free], s_free[free] - A[free][:, bound] @ F[bound])
        slip = s_free - A @ F
        excess = np.where(free, np.abs(F) - limit, 0.0)
        if excess.max() > force_tol:
            i = int(np.argmax(excess / np.maximum(limit, 1e-300)))
            bound[i], sign[i] = True, np.sign(F[i])
            continue
        wrong = np.where(bound & (sign != 0.0), -sign * slip, 0.0)
        if wrong.max() <= slip_tol:
            return F, slip
        i = int(np.argmax(wrong))
        bound[i], sign[i] = False, 0.0
    raise WbcError("coulomb_forces: the active-set loop did not settle (A not positive "
                   "definite?)")


class OmniDynamics(Actuation):
    """Platform dynamics with per-wheel Coulomb friction, wheel servos and servo errors.

    Args:
        mu: friction coefficient(s) μ_i [-] between wheel and ground (scalar or (4,), > 0).
        servo: ``"torque"`` — the command holds the wheel torques [N m]; ``"angle"`` — wheel
            angle increments Δθ [rad] (eq. 3), tracked by each wheel's PID servo (eq. 4) at the
            sub-step rate on the wheel's own encoder, the target being the wheel's angle at the
            tick's start plus Δθ; ``"angle_target"`` — the same servos tracking absolute wheel
            angle targets [rad], counted from the run's start. The servos' integral persists.
        gains: the servos' ``(k_p, k_v, k_i)`` (angle servos), wheel side.
        active: which wheels are powered, (n_wheels,) bools (default all); an unpowered wheel
            gets no torque and rolls freely (the paper's two-motor experiment).
        gain_error: relative torque gain error(s) of the servos [-], scalar or (n_wheels,).
        torque_noise: standard deviation σ of the torque noise [N m], drawn per tick and wheel.
        radius_error: relative error(s) of the real wheel radii [-] (odometry assumes the
            nominal one).
        wheel_inertia: ``I_w`` [kg m²]; yaw_inertia: ``I_z`` [kg m²].
        mass_com: ``fn(robot, q) -> (mass [kg], com (3,) [m] in the base frame)``; default the
            paper's masses, :func:`wbc.robots.system_com`.
        arm_velocity: ``fn(t) -> (n_arm,)`` joint velocities [rad/s] the arm follows exactly
            (it is position-controlled; default at rest); the command carries only the wheels.
        substeps: sub-steps per control tick (≥ 1).
        g: gravity [m/s²].
    """

    def __init__(self, mu=0.5, servo: str = "torque", gains=SERVO_GAINS, active=None,
                 gain_error=0.0, torque_noise: float = 0.0, radius_error=0.0,
                 wheel_inertia: float = WHEEL_INERTIA, yaw_inertia: float = YAW_INERTIA,
                 mass_com: Callable | None = None,
                 arm_velocity: Callable[[float], Any] | None = None, substeps: int = 10,
                 g: float = 9.81) -> None:
        if servo not in ("torque", "angle", "angle_target"):
            raise InvalidValueError(f"servo must be 'torque', 'angle' or 'angle_target', got "
                                    f"{servo!r}")
        if int(substeps) < 1:
            raise InvalidValueError(f"substeps must be >= 1, got {substeps!r}")
        for name, value in (("wheel_inertia", wheel_inertia), ("yaw_inertia", yaw_inertia),
                            ("g", g)):
            if not (np.isfinite(value) and value > 0):
                raise InvalidValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not (np.isfinite(torque_noise) and torque_noise >= 0):
            raise InvalidValueError(f"torque_noise must be >= 0 [N m], got {torque_noise!r}")
        self.mu, self.servo, self.gains, self.active = mu, servo, tuple(gains), active
        self.gain_error, self.torque_noise, self.radius_error = gain_error, torque_noise, \
            radius_error
        self.wheel_inertia, self.yaw_inertia, self.g = wheel_inertia, yaw_inertia, g
        self.mass_com = mass_com if mass_com is not None else (
            lambda robot, q: system_com(robot, q, frame="base"))
        self.arm_velocity, self.substeps = arm_velocity, int(substeps)

    def _per_wheel(self, value, name: str) -> np.ndarray:
        arr = np.asarray(value, dtype=float)
        if arr.ndim == 0:
            arr = np.full(self._n, float(arr))
        if arr.shape != (self._n,):
            raise ShapeError(f"{name} must be a scalar or have shape ({self._n},), got "
                             f"{arr.shape}")
        if not np.isfinite(arr).all():
            raise InvalidValueError(f"{name} must be finite, got {value!r}")
        return arr

    def reset(self, robot, dt: float) -> None:
        base: Any = getattr(robot, "base", None)
        if not hasattr(base, "wheel_positions") or int(robot.nv_base) != 3:
            raise WbcError("OmniDynamics needs a robot on an omni base (robot.base.jacobian, "
                           f"wheel_positions), got {type(base).__name__}")
        self._J = np.asarray(base.jacobian, dtype=float)
        self._n = self._J.shape[0]
        self._r = float(base.radius)
        self._G = self._r * self._J  # rows (u_i, L): contact speeds per twist
        self._J_pinv = np.linalg.pinv(self._J)
        self._wheel_xy = np.asarray(base.wheel_positions, dtype=float)
        self._mu = self._per_wheel(self.mu, "mu")
        if (self._mu <= 0).any():
            raise InvalidValueError(f"mu must be > 0, got {self.mu!r}")
        radius_error = self._per_wheel(self.radius_error, "radius_error")
        if (radius_error <= -1).any():
            raise InvalidValueError(f"radius_error must be > -1, got {self.radius_error!r}")
        self._radii = self._r * (1.0 + radius_error)
        self._gain = 1.0 + self._per_wheel(self.gain_error, "gain_error")
        active = np.ones(self._n, bool) if self.active is None else np.asarray(self.active)
        if active.shape != (self._n,):
            raise ShapeError(f"active must have shape ({self._n},), got {active.shape}")
        self._gain = self._gain * active.astype(float)
        self._h = dt / self.substeps
        self._dt = dt
        mass, _ = self.mass_com(robot, robot.neutral())
        self._mass = float(mass)
        self._M_inv = np.diag([1.0 / mass, 1.0 / mass, 1.0 / self.yaw_inertia])
        R = self._radii
        self._A = self._h * (np.diag(R**2 / self.wheel_inertia)
                             + self._G @ self._M_inv @ self._G.T)
        self._A_inv = np.linalg.inv(self._A)
        self._n_arm = int(robot.nv) - 3
        # wheel state, initialised from the first tick's velocity (rolling without slip)
        self._rates: np.ndarray | None = None
        self._integral = np.zeros(self._n)
        self._angle = np.zeros(self._n)  # wheel angles since the run's start [rad]

    def normal_forces(self, robot, q) -> np.ndarray:
        """The wheels' normal forces [N] in configuration ``q`` (true configuration)."""
        mass, com = self.mass_com(robot, q)
        return normal_forces(self._wheel_xy, np.asarray(com)[:2], mass, self.g)

    def apply(self, state: ActuationState) -> None:
        command = np.asarray(state.command, dtype=float)
        if command.shape != (self._n,):
            raise ShapeError(f"OmniDynamics: the command must hold the {self._n} wheel "
                             f"{'torques' if self.servo == 'torque' else 'angle commands'}, "
                             f"got shape {command.shape}")
        v = state.v[:3].copy()
        if self._rates is None:
            self._rates = (self._G @ v) / self._radii
        rates = self._rates
        normal = self.normal_forces(state.robot, state.q)
        limit = self._mu * normal
        # an unpowered wheel gets no noise either
        noise = self.torque_noise * state.rng.standard_normal(self._n) * (self._gain != 0)
        if self.servo == "torque":  # the torques hold over the tick
            command = self._gain * command + noise
        elif self.servo == "angle_target":  # as angles since the tick's start [rad]
            command = command - self._angle
        compiled = dynamics_c.library() if self._n == 4 else None
        run = self._python_substeps if compiled is None else self._compiled_substeps
        v, rates, turned, slid, peak, torque_sum = run(v, rates, command, limit, noise)
        self._rates = rates
        self._angle += turned
        state.v_true = np.empty(int(state.robot.nv))
        state.v_measured = np.empty_like(state.v_true)
        state.v_true[:3] = v
        state.v_measured[:3] = self._J_pinv @ rates
        arm = (np.zeros(self._n_arm) if self.arm_velocity is None
               else checked_vector(self.arm_velocity(state.t), self._n_arm, "arm_velocity(t)",
                                   broadcast=False))
        state.v_true[3:] = arm
        state.v_measured[3:] = arm
        state.signals["slip_distance"] = slid
        state.signals["friction_utilisation"] = peak
        state.signals["wheel_torque"] = torque_sum / self.substeps
        state.signals["normal_forces"] = normal
        state.signals["wheel_rates"] = rates.copy()

    def _python_substeps(self, v, rates, command, limit, noise):
        """The tick's sub-steps in numpy (the compiled loop's referee, and the loop where no
        compiler is at hand): ``command`` holds the torques [N m] (``servo="torque"``) or the
        servos' targets [rad] as angles since the tick's start; ``v`` (3,) [m/s, rad/s] the
        platform's twist and ``rates`` [rad/s] the wheels' at the tick's start, ``limit`` [N]
        the friction limits, ``noise`` [N m] the servos' torque noise. Advances the servos'
        integral; returns the tick's end ``v`` and ``rates`` and its ``turned`` [rad],
        ``slid`` [m], ``peak`` utilisation and ``torque_sum`` [N m] (over the sub-steps)."""
        kp, kv, ki = self.gains
        h, R, G, M_inv = self._h, self._radii, self._G, self._M_inv
        inertia, A, A_inv = self.wheel_inertia, self._A, self._A_inv
        safe_limit = np.maximum(limit, 1e-300)
        torque_servo = self.servo == "torque"
        if torque_servo:
            tau = command
            drive = h * R * tau / inertia
        turned = np.zeros(self._n)  # wheel angle since the tick's start [rad]
        slid = np.zeros(self._n)
        peak = np.zeros(self._n)
        torque_sum = np.zeros(self._n)
        for _ in range(self.substeps):
            if not torque_servo:  # eq. 4 on the wheel's own encoder; the target holds
                error = command - turned
                self._integral += error * h
                tau = self._gain * (kp * error - kv * rates + ki * self._integral) + noise
                drive = h * R * tau / inertia
            coriolis = np.array([v[2] * v[1], -v[2] * v[0], 0.0])
            s_free = R * rates + drive - G @ (v + h * coriolis)
            F, slip = coulomb_forces(A, s_free, limit, A_inv)
            rates = rates + h * (tau - R * F) / inertia
            v = v + h * (coriolis + M_inv @ (G.T @ F))
            turned += h * rates
            slid += h * np.abs(slip)
            peak = np.maximum(peak, np.abs(F) / safe_limit)
            torque_sum += tau
        return v, rates, turned, slid, peak, torque_sum

    def _compiled_substeps(self, v, rates, command, limit, noise):
        """:meth:`_python_substeps` (same arguments and results) by the compiled loop of
        :mod:`papers.omni.dynamics_c` (four wheels)."""
        v, rates = v.copy(), rates.copy()
        turned, slid, peak, torque_sum = (np.zeros(self._n) for _ in range(4))
        kp, kv, ki = self.gains
        failed = dynamics_c.library()(
            self.substeps, int(self.servo != "torque"), self._h, float(self.wheel_inertia),
            float(kp), float(kv), float(ki), self._radii, self._G, self._M_inv, self._A,
            self._A_inv, limit, np.maximum(limit, 1e-300), self._gain, noise,
            np.ascontiguousarray(command, dtype=float), v, rates, self._integral, turned, slid,
            peak, torque_sum)
        if failed:
            raise WbcError("coulomb_forces: the active-set loop did not settle (A not positive "
                           "definite?)")
        return v, rates, turned, slid, peak, torque_sum
