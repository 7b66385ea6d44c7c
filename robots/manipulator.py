"""A mobile manipulator: a planar wheeled base carrying an arm, as one pinocchio model.

Model
-----
The whole robot is **one pinocchio model**: three scalar root joints — prismatic ``base_x``,
prismatic ``base_y`` and revolute ``base_theta`` (about the world's vertical) — carry the base
body and the frame ``"base"``; the arm is appended at the fixed frame ``"mount"`` (the mounting
transform, in the base frame). Scalar joints keep pinocchio's configuration equal to ours
(``q = [x, y, θ, q_arm]``, no cos/sin pair as with ``JointModelPlanar``), so pinocchio computes
whole-body poses, Jacobians, J̇v and the centre of mass directly. Only the base's *velocity*
coordinates differ from pinocchio's ``(ẋ, ẏ, θ̇)``: with ``H(θ)`` of the base model,

    q̇ = S(q) v,   S = blockdiag(H(θ), I),   J_v = J_pin S,   J̇_v v = J̇_pin q̇ + J_pin Ṡ v,

the last term being the base's pose-rate drift (:meth:`PlanarBase.pose_rate_drift`).

Coordinates
-----------
* ``q`` (``nq = 3 + n_arm``): base pose ``x, y`` [m], ``θ`` [rad] in the world, then the arm
  joints [rad].
* ``v`` (``nv = base.nv + n_arm``): the base's velocity coordinates in the **base frame** —
  ``(v_x, v_y, ω)`` for holonomic bases, ``(v, ω)`` for the differential drive (so
  ``nv = nq − 1``) — then the arm joint rates [rad/s].

Frames and Jacobians
--------------------
Every frame of the pinocchio model is available by name (:attr:`MobileManipulator.frame_names`),
at least ``"base"`` (the base frame: origin at the base pose, x forward, z up), ``"mount"`` and
``"ee"`` (the arm's end effector). Arm frames whose names clash with these are renamed
``"arm_<name>"``.

``frame_jacobian(q, frame, reference)`` returns ``J`` (6 × nv), rows ``[linear; angular]``, such
that the frame's twist is ``J v``:

* ``reference="world"``: pinocchio's ``LOCAL_WORLD_ALIGNED`` — the linear velocity of the
  frame's **origin** and the angular velocity, both in **world axes**;
* ``reference="base"``: the same twist (still relative to the world) expressed in the **base
  frame's axes**, ``blockdiag(Rᵀ, Rᵀ) J_world`` with ``R = Rz(θ)``. Its arm columns are the
  arm's own Jacobian in its base frame, independent of the base pose;
* ``reference="local"``: the same twist in the **frame's own axes** (pinocchio ``LOCAL``),
  ``blockdiag(R_fᵀ, R_fᵀ) J_world``.

:meth:`MobileManipulator.frame_drift` returns ``J̇ v = d/dt (J v)`` at ``v̇ = 0`` for the
Jacobian of the same ``reference`` (for ``"base"`` and ``"local"`` this includes the rotation of
the expression axes; ``"world"`` is pinocchio's classical acceleration of the frame's origin).

Hot path: one kinematics update per tick
----------------------------------------
Every getter takes ``q`` (and ``v`` where needed). Kinematics are cached on the last ``(q, v)``:
a getter called with the configuration of the last update reuses it; ``q=None`` means "the
configuration of the last :meth:`MobileManipulator.update`". Getters write into ``out=`` when
given — any float array of the right shape, for example a column-major view into a compiled
stack's parameter vector (see :func:`wbc.robots.views.column_major_view`) — so a tick does no
per-call allocation or conversion on the Python side::

    robot.update(q, v)                                    # FK, Jacobians, frames, accelerations
    robot.frame_jacobian(None, "ee", out=J_view)          # (6, nv) written into p in place
    robot.frame_drift(None, None, "ee", out=drift_view)   # (6,)
    robot.frame_pose(None, "ee", out=pose_view)           # (4, 4)

With ``Controller(..., kinematics="compiled")`` a tick needs no update at all:
:meth:`MobileManipulator.symbolic_frame` gives the pose and the ``"world"`` Jacobian as a CasADi
function of ``q``, evaluated inside the compiled level functions
(:meth:`MobileManipulator.symbolic_drift` gives the ``"world"`` drift of ``(q, v)``).

A :class:`MobileManipulator` holds one pinocchio ``Data``: it is not thread-safe; use
:meth:`MobileManipulator.clone` (shares the model, owns new buffers) per thread.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.errors import InvalidValueError, NonFiniteError, ShapeError, UnknownNameError

from .arms import Arm, arm_from_model, arm_from_urdf
from .fixed_base import symbolic_frame_drift, symbolic_frame_kinematics
from .limits import Limits
from .planar_base import HOLONOMIC_MAP, UNICYCLE_MAP, PlanarBase

__all__ = ["MobileManipulator"]

_BASE_JOINTS = ("base_x", "base_y", "base_theta")
_RESERVED_FRAMES = ("universe", "base", "mount", "ee", *_BASE_JOINTS)
_REFERENCES = ("world", "base", "local")
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _as_se3(mount) -> pin.SE3:
    if mount is None:
        return pin.SE3.Identity()
    if isinstance(mount, pin.SE3):
        return pin.SE3(mount)
    matrix = np.asarray(mount, dtype=float)
    if matrix.shape != (4, 4):
        raise ShapeError(f"mount must be a pinocchio SE3 or a (4, 4) matrix, got {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise NonFiniteError("mount holds NaN or inf")
    rotation = matrix[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
        raise InvalidValueError("mount's rotation block is not a rotation matrix")
    return pin.SE3(rotation, matrix[:3, 3])


class MobileManipulator:
    """A planar base + an arm + the arm's mounting transform.

    Args:
        base: the base model (:class:`~wbc.robots.planar_base.PlanarBase`).
        arm: an :class:`~wbc.robots.arms.Arm`, a pinocchio ``Model`` or a URDF path.
        mount: pose of the arm's root in the base frame (pinocchio ``SE3`` or 4 × 4 matrix;
            default identity).
        ee_frame: the arm frame used as ``"ee"`` (required for a model or URDF; overrides an
            ``Arm``'s own).
        name: robot name.
        home: home configuration ``q`` (default: base at the origin, arm at its home).

    Example — a UR5 of your own on the mecanum base, 0.1 m ahead of its centre::

        import numpy as np
        from wbc.robots import MobileManipulator, mecanum_base
        mount = np.eye(4); mount[0, 3] = 0.1
        robot = MobileManipulator(mecanum_base(), "/path/to/ur5_robot.urdf", mount,
                                  ee_frame="tool0", name="mecanum_ur5")
        J = robot.frame_jacobian(robot.neutral(), "ee")      # (6, 9)

    (:func:`wbc.robots.from_urdf` does the same with a base given by name.)
    """

    def __init__(
        self,
        base: PlanarBase,
        arm: Arm | pin.Model | str | os.PathLike[str],
        mount=None,
        *,
        ee_frame: str | None = None,
        name: str | None = None,
        home=None,
    ) -> None:
        if not isinstance(base, PlanarBase):
            raise TypeError(f"base must be a PlanarBase, got {type(base).__name__}")
        if isinstance(arm, (str, os.PathLike)):
            if ee_frame is None:
                raise ValueError("ee_frame is required when the arm is given as a URDF path")
            arm = arm_from_urdf(arm, ee_frame)
        elif isinstance(arm, pin.Model):
            if ee_frame is None:
                raise ValueError("ee_frame is required when the arm is given as a pinocchio Model")
            arm = arm_from_model(arm, ee_frame)
        elif not isinstance(arm, Arm):
            raise TypeError(
                f"arm must be an Arm, a pinocchio Model or a URDF path, got {type(arm).__name__}"
            )
        if ee_frame is not None and ee_frame != arm.ee_frame:
            arm = dataclasses.replace(arm, ee_frame=ee_frame)  # validated again

        self.name = name or f"{base.name}_{arm.name}"
        self.base = base
        self.arm = arm
        self._mount = _as_se3(mount)
        self.model = self._build_model()
        self.n_arm = arm.n
        self.nq = 3 + self.n_arm
        self.nv_base = base.nv
        self.nv = self.nv_base + self.n_arm
        self.limits = Limits(
            q_lower=np.concatenate([np.full(3, -np.inf), arm.q_lower]),
            q_upper=np.concatenate([np.full(3, np.inf), arm.q_upper]),
            v_lower=np.concatenate([base.v_lower, -arm.v_max]),
            v_upper=np.concatenate([base.v_upper, arm.v_max]),
            a_lower=np.concatenate([base.a_lower, -arm.a_max]),
            a_upper=np.concatenate([base.a_upper, arm.a_max]),
        )
        if home is None:
            home = np.concatenate([np.zeros(3), arm.home])
        self._home = self._check_q(home).copy()
        self._frame_ids: dict[str, int] = {}
        for index, frame in enumerate(self.model.frames):
            self._frame_ids.setdefault(frame.name, index)
        self._ancestors = self._arm_ancestor_mask()
        # frame id -> symbolic_frame function; immutable, so shared by clones
        self._symbolic: dict[int, ca.Function] = {}
        self._symbolic_drift: dict[int, ca.Function] = {}  # symbolic_drift's, likewise
        self._allocate()

    # ------------------------------------------------------------------ construction
    def _build_model(self) -> pin.Model:
        model = pin.Model()
        model.name = self.name
        big = np.array([1e10])
        parent = 0
        for joint_name, joint in zip(
            _BASE_JOINTS, (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelRZ()), strict=True
        ):
            parent = model.addJoint(
                parent, joint, pin.SE3.Identity(), joint_name, big, big, -big, big
            )
        model.appendBodyToJoint(parent, self.base.spatial_inertia(), pin.SE3.Identity())
        base_frame = model.addFrame(
            pin.Frame("base", parent, 0, pin.SE3.Identity(), pin.FrameType.BODY)
        )
        mount_frame = model.addFrame(
            pin.Frame("mount", parent, base_frame, self._mount, pin.FrameType.OP_FRAME)
        )
        arm_model = pin.Model(self.arm.model)
        clashes = set(_RESERVED_FRAMES)
        ee_name = self.arm.ee_frame
        for index in range(1, len(arm_model.frames)):
            frame = arm_model.frames[index]
            if frame.name in clashes:
                new_name = "arm_" + frame.name
                if frame.name == ee_name:
                    ee_name = new_name
                frame.name = new_name
                arm_model.frames[index] = frame
        for joint_name in list(arm_model.names)[1:]:
            if joint_name in _BASE_JOINTS:
                raise ValueError(f"arm joint name {joint_name!r} is reserved for the base")
        whole = pin.appendModel(model, arm_model, mount_frame, pin.SE3.Identity())
        ee_id = whole.getFrameId(ee_name)
        ee = whole.frames[ee_id]
        whole.addFrame(pin.Frame("ee", ee.parentJoint, ee_id, ee.placement, pin.FrameType.OP_FRAME))
        whole.name = self.name
        return whole

    def _arm_ancestor_mask(self) -> np.ndarray:
        """``mask[k, i]``: arm velocity index k's joint is a strict ancestor of index i's."""
        joint_of = {}
        for j in range(1, self.model.njoints):
            joint_of[self.model.joints[j].idx_v] = j
        arm_joints = [joint_of[3 + k] for k in range(self.n_arm)]
        mask = np.zeros((self.n_arm, self.n_arm), dtype=bool)
        for i, ji in enumerate(arm_joints):
            supports = set(self.model.supports[ji])
            for k, jk in enumerate(arm_joints):
                mask[k, i] = jk != ji and jk in supports
        return mask

    def _allocate(self) -> None:
        self.data = self.model.createData()
        self._q = np.zeros(self.nq)
        self._v = np.zeros(self.nv)
        self._qdot = np.zeros(self.nq)
        self._qddot = np.zeros(self.nq)
        self._s = np.zeros((self.nq, self.nv))  # S(q) of the last update
        self._s[3:, self.nv_base :] = np.eye(self.n_arm)
        self._h = self._s[:3, : self.nv_base]  # H(θ), a view into S
        self.base.pose_rate_matrix(0.0, out=self._h)  # constant entries
        body = self.base.body_map
        self._body_kind = (
            "holonomic"
            if body.shape == (3, 3) and np.array_equal(body, HOLONOMIC_MAP)
            else "unicycle"
            if body.shape == (3, 2) and np.array_equal(body, UNICYCLE_MAP)
            else "generic"
        )
        self._valid = False
        self._has_v = False
        self._com_valid = False

    def clone(self) -> MobileManipulator:
        """A copy sharing the (immutable) model, with its own pinocchio ``Data`` and caches."""
        other = copy.copy(self)
        other._allocate()
        return other

    # ------------------------------------------------------------------ basics
    @property
    def mount(self) -> pin.SE3:
        """Pose of the arm's root in the base frame."""
        return pin.SE3(self._mount)

    @property
    def frame_names(self) -> list[str]:
        """Names of the frames available to the getters (``"universe"`` excluded)."""
        return [name for name in self._frame_ids if name != "universe"]

    @property
    def configuration_names(self) -> list[str]:
        """Names of the entries of ``q``."""
        return ["x", "y", "theta", *self.arm.joint_names]

    @property
    def velocity_names(self) -> list[str]:
        """Names of the entries of ``v``."""
        return [*self.base.velocity_names, *self.arm.joint_names]

    def neutral(self) -> np.ndarray:
        """The home configuration (base at the world origin, arm at its home posture)."""
        return self._home.copy()

    def random_configuration(
        self, rng: np.random.Generator | None = None, base_range: float = 2.0
    ) -> np.ndarray:
        """A random configuration: base in ``[−base_range, base_range]²`` [m] × [−π, π], arm
        uniform within its position limits (``[−π, π]`` where unbounded)."""
        rng = np.random.default_rng() if rng is None else rng
        lower = np.where(np.isfinite(self.arm.q_lower), self.arm.q_lower, -math.pi)
        upper = np.where(np.isfinite(self.arm.q_upper), self.arm.q_upper, math.pi)
        base = rng.uniform([-base_range, -base_range, -math.pi], [base_range, base_range, math.pi])
        return np.concatenate([base, rng.uniform(lower, upper)])

    def frame_id(self, frame: str | int) -> int:
        """Index of a frame given by name (or already by index) in :attr:`model`."""
        if isinstance(frame, str):
            try:
                return self._frame_ids[frame]
            except KeyError:
                raise UnknownNameError(
                    f"robot {self.name!r} has no frame {frame!r}; frames: {self.frame_names}"
                ) from None
        if isinstance(frame, (int, np.integer)) and 0 <= int(frame) < len(self.model.frames):
            return int(frame)
        raise UnknownNameError(
            f"robot {self.name!r}: frame must be a name or an index below "
            f"{len(self.model.frames)}, got {frame!r}; frames: {self.frame_names}"
        )

    def _check_q(self, q) -> np.ndarray:
        return self._check_state(q, self.nq, "configuration q",
                                 f"x, y, theta, {self.n_arm} arm joints")

    def _check_v(self, v) -> np.ndarray:
        return self._check_state(v, self.nv, "velocity v",
                                 f"{', '.join(self.base.velocity_names)}, {self.n_arm} arm joints")

    def _check_state(self, value, size: int, what: str, layout: str) -> np.ndarray:
        value = np.asarray(value, dtype=float)
        if value.shape != (size,):
            raise ShapeError(f"robot {self.name!r}: {what} must have shape ({size},) "
                             f"[{layout}], got {value.shape}")
        # one dot product is cheaper than isfinite().all(); exact check only when it fails
        if not math.isfinite(value @ value) and not np.all(np.isfinite(value)):
            raise NonFiniteError(f"robot {self.name!r}: {what} holds NaN or inf: {value}")
        return value

    @staticmethod
    def _check_reference(reference: str) -> None:
        if reference not in _REFERENCES:
            raise UnknownNameError(
                f"unknown reference {reference!r}; use one of {list(_REFERENCES)}"
            )

    @staticmethod
    def _out(out, shape: tuple[int, ...], what: str) -> np.ndarray:
        if out is None:
            return np.empty(shape)
        if out.shape != shape:
            raise ShapeError(f"out for {what} must have shape {shape}, got {out.shape}")
        return out

    # ------------------------------------------------------------------ velocity maps
    def velocity_map(self, q) -> np.ndarray:
        """``S(q)`` (nq × nv) with ``q̇ = S v``: ``blockdiag(H(θ), I)``."""
        q = self._check_q(q)
        s = np.zeros((self.nq, self.nv))
        self.base.pose_rate_matrix(q[2], out=s[:3, : self.nv_base])
        s[3:, self.nv_base :] = np.eye(self.n_arm)
        return s

    def integrate(self, q, v, dt: float) -> np.ndarray:
        """Configuration after ``dt`` [s] at constant ``v``.

        The base moves exactly along the arc of its constant body twist (SE(2) exponential);
        the arm joints move linearly.
        """
        q = self._check_q(q)
        v = self._check_v(v)
        base = self.base.integrate_pose(q[:3], v[: self.nv_base], dt)
        return np.concatenate([base, q[3:] + dt * v[self.nv_base :]])

    # ------------------------------------------------------------------ kinematics update
    def update(self, q, v=None) -> None:
        """Run the kinematics once: forward kinematics, joint Jacobians, frame placements and,
        with ``v``, the velocities and drift accelerations (for :meth:`frame_drift`)."""
        q = self._check_q(q)
        model, data = self.model, self.data
        theta = float(q[2])
        c, s = math.cos(theta), math.sin(theta)
        h = self._h
        # only the cos/sin entries of H(θ) change; element writes avoid temporaries (hot path)
        if self._body_kind == "holonomic":
            h[0, 0] = c
            h[0, 1] = -s
            h[1, 0] = s
            h[1, 1] = c
        elif self._body_kind == "unicycle":
            h[0, 0] = c
            h[1, 0] = s
        else:
            self.base.pose_rate_matrix(theta, out=h)
        if v is None:
            pin.computeJointJacobians(model, data, q)
            self._has_v = False
        else:
            v = self._check_v(v)
            nb = self.nv_base
            if self._body_kind == "holonomic":
                vx, vy, omega = v[:3].tolist()
            elif self._body_kind == "unicycle":
                (vx, omega), vy = v[:2].tolist(), 0.0
            else:
                vx, vy, omega = (self.base.body_map @ v[:nb]).tolist()
            # q̇ = S v and q̈ = Ṡ v (base pose rates and their drift at constant v)
            self._qdot[:3] = (c * vx - s * vy, s * vx + c * vy, omega)
            self._qdot[3:] = v[nb:]
            self._qddot[:3] = (-omega * (s * vx + c * vy), omega * (c * vx - s * vy), 0.0)
            pin.forwardKinematics(model, data, q, self._qdot, self._qddot)
            pin.computeJointJacobians(model, data)
            self._v[:] = v
            self._has_v = True
        pin.updateFramePlacements(model, data)
        self._q[:] = q
        self._valid = True
        self._com_valid = False

    @staticmethod
    def _same(value, cached: np.ndarray) -> bool:
        """Whether ``value`` equals the cached array (cheap; any non-array input is "new")."""
        return type(value) is np.ndarray and value.shape == cached.shape and (value == cached).all()

    def _ensure(self, q) -> None:
        """Kinematics at ``q`` (``None``: the last update's)."""
        if q is None:
            if not self._valid:
                raise RuntimeError(f"robot {self.name!r}: pass q or call update(q) first")
            return
        if not (self._valid and self._same(q, self._q)):
            self.update(q)

    def _ensure_velocity(self, q, v) -> None:
        """Kinematics at ``(q, v)`` (``None``: the last update's), with one update at most."""
        if v is None:
            self._ensure(q)
            if not self._has_v:
                raise RuntimeError(f"robot {self.name!r}: pass v or call update(q, v) first")
            return
        if q is None:
            if not self._valid:
                raise RuntimeError(f"robot {self.name!r}: pass q or call update(q) first")
            q_same = True
        else:
            q_same = self._valid and self._same(q, self._q)
        if not (q_same and self._has_v and self._same(v, self._v)):
            self.update(self._q if q is None else q, v)

    # ------------------------------------------------------------------ frame quantities
    def frame_pose(
        self, q=None, frame: str | int = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """Homogeneous pose (4 × 4) of ``frame`` in the world [m]."""
        self._ensure(q)
        placement = self.data.oMf[self.frame_id(frame)]
        out = self._out(out, (4, 4), "frame_pose")
        out[:3, :3] = placement.rotation
        out[:3, 3] = placement.translation
        out[3, :3] = 0.0
        out[3, 3] = 1.0
        return out

    def frame_position(
        self, q=None, frame: str | int = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """Position (3,) [m] of ``frame``'s origin in the world."""
        self._ensure(q)
        out = self._out(out, (3,), "frame_position")
        out[:] = self.data.oMf[self.frame_id(frame)].translation
        return out

    def frame_jacobian(
        self,
        q=None,
        frame: str | int = "ee",
        reference: str = "world",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Geometric Jacobian (6 × nv), rows ``[linear; angular]``: the twist of ``frame`` is
        ``J v`` — origin velocity [m/s] and angular velocity [rad/s] in world axes
        (``reference="world"``, pinocchio's LOCAL_WORLD_ALIGNED), base axes
        (``reference="base"``) or the frame's axes (``reference="local"``)."""
        self._check_reference(reference)
        self._ensure(q)
        pin_reference = pin.ReferenceFrame.LOCAL if reference == "local" else _LWA
        jac = pin.getFrameJacobian(self.model, self.data, self.frame_id(frame), pin_reference)
        out = self._out(out, (6, self.nv), "frame_jacobian")
        np.matmul(jac, self._s, out=out)
        if reference == "base":
            self._rotate_to_base(out)
        return out

    def symbolic_frame(self, frame: str | int = "ee") -> ca.Function:
        """``q -> (pose, J)`` as a CasADi function (cached per frame), for
        ``Controller(..., kinematics="compiled")``.

        ``pose`` (4 × 4) is :meth:`frame_pose` (world pose, translation [m]) and ``J``
        (6 × nv) is :meth:`frame_jacobian` with ``reference="world"``: rows ``[linear [m/s];
        angular [rad/s]]`` of the frame origin's twist in world axes per unit of the robot's
        *own* velocity coordinates ``v`` (base frame ``(v_x, v_y, ω)`` or ``(v, ω)``, then
        the arm rates), i.e. ``J_pin(q) S(q)`` with ``S = blockdiag(H(θ), I)``. ``frame`` is
        anything :meth:`frame_id` accepts; an unknown one raises
        :class:`~wbc.UnknownNameError` as the numeric getters do.
        """
        fid = self.frame_id(frame)
        function = self._symbolic.get(fid)
        if function is None:
            function = self._symbolic[fid] = self._symbolic_frame(fid)
        return function

    def _symbolic_frame(self, fid: int) -> ca.Function:
        # pinocchio's configuration is ours (scalar root joints PX, PY, RZ), so the 1-DoF
        # chain kinematics give pose and J_pin = ∂(twist)/∂q̇ directly; only the base columns
        # change, by H(θ) = Rz(θ) B as in update()
        joint_space = symbolic_frame_kinematics(self.model, fid)
        q = ca.SX.sym("q", self.nq)
        pose, J_pin = joint_space(q)
        J = ca.horzcat(J_pin[:, :3] @ self._symbolic_pose_rate_matrix(q[2]), J_pin[:, 3:])
        return ca.Function(joint_space.name(), [q], [pose, J], ["q"], ["pose", "J"])

    def _symbolic_pose_rate_matrix(self, theta: ca.SX) -> ca.SX:
        """``H(θ) = Rz(θ) B`` (3 × base.nv) as a CasADi expression (cf.
        :meth:`PlanarBase.pose_rate_matrix`)."""
        c, s = ca.cos(theta), ca.sin(theta)
        rz = ca.SX(3, 3)  # structural zeros keep the products with it lean
        rz[0, 0], rz[0, 1], rz[1, 0], rz[1, 1], rz[2, 2] = c, -s, s, c, 1
        return rz @ ca.sparsify(ca.DM(self.base.body_map))

    def _symbolic_configuration_rate(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """``q̇ = S(q) v``: base pose rates ``H(θ) v_b`` [m/s, m/s, rad/s], arm rates as is."""
        nb = self.nv_base
        return ca.vertcat(self._symbolic_pose_rate_matrix(q[2]) @ v[:nb], v[nb:])

    def symbolic_drift(self, frame: str | int = "ee") -> ca.Function:
        """``(q, v) -> drift`` as a CasADi function (cached per frame): :meth:`frame_drift`
        with ``reference="world"``.

        ``drift`` (6 × 1) is ``J̇ v = d/dt (J v)`` at ``v̇ = 0`` for the ``J = J_pin(q) S(q)``
        of :meth:`symbolic_frame`, rows ``[linear [m/s²]; angular [rad/s²]]`` in world axes:
        ``J̇_pin q̇ + J_pin Ṡ v`` with ``q̇ = S(q) v``, the base map's rotation rate included
        exactly as in the numeric getter. ``frame`` is anything :meth:`frame_id` accepts; an
        unknown one raises :class:`~wbc.UnknownNameError`.
        """
        fid = self.frame_id(frame)
        function = self._symbolic_drift.get(fid)
        if function is None:
            # differentiating J_pin S (not J_pin alone) along q̇ = S v gives the Ṡ v term
            function = self._symbolic_drift[fid] = symbolic_frame_drift(
                self.symbolic_frame(fid), self._symbolic_configuration_rate
            )
        return function

    def _rotate_to_base(self, rows: np.ndarray) -> None:
        """Apply ``blockdiag(Rᵀ, Rᵀ)``, ``R = Rz(θ)``, in place to 6-row arrays."""
        c, s = math.cos(self._q[2]), math.sin(self._q[2])
        for i in (0, 3):
            x = rows[i].copy()
            rows[i] = c * x + s * rows[i + 1]
            rows[i + 1] = -s * x + c * rows[i + 1]

    def base_jacobian(
        self, q=None, frame: str | int = "ee", reference: str = "world"
    ) -> np.ndarray:
        """Base columns (6 × base.nv) of :meth:`frame_jacobian`: Sorour et al.'s ``H J_b``."""
        return self.frame_jacobian(q, frame, reference)[:, : self.nv_base].copy()

    def arm_jacobian(self, q=None, frame: str | int = "ee", reference: str = "world") -> np.ndarray:
        """Arm columns (6 × n_arm) of :meth:`frame_jacobian`."""
        return self.frame_jacobian(q, frame, reference)[:, self.nv_base :].copy()

    def frame_jacobian_rpy(
        self, q=None, frame: str | int = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """Analytic Jacobian ``M_RPY J`` (6 × nv) of Sorour et al.: rows ``[ṗ; d(rpy)/dt]``.

        ``rpy = (roll, pitch, yaw)`` with ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (pinocchio's
        ``matrixToRpy``); ``M_RPY = blockdiag(I, E⁻¹)`` where ``ω_world = E(rpy) d(rpy)/dt``.
        Singular at pitch = ±π/2.
        """
        out = self.frame_jacobian(q, frame, "world", out)
        rotation = self.data.oMf[self.frame_id(frame)].rotation
        e_inv = pin.rpy.computeRpyJacobianInverse(
            pin.rpy.matrixToRpy(rotation), pin.ReferenceFrame.WORLD
        )
        out[3:] = e_inv @ out[3:]
        return out

    def frame_rpy(self, q=None, frame: str | int = "ee") -> np.ndarray:
        """``(roll, pitch, yaw)`` [rad] of ``frame``'s orientation, ``R = Rz Ry Rx``."""
        self._ensure(q)
        return pin.rpy.matrixToRpy(self.data.oMf[self.frame_id(frame)].rotation)

    def frame_velocity(
        self,
        q=None,
        v=None,
        frame: str | int = "ee",
        reference: str = "world",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Twist ``J v`` (6,) of ``frame``: ``[linear [m/s]; angular [rad/s]]``."""
        self._check_reference(reference)
        self._ensure_velocity(q, v)
        pin_reference = pin.ReferenceFrame.LOCAL if reference == "local" else _LWA
        twist = pin.getFrameVelocity(self.model, self.data, self.frame_id(frame), pin_reference)
        out = self._out(out, (6,), "frame_velocity")
        out[:3] = twist.linear
        out[3:] = twist.angular
        if reference == "base":
            self._rotate_to_base(out)
        return out

    def frame_drift(
        self,
        q=None,
        v=None,
        frame: str | int = "ee",
        reference: str = "world",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """``J̇ v`` (6,): the frame's twist derivative at zero acceleration ``v̇ = 0``
        [m/s², rad/s²], so that ``d/dt (J v) = J v̇ + J̇ v`` for the Jacobian ``J`` of the same
        ``reference`` (base and frame axes rotate: their rotation rate enters ``J̇``)."""
        self._check_reference(reference)
        self._ensure_velocity(q, v)
        fid = self.frame_id(frame)
        acc = pin.getFrameClassicalAcceleration(self.model, self.data, fid, _LWA)
        out = self._out(out, (6,), "frame_drift")
        out[:3] = acc.linear
        out[3:] = acc.angular
        if reference == "base":
            twist = pin.getFrameVelocity(self.model, self.data, fid, _LWA)
            body = np.concatenate([twist.linear, twist.angular])
            self._rotate_to_base(out)
            self._rotate_to_base(body)
            yaw_rate = self._qdot[2]
            for i in (0, 3):  # d/dt (Rᵀ a) = Rᵀ ȧ − θ̇ ẑ × (Rᵀ a)
                out[i] += yaw_rate * body[i + 1]
                out[i + 1] -= yaw_rate * body[i]
        elif reference == "local":
            twist = pin.getFrameVelocity(self.model, self.data, fid, pin.ReferenceFrame.LOCAL)
            rotation_t = self.data.oMf[fid].rotation.T
            # d/dt (Rᵀ a) = Rᵀ ȧ − ω_local × (Rᵀ a); the angular term vanishes (ω × ω = 0)
            out[:3] = rotation_t @ out[:3] - np.cross(twist.angular, twist.linear)
            out[3:] = rotation_t @ out[3:]
        return out

    # ------------------------------------------------------------------ centre of mass
    def com(self, q=None, out: np.ndarray | None = None) -> np.ndarray:
        """Centre of mass (3,) [m] of the whole robot (base body + arm) in the world."""
        self._ensure(q)
        if not self._com_valid:
            pin.centerOfMass(self.model, self.data, pin.KinematicLevel.POSITION, False)
            self._com_valid = True
        out = self._out(out, (3,), "com")
        out[:] = self.data.com[0]
        return out

    def com_jacobian(self, q=None, out: np.ndarray | None = None) -> np.ndarray:
        """Jacobian (3 × nv) of the centre of mass in world axes: ``ċ = J_c v``."""
        self._ensure(q)
        jac = pin.jacobianCenterOfMass(self.model, self.data, False)
        out = self._out(out, (3, self.nv), "com_jacobian")
        np.matmul(jac, self._s, out=out)
        return out

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    # ------------------------------------------------------------------ manipulability
    def _arm_jacobian_and_derivatives(self, frame) -> tuple[np.ndarray, np.ndarray]:
        """Arm Jacobian ``J`` (6 × n, LOCAL_WORLD_ALIGNED) and ``∂J/∂q_k`` (n × 6 × n)."""
        fid = self.frame_id(frame)
        spatial = pin.getFrameJacobian(self.model, self.data, fid, pin.ReferenceFrame.WORLD)[:, 3:]
        point = self.data.oMf[fid].translation
        v0, w = spatial[:3].T, spatial[3:].T  # (n, 3): spatial twists at the world origin
        linear = v0 + np.cross(w, point)  # velocity of the frame's origin
        mask = self._ancestors[:, :, None]
        # ∂S_i/∂q_k = ad(S_k) S_i for k an ancestor of i (spatial, world origin)
        d_w = np.cross(w[:, None, :], w[None, :, :]) * mask
        d_v0 = (
            np.cross(w[:, None, :], v0[None, :, :]) + np.cross(v0[:, None, :], w[None, :, :])
        ) * mask
        # origin velocity column: v0_i + w_i × p, with ∂p/∂q_k = linear_k
        d_linear = d_v0 + np.cross(d_w, point) + np.cross(w[None, :, :], linear[:, None, :])
        jac = np.vstack([linear.T, w.T])
        d_jac = np.concatenate([d_linear, d_w], axis=2).transpose(0, 2, 1)
        return jac, d_jac

    def manipulability(self, q=None, frame: str | int = "ee") -> float:
        """Yoshikawa's measure ``det(J Jᵀ)`` of the arm.

        ``J`` (6 × n_arm) is the arm's columns of the geometric Jacobian of ``frame`` (origin
        velocity and angular velocity). The value does not depend on the base pose nor on the
        axes the twist is expressed in (world or base).
        """
        self._ensure(q)
        jac = pin.getFrameJacobian(self.model, self.data, self.frame_id(frame), _LWA)[:, 3:]
        return float(np.linalg.det(jac @ jac.T))

    def manipulability_gradient(
        self, q=None, frame: str | int = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """Gradient (n_arm,) of :meth:`manipulability` with respect to the arm joints.

        ``∂ det(A)/∂q_k = 2 tr(adj(A) J (∂J/∂q_k)ᵀ)`` with ``A = J Jᵀ``; the adjugate keeps it
        finite at singularities. ``∂J/∂q_k`` is computed analytically from the spatial
        Jacobian (``∂S_i/∂q_k = ad(S_k) S_i``). The gradient with respect to the base pose is
        zero.
        """
        self._ensure(q)
        jac, d_jac = self._arm_jacobian_and_derivatives(frame)
        eigenvalues, vectors = np.linalg.eigh(jac @ jac.T)
        others = np.where(np.eye(6, dtype=bool), 1.0, eigenvalues[None, :]).prod(axis=1)
        adjugate = (vectors * others) @ vectors.T
        weights = adjugate @ jac
        out = self._out(out, (self.n_arm,), "manipulability_gradient")
        out[:] = 2.0 * np.einsum("ri,kri->k", weights, d_jac)
        return out

    def __repr__(self) -> str:
        return (
            f"MobileManipulator(name={self.name!r}, base={self.base.name!r}, "
            f"arm={self.arm.name!r}, "
            f"nq={self.nq}, nv={self.nv})"
        )
