"""Hand-written CasADi kinematics of pinocchio models: frame poses, Jacobians and drifts as
CasADi functions, for ``Controller(..., kinematics="compiled")``.

Why hand-written
----------------
Pinocchio has a CasADi back end (``pinocchio.casadi``), but the ``pin`` wheels on the Python
package index are built without it; wbc must install from the index alone. The kinematics of a
chain of 1-DoF joints are short, so this module writes them directly in CasADi from the model's
joint placements and frame placements (no pinocchio call inside the functions).

Supported joints
----------------
1-DoF **revolute** and **prismatic** joints, with an axis along x, y or z of the joint frame
(``JointModelRX`` … ``JointModelPZ``) or any unit axis (``JointModelRevoluteUnaligned``,
``JointModelPrismaticUnaligned``), and a **free-flyer root** (``JointModelFreeFlyer`` as the
first joint, attached to the universe; see below). Every other joint type (spherical, planar,
helical, unbounded revolute, mimic, a free flyer elsewhere, …) is refused by
:func:`check_joints`, which the robots call when they are built — an unsupported joint is a
:class:`~wbc.WbcError` at load time, never a wrong Jacobian later. (The URDF loaders of
:mod:`wbc.robots.arms` and :mod:`wbc.robots.whole_body` turn URDF ``continuous`` joints into
plain revolute joints first.)

Free-flyer root. Its configuration is pinocchio's ``(x, y, z, q_x, q_y, q_z, q_w)`` — position
[m] and unit quaternion of the root body in the world — and its velocity pinocchio's
``(v, ω)``: the root's linear and angular velocity in the **root body's axes**. The rotation is
built from the *normalised* quaternion (equal to pinocchio's at a unit quaternion). Its six
Jacobian columns for a frame at ``p_f`` are, with ``R``, ``p`` the root's world rotation and
position, ``[R, −[p_f − p]× R]`` (linear rows) and ``[0, R]`` (angular rows).
:func:`free_flyer_rate` is the configuration rate ``q̇(q, v)`` the drifts differentiate along
(``ṗ = R v``, ``q̇uat = ½ quat ⊗ (ω, 0)``).

Conventions
-----------
Poses are world poses (4 × 4; translation [m]) and the centre of mass a world point [m];
Jacobians ``(6, nv)`` have rows ``[linear; angular]``: the frame origin's velocity [m/s] and
the angular velocity [rad/s] in world axes, per unit joint rate (pinocchio's
``LOCAL_WORLD_ALIGNED``). Drifts ``J̇ v`` (6 × 1) are one forward-mode directional derivative
of ``J(q) v`` along ``q̇``.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.errors import ShapeError, WbcError

__all__ = [
    "check_joints",
    "free_flyer_rate",
    "quaternion_rotation",
    "symbolic_center_of_mass",
    "function_name",
    "pose_rate_matrix",
    "symbolic_frame_drift",
    "symbolic_frame_kinematics",
]

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_UNALIGNED = ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned")


_FREE_FLYER = "JointModelFreeFlyer"


def _joint_kind(joint) -> tuple[str, np.ndarray | None] | None:
    """``("R" | "P", unit axis in the joint frame)`` of a supported 1-DoF joint, ``("F",
    None)`` of a free flyer (supported as the root only, see :func:`check_joints`), else
    ``None``."""
    name = joint.shortname()
    if name == _FREE_FLYER:
        return "F", None
    if name in _UNALIGNED:
        axis = np.asarray(joint.extract().axis, dtype=float)
        return name[10], axis / np.linalg.norm(axis)
    if len(name) == 12 and name[10] in "RP" and name[11] in _AXES:  # JointModelRZ, ...PX
        return name[10], np.array(_AXES[name[11]])
    return None


def check_joints(model: pin.Model, what: str = "robot") -> None:
    """Raise :class:`~wbc.WbcError` naming every joint of ``model`` the symbolic kinematics do
    not support (see the module docstring); ``what`` names the robot in the message."""
    bad = [f"{model.names[j]} ({model.joints[j].shortname()})"
           for j in range(1, model.njoints) if not _supported(model, j)]
    if bad:
        raise WbcError(f"{what}: unsupported joints {bad}; wbc robots support 1-DoF revolute "
                       f"and prismatic joints (aligned or unaligned axes) and a free-flyer "
                       f"root (the first joint, on the universe) only")


def _supported(model: pin.Model, j: int) -> bool:
    """Whether joint ``j`` is supported where it is (a free flyer as the root only)."""
    kind = _joint_kind(model.joints[j])
    if kind is None:
        return False
    return kind[0] != "F" or (j == 1 and model.parents[j] == 0)


def quaternion_rotation(quaternion: ca.SX) -> ca.SX:
    """Rotation matrix (3 × 3) of a quaternion ``(x, y, z, w)`` (pinocchio's order), normalised
    first, so that the result is a rotation for any non-zero quaternion."""
    x, y, z, w = (quaternion[i] for i in range(4))
    n2 = x * x + y * y + z * z + w * w
    s = 2.0 / n2  # 2 / |quat|²: the normalisation, folded into the products
    R = ca.SX(3, 3)
    R[0, 0], R[0, 1], R[0, 2] = 1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)
    R[1, 0], R[1, 1], R[1, 2] = s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)
    R[2, 0], R[2, 1], R[2, 2] = s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)
    return R


def free_flyer_rate(q: ca.SX, v: ca.SX) -> ca.SX:
    """``q̇ = S(q) v`` (nq × 1) of a model whose root is a free flyer and whose other joints are
    1-DoF: position rate ``R v_lin`` [m/s] (``R`` the root's rotation), quaternion rate
    ``½ quat ⊗ (ω, 0)`` [1/s] (``ω`` in the root's axes), then the joint rates as they are."""
    quat = q[3:7]
    u, w = quat[:3], quat[3]
    omega = v[3:6]
    return ca.vertcat(quaternion_rotation(quat) @ v[:3],
                      0.5 * (w * omega + ca.cross(u, omega)),
                      -0.5 * ca.dot(u, omega),
                      v[6:])


def _skew(p: ca.SX) -> ca.SX:
    """``[p]×`` (3 × 3), so that ``[p]× a = p × a``."""
    K = ca.SX(3, 3)
    K[0, 1], K[0, 2], K[1, 0], K[1, 2], K[2, 0], K[2, 1] = -p[2], p[1], p[2], -p[0], -p[1], p[0]
    return K


def function_name(prefix: str, frame_name: str) -> str:
    """A CasADi function name ``<prefix>_<frame>``: CasADi names must be identifiers without
    ``"__"``, URDF frame names need not be (e.g. ``"base_link-base_fixed_joint"``)."""
    return "_".join([prefix, *re.findall(r"[A-Za-z0-9]+", frame_name)])


def _rotation(axis: np.ndarray, angle) -> ca.SX:
    """Rodrigues' formula ``I + sin θ [a]× + (1 − cos θ) [a]×²`` (exact for unit axes)."""
    K = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.SX.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def _forward(model: pin.Model, q: ca.SX, joints: list[int]):
    """World rotation and position after each joint's motion, and each joint's Jacobian
    column data ``(idx_v, kind, world axis, joint origin)``, for ``joints`` in increasing index
    order (every joint's parent before it; the parents needed must be in the list)."""
    poses = {0: (ca.SX.eye(3), ca.SX.zeros(3))}
    columns = {}
    for j in joints:
        joint, M = model.joints[j], model.jointPlacements[j]
        kind_axis = _joint_kind(joint)
        if kind_axis is None or not _supported(model, j):
            check_joints(model, model.name or "model")  # raises, naming the joint
            raise AssertionError(f"joint {j} is not supported, yet check_joints passed")
        kind, axis = kind_axis
        R, p = poses[model.parents[j]]
        p = p + R @ ca.DM(M.translation)
        R = R @ ca.DM(M.rotation)
        if kind == "F":  # the root: its columns use the pose after its motion
            iq = joint.idx_q
            p = p + R @ q[iq: iq + 3]
            R = R @ quaternion_rotation(q[iq + 3: iq + 7])
            columns[j] = (joint.idx_v, kind, R, p)
            poses[j] = (R, p)
            continue
        assert axis is not None  # a 1-DoF joint has an axis
        world_axis = R @ ca.DM(axis)
        columns[j] = (joint.idx_v, kind, world_axis, p)
        if kind == "R":
            R = R @ _rotation(axis, q[joint.idx_q])
        else:
            p = p + world_axis * q[joint.idx_q]
        poses[j] = (R, p)
    return poses, columns


def symbolic_frame_kinematics(model: pin.Model, frame_id: int) -> ca.Function:
    """CasADi function ``q -> (pose (4, 4), J (6, nv))`` of a frame of a model made of
    supported joints: world pose and Jacobian in world-aligned axes at the frame origin
    (pinocchio's ``LOCAL_WORLD_ALIGNED``), built from the model's joint placements.

    Raises:
        WbcError: a joint on the frame's chain is not supported (robots check at load time).
    """
    frame = model.frames[frame_id]
    q = ca.SX.sym("q", model.nq)
    chain, j = [], frame.parentJoint
    while j > 0:
        chain.append(j)
        j = model.parents[j]
    poses, columns = _forward(model, q, chain[::-1])
    R, p = poses[frame.parentJoint]
    p_f = p + R @ ca.DM(frame.placement.translation)
    R_f = R @ ca.DM(frame.placement.rotation)
    pose = ca.vertcat(ca.horzcat(R_f, p_f), ca.DM([[0, 0, 0, 1]]))
    J = ca.SX.zeros(6, model.nv)
    for idx_v, kind, axis, origin in columns.values():
        if kind == "F":  # axis: the root's rotation R; linear [R, −[p_f − p]× R], angular [0, R]
            J[:3, idx_v: idx_v + 3] = axis
            J[:3, idx_v + 3: idx_v + 6] = -_skew(p_f - origin) @ axis
            J[3:, idx_v + 3: idx_v + 6] = axis
        elif kind == "R":
            J[:3, idx_v] = ca.cross(axis, p_f - origin)
            J[3:, idx_v] = axis
        else:
            J[:3, idx_v] = axis
    return ca.Function(function_name("kinematics", frame.name), [q], [pose, J], ["q"],
                       ["pose", "J"])


def symbolic_center_of_mass(model: pin.Model) -> ca.Function:
    """CasADi function ``q -> com (3, 1)`` [m]: the centre of mass of the bodies the joints
    carry, in the world (as pinocchio's ``centerOfMass``: a body attached to the universe, such
    as a fixed base's root link, is not counted)."""
    q = ca.SX.sym("q", model.nq)
    poses, _ = _forward(model, q, list(range(1, model.njoints)))
    weighted, mass = ca.SX.zeros(3), 0.0
    for j in range(1, model.njoints):
        inertia = model.inertias[j]
        R, p = poses[j]
        weighted = weighted + inertia.mass * (p + R @ ca.DM(inertia.lever))
        mass += inertia.mass
    return ca.Function("center_of_mass", [q], [weighted / mass], ["q"], ["com"])


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


def pose_rate_matrix(theta: ca.SX, body_map: np.ndarray) -> ca.SX:
    """``H(θ) = Rz(θ) B`` (3 × nv_base) as a CasADi expression: a planar base's velocity
    coordinates -> world pose rates ``(ẋ, ẏ, θ̇)`` (cf.
    :meth:`wbc.robots.planar_base.PlanarBase.pose_rate_matrix`)."""
    c, s = ca.cos(theta), ca.sin(theta)
    rz = ca.SX(3, 3)  # structural zeros keep the products with it lean
    rz[0, 0], rz[0, 1], rz[1, 0], rz[1, 1], rz[2, 2] = c, -s, s, c, 1
    return rz @ ca.sparsify(ca.DM(body_map))
