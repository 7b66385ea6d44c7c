"""`FloatingBaseRobot`: a robot whose root is a free flyer (a humanoid, a quadruped, a drone
with an arm) on pinocchio.

The model's first joint is pinocchio's ``JointModelFreeFlyer``: ``q = [x, y, z, q_x, q_y, q_z,
q_w, joints]`` (root position [m] and unit quaternion in the world) and ``v = [v, ω, joint
rates]`` with the root's linear [m/s] and angular [rad/s] velocity in the **root body's axes**
(pinocchio's convention; see the Coordinates section of :mod:`wbc.robots.pinocchio_robot`).
``v`` is pinocchio's own velocity, so the Jacobians are pinocchio's (``S = I`` over ``v``);
:meth:`FloatingBaseRobot.integrate` is pinocchio's Lie-group exponential (the root moves along
the screw of its constant body twist) and ``difference`` its logarithm. ``reference="base"``
expresses twists in the root body's axes (its full rotation), ``n_arm = nv − 6`` counts the
actuated joints, which posture tasks and joint limits act on. Frame ``"base"`` is the root body
(unless the model has a frame of that name).

Everything else — the getters with ``out=``, one update per tick, the symbolic forms (the free
flyer in :mod:`wbc.robots.symbolic`), the quantity registry, clones — is
:class:`~wbc.robots.pinocchio_robot.PinocchioRobot`'s. Build one from a URDF with
:func:`wbc.robots.from_urdf` (``root="free_flyer"``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.checks import checked_number

from .limits import Limits
from .pinocchio_robot import PinocchioRobot
from .symbolic import free_flyer_rate, quaternion_rotation

__all__ = ["FloatingBaseRobot"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class FloatingBaseRobot(PinocchioRobot):
    """A robot with a free-flyer root (see the module docstring).

    Args:
        model: the pinocchio model; joint 1 is a ``JointModelFreeFlyer`` on the universe, every
            other joint 1-DoF revolute or prismatic (:func:`wbc.robots.symbolic.check_joints`).
        name: robot name (default: the model's).
        limits: limits over ``q`` / ``v`` (default: the model's for the joints — ``±inf``
            where pinocchio holds its "no limit" value — and ``±inf`` for the root's 7
            configuration and 6 velocity entries; no acceleration limit).
        home: the configuration :meth:`neutral` returns (default: the root at the origin with
            the identity orientation, the joints at pinocchio's neutral clipped into their
            limits).
        frames: aliases ``alias -> model frame name`` (e.g. ``{"ee": "gripper_left_base_link"}``).

    Raises:
        ShapeError: joint 1 is not a free flyer.
        WbcError: another joint type the kinematics do not support.
    """

    def __init__(self, model: pin.Model, *, name: str = "", limits: Limits | None = None,
                 home=None, frames: Mapping[str, str] | None = None) -> None:
        if limits is None:
            limits = default_limits(model)
        if home is None:
            home = np.clip(pin.neutral(model), limits.q_lower, limits.q_upper)
        aliases = dict(frames or {})
        if not model.existFrame("base") and "base" not in aliases:
            # the root body: the first body frame the free flyer carries
            body = next((f.name for f in model.frames
                         if f.parentJoint == 1 and f.type == pin.FrameType.BODY), None)
            if body is not None and [f.name for f in model.frames].count(body) == 1:
                aliases["base"] = body
        super().__init__(model, name=name or model.name, limits=limits, home=home,
                         aliases=aliases, root="free_flyer")

    # ------------------------------------------------------------------ configurations
    def random_configuration(self, rng: np.random.Generator | None = None,
                             base_range: float = 2.0) -> np.ndarray:
        """A random configuration: the root's position uniform in the box
        ``[−base_range, base_range]³`` [m], its orientation a uniform random unit quaternion;
        the joints uniform within their limits (``[−π, π]`` [rad] where unbounded)."""
        rng = np.random.default_rng() if rng is None else rng
        base_range = checked_number(base_range, "base_range")
        lower = self.limits.q_lower[7:]
        upper = self.limits.q_upper[7:]
        lower = np.where(np.isfinite(lower), lower, -math.pi)
        upper = np.where(np.isfinite(upper), upper, math.pi)
        quaternion = rng.normal(size=4)  # isotropic: uniform on the unit sphere once normalised
        quaternion /= np.linalg.norm(quaternion)
        position = rng.uniform(-base_range, base_range, 3)
        return np.concatenate([position, quaternion, rng.uniform(lower, upper)])

    def integrate(self, q, v, dt: float) -> np.ndarray:
        """Configuration after ``dt`` [s] at constant ``v``: pinocchio's ``integrate`` (the root
        along the SE(3) exponential of its constant body twist, the joints linearly)."""
        q = self._check_q(q)
        v = self._check_v(v)
        out = pin.integrate(self.model, q, v * dt)
        if dt == 0.0 or not v[:6].any():
            out[:7] = q[:7]  # a root at rest stays exactly where it is (no renormalisation)
        return out

    def velocity_map(self, q) -> np.ndarray:
        """``S(q)`` (nq × nv) with ``q̇ = S v``: ``blockdiag(R, ½ Q(quat), I)`` (``R`` the root's
        rotation; ``Q`` maps ``ω`` to ``quat ⊗ (ω, 0)``)."""
        q = self._check_q(q)
        x, y, z, w = q[3:7]
        s = np.zeros((self.nq, self.nv))
        s[:3, :3] = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        # quat ⊗ (ω, 0): vector part w ω + u × ω, scalar part −u·ω
        s[3:7, 3:6] = 0.5 * np.array([[w, -z, y], [z, w, -x], [-y, x, w], [-x, -y, -z]])
        s[7:, 6:] = np.eye(self.n_arm)
        return s

    # ------------------------------------------------------------------ kinematics update
    def _allocate(self) -> None:
        super()._allocate()
        self._zero_acceleration = np.zeros(self.nv)  # v̇ = 0: the drifts' acceleration

    def update(self, q, v=None) -> None:
        """Run the kinematics once (see :meth:`PinocchioRobot.update`): pinocchio's velocity is
        ``v`` itself, so no velocity map is computed."""
        q = self._check_q(q)
        model, data = self.model, self.data
        if v is None:
            pin.computeJointJacobians(model, data, q)
            self._has_v = False
        else:
            v = self._check_v(v)
            pin.forwardKinematics(model, data, q, v, self._zero_acceleration)
            pin.computeJointJacobians(model, data)
            self._v[:] = v
            self._has_v = True
        pin.updateFramePlacements(model, data)
        self._q[:] = q
        self._valid = True
        self._com_valid = False

    # ------------------------------------------------------------------ frame quantities
    def _rotate_to_base(self, rows: np.ndarray) -> None:
        """Apply ``blockdiag(Rᵀ, Rᵀ)``, ``R`` the root body's rotation, in place to 6 rows."""
        rotation_t = self.data.oMi[1].rotation.T
        rows[:3] = rotation_t @ rows[:3]
        rows[3:] = rotation_t @ rows[3:]

    def frame_jacobian(self, q=None, frame: str | int = "ee", reference: str = "world",
                       out: np.ndarray | None = None) -> np.ndarray:
        """:meth:`PinocchioRobot.frame_jacobian`; ``reference="base"``: the root body's axes."""
        out = super().frame_jacobian(q, frame, reference, out)
        if reference == "base":
            self._rotate_to_base(out)
        return out

    def frame_velocity(self, q=None, v=None, frame: str | int = "ee", reference: str = "world",
                       out: np.ndarray | None = None) -> np.ndarray:
        """:meth:`PinocchioRobot.frame_velocity`; ``reference="base"``: the root body's axes."""
        out = super().frame_velocity(q, v, frame, reference, out)
        if reference == "base":
            self._rotate_to_base(out)
        return out

    def frame_drift(self, q=None, v=None, frame: str | int = "ee", reference: str = "world",
                    out: np.ndarray | None = None) -> np.ndarray:
        """:meth:`PinocchioRobot.frame_drift`; for ``reference="base"`` the rotation of the
        root's axes enters: ``d/dt (Rᵀ a) = Rᵀ ȧ − ω_b × (Rᵀ a)`` with ``ω_b`` the root's
        angular velocity in its own axes (``v[3:6]``)."""
        if reference != "base":
            return super().frame_drift(q, v, frame, reference, out)
        out = super().frame_drift(q, v, frame, "world", out)
        twist = pin.getFrameVelocity(self.model, self.data, self.frame_id(frame), _LWA)
        body = twist.vector.copy()
        self._rotate_to_base(out)
        self._rotate_to_base(body)
        omega = self._v[3:6]
        out[:3] -= np.cross(omega, body[:3])
        out[3:] -= np.cross(omega, body[3:])
        return out

    def com_jacobian(self, q=None, out: np.ndarray | None = None) -> np.ndarray:
        """Jacobian (3 × nv) of the centre of mass in world axes: ``ċ = J_c v`` (pinocchio's)."""
        self._ensure(q)
        jac = pin.jacobianCenterOfMass(self.model, self.data, False)
        out = self._out(out, (3, self.nv), "com_jacobian")
        out[...] = jac
        return out

    # ------------------------------------------------------------------ symbolic forms
    def _symbolic_base_axes(self, q: ca.SX) -> ca.SX:
        """``Rᵀ`` of the root body's rotation (its joint placement times the quaternion's)."""
        placement = ca.DM(self.model.jointPlacements[1].rotation)
        return (placement @ quaternion_rotation(q[3:7])).T

    def _symbolic_velocity_map_product(self, q: ca.SX, matrix: ca.SX) -> ca.SX:
        """``matrix S(q)``: a matrix over ``q̇`` (nq columns) made one over ``v``."""
        x, y, z, w = (q[i] for i in range(3, 7))
        quaternion_map = 0.5 * ca.vertcat(ca.horzcat(w, -z, y), ca.horzcat(z, w, -x),
                                          ca.horzcat(-y, x, w), ca.horzcat(-x, -y, -z))
        return ca.horzcat(matrix[:, :3] @ quaternion_rotation(q[3:7]),
                          matrix[:, 3:7] @ quaternion_map, matrix[:, 7:])

    def _symbolic_configuration_rate(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """``q̇ = S(q) v`` (:func:`wbc.robots.symbolic.free_flyer_rate`)."""
        return free_flyer_rate(q, v)


def default_limits(model: pin.Model) -> Limits:
    """Limits of a free-flyer model: the joints' from the model (pinocchio's "no limit" values
    ``±1.8e308`` and non-positive velocity limits as ``±inf``), the root's ``±inf``, no
    acceleration limit."""
    lower = model.lowerPositionLimit.copy()
    upper = model.upperPositionLimit.copy()
    lower[:7], upper[:7] = -np.inf, np.inf
    lower[lower <= -1e300] = -np.inf
    upper[upper >= 1e300] = np.inf
    v_max = model.velocityLimit.copy()
    v_max[(v_max <= 0.0) | (v_max >= 1e300)] = np.inf
    v_max[:6] = np.inf
    return Limits(q_lower=lower, q_upper=upper, v_lower=-v_max, v_upper=v_max,
                  a_lower=np.full(model.nv, -np.inf), a_upper=np.full(model.nv, np.inf))
