"""The omni platform's two controllers of the torque-redundancy paper (§3), for ``wbc.sim``.

* :class:`OmniPositionControl` — eq. 3, position control through the wheel Jacobian: each
  tick the wheels are sent the angle increments ``Δθ = D J Δx_b`` that take the platform from
  its present pose ``x`` to the desired one ``x_d`` (``Δx_b = (Rᵀ(φ) (p_d − p), φ_d − φ)``,
  the displacement in the platform frame, where eq. 1's ``J`` applies; two readings of "present
  pose", see the class). Each wheel's servo then closes its own PID loop (eq. 4) — on the real
  robot inside the servo controllers, here in
  :class:`~wbc.papers.omni.dynamics.OmniDynamics` (``servo="angle"`` or ``"angle_target"``).
  ``D = g I`` converts wheel angles into motor angles through the gear ratio ``g``; our servo
  model works on the wheel side, so ``D = I`` here (the reduction cancels between eq. 3 and
  eq. 4's gains).
* :class:`OmniForceControl` — eq. 6, ``f_d = M ẍ_d + k_v (ẋ_d − ẋ) + k_p (x_d − x)`` in the
  world frame, turned into the platform frame and distributed over the four wheel torques
  (eqs. 7–13) by a distribution: the closed forms :func:`wbc.solvers.reference.torque_distribution`
  (default) or any ``fn(f_d, normal_forces) -> tau`` — e.g. the QP stacks'
  :class:`wbc.tasks.TorqueDistribution` on a backend. The normal forces it is given come from
  the whole system's centre of mass in the measured configuration (the arm's joints are
  measured), :func:`wbc.robots.system_com` and :func:`wbc.robots.normal_forces`.

Both are plain objects with ``step(q, v, **references) -> command`` (the wheels' command,
``(4,)``) that :class:`wbc.sim.Simulation` runs; ``q = [x, y, φ, arm joints]`` is the
controller's (odometry) estimate and ``v`` the measured body twist + arm rates. References:
``target`` — the desired pose ``(x_d [m], y_d [m], φ_d [rad])`` in the world; for the force
controller also ``velocity`` ``ẋ_d`` [m/s, m/s, rad/s] and ``acceleration`` ``ẍ_d`` [m/s²,
m/s², rad/s²] in the world (default zero).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np

from wbc.checks import checked_vector
from wbc.errors import InvalidValueError, WbcError
from wbc.robots.omni import normal_forces, system_com

from .closed_form import DISTRIBUTION_METHODS, torque_distribution
from .dynamics import YAW_INERTIA

__all__ = ["OmniForceControl", "OmniPositionControl", "platform_error"]


def platform_error(q, target) -> np.ndarray:
    """``x_d − x`` in the world [m, m, rad], the heading error wrapped to ``(−π, π]``."""
    target = checked_vector(target, 3, "target", broadcast=False)
    error = target - np.asarray(q[:3], dtype=float)
    error[2] = math.remainder(error[2], 2.0 * math.pi)
    return error


def _to_platform(phi: float, world) -> np.ndarray:
    """A world-frame ``(x, y, yaw)`` triple expressed in the platform frame (heading ``phi``)."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([c * world[0] + s * world[1], -s * world[0] + c * world[1], world[2]])


def _reference(references: dict, name: str, required: bool = False) -> np.ndarray:
    if name not in references:
        if required:
            raise WbcError(f"reference {name!r} missing: give the desired platform pose "
                           "(x_d [m], y_d [m], φ_d [rad]) in the world")
        return np.zeros(3)
    return checked_vector(references[name], 3, name, broadcast=False)


class OmniPositionControl:
    """Eq. 3: wheel angle commands ``D J Δx_b`` [rad] towards the target (module docstring).

    Eq. 3 reads ``Δθ(t) = D J (x_d(t) − x(t))`` with ``x(t)`` "the present position"; the text
    does not say where the present position comes from. Two readings, ``present=``:

    * ``"odometry"`` (default) — ``x(t)`` is the odometry pose the controller is given; the
      command is the increment ``Δθ`` from the wheels' present angles, for the servos of
      :class:`~wbc.papers.omni.dynamics.OmniDynamics` with ``servo="angle"``.
    * ``"reference"`` — ``x(t)`` is where the previous command put the platform,
      ``x_d(t − dt)`` (the first tick: the measured start pose), as in the displacement
      commands per sampling time the paper describes for its arm; the increments are summed
      into absolute wheel angle targets (the command, for ``servo="angle_target"``): each
      wheel's servo then tracks its own angle trajectory, and the platform's pose is never fed
      back. One controller per run (it keeps the sum).

    Args:
        robot: a mobile manipulator on an omni base (``"omni4_arm6"``).
        present: ``"odometry"`` or ``"reference"``.
    """

    last_solution = None

    def __init__(self, robot, present: str = "odometry") -> None:
        if present not in ("odometry", "reference"):
            raise InvalidValueError(f"present must be 'odometry' or 'reference', got "
                                    f"{present!r}")
        self.present = present
        self.jacobian = np.asarray(robot.base.jacobian, dtype=float)
        self._previous: np.ndarray | None = None
        self._targets = np.zeros(self.jacobian.shape[0])

    def step(self, q, v=None, **references) -> np.ndarray:
        target = _reference(references, "target", required=True)
        if self.present == "odometry":
            return self.jacobian @ _to_platform(float(q[2]), platform_error(q, target))
        present = np.asarray(q[:3], dtype=float) if self._previous is None else self._previous
        self._targets = self._targets + self.jacobian @ _to_platform(
            float(present[2]), platform_error(present, target))
        self._previous = target
        return self._targets.copy()


class OmniForceControl:
    """Eq. 6 force control with a wheel-torque distribution (module docstring).

    Args:
        robot: a mobile manipulator on an omni base (``"omni4_arm6"``).
        method: distribution of the closed forms, ``"min_norm"``, ``"proportional"`` or
            ``"minmax"`` (ignored when ``distribution`` is given).
        mu: friction coefficient(s) μ_i the distribution assumes (scalar or (4,), > 0).
        kp: position gains ``k_p`` (x, y, yaw) [N/m, N/m, N m/rad].
        kv: velocity gains ``k_v`` (x, y, yaw) [N s/m, N s/m, N m s/rad].
        yaw_inertia: ``M``'s yaw entry [kg m²]; its mass entries are the system's mass
            (:func:`wbc.robots.system_com`, 45 kg).
        distribution: ``fn(f_d (3,), normal_forces (4,)) -> tau (4,)`` replacing the closed
            form (e.g. a :class:`wbc.tasks.TorqueDistribution`; its ``last_solution`` becomes
            this controller's).

    Default gains: ``M ω²`` and ``2 M ω`` with ``ω = 4 rad/s`` (critically damped, a 0.25 s
    time constant, well below the wheels' servo bandwidth), chosen here — the paper gives none.

    Attributes:
        last_wrench: the last ``f_d`` in the platform frame [N, N, N m];
        last_normal_forces: the normal forces [N] it was distributed with.
    """

    def __init__(self, robot, method: str = "proportional", mu=0.5, kp=None, kv=None,
                 yaw_inertia: float = YAW_INERTIA,
                 distribution: Callable | None = None) -> None:
        self.robot = robot
        self.jacobian = np.asarray(robot.base.jacobian, dtype=float)
        self._wheel_xy = np.asarray(robot.base.wheel_positions, dtype=float)
        self.mass = float(system_com(robot, robot.neutral())[0])
        if not (np.isfinite(yaw_inertia) and yaw_inertia > 0):
            raise InvalidValueError(f"yaw_inertia must be > 0 [kg m²], got {yaw_inertia!r}")
        self.inertia = np.array([self.mass, self.mass, float(yaw_inertia)])
        omega = 4.0
        self.kp = (self.inertia * omega**2 if kp is None
                   else checked_vector(kp, 3, "kp", broadcast=False))
        self.kv = (self.inertia * 2.0 * omega if kv is None
                   else checked_vector(kv, 3, "kv", broadcast=False))
        if distribution is None:
            if method not in DISTRIBUTION_METHODS:
                raise InvalidValueError(f"method must be one of {DISTRIBUTION_METHODS}, got "
                                        f"{method!r}")
            distribution = partial(torque_distribution, self.jacobian, mu=mu, method=method)
        self.distribution = distribution
        self.last_wrench = np.zeros(3)
        self.last_normal_forces = np.zeros(self.jacobian.shape[0])

    @property
    def last_solution(self):
        """The QP solution of a stack distribution (``None`` for the closed forms)."""
        return getattr(self.distribution, "last_solution", None)

    def step(self, q, v, **references) -> np.ndarray:
        phi = float(q[2])
        error = platform_error(q, _reference(references, "target", required=True))
        c, s = math.cos(phi), math.sin(phi)
        velocity = np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])  # world
        world = (self.inertia * _reference(references, "acceleration")
                 + self.kv * (_reference(references, "velocity") - velocity)
                 + self.kp * error)
        self.last_wrench = _to_platform(phi, world)
        _, com = system_com(self.robot, q, frame="base")
        self.last_normal_forces = normal_forces(self._wheel_xy, com[:2], self.mass)
        return np.asarray(self.distribution(self.last_wrench, self.last_normal_forces),
                          dtype=float)
