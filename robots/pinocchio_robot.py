"""`PinocchioRobot`: the numeric and symbolic kinematics every wbc robot shares.

One class serves three kinds of root: an arm on a planar wheeled base
(:class:`~wbc.robots.manipulator.MobileManipulator`, ``root == "planar"``), a fixed-base arm
(:class:`~wbc.robots.fixed_base.FixedBaseRobot`, ``root == "fixed"``), the special case without
base, and a free-floating robot — a humanoid, a quadruped —
(:class:`~wbc.robots.floating_base.FloatingBaseRobot`, ``root == "free_flyer"``), whose
subclass overrides what the free flyer changes. Whole-robot URDFs load with any of the three
through :func:`wbc.robots.from_urdf` (``root=...``, :mod:`wbc.robots.whole_body`).

Coordinates
-----------
The robot's configuration ``q`` *is* the pinocchio model's: for a mobile base, three scalar root
joints give the base pose ``x, y`` [m], ``θ`` [rad] (see :mod:`wbc.robots.model_assembly`),
then the arm joints [rad or m]; for a fixed base, the joints only. The velocity coordinates
``v`` are the base's own — ``(v_x, v_y, ω)`` in the **base frame** for holonomic bases,
``(v, ω)`` for the differential drive — then the joint rates. They map to pinocchio's ``q̇`` by

    q̇ = S(q) v,   S = blockdiag(H(θ), I),   J_v = J_pin S,   J̇_v v = J̇_pin q̇ + J_pin Ṡ v,

with ``H(θ) = Rz(θ) B`` of the base model (:class:`~wbc.robots.planar_base.PlanarBase`); a fixed
base has ``S = I``.

A **free-flyer root** (pinocchio's ``JointModelFreeFlyer``) has ``nq_base = 7`` configuration
entries — the root body's position ``x, y, z`` [m] in the world and its orientation as a unit
quaternion ``q_x, q_y, q_z, q_w`` (pinocchio's order) — and ``nv_base = 6`` velocity entries:
the root body's linear velocity [m/s] and angular velocity [rad/s], both in the **root body's
axes** (pinocchio's own convention, the free-floating counterpart of the planar bases' "base
frame" velocities). ``v`` is then pinocchio's own velocity: the Jacobians over ``v`` are
pinocchio's (no ``S`` in them), :meth:`integrate` and :meth:`difference` are pinocchio's
Lie-group ``integrate`` / ``difference``, and ``q̇ = S(q) v`` with ``S =
blockdiag(R, ½ Q(quat), I)`` is used only by the symbolic drifts
(:func:`wbc.robots.symbolic.free_flyer_rate`). The joints after the root (``n_arm = nv − 6``
of them, each 1-DoF) are what posture tasks and joint limits act on.

Frames and Jacobians
--------------------
Every frame of the model is available by name (:attr:`PinocchioRobot.frame_names`, aliases such
as ``"ee"`` included) or by index. ``frame_jacobian(q, frame, reference)`` returns ``J``
(6 × nv), rows ``[linear; angular]``, such that the frame's twist is ``J v``:

* ``reference="world"``: pinocchio's ``LOCAL_WORLD_ALIGNED`` — the linear velocity of the
  frame's **origin** and the angular velocity, both in **world axes**;
* ``reference="base"``: the same twist expressed in the **base frame's axes**,
  ``blockdiag(Rᵀ, Rᵀ) J_world`` with ``R = Rz(θ)`` (world axes for a fixed base; the root
  body's full rotation for a free flyer);
* ``reference="local"``: the same twist in the **frame's own axes** (pinocchio ``LOCAL``).

``frame_drift`` returns ``J̇ v = d/dt (J v)`` at ``v̇ = 0`` for the Jacobian of the same
``reference`` (for ``"base"`` and ``"local"`` this includes the rotation of the expression axes;
``"world"`` is pinocchio's classical acceleration of the frame's origin).

Hot path: one kinematics update per tick
----------------------------------------
Every getter takes ``q`` (and ``v`` where needed). Kinematics are cached on the last ``(q, v)``:
a getter called with the configuration of the last update reuses it; ``q=None`` means "the
configuration of the last :meth:`PinocchioRobot.update`". Getters write into ``out=`` when
given — any float array of the right shape, for example a column-major view into a compiled
stack's parameter vector (:func:`wbc.robots.views.column_major_view`) — element-wise, so a tick
does no per-call allocation or conversion on the Python side::

    robot.update(q, v)                                    # FK, Jacobians, frames, accelerations
    robot.frame_jacobian(None, "ee", out=J_view)          # (6, nv) written into p in place
    robot.frame_drift(None, None, "ee", out=drift_view)   # (6,)
    robot.frame_pose(None, "ee", out=pose_view)           # (4, 4)

The controller reaches these through :attr:`PinocchioRobot.quantities`
(:mod:`wbc.robots.model_quantities`). With ``Controller(..., kinematics="compiled")`` a tick
needs no update at all: :meth:`PinocchioRobot.symbolic_frame` and
:meth:`PinocchioRobot.symbolic_drift` give the same quantities as CasADi functions
(:mod:`wbc.robots.symbolic`), evaluated inside the compiled level functions.

Sharing, as pinocchio does
--------------------------
What never changes — the pinocchio ``Model``, the frame table, the limits, the compiled CasADi
functions — is shared between a robot and its :meth:`~PinocchioRobot.clone`; what changes each
tick — the pinocchio ``Data``, the cached ``(q, v)``, ``S(q)``, the quantity fillers — belongs to
one instance. A robot is not thread-safe: clone it per controller or thread.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.errors import NonFiniteError, ShapeError, UnknownNameError

from . import manipulability as _manipulability
from .arms import FRAME_KINDS
from .limits import Limits
from .model_quantities import register_quantities
from .planar_base import HOLONOMIC_MAP, UNICYCLE_MAP, PlanarBase
from .symbolic import (
    check_joints,
    pose_rate_matrix,
    symbolic_center_of_mass,
    symbolic_frame_drift,
    symbolic_frame_kinematics,
)

__all__ = ["FREE_FLYER_CONFIGURATION", "FREE_FLYER_VELOCITY", "PinocchioRobot", "REFERENCES"]

REFERENCES = ("world", "base", "local")
"""The axes a Jacobian or drift can be expressed in (see the module docstring)."""
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_BASE_NQ = 3  # configuration entries of a planar base: x, y, θ
_FREE_FLYER_NQ, _FREE_FLYER_NV = 7, 6  # x, y, z, quaternion; linear, angular velocity
#: names of a free flyer's configuration and velocity entries (velocity in the root's axes)
FREE_FLYER_CONFIGURATION = ("x", "y", "z", "qx", "qy", "qz", "qw")
FREE_FLYER_VELOCITY = ("vx", "vy", "vz", "wx", "wy", "wz")


class PinocchioRobot:
    """Kinematics of a pinocchio model, with or without a planar base (module docstring).

    Subclasses build the model; see :class:`~wbc.robots.manipulator.MobileManipulator` and
    :class:`~wbc.robots.fixed_base.FixedBaseRobot`.

    Args:
        model: the pinocchio model; for a mobile base its first three joints are the base's
            (``x``, ``y``, ``θ``), every joint is a supported 1-DoF joint
            (:func:`wbc.robots.symbolic.check_joints`).
        name: robot name.
        limits: position limits over ``q``, velocity and acceleration limits over ``v``.
        home: the configuration :meth:`neutral` returns.
        base: the planar base model, ``None`` for a fixed base or a free flyer.
        aliases: extra frame names, ``alias -> model frame name``.
        root: ``"free_flyer"`` when the model's first joint is a ``JointModelFreeFlyer`` (what
            :class:`~wbc.robots.floating_base.FloatingBaseRobot` passes); otherwise ``None``
            (``"planar"`` with a base, ``"fixed"`` without).

    Frames several of which share a name (a URDF link and joint of the same name) are known
    only as ``"<kind>:<name>"`` (``"link:tool0"``, ``"joint:tool0"``, see
    :mod:`wbc.robots.arms`); the bare name raises :class:`~wbc.UnknownNameError` listing them.

    Raises:
        WbcError: a joint type is not supported.
        UnknownNameError: an alias names no frame.
    """

    #: the URDF file the robot was built from (``None`` for a model built in code); the
    #: collision helpers read the geometry from it
    urdf_path: str | None = None
    #: URDF joints removed from the model (locked at a value), e.g. gripper fingers or the
    #: wheels of a whole-robot URDF (:mod:`wbc.robots.whole_body`)
    locked_joints: tuple[str, ...] = ()
    #: the locked joints that were a whole-robot URDF's wheels (:mod:`wbc.robots.whole_body`)
    wheel_joints: tuple[str, ...] = ()

    def __init__(self, model: pin.Model, *, name: str, limits: Limits, home,
                 base: PlanarBase | None = None, aliases: Mapping[str, str] | None = None,
                 root: str | None = None) -> None:
        check_joints(model, f"robot {name!r}")
        self.model = model
        self.name = name
        self.base = base
        if root == "free_flyer":
            if base is not None or model.njoints < 2 or \
                    model.joints[1].shortname() != "JointModelFreeFlyer":
                raise ShapeError(f"robot {name!r}: root='free_flyer' needs a model whose "
                                 f"first joint is a JointModelFreeFlyer, and no planar base")
            self.root = "free_flyer"
            self.nq_base, self.nv_base, self._root_joints = _FREE_FLYER_NQ, _FREE_FLYER_NV, 1
        elif root is None:
            self.root = "fixed" if base is None else "planar"
            self.nq_base = 0 if base is None else _BASE_NQ
            self.nv_base = 0 if base is None else base.nv
            self._root_joints = self.nq_base  # x, y, θ: three scalar joints
        else:
            raise UnknownNameError(f"robot {name!r}: root must be 'free_flyer' or None, got "
                                   f"{root!r}")
        self.nq = model.nq
        self.n_arm = model.nq - self.nq_base
        self.nv = self.nv_base + self.n_arm
        # pinocchio's velocity index of the first joint after the root (3 for a planar base,
        # whose pinocchio velocity is q̇; 6 for a free flyer; 0 for a fixed base)
        self._arm_v0 = model.nv - self.n_arm
        self.limits = limits
        if limits.nq != self.nq or limits.nv != self.nv:
            raise ShapeError(f"robot {name!r}: limits of sizes nq = {limits.nq}, nv = "
                             f"{limits.nv}, expected {self.nq} and {self.nv}")
        self._frame_ids: dict[str, int] = {}
        names = [frame.name for frame in model.frames]
        # a name several frames share (a URDF link and joint) is refused, its frames are
        # "<kind>:<name>" (as wbc.robots.arms renames them)
        self._ambiguous = {name for name in names if names.count(name) > 1}
        for index, frame in enumerate(model.frames):
            if frame.name in self._ambiguous:
                kind = FRAME_KINDS.get(frame.type, "frame")
                self._frame_ids.setdefault(f"{kind}:{frame.name}", index)
            else:
                self._frame_ids[frame.name] = index
        for alias, target in (aliases or {}).items():
            self._frame_ids[alias] = self.frame_id(target)
        base_names = "".join(f"{n}, " for n in self.configuration_names[: self.nq_base])
        base_rates = "".join(f"{n}, " for n in self.velocity_names[: self.nv_base])
        self._layouts = (f"{base_names}{self.n_arm} joints", f"{base_rates}{self.n_arm} joints")
        self._home = self._check_q(home).copy()
        self._ancestors = _manipulability.ancestor_mask(model, self._arm_v0, self.n_arm)
        self._body_kind = self._kind_of_base()
        # compiled CasADi functions, by (kind, frame id); immutable, so shared by clones
        self._symbolic: dict[tuple[str, int], ca.Function] = {}
        self._allocate()

    def _kind_of_base(self) -> str:
        """Which fast path :meth:`update` takes for ``S(q)`` (element writes, hot path); a free
        flyer's is its own :meth:`~wbc.robots.floating_base.FloatingBaseRobot.update`."""
        if self.root == "free_flyer":
            return "free_flyer"
        if self.base is None:
            return "fixed"
        body = self.base.body_map
        if body.shape == (3, 3) and np.array_equal(body, HOLONOMIC_MAP):
            return "holonomic"
        if body.shape == (3, 2) and np.array_equal(body, UNICYCLE_MAP):
            return "unicycle"
        return "generic"

    def _allocate(self) -> None:
        """The per-instance state: pinocchio ``Data``, caches, ``S(q)``, the quantity registry."""
        self.data = self.model.createData()
        self._q = np.zeros(self.nq)
        self._v = np.zeros(self.nv)
        self._qdot = np.zeros(self.nq)
        self._qddot = np.zeros(self.nq)  # stays zero for a fixed base (S constant)
        self._s = np.zeros((self.nq, self.nv))  # S(q) of the last update
        self._s[self.nq_base:, self.nv_base:] = np.eye(self.n_arm)
        self._h = self._s[: self.nq_base, : self.nv_base]  # H(θ), a view into S
        if self.base is not None:
            self.base.pose_rate_matrix(0.0, out=self._h)  # constant entries
        self._valid = False
        self._has_v = False
        self._com_valid = False
        self.quantities = register_quantities(self)

    def clone(self):
        """A copy sharing the (immutable) model and compiled functions, with its own pinocchio
        ``Data``, caches and quantity registry."""
        other = copy.copy(self)
        other._allocate()
        return other

    # ------------------------------------------------------------------ names and sizes
    @property
    def frame_names(self) -> list[str]:
        """Names of the frames available to the getters, aliases included (``"universe"``
        excluded)."""
        return [name for name in self._frame_ids if name != "universe"]

    def has_frame(self, frame: str) -> bool:
        """Whether ``frame`` is one of :attr:`frame_names`."""
        return frame != "universe" and frame in self._frame_ids

    @property
    def joint_names(self) -> list[str]:
        """Names of the joints after the base, in configuration order."""
        return list(self.model.names)[1 + self._root_joints:]

    @property
    def configuration_names(self) -> list[str]:
        """Names of the entries of ``q``."""
        if self.root == "free_flyer":
            return [*FREE_FLYER_CONFIGURATION, *self.joint_names]
        return [*(("x", "y", "theta") if self.base is not None else ()), *self.joint_names]

    @property
    def velocity_names(self) -> list[str]:
        """Names of the entries of ``v``."""
        if self.root == "free_flyer":
            return [*FREE_FLYER_VELOCITY, *self.joint_names]
        base = self.base.velocity_names if self.base is not None else ()
        return [*base, *self.joint_names]

    def frame_id(self, frame: str | int) -> int:
        """Index of a frame given by name (or already by index) in :attr:`model`."""
        if isinstance(frame, str):
            try:
                return self._frame_ids[frame]
            except KeyError:
                if frame in self._ambiguous:
                    raise UnknownNameError(
                        f"robot {self.name!r}: frame name {frame!r} is ambiguous; pick one of "
                        f"{[name for name in self._frame_ids if name.partition(':')[2] == frame]}"
                    ) from None
                raise UnknownNameError(
                    f"robot {self.name!r} has no frame {frame!r}; frames: {self.frame_names}"
                ) from None
        if isinstance(frame, (int, np.integer)) and 0 <= int(frame) < len(self.model.frames):
            return int(frame)
        raise UnknownNameError(
            f"robot {self.name!r}: frame must be a name or an index below "
            f"{len(self.model.frames)}, got {frame!r}; frames: {self.frame_names}"
        )

    # ------------------------------------------------------------------ configurations
    def neutral(self) -> np.ndarray:
        """The home configuration (a copy)."""
        return self._home.copy()

    def random_configuration(
        self, rng: np.random.Generator | None = None, base_range: float = 2.0
    ) -> np.ndarray:
        """A random configuration: joints uniform within their position limits (``[−π, π]``
        [rad] where unbounded); a base pose uniform in ``[−base_range, base_range]²`` [m] ×
        ``[−π, π]`` [rad]."""
        rng = np.random.default_rng() if rng is None else rng
        lower = self.limits.q_lower[self.nq_base:]
        upper = self.limits.q_upper[self.nq_base:]
        lower = np.where(np.isfinite(lower), lower, -math.pi)
        upper = np.where(np.isfinite(upper), upper, math.pi)
        base = (rng.uniform([-base_range, -base_range, -math.pi], [base_range, base_range, math.pi])
                if self.base is not None else ())
        return np.concatenate([base, rng.uniform(lower, upper)])

    def difference(self, q0, q1) -> np.ndarray:
        """The tangent vector from ``q0`` to ``q1``: pinocchio's Lie-group ``difference``, of
        size ``model.nv``, so that ``pin.integrate(model, q0, d) == q1``.

        For a fixed base and a free flyer this is in the robot's velocity coordinates (for the
        free flyer ``integrate(q0, d, 1.0) == q1``). For a planar base it is over pinocchio's
        scalar root joints — the world pose differences ``(Δx [m], Δy [m], Δθ [rad])``, then
        the joints — not over the base's own velocity coordinates, which a differential drive
        cannot always realise.
        """
        return pin.difference(self.model, self._check_q(q0), self._check_q(q1))

    def integrate(self, q, v, dt: float) -> np.ndarray:
        """Configuration after ``dt`` [s] at constant ``v``.

        A base moves exactly along the arc of its constant body twist (SE(2) exponential); the
        joints move linearly (``q + v·dt``, exact for 1-DoF joints).
        """
        q = self._check_q(q)
        v = self._check_v(v)
        joints = q[self.nq_base:] + dt * v[self.nv_base:]
        if self.base is None:
            return joints
        base = self.base.integrate_pose(q[:3], v[: self.nv_base], dt)
        return np.concatenate([base, joints])

    def velocity_map(self, q) -> np.ndarray:
        """``S(q)`` (nq × nv) with ``q̇ = S v``: ``blockdiag(H(θ), I)`` (``I`` without base)."""
        q = self._check_q(q)
        s = np.zeros((self.nq, self.nv))
        if self.base is not None:
            self.base.pose_rate_matrix(q[2], out=s[:3, : self.nv_base])
        s[self.nq_base:, self.nv_base:] = np.eye(self.n_arm)
        return s

    # ------------------------------------------------------------------ input checks
    def _check_q(self, q) -> np.ndarray:
        return self._check_state(q, self.nq, "configuration q", self._layouts[0])

    def _check_v(self, v) -> np.ndarray:
        return self._check_state(v, self.nv, "velocity v", self._layouts[1])

    def _check_state(self, value, size: int, what: str, layout: str) -> np.ndarray:
        value = np.asarray(value, dtype=float)
        if value.shape != (size,):
            raise ShapeError(f"robot {self.name!r}: {what} must have shape ({size},) "
                             f"[{layout}], got {value.shape}")
        # one dot product (ndarray.dot: the fastest call) is cheaper than isfinite().all();
        # the exact check runs only when it fails (NaN, inf, or an overflow of huge values)
        if not math.isfinite(value.dot(value)) and not np.all(np.isfinite(value)):
            raise NonFiniteError(f"robot {self.name!r}: {what} holds NaN or inf: {value}")
        return value

    @staticmethod
    def _check_reference(reference: str) -> None:
        if reference not in REFERENCES:
            raise UnknownNameError(
                f"unknown reference {reference!r}; use one of {list(REFERENCES)}"
            )

    @staticmethod
    def _out(out, shape: tuple[int, ...], what: str) -> np.ndarray:
        if out is None:
            return np.empty(shape)
        if out.shape != shape:
            raise ShapeError(f"out for {what} must have shape {shape}, got {out.shape}")
        return out

    # ------------------------------------------------------------------ kinematics update
    def update(self, q, v=None) -> None:
        """Run the kinematics once: forward kinematics, joint Jacobians, frame placements and,
        with ``v``, the velocities and drift accelerations (for :meth:`frame_drift`)."""
        q = self._check_q(q)
        model, data, kind = self.model, self.data, self._body_kind
        if kind != "fixed":
            theta = float(q[2])
            c, s = math.cos(theta), math.sin(theta)
            h = self._h
            # only the cos/sin entries of H(θ) change; element writes avoid temporaries
            if kind == "holonomic":
                h[0, 0] = c
                h[0, 1] = -s
                h[1, 0] = s
                h[1, 1] = c
            elif kind == "unicycle":
                h[0, 0] = c
                h[1, 0] = s
            else:
                base = self.base
                assert base is not None  # kind != "fixed"
                base.pose_rate_matrix(theta, out=h)
        if v is None:
            pin.computeJointJacobians(model, data, q)
            self._has_v = False
        else:
            v = self._check_v(v)
            if kind == "fixed":
                qdot = v
            else:
                nb = self.nv_base
                if kind == "holonomic":
                    vx, vy, omega = v[:3].tolist()
                elif kind == "unicycle":
                    (vx, omega), vy = v[:2].tolist(), 0.0
                else:
                    base = self.base
                    assert base is not None  # kind != "fixed"
                    vx, vy, omega = (base.body_map @ v[:nb]).tolist()
                # q̇ = S v and q̈ = Ṡ v (base pose rates and their drift at constant v)
                qdot = self._qdot
                qdot[:3] = (c * vx - s * vy, s * vx + c * vy, omega)
                qdot[3:] = v[nb:]
                self._qddot[:3] = (-omega * (s * vx + c * vy), omega * (c * vx - s * vy), 0.0)
            pin.forwardKinematics(model, data, q, qdot, self._qddot)
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
        homogeneous = self.data.oMf[self.frame_id(frame)].homogeneous  # one conversion
        out = self._out(out, (4, 4), "frame_pose")
        out[...] = homogeneous
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
        if self.base is None:
            out[...] = jac  # S = I
        else:
            np.matmul(jac, self._s, out=out)
            if reference == "base":
                self._rotate_to_base(out)
        return out

    def _rotate_to_base(self, rows: np.ndarray) -> None:
        """Apply ``blockdiag(Rᵀ, Rᵀ)``, ``R = Rz(θ)``, in place to 6-row arrays."""
        c, s = math.cos(self._q[2]), math.sin(self._q[2])
        for i in (0, 3):
            x = rows[i].copy()
            rows[i] = c * x + s * rows[i + 1]
            rows[i + 1] = -s * x + c * rows[i + 1]

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
        out[:] = twist.vector  # [linear; angular], one conversion
        if reference == "base" and self.base is not None:
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
        out[:] = acc.vector  # [linear; angular], one conversion
        if reference == "base" and self.base is not None:
            twist = pin.getFrameVelocity(self.model, self.data, fid, _LWA)
            body = twist.vector.copy()  # [linear; angular]
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

    # ------------------------------------------------------------------ symbolic forms
    def _cached(self, kind: str, fid: int, build) -> ca.Function:
        """The compiled function ``(kind, fid)``, built once and shared by clones."""
        function = self._symbolic.get((kind, fid))
        if function is None:
            function = self._symbolic[(kind, fid)] = build()
        return function

    def symbolic_frame(self, frame: str | int = "ee") -> ca.Function:
        """``q -> (pose, J)`` as a CasADi function (cached per frame), for
        ``Controller(..., kinematics="compiled")``.

        ``pose`` (4 × 4) is :meth:`frame_pose` (world pose, translation [m]) and ``J``
        (6 × nv) is :meth:`frame_jacobian` with ``reference="world"``: rows ``[linear [m/s];
        angular [rad/s]]`` of the frame origin's twist in world axes per unit of the robot's
        *own* velocity coordinates ``v``, i.e. ``J_pin(q) S(q)``. ``frame`` is anything
        :meth:`frame_id` accepts; an unknown one raises :class:`~wbc.UnknownNameError` as the
        numeric getters do.
        """
        fid = self.frame_id(frame)
        return self._cached("frame", fid, lambda: self._symbolic_frame(fid))

    def _symbolic_frame(self, fid: int) -> ca.Function:
        joint_space = symbolic_frame_kinematics(self.model, fid)
        if self.base is None:
            return joint_space
        # pinocchio's configuration is ours (scalar root joints PX, PY, RZ), so the 1-DoF
        # chain kinematics give pose and J_pin = ∂(twist)/∂q̇ directly; only the base columns
        # change, by S(q)
        q = ca.SX.sym("q", self.nq)
        pose, J_pin = joint_space(q)
        J = self._symbolic_velocity_map_product(q, J_pin)
        return ca.Function(joint_space.name(), [q], [pose, J], ["q"], ["pose", "J"])

    def _symbolic_velocity_map_product(self, q: ca.SX, matrix: ca.SX) -> ca.SX:
        """``matrix S(q)``: a matrix over ``q̇`` (nq columns) made one over ``v``; only the base
        columns change, by ``H(θ) = Rz(θ) B`` as in :meth:`update` (lean: no products with the
        identity block)."""
        if self.base is None:
            return matrix
        return ca.horzcat(matrix[:, :3] @ pose_rate_matrix(q[2], self.base.body_map),
                          matrix[:, 3:])

    def _symbolic_base_axes(self, q: ca.SX) -> ca.SX | None:
        """``Rᵀ`` (3 × 3) of the base frame's rotation ``R = Rz(θ)`` as a CasADi expression of
        ``q`` (``None`` for a fixed base: world axes), for the ``J_base`` quantity."""
        if self.base is None:
            return None
        c, s = ca.cos(q[2]), ca.sin(q[2])
        rt = ca.SX(3, 3)
        rt[0, 0], rt[0, 1], rt[1, 0], rt[1, 1], rt[2, 2] = c, s, -s, c, 1
        return rt

    def _symbolic_configuration_rate(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """``q̇ = S(q) v``: base pose rates ``H(θ) v_b`` [m/s, m/s, rad/s], joint rates as is."""
        nb, base = self.nv_base, self.base
        assert base is not None  # called for a mobile base only
        return ca.vertcat(pose_rate_matrix(q[2], base.body_map) @ v[:nb], v[nb:])

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
        # differentiating J_pin S (not J_pin alone) along q̇ = S v gives the Ṡ v term
        rate = None if self.root == "fixed" else self._symbolic_configuration_rate
        return self._cached("drift", fid,
                            lambda: symbolic_frame_drift(self.symbolic_frame(fid), rate))

    def symbolic_com(self) -> ca.Function:
        """``q -> com (3, 1)``: :meth:`com` as a CasADi function (cached, shared by clones)."""
        return self._cached("com", -1, lambda: symbolic_center_of_mass(self.model))

    def symbolic_com_jacobian(self) -> ca.Function:
        """``q -> J_com (3, nv)``: :meth:`com_jacobian` as a CasADi function (cached), the
        derivative of :meth:`symbolic_com` times ``S(q)``."""

        def build() -> ca.Function:
            q = ca.SX.sym("q", self.nq)
            jacobian = ca.jacobian(self.symbolic_com()(q), q)
            return ca.Function("com_jacobian", [q],
                               [self._symbolic_velocity_map_product(q, jacobian)], ["q"],
                               ["J_com"])

        return self._cached("com_jacobian", -1, build)

    # ------------------------------------------------------------------ centre of mass
    def com(self, q=None, out: np.ndarray | None = None) -> np.ndarray:
        """Centre of mass (3,) [m] of the whole robot in the world."""
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
        """Total mass [kg] of the bodies the joints carry (those of :meth:`com`: a fixed base's
        root link, attached to the universe, is not counted, as in pinocchio)."""
        return float(sum(inertia.mass for inertia in list(self.model.inertias)[1:]))

    # ------------------------------------------------------------------ manipulability
    def _arm_jacobian_and_derivatives(self, frame) -> tuple[np.ndarray, np.ndarray]:
        """Arm Jacobian ``J`` (6 × n_arm, LOCAL_WORLD_ALIGNED) and ``∂J/∂q_k``
        (n_arm × 6 × n_arm) at the last update."""
        return _manipulability.arm_jacobian_derivatives(
            self.model, self.data, self.frame_id(frame), self._arm_v0, self._ancestors)

    def manipulability(self, q=None, frame: str | int = "ee") -> float:
        """Yoshikawa's measure ``det(J Jᵀ)`` of the arm.

        ``J`` (6 × n_arm) is the arm's columns of the geometric Jacobian of ``frame`` (origin
        velocity and angular velocity). The value does not depend on the base pose nor on the
        axes the twist is expressed in (world or base).
        """
        self._ensure(q)
        jac = pin.getFrameJacobian(self.model, self.data, self.frame_id(frame), _LWA)
        return _manipulability.manipulability(jac[:, self._arm_v0:])

    def manipulability_gradient(
        self, q=None, frame: str | int = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """Gradient (n_arm,) of :meth:`manipulability` with respect to the arm joints
        (:func:`wbc.robots.manipulability.manipulability_gradient`); the gradient with respect
        to the base pose is zero."""
        self._ensure(q)
        jac, d_jac = self._arm_jacobian_and_derivatives(frame)
        out = self._out(out, (self.n_arm,), "manipulability_gradient")
        return _manipulability.manipulability_gradient(jac, d_jac, out)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, nq={self.nq}, nv={self.nv})"
