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
  measured), :func:`wbc.robots.system_com` and :func:`wbc.robots.normal_forces`. With a
  :class:`~wbc.papers.omni.distribution_tasks.TorqueDistribution`, its fast path (the
  default, ``fused=``) computes eq. 6, the centre of mass and the normal forces in one
  generated C call (:func:`model_function`) that writes them into the distribution's
  parameters, then solves the distribution (on daqp itself one C call): ``wbc study omni``
  measured 9.6 µs against 92 µs for the ordinary path (median, interleaved, daqp).

  The paper's normal forces (eqs. 8–9) are the statics'. With ``com_height=`` the controller
  also models the *load transfer* of the acceleration it commands: the platform force
  ``(F_x, F_y)`` of ``f_d`` acts through the centre of mass at height ``h`` above the floor,
  and the moment balance about the contact plane moves ``h F`` of moment between the wheels
  (:func:`load_transfer`) — the effect the statics neglect (``omni4_arm6``: h = 0.39 m; at
  1 m/s² the lightly loaded wheel's 40 N become 13 N or 68 N). ``h`` is the controller's
  belief; a plant's true height may differ (the study's documented mismatch).

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

import casadi as ca
import numpy as np

from wbc.cbuild import compiled_c, compiler_available
from wbc.checks import checked_vector
from wbc.errors import InvalidValueError, WbcError
from wbc.robots.omni import ARM_MASS, GRAVITY, PLATFORM_MASS, normal_forces, system_com
from wbc.robots.symbolic import symbolic_center_of_mass

from .closed_form import DISTRIBUTION_METHODS, H_CRITERIA, torque_distribution
from .distribution_tasks import TorqueDistribution
from .dynamics import YAW_INERTIA

__all__ = ["LIFTED_LOAD", "OmniForceControl", "OmniPositionControl", "load_transfer",
           "platform_error"]


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


#: the margin [N] per newton of weight below which a normal force sends the tick to the ordinary
#: path (which refuses a lifted or unloaded wheel): far above the generated forces' round-off.
FORCE_MARGIN = 1e-9
#: marks a reference not given (``None`` is a value, which the ordinary path refuses)
_MISSING = object()
#: the load [N per N of a wheel's share of the weight, m g / N] the load-transfer model leaves a
#: wheel it would lift: a lifted wheel transmits no traction, and the distributions then give it
#: (almost) no torque — they need a positive load to weigh it (``com_height=``). 1 %: small
#: enough that the wheel's torque is negligible, large enough to keep the distribution's
#: weights within four orders of magnitude of each other.
LIFTED_LOAD = 0.01


def load_transfer(wheel_xy, height: float) -> np.ndarray:
    """``T`` (N, 2) [-]: the change of the wheels' normal forces [N] per platform force
    ``(F_x, F_y)`` [N] applied at the floor by the wheels, ``Δf = T F``.

    The wheels' traction ``F = m a`` accelerates the centre of mass, which lies ``height`` [m]
    above the floor: the moment balance about the contact plane becomes
    ``Σ f_i (x_i, y_i) = m g (x_c, y_c) − height · F`` (the weight's moment less the inertial
    force's), split over the wheels as the statics split theirs
    (:func:`wbc.robots.normal_forces`' minimum-norm ``A⁺``): ``T = −height · A⁺[:, 1:3]``.
    Accelerating towards a wheel unloads it.

    Args:
        wheel_xy: contact points (N, 2) [m] in the platform frame (not all on one line).
        height: centre of mass above the floor [m], ≥ 0.
    """
    wheel_xy = np.asarray(wheel_xy, dtype=float)
    if not (np.isfinite(height) and height >= 0):
        raise InvalidValueError(f"com_height must be a finite height >= 0 [m], got {height!r}")
    A = np.vstack([np.ones(len(wheel_xy)), wheel_xy.T])
    return -float(height) * (A.T @ np.linalg.inv(A @ A.T))[:, 1:3]


def model_function(robot, inertia: np.ndarray, kp: np.ndarray, kv: np.ndarray,
                   transfer: np.ndarray | None = None) -> ca.Function:
    """Eq. 6, the whole system's centre of mass and the wheels' normal forces as one CasADi
    function — what :meth:`OmniForceControl.step` computes before the distribution, for its
    fast path.

    Inputs: ``q`` (nq,) ``[x, y, φ, arm joints]`` [m, m, rad, rad]; ``v`` (3,) the body twist
    [m/s, m/s, rad/s]; ``target`` (3,) ``x_d`` (its heading unused); ``heading_error`` (1,)
    ``φ_d − φ`` wrapped to ``(−π, π]`` [rad] (given: ``math.remainder`` is exact, a generated
    ``floor`` picks the other sign of π at ties, e.g. ``φ_d = π`` from ``φ = 0``);
    ``velocity``, ``acceleration`` (3,) ``ẋ_d``, ``ẍ_d`` in the world.

    Outputs: ``f_d`` (3,) the platform-frame wrench [N, N, N m]; ``normal_forces`` (N,) [N]
    (:func:`wbc.robots.normal_forces` before its clipping at 0, the weight's split by the
    constant ``Aᵀ (A Aᵀ)⁻¹``; with ``transfer`` (:func:`load_transfer`'s ``T``) plus
    ``T f_d[:2]``, at least :data:`LIFTED_LOAD` of a wheel's share); ``ok`` — 1 when every
    static normal force exceeds :data:`FORCE_MARGIN` per newton of weight and the inputs and
    ``f_d`` are finite (else the ordinary path answers, and raises as it does).

    Raises:
        WbcError: the arm has joints the symbolic kinematics do not cover.
    """
    q = ca.SX.sym("q", int(robot.nq))
    v, target, velocity, acceleration = (ca.SX.sym(name, 3) for name in
                                         ("v", "target", "velocity", "acceleration"))
    heading_error = ca.SX.sym("heading_error")
    # eq. 6 in the world, turned into the platform frame (as _to_platform)
    c, s = ca.cos(q[2]), ca.sin(q[2])
    world_velocity = ca.vertcat(c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])
    error = ca.vertcat(target[:2] - q[:2], heading_error)
    world = (ca.DM(inertia) * acceleration + ca.DM(kv) * (velocity - world_velocity)
             + ca.DM(kp) * error)
    f_d = ca.vertcat(c * world[0] + s * world[1], -s * world[0] + c * world[1], world[2])
    # system_com(robot, q, frame="base"): the arm's bodies (its fixed root link included) mounted
    # on the platform, with the paper's masses
    arm = robot.arm.model
    root = arm.inertias[0]
    moving_mass = sum(arm.inertias[j].mass for j in range(1, arm.njoints))
    arm_local = ((moving_mass * symbolic_center_of_mass(arm)(q[3:]) + root.mass * root.lever)
                 / (moving_mass + root.mass))
    mount = robot.mount
    arm_com = ca.DM(mount.rotation) @ arm_local + mount.translation
    com = (PLATFORM_MASS * np.asarray(robot.base.com, dtype=float) + ARM_MASS * arm_com) / (
        PLATFORM_MASS + ARM_MASS)
    # normal_forces: the minimum-norm split f = Aᵀ (A Aᵀ)⁻¹ m g (1, x_c, y_c)
    wheel_xy = np.asarray(robot.base.wheel_positions, dtype=float)
    A = np.vstack([np.ones(len(wheel_xy)), wheel_xy.T])
    weight = (PLATFORM_MASS + ARM_MASS) * GRAVITY
    forces = ca.DM(A.T @ np.linalg.inv(A @ A.T)) @ (weight * ca.vertcat(1.0, com[0], com[1]))
    static = forces
    if transfer is not None:
        forces = ca.fmax(forces + ca.DM(transfer) @ f_d[:2],
                         LIFTED_LOAD * weight / len(wheel_xy))
    # comparisons are false on NaN; the inputs' sum is tested too, as a zero gain would
    # otherwise drop a non-finite reference from f_d (CasADi simplifies 0·x to 0)
    ok = ca.fabs(ca.sum1(ca.vertcat(q, v, target, velocity, acceleration))) < ca.inf
    for i in range(static.shape[0]):
        ok = ca.logic_and(ok, static[i] > FORCE_MARGIN * weight)
    for i in range(3):
        ok = ca.logic_and(ok, ca.fabs(f_d[i]) < ca.inf)
    return ca.Function("omni_force_model", [q, v, target, heading_error, velocity, acceleration],
                       [f_d, forces, ok],
                       ["q", "v", "target", "heading_error", "velocity", "acceleration"],
                       ["f_d", "normal_forces", "ok"])


def _plain(value, size: int) -> bool:
    """``value`` is a float64 ndarray of shape ``(size,)``: the input the fast path copies
    without a check (anything else takes the ordinary path, whose checks then apply)."""
    return type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (size,)


class OmniForceControl:
    """Eq. 6 force control with a wheel-torque distribution (module docstring).

    Args:
        robot: a mobile manipulator on an omni base (``"omni4_arm6"``).
        method: distribution of the closed forms, ``"min_norm"``, ``"proportional"`` or
            ``"minmax"`` (ignored when ``distribution`` is given).
        criterion: the closed form's reconstruction of eq. 12's ``H`` for ``"proportional"``,
            ``"utilisation"`` or ``"ratios"`` (:mod:`~wbc.papers.omni.closed_form`; ignored
            when ``distribution`` is given).
        mu: friction coefficient(s) μ_i the distribution assumes (scalar or (4,), > 0).
        kp: position gains ``k_p`` (x, y, yaw) [N/m, N/m, N m/rad].
        kv: velocity gains ``k_v`` (x, y, yaw) [N s/m, N s/m, N m s/rad].
        yaw_inertia: ``M``'s yaw entry [kg m²]; its mass entries are the system's mass
            (:func:`wbc.robots.system_com`, 45 kg).
        distribution: ``fn(f_d (3,), normal_forces (4,)) -> tau (4,)`` replacing the closed
            form (e.g. a :class:`wbc.tasks.TorqueDistribution`; its ``last_solution`` becomes
            this controller's).
        com_height: ``None`` (default): the normal forces are the statics' (eqs. 8–9, as the
            paper). A height [m] ≥ 0: the height of the centre of mass above the floor the
            controller assumes, and the normal forces include the load transfer of the tick's
            ``f_d`` (:func:`load_transfer`; a wheel it would lift keeps :data:`LIFTED_LOAD` of
            its share of the weight). ``0`` gives the statics' forces.
        fused: the fast path — eq. 6, the centre of mass and the normal forces as one generated
            C call (:func:`model_function`) writing ``f_d`` and the normal forces straight into
            a :class:`TorqueDistribution`'s parameters, then its solve (itself one C call when
            the distribution is fused). ``"auto"`` (default): when ``distribution`` is a
            :class:`TorqueDistribution` and a C compiler is present; ``True``: the same, but
            a controller that cannot take it is a :class:`~wbc.WbcError`; ``False``: the
            ordinary path (Python, pinocchio, the distribution's ``__call__``). ``self.fused``
            says which path is used and ``self.fused_reason`` why not. A tick whose inputs are
            not float64 arrays of their shapes (``q`` (nq,), ``v`` (nv,), references (3,)),
            non-finite, or that would load a wheel with (nearly) nothing takes the ordinary
            path, which answers or raises as it does. The two paths agree to round-off (see
            ``tests/test_omni_fast.py``).

    Default gains: ``M ω²`` and ``2 M ω`` with ``ω = 4 rad/s`` (critically damped, a 0.25 s
    time constant, well below the wheels' servo bandwidth), chosen here — the paper gives none.

    Attributes:
        last_wrench: the last ``f_d`` in the platform frame [N, N, N m];
        last_normal_forces: the normal forces [N] it was distributed with;
        com_height: the assumed height [m] (``None``: statics).
    """

    def __init__(self, robot, method: str = "proportional", mu=0.5, kp=None, kv=None,
                 yaw_inertia: float = YAW_INERTIA,
                 distribution: Callable | None = None, fused: bool | str = "auto",
                 criterion: str = "utilisation", com_height: float | None = None) -> None:
        if fused not in (True, False, "auto"):
            raise WbcError(f"fused must be True, False or 'auto', got {fused!r}")
        self.robot = robot
        self.jacobian = np.asarray(robot.base.jacobian, dtype=float)
        self._wheel_xy = np.asarray(robot.base.wheel_positions, dtype=float)
        self.mass = float(system_com(robot, robot.neutral())[0])
        self.com_height = com_height
        #: load_transfer's T, or None (statics)
        self._transfer = (None if com_height is None
                          else load_transfer(self._wheel_xy, com_height))
        self._lifted = LIFTED_LOAD * self.mass * GRAVITY / len(self._wheel_xy)
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
            if criterion not in H_CRITERIA:
                raise InvalidValueError(f"criterion must be one of {H_CRITERIA}, got "
                                        f"{criterion!r}")
            distribution = partial(torque_distribution, self.jacobian, mu=mu, method=method,
                                   criterion=criterion)
        self.distribution = distribution
        self.last_wrench = np.zeros(3)
        self.last_normal_forces = np.zeros(self.jacobian.shape[0])
        self.fused = self._fast_path(fused)

    def _fast_path(self, fused) -> bool:
        """Build the fast path's buffers if ``fused`` allows it (class docstring); else
        ``False`` with ``self.fused_reason`` saying why."""
        distribution = self.distribution
        if fused is False:
            self.fused_reason: str | None = "turned off (fused=False)"
        elif not isinstance(distribution, TorqueDistribution):
            self.fused_reason = ("the distribution is not a TorqueDistribution (its inputs are "
                                 "not parameters the generated code can write)")
        elif distribution.n != self.jacobian.shape[0]:
            self.fused_reason = (f"the distribution has {distribution.n} wheels, the robot "
                                 f"{self.jacobian.shape[0]}")
        elif not compiler_available():
            self.fused_reason = "no C compiler found ($CC, default cc)"
        else:
            try:
                model = compiled_c(model_function(self.robot, self.inertia, self.kp, self.kv,
                                                  self._transfer))
            except (WbcError, RuntimeError) as err:  # joints without symbolic forms; cc failed
                self.fused_reason = f"the model function cannot be generated: {err}"
            else:
                self.fused_reason = None
        if self.fused_reason is not None:
            if fused is True:
                raise WbcError(f"fused=True, but the controller cannot take the fast path: "
                               f"{self.fused_reason}")
            return False
        assert isinstance(distribution, TorqueDistribution)
        self._distribution = distribution
        workspace = distribution.workspace
        nq = int(self.robot.nq)
        # inputs; the outputs land in the distribution's parameters (no copy on the tick)
        self._inputs = [np.zeros(nq), np.zeros(3), np.zeros(3), np.zeros(1), np.zeros(3),
                        np.zeros(3)]
        f_d = workspace.view("wrench.f_d").reshape(-1)  # views of p, contiguous
        forces = (workspace.view("friction.normal_forces").reshape(-1)
                  if "friction.normal_forces" in distribution.stack.compile().parameters
                  else np.zeros(self.jacobian.shape[0]))  # min_norm: not a parameter
        ok = np.zeros(1)
        buffer, self._model = model.buffer()
        # (casadi's stubs know only the (index, buffer, size) form of set_arg/set_res)
        for i, array in enumerate(self._inputs):
            buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        for i, array in enumerate((f_d, forces, ok)):
            buffer.set_res(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        self._model_buffer = buffer  # keeps the bound buffers alive
        self._f_d, self._forces, self._ok = f_d, forces, ok
        self._nv = int(self.robot.nv)
        self._tau = distribution.stack.variables.slice("tau")
        return True

    @property
    def last_solution(self):
        """The QP solution of a stack distribution (``None`` for the closed forms)."""
        return getattr(self.distribution, "last_solution", None)

    def step(self, q, v, **references) -> np.ndarray:
        """The wheels' command [N m] (N,) for the estimate ``q``, the measured ``v`` and the
        references (module docstring), on the fast path when ``self.fused``."""
        if self.fused:
            return self._fast_step(q, v, references)
        return self._ordinary_step(q, v, references)

    def _ordinary_step(self, q, v, references: dict) -> np.ndarray:
        """Eq. 6 in numpy, the centre of mass by pinocchio, then the distribution's call."""
        phi = float(q[2])
        error = platform_error(q, _reference(references, "target", required=True))
        c, s = math.cos(phi), math.sin(phi)
        velocity = np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])  # world
        world = (self.inertia * _reference(references, "acceleration")
                 + self.kv * (_reference(references, "velocity") - velocity)
                 + self.kp * error)
        self.last_wrench = _to_platform(phi, world)
        _, com = system_com(self.robot, q, frame="base")
        forces = normal_forces(self._wheel_xy, com[:2], self.mass)
        if self._transfer is not None:
            forces = np.maximum(forces + self._transfer @ self.last_wrench[:2], self._lifted)
        self.last_normal_forces = forces
        return np.asarray(self.distribution(self.last_wrench, self.last_normal_forces),
                          dtype=float)

    def _fast_step(self, q, v, references: dict) -> np.ndarray:
        """:meth:`step` on the fast path (class docstring): the same command and attributes,
        two C calls (the model function, the distribution's solve) around copies. (A tick
        handed to the ordinary path after the model call has written its ``f_d`` and normal
        forces into the distribution's parameters; the ordinary path writes them again, or
        raises before its solve, as the next tick rewrites them.)"""
        q_in, v_in, target_in, heading_in, velocity_in, acceleration_in = self._inputs
        target = references.get("target", _MISSING)
        velocity = references.get("velocity", _MISSING)
        acceleration = references.get("acceleration", _MISSING)
        if not (_plain(q, q_in.size) and _plain(v, self._nv) and _plain(target, 3)
                and (velocity is _MISSING or _plain(velocity, 3))
                and (acceleration is _MISSING or _plain(acceleration, 3))):
            return self._ordinary_step(q, v, references)
        heading = float(target[2]) - float(q[2])
        if not math.isfinite(heading):  # (math.remainder raises on inf)
            return self._ordinary_step(q, v, references)
        q_in[:] = q
        v_in[:] = v[:3]
        target_in[:] = target
        heading_in[0] = math.remainder(heading, 2.0 * math.pi)
        if velocity is _MISSING:
            velocity_in.fill(0.0)
        else:
            velocity_in[:] = velocity
        if acceleration is _MISSING:
            acceleration_in.fill(0.0)
        else:
            acceleration_in[:] = acceleration
        self._model()
        if self._ok[0] != 1.0:  # a lifted wheel or a non-finite value: the ordinary path raises
            return self._ordinary_step(q, v, references)
        self.last_wrench = self._f_d.copy()
        self.last_normal_forces = self._forces.copy()
        distribution = self._distribution
        solution = distribution.last_solution = distribution.solve()
        return solution.x[self._tau].copy()
