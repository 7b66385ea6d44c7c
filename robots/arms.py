"""Fixed-base arms as pinocchio models, with their limits.

An :class:`Arm` bundles a pinocchio ``Model`` (one scalar joint per degree of freedom, so that
``nq == nv``), the name of its end-effector frame, a home configuration and position / velocity /
acceleration limits. Arms come from URDF files (:func:`arm_from_urdf`, :func:`panda`,
:func:`ur10`, :func:`ur5`) or are built in code from published parameters
(:mod:`wbc.robots.kuka_lwr4`, :mod:`wbc.robots.kinova_gen3`, both through
:func:`build_serial_arm`).

URDF ``continuous`` joints, which pinocchio parses as unbounded revolute joints with a
(cos, sin) configuration, are converted to plain revolute joints with infinite position limits.

Frame names. A URDF may give a link and a joint the same name (pinocchio then holds two frames
of that name, a ``BODY`` and a ``JOINT``/``FIXED_JOINT`` one, and refuses to look either up by
name). Such frames are renamed ``"link:<name>"`` and ``"joint:<name>"`` (``"frame:<name>"`` for
operational frames, ``"sensor:<name>"``) when the arm is built: pick the end effector with
``ee_frame="link:tool0"``; the bare ambiguous name is an :class:`~wbc.UnknownNameError` that
lists the candidates with their types. Unambiguous names are kept as they are.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from wbc.checks import as_float_array, check_finite, checked_name
from wbc.errors import InvalidValueError, ModelLoadError, ShapeError, UnknownNameError

from .resources import urdf_path

__all__ = ["Arm", "arm_from_model", "arm_from_urdf", "build_serial_arm", "load_urdf_model",
           "panda", "ur10", "ur5", "FRAME_KINDS"]

#: the prefix of a renamed ambiguous frame, by pinocchio frame type (see the module docstring)
FRAME_KINDS = {pin.FrameType.BODY: "link", pin.FrameType.JOINT: "joint",
               pin.FrameType.FIXED_JOINT: "joint", pin.FrameType.OP_FRAME: "frame",
               pin.FrameType.SENSOR: "sensor"}


@dataclass
class Arm:
    """A fixed-base arm.

    Attributes:
        name: arm name.
        model: pinocchio model; every joint is a scalar revolute or prismatic joint.
        ee_frame: name of the end-effector frame in ``model``.
        q_lower, q_upper: position limits [rad or m], shape (n,); ``±inf`` when unbounded.
        v_max: symmetric velocity limits [rad/s or m/s], shape (n,).
        a_max: symmetric acceleration limits [rad/s² or m/s²], shape (n,); ``inf`` if unknown.
        home: a home configuration within the limits, shape (n,).
        source: where the kinematic and inertial parameters come from.
    """

    name: str
    model: pin.Model
    ee_frame: str
    q_lower: np.ndarray
    q_upper: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray
    home: np.ndarray
    source: str = field(default="")

    def __post_init__(self) -> None:
        checked_name(self.name, "name of an arm", optional=False)
        if not isinstance(self.model, pin.Model):
            raise InvalidValueError(f"arm {self.name!r}: model must be a pinocchio Model, got "
                                    f"{type(self.model).__name__}")
        checked_name(self.ee_frame, f"ee_frame of arm {self.name!r}", optional=False)
        n = self.model.nv
        if self.model.nq != n:
            raise ShapeError(
                f"arm {self.name!r}: every joint must be scalar (nq == nv), got nq "
                f"{self.model.nq}, nv {n}"
            )
        for attr in ("q_lower", "q_upper", "v_max", "a_max", "home"):
            what = f"arm {self.name!r}: {attr}"
            value = np.array(as_float_array(getattr(self, attr), what), dtype=float)
            if value.shape != (n,):
                raise ShapeError(f"{what} must have shape ({n},), got {value.shape}")
            check_finite(value, what, allow_inf=attr != "home")
            setattr(self, attr, value)
        for attr in ("v_max", "a_max"):
            if (getattr(self, attr) <= 0).any():
                raise InvalidValueError(f"arm {self.name!r}: {attr} must be > 0, got "
                                        f"{getattr(self, attr)}")
        if (self.q_lower > self.q_upper).any():
            raise InvalidValueError(f"arm {self.name!r}: q_lower > q_upper at joints "
                                    f"{np.flatnonzero(self.q_lower > self.q_upper).tolist()}")
        frames = [f.name for f in self.model.frames]
        if frames.count(self.ee_frame) != 1:
            candidates = [f"{name!r} ({self.model.frames[i].type})"
                          for i, name in enumerate(frames) if name.partition(":")[2]
                          == self.ee_frame or (name == self.ee_frame)]
            raise UnknownNameError(
                f"arm {self.name!r}: ee_frame {self.ee_frame!r} "
                + (f"is ambiguous; pick one of {', '.join(candidates)}" if candidates else
                   f"is not a frame; frames: {frames}"))

    @property
    def n(self) -> int:
        """Number of arm joints."""
        return self.model.nv

    @property
    def joint_names(self) -> list[str]:
        """Names of the arm's joints, in configuration order."""
        return list(self.model.names)[1:]


# ---------------------------------------------------------------------- URDF arms
_REVOLUTE_UNBOUNDED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}


def _scalar_joint_model(joint) -> tuple[object, bool]:
    """A scalar pinocchio joint model equivalent to ``joint``, and whether it was unbounded."""
    short = joint.shortname()
    if joint.nq == 1 and joint.nv == 1:
        return joint, False
    if short in _REVOLUTE_UNBOUNDED:
        return _REVOLUTE_UNBOUNDED[short](), True
    if short == "JointModelRevoluteUnboundedUnaligned":
        return pin.JointModelRevoluteUnaligned(np.asarray(joint.axis, dtype=float)), True
    raise ValueError(
        f"joint type {short} (nq {joint.nq}, nv {joint.nv}) is not supported in an arm: only "
        "revolute, continuous and prismatic joints are"
    )


def _with_scalar_joints(model: pin.Model) -> tuple[pin.Model, np.ndarray]:
    """Copy of ``model`` with continuous joints made plain revolute joints; a free-flyer root
    (joint 1, what a whole-robot URDF loaded with ``root="free_flyer"`` has) is kept as is.

    Returns:
        The copy and a boolean mask, per configuration index, of the entries of joints that
        were unbounded (``nq == nv`` after the root).
    """
    def kept(j: int) -> bool:
        return j == 1 and model.joints[j].shortname() == "JointModelFreeFlyer"

    if all(kept(j) or (model.joints[j].nq == 1 and model.joints[j].nv == 1)
           for j in range(1, model.njoints)):
        return model, np.zeros(model.nq, dtype=bool)
    out = pin.Model()
    out.name = model.name
    unbounded: list[bool] = []
    for j in range(1, model.njoints):
        source = model.joints[j]
        if kept(j):
            joint, was_unbounded = source, False
        else:
            joint, was_unbounded = _scalar_joint_model(source)
        nq, nv = (source.nq, source.nv) if kept(j) else (1, 1)
        idx_q, idx_v = source.idx_q, source.idx_v
        if was_unbounded:
            lower, upper = np.array([-np.inf]), np.array([np.inf])
        else:
            lower = model.lowerPositionLimit[idx_q : idx_q + nq].copy()
            upper = model.upperPositionLimit[idx_q : idx_q + nq].copy()
        new = out.addJoint(
            int(model.parents[j]),
            joint,
            model.jointPlacements[j],
            model.names[j],
            model.effortLimit[idx_v : idx_v + nv].copy(),
            model.velocityLimit[idx_v : idx_v + nv].copy(),
            lower,
            upper,
        )
        out.appendBodyToJoint(new, model.inertias[j], pin.SE3.Identity())
        unbounded.extend([was_unbounded] * nq)
    out.inertias[0] = model.inertias[0]
    for frame in list(model.frames)[1:]:
        out.addFrame(pin.Frame(frame), False)
    return out, np.array(unbounded, dtype=bool)


def _unambiguous_frames(model: pin.Model) -> pin.Model:
    """``model``, or a copy whose frames sharing a name are renamed ``"<kind>:<name>"``
    (:data:`FRAME_KINDS`, see the module docstring)."""
    names = [frame.name for frame in model.frames]
    shared = {name for name in names if names.count(name) > 1}
    if not shared:
        return model
    model = pin.Model(model)
    for index, frame in enumerate(model.frames):
        if frame.name in shared:
            frame.name = f"{FRAME_KINDS.get(frame.type, 'frame')}:{frame.name}"
            model.frames[index] = frame
    names = [frame.name for frame in model.frames]
    clashes = sorted({name for name in names if names.count(name) > 1})
    if clashes:
        raise ModelLoadError(f"model {model.name!r}: frames {clashes} share a name and a type")
    return model


def load_urdf_model(path: str, free_flyer: bool = False) -> pin.Model:
    """``pin.buildModelFromUrdf(path)`` (with a ``JointModelFreeFlyer`` root joint when
    ``free_flyer``), or one :class:`~wbc.ModelLoadError` naming the file and the parser's
    reason. urdfdom writes its reasons to the C-level stderr (file
    descriptor 2, out of reach of ``sys.stderr``): they are captured there and put in the
    message instead of being printed."""
    if not os.path.isfile(path):
        raise ModelLoadError(f"URDF file {path!r} does not exist")
    with tempfile.TemporaryFile(mode="w+b") as captured:
        saved = os.dup(2)
        os.dup2(captured.fileno(), 2)
        try:
            model = (pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer()) if free_flyer
                     else pin.buildModelFromUrdf(path))
            reason = ""
        except ValueError as err:  # pinocchio's words: "does not contain a valid URDF model"
            model, reason = None, str(err)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        details = captured.read().decode(errors="replace")
    if model is None:
        lines = [line.strip() for line in details.splitlines()
                 if line.strip().startswith("Error:")]
        why = "; ".join(line.removeprefix("Error:").strip() for line in lines) or reason
        raise ModelLoadError(f"URDF file {path!r} cannot be loaded: {why}")
    return model


def arm_from_urdf(
    path: str | os.PathLike[str],
    ee_frame: str,
    *,
    name: str | None = None,
    locked_joints: Sequence[str] = (),
    locked_values: Sequence[float] | None = None,
    v_max=None,
    a_max=None,
    home=None,
    source: str | None = None,
) -> Arm:
    """Load an arm from a URDF file.

    Args:
        path: the URDF file.
        ee_frame: name of the end-effector frame (a link or joint name of the URDF).
        name: arm name (default: the URDF's robot name).
        locked_joints: joints to remove (a list or tuple of names, e.g. gripper fingers), held at
            ``locked_values``
            (default: their neutral value).
        v_max: velocity limits, shape (n,) (default: the URDF's ``velocity`` attributes;
            ``inf`` where missing).
        a_max: acceleration limits, shape (n,) (default ``inf``: URDF has none).
        home: home configuration (default: the neutral configuration clipped into the limits).
        source: provenance note.

    Returns:
        The :class:`Arm`.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidValueError(f"path of a URDF must be a str or a path, got {path!r}"[:120])
    path = os.fspath(path)
    checked_name(ee_frame, "ee_frame", optional=False)
    if not isinstance(locked_joints, (list, tuple)) or not all(isinstance(j, str)
                                                                for j in locked_joints):
        raise InvalidValueError(f"locked_joints must be a sequence of joint names, got "
                                f"{locked_joints!r}")
    values = None if locked_values is None else as_float_array(locked_values, "locked_values")
    if values is not None:
        if values.shape != (len(locked_joints),):
            raise ShapeError(f"locked_values must have one value per locked joint "
                             f"({len(locked_joints)}), got shape {values.shape}")
        check_finite(values, "locked_values")
    model = load_urdf_model(path)
    if locked_joints:
        missing = [j for j in locked_joints if not model.existJointName(j)]
        if missing:
            raise UnknownNameError(
                f"cannot lock joints {missing}: not in {path}; joints: {list(model.names)[1:]}"
            )
        reference = pin.neutral(model)
        if values is not None:
            for joint_name, value in zip(locked_joints, values, strict=True):
                jid = model.getJointId(joint_name)
                reference[model.joints[jid].idx_q] = value
        ids = [model.getJointId(j) for j in locked_joints]
        model = pin.buildReducedModel(model, ids, reference)
    return arm_from_model(
        model,
        ee_frame,
        name=name,
        v_max=v_max,
        a_max=a_max,
        home=home,
        source=source or f"URDF {path}",
    )


def arm_from_model(
    model: pin.Model,
    ee_frame: str,
    *,
    name: str | None = None,
    v_max=None,
    a_max=None,
    home=None,
    source: str = "user pinocchio model",
) -> Arm:
    """Wrap a fixed-base pinocchio model as an :class:`Arm`.

    Continuous joints become plain revolute joints with infinite limits. Limits default to the
    model's (``±inf`` where pinocchio holds its "no limit" value), no acceleration limit, and the
    neutral configuration clipped into the limits as home.
    """
    if not isinstance(model, pin.Model):
        raise InvalidValueError(f"model must be a pinocchio Model, got {type(model).__name__}")
    checked_name(name, "name of an arm")
    checked_name(ee_frame, "ee_frame", optional=False)
    v_max, a_max, home = (None if value is None else as_float_array(value, label)
                          for label, value in (("v_max", v_max), ("a_max", a_max),
                                               ("home", home)))
    model, unbounded = _with_scalar_joints(model)
    model = _unambiguous_frames(model)
    q_lower = model.lowerPositionLimit.copy()
    q_upper = model.upperPositionLimit.copy()
    # continuous joints and pinocchio's ±max double "no limit" become ±inf
    q_lower[unbounded | (q_lower <= -1e300)] = -np.inf
    q_upper[unbounded | (q_upper >= 1e300)] = np.inf
    if v_max is None:
        v_max = model.velocityLimit.copy()
        v_max[(v_max <= 0.0) | (v_max >= 1e300)] = np.inf
    if a_max is None:
        a_max = np.full(model.nv, np.inf)
    if home is None:
        home = np.clip(pin.neutral(model), q_lower, q_upper)
    return Arm(
        name=name or model.name or "arm",
        model=model,
        ee_frame=ee_frame,
        q_lower=q_lower,
        q_upper=q_upper,
        v_max=np.asarray(v_max, dtype=float),
        a_max=np.asarray(a_max, dtype=float),
        home=np.asarray(home, dtype=float),
        source=source,
    )


def panda() -> Arm:
    """Franka Emika Panda (7 DoF) from example-robot-data's ``panda.urdf``, fingers locked open.

    End effector ``panda_link8`` (the flange; the hand's TCP is available as the frame
    ``panda_hand_tcp``). Position and velocity limits from the URDF; acceleration limits from
    Franka's datasheet: 15, 7.5, 10, 12.5, 15, 20, 20 rad/s². Home: the "ready" posture
    ``[0, −π/4, 0, −3π/4, 0, π/2, π/4]``.
    """
    return arm_from_urdf(
        urdf_path("panda_description/urdf/panda.urdf"),
        "panda_link8",
        name="panda",
        locked_joints=("panda_finger_joint1", "panda_finger_joint2"),
        locked_values=(0.04, 0.04),
        a_max=[15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
        home=[0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4],
        source="example-robot-data panda_description/urdf/panda.urdf",
    )


def ur10() -> Arm:
    """Universal Robots UR10 (6 DoF, ≈ 28.9 kg moving mass + 4 kg base) from example-robot-data.

    The stand-in for the torque-redundancy paper's unnamed 6-DoF arm of about 30 kg.
    End effector ``tool0``. Position and velocity limits from the URDF; acceleration limits
    assumed 10 rad/s² (UR publishes none). Home ``[0, −π/2, π/2, −π/2, −π/2, 0]``.
    """
    return _universal_robot("ur10")


def ur5() -> Arm:
    """Universal Robots UR5 (6 DoF) from example-robot-data; end effector ``tool0``.

    Acceleration limits assumed 10 rad/s². Home ``[0, −π/2, π/2, −π/2, −π/2, 0]``.
    """
    return _universal_robot("ur5")


def _universal_robot(model: str) -> Arm:
    """A UR arm of example-robot-data: ``tool0``, 10 rad/s² assumed, the common home pose."""
    path = f"ur_description/urdf/{model}_robot.urdf"
    return arm_from_urdf(
        urdf_path(path),
        "tool0",
        name=model,
        a_max=np.full(6, 10.0),
        home=[0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0],
        source=f"example-robot-data {path}",
    )


# ---------------------------------------------------------------------- arms built in code
@dataclass(frozen=True)
class Segment:
    """One revolute joint of a serial arm and the body it moves.

    Attributes:
        joint: joint name.
        placement: pose of the joint frame in the previous joint frame at zero angle
            (the arm's base frame for the first joint); the joint turns about its local z.
        body: name of the body (link) moved by the joint.
        inertia: the body's spatial inertia in the joint frame.
    """

    joint: str
    placement: pin.SE3
    body: str
    inertia: pin.Inertia


def build_serial_arm(
    name: str,
    segments: Sequence[Segment],
    *,
    base_body: str,
    base_inertia: pin.Inertia,
    tool_frame: str,
    tool_placement: pin.SE3,
    q_lower,
    q_upper,
    v_max,
    a_max,
    home,
    source: str,
) -> Arm:
    """Build a serial chain of revolute (local z) joints as a pinocchio model.

    Each joint gets a body frame named after its segment's body; the fixed base body's inertia is
    attached to the universe and the tool frame to the last joint.
    """
    model = pin.Model()
    model.name = name
    model.appendBodyToJoint(0, base_inertia, pin.SE3.Identity())
    model.addFrame(pin.Frame(base_body, 0, 0, pin.SE3.Identity(), pin.FrameType.BODY))
    parent = 0
    parent_frame = 1
    for seg in segments:
        jid = model.addJoint(parent, pin.JointModelRZ(), seg.placement, seg.joint)
        joint_frame = model.addFrame(
            pin.Frame(seg.joint, parent, parent_frame, seg.placement, pin.FrameType.JOINT)
        )
        model.appendBodyToJoint(jid, seg.inertia, pin.SE3.Identity())
        parent_frame = model.addFrame(
            pin.Frame(seg.body, jid, joint_frame, pin.SE3.Identity(), pin.FrameType.BODY)
        )
        parent = jid
    model.addFrame(
        pin.Frame(tool_frame, parent, parent_frame, tool_placement, pin.FrameType.OP_FRAME)
    )
    n = model.nv
    model.lowerPositionLimit = np.maximum(np.asarray(q_lower, float), -1e10)[:n]
    model.upperPositionLimit = np.minimum(np.asarray(q_upper, float), 1e10)[:n]
    return Arm(
        name=name,
        model=model,
        ee_frame=tool_frame,
        q_lower=q_lower,
        q_upper=q_upper,
        v_max=v_max,
        a_max=a_max,
        home=home,
        source=source,
    )


def rotation_x(angle: float) -> np.ndarray:
    """Rotation matrix about x by ``angle`` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
