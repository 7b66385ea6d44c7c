"""`FixedBaseRobot`: a fixed-base arm on pinocchio, with the robot protocol of the controller.

The protocol (shared with the mobile manipulators of :mod:`wbc.robots`; see
:class:`wbc.Controller`):

* ``nq``, ``nv``, ``neutral()``, ``limits`` (:class:`wbc.robots.limits.Limits`);
* ``update(q, v=None)``: one kinematics update (placements, Jacobians, and with ``v`` the
  frame drifts) that the getters below then read;
* ``frame_pose(q=None, frame="ee", out=None) -> (4, 4)`` world pose;
* ``frame_jacobian(q=None, frame="ee", reference="world", out=None) -> (6, nv)``, rows
  ``[linear; angular]``, such that the frame's twist is ``J @ v``: ``"world"`` = world-aligned
  axes at the frame origin (pinocchio ``LOCAL_WORLD_ALIGNED``), ``"base"`` = base axes (the
  same for a fixed base), ``"local"`` = frame axes (pinocchio ``LOCAL``);
* ``frame_drift(q=None, v=None, frame="ee", out=None) -> (6,)``: ``J̇ v`` in world-aligned axes
  (the frame origin's classical acceleration at zero joint acceleration);
* optionally ``symbolic_frame(frame) -> casadi.Function``: ``q -> (pose (4, 4), J (6, nv))``,
  the same quantities as CasADi expressions, so that a controller built with
  ``kinematics="compiled"`` computes them inside its compiled (JIT) level functions instead of
  calling pinocchio every tick;
* optionally ``symbolic_drift(frame) -> casadi.Function``: ``(q, v) -> J̇ v (6, 1)``, the
  CasADi counterpart of ``frame_drift`` (world-aligned axes).

With ``q=None`` a getter reads the last :meth:`~FixedBaseRobot.update` (the controller's path:
one update per tick, then allocation-free getters writing into ``out``); with a ``q`` it
updates first (convenient, slower). A fixed base has ``nq == nv`` (revolute/prismatic joints
only); there are no base coordinates.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.errors import ShapeError, UnknownNameError, WbcError

from .limits import Limits
from .resources import urdf_path

__all__ = ["FixedBaseRobot", "load_panda"]

_REFERENCES = {
    "world": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
    "base": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,  # the base frame is the world frame
    "local": pin.ReferenceFrame.LOCAL,
}


class FixedBaseRobot:
    """A fixed-base arm described by a pinocchio model.

    Args:
        model: the pinocchio model (every joint 1-DoF, so that ``nq == nv``).
        frames: aliases ``alias -> model frame name`` (e.g. ``{"ee": "panda_hand"}``); every
            model frame is also reachable by its own name.
        name: a label for reports.
        acceleration_limit: ``(nv,)`` or scalar acceleration limits [rad/s²] (URDFs carry
            none; default ``inf``).
    """

    def __init__(
        self,
        model: pin.Model,
        frames: Mapping[str, str] | None = None,
        name: str = "",
        acceleration_limit=np.inf,
    ) -> None:
        if model.nq != model.nv:
            raise ShapeError(
                f"FixedBaseRobot needs 1-DoF joints (nq == nv), got nq = "
                f"{model.nq}, nv = {model.nv}"
            )
        self.model = model
        self.data = model.createData()
        self.name = name or model.name
        self.nq, self.nv = model.nq, model.nv
        self._ids: dict[str, int] = {}
        for frame in model.frames:
            self._ids.setdefault(frame.name, model.getFrameId(frame.name))
        for alias, target in (frames or {}).items():
            self._ids[alias] = self._frame_id(target)
        acc = np.broadcast_to(np.asarray(acceleration_limit, dtype=float), (self.nv,))
        self.limits = Limits(
            q_lower=model.lowerPositionLimit.copy(),
            q_upper=model.upperPositionLimit.copy(),
            v_lower=-model.velocityLimit,
            v_upper=model.velocityLimit.copy(),
            a_lower=-acc,
            a_upper=acc.copy(),
        )
        self.n_arm = self.nv  # no base coordinates
        self._zero_v = np.zeros(self.nv)
        self._symbolic: dict[int, ca.Function] = {}
        self._symbolic_drift: dict[int, ca.Function] = {}

    # ------------------------------------------------------------------ names
    @property
    def frame_names(self) -> list[str]:
        """Every name a frame can be asked by (aliases included)."""
        return list(self._ids)

    def has_frame(self, frame: str) -> bool:
        return frame in self._ids

    def _frame_id(self, frame: str) -> int:
        try:
            return self._ids[frame]
        except KeyError:
            raise UnknownNameError(
                f"robot {self.name!r} has no frame {frame!r}; frames are {sorted(self._ids)}"
            ) from None

    # ------------------------------------------------------------------ state
    def neutral(self) -> np.ndarray:
        """The neutral configuration (zeros, clipped into the position limits)."""
        return np.clip(pin.neutral(self.model), self.limits.q_lower, self.limits.q_upper)

    def integrate(self, q: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        """Configuration after ``dt`` [s] at constant joint velocity ``v`` (pinocchio's
        integration on the model's configuration space; ``q + v·dt`` for 1-DoF joints)."""
        return pin.integrate(self.model, np.asarray(q, float), np.asarray(v, float) * dt)

    def update(self, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """One kinematics update at ``q`` (and ``v``, for the drifts): joint placements, joint
        Jacobians, frame placements."""
        if v is None:
            pin.computeJointJacobians(self.model, self.data, q)
        else:
            pin.forwardKinematics(self.model, self.data, q, v, self._zero_v)
            pin.computeJointJacobians(self.model, self.data)
        pin.updateFramePlacements(self.model, self.data)

    # ------------------------------------------------------------------ frame getters
    def frame_pose(
        self, q: np.ndarray | None = None, frame: str = "ee", out: np.ndarray | None = None
    ) -> np.ndarray:
        """World pose ``(4, 4)`` of ``frame`` (at ``q``, or at the last update)."""
        fid = self._frame_id(frame)
        if q is not None:
            self.update(q)
        if out is None:
            return self.data.oMf[fid].homogeneous
        out[...] = self.data.oMf[fid].homogeneous
        return out

    def frame_jacobian(
        self,
        q: np.ndarray | None = None,
        frame: str = "ee",
        reference: str = "world",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Frame Jacobian ``(6, nv)``, rows ``[linear; angular]`` (see the module docstring)."""
        fid = self._frame_id(frame)
        ref = _REFERENCES.get(reference)
        if ref is None:
            raise UnknownNameError(
                f"unknown reference {reference!r}; use one of {sorted(_REFERENCES)}"
            )
        if q is not None:
            self.update(q)
        J = pin.getFrameJacobian(self.model, self.data, fid, ref)
        if out is None:
            return J
        out[...] = J
        return out

    def frame_drift(
        self,
        q: np.ndarray | None = None,
        v: np.ndarray | None = None,
        frame: str = "ee",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """``J̇ v`` ``(6,)`` of ``frame`` in world-aligned axes (at ``(q, v)``, or at the last
        update, which must have been given ``v``)."""
        fid = self._frame_id(frame)
        if q is not None:
            self.update(q, np.zeros(self.nv) if v is None else v)
        acc = pin.getFrameClassicalAcceleration(
            self.model, self.data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        if out is None:
            return acc.vector
        out[:3] = acc.linear
        out[3:] = acc.angular
        return out

    def symbolic_frame(self, frame: str = "ee") -> ca.Function:
        """``q -> (pose, J)``: the world pose ``(4, 4)`` and world-aligned Jacobian ``(6, nv)``
        of ``frame`` as a CasADi function of the configuration (cached per frame)."""
        fid = self._frame_id(frame)
        if fid not in self._symbolic:
            self._symbolic[fid] = symbolic_frame_kinematics(self.model, fid)
        return self._symbolic[fid]

    def symbolic_drift(self, frame: str = "ee") -> ca.Function:
        """``(q, v) -> drift``: :meth:`frame_drift` as a CasADi function (cached per frame).

        ``drift`` ``(6, 1)`` is ``J̇ v`` in world-aligned axes, rows ``[linear [m/s²]; angular
        [rad/s²]]``: the frame origin's classical acceleration at zero joint acceleration, for
        ``q`` [rad or m] and joint rates ``v`` [rad/s or m/s]. An unknown ``frame`` raises
        :class:`~wbc.UnknownNameError` as the numeric getters do.
        """
        fid = self._frame_id(frame)
        if fid not in self._symbolic_drift:
            # nq == nv and every joint is 1-DoF: the configuration rate is v itself
            self._symbolic_drift[fid] = symbolic_frame_drift(self.symbolic_frame(frame))
        return self._symbolic_drift[fid]

    def __repr__(self) -> str:
        return f"FixedBaseRobot({self.name!r}, nq={self.nq}, nv={self.nv})"


_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _joint_kind(joint) -> tuple[str, np.ndarray]:
    """``("R" | "P", unit axis in the joint frame)`` of a 1-DoF pinocchio joint."""
    name = joint.shortname()
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(joint.extract().axis, dtype=float)
        return name[10], axis / np.linalg.norm(axis)
    if len(name) == 12 and name[10] in "RP" and name[11] in _AXES:  # JointModelRZ, ...PX
        return name[10], np.array(_AXES[name[11]])
    raise WbcError(f"symbolic kinematics support 1-DoF revolute and prismatic joints, not "
                   f"{name}")


def _rotation(axis: np.ndarray, angle) -> ca.SX:
    """Rodrigues' formula ``I + sin θ [a]× + (1 − cos θ) [a]×²`` (exact for unit axes)."""
    K = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.SX.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def symbolic_frame_kinematics(model: pin.Model, frame_id: int) -> ca.Function:
    """CasADi function ``q -> (pose (4, 4), J (6, nv))`` of a frame of a model made of 1-DoF
    revolute/prismatic joints: world pose and Jacobian in world-aligned axes at the frame
    origin (pinocchio's ``LOCAL_WORLD_ALIGNED``), built from the model's joint placements."""
    frame = model.frames[frame_id]
    q = ca.SX.sym("q", model.nq)
    chain, j = [], frame.parentJoint
    while j > 0:
        chain.append(j)
        j = model.parents[j]
    R, p = ca.SX.eye(3), ca.SX.zeros(3)
    columns = []  # (idx_v, kind, world axis, joint origin)
    for j in reversed(chain):
        joint, M = model.joints[j], model.jointPlacements[j]
        kind, axis = _joint_kind(joint)
        p = p + R @ ca.DM(M.translation)
        R = R @ ca.DM(M.rotation)
        world_axis = R @ ca.DM(axis)
        columns.append((joint.idx_v, kind, world_axis, p))
        if kind == "R":
            R = R @ _rotation(axis, q[joint.idx_q])
        else:
            p = p + world_axis * q[joint.idx_q]
    p_f = p + R @ ca.DM(frame.placement.translation)
    R_f = R @ ca.DM(frame.placement.rotation)
    pose = ca.vertcat(ca.horzcat(R_f, p_f), ca.DM([[0, 0, 0, 1]]))
    J = ca.SX.zeros(6, model.nv)
    for idx_v, kind, axis, origin in columns:
        if kind == "R":
            J[:3, idx_v] = ca.cross(axis, p_f - origin)
            J[3:, idx_v] = axis
        else:
            J[:3, idx_v] = axis
    # CasADi function names must be identifiers without "__"; URDF frame names need not be
    # (e.g. "base_link-base_fixed_joint")
    name = "_".join(["kinematics", *re.findall(r"[A-Za-z0-9]+", frame.name)])
    return ca.Function(name, [q], [pose, J], ["q"], ["pose", "J"])


def symbolic_frame_drift(
    kinematics: ca.Function,
    configuration_rate: Callable[[ca.SX, ca.SX], ca.SX] | None = None,
) -> ca.Function:
    """CasADi function ``(q, v) -> J̇ v (6, 1)`` from a frame function ``q -> (pose, J)``.

    ``J̇ v = d/dt (J(q) v)`` at constant ``v``, i.e. ``(∂(J v)/∂q) q̇`` (one forward-mode
    directional derivative) with ``q̇ = configuration_rate(q, v)`` — ``v`` itself when ``None``
    (``nq == nv``). Rows ``[linear [m/s²]; angular [rad/s²]]`` in the axes of ``J``'s rows.
    Because the whole of ``J(q)`` is differentiated, a ``J`` that already carries a
    configuration-dependent velocity map (``J = J_pin(q) S(q)`` of a mobile base) yields
    ``J̇_pin q̇ + J_pin Ṡ v``, the map's rate included.
    """
    nq, nv = kinematics.size1_in(0), kinematics.size2_out(1)
    q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
    _, J = kinematics(q)  # SX call: the expressions are inlined, so AD sees through them
    qdot = v if configuration_rate is None else configuration_rate(q, v)
    if qdot.shape != (nq, 1):
        raise ShapeError(f"configuration rate must have shape ({nq}, 1), got {qdot.shape}")
    drift = ca.jtimes(J @ v, q, qdot)
    # same identifier scheme as the frame function ("kinematics_<frame>" -> "drift_<frame>")
    name = "drift" + kinematics.name().removeprefix("kinematics")
    return ca.Function(name, [q, v], [drift], ["q", "v"], ["drift"])


def load_panda(
    fingers: bool = False,
    frames: Mapping[str, str] | None = None,
    q_locked: Sequence[float] | None = None,
) -> FixedBaseRobot:
    """Franka Emika Panda from example-robot-data's URDF (found offline, no Python loader).

    Args:
        fingers: keep the two finger joints (``nq = 9``); by default they are locked at
            ``q_locked`` (default: closed) and the arm has 7 joints.
        frames: extra aliases; ``"ee"`` is ``panda_hand`` and ``"tcp"`` ``panda_hand_tcp``.
        q_locked: configuration the locked finger joints are frozen at (2 values [m]).
    """
    model = pin.buildModelFromUrdf(str(urdf_path("panda_description/urdf/panda.urdf")))
    if not fingers:
        locked = [model.getJointId(f"panda_finger_joint{i}") for i in (1, 2)]
        q_ref = pin.neutral(model)
        if q_locked is not None:
            q_ref[-2:] = np.asarray(q_locked, dtype=float)
        model = pin.buildReducedModel(model, locked, q_ref)
    aliases = {"ee": "panda_hand"}
    if model.existFrame("panda_hand_tcp"):
        aliases["tcp"] = "panda_hand_tcp"
    aliases.update(frames or {})
    return FixedBaseRobot(model, aliases, name="panda")
