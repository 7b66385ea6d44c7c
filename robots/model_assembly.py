"""Building a mobile manipulator's whole-body pinocchio model from a base, an arm and a mount.

The model has three scalar root joints — prismatic ``base_x``, prismatic ``base_y`` and revolute
``base_theta`` (about the world's vertical) — carrying the base body and the frame ``"base"``;
the arm is appended at the fixed frame ``"mount"`` (the mounting transform, in the base frame),
and its end-effector frame is aliased ``"ee"``. Scalar joints keep pinocchio's configuration
equal to the robot's ``q = [x, y, θ, q_arm]`` (no cos/sin pair as with ``JointModelPlanar``).
Arm frames whose names clash with the base's are renamed ``"arm_<name>"``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from wbc.errors import InvalidValueError, NonFiniteError, ShapeError

from .arms import Arm
from .planar_base import PlanarBase

__all__ = ["BASE_JOINTS", "as_se3", "whole_body_model"]

BASE_JOINTS = ("base_x", "base_y", "base_theta")
"""Names of the three root joints; their configuration is the base pose ``(x, y, θ)``."""
_RESERVED_FRAMES = ("universe", "base", "mount", "ee", *BASE_JOINTS)


def as_se3(mount) -> pin.SE3:
    """A mounting transform as a pinocchio ``SE3``: ``None`` (identity), an ``SE3`` (copied) or
    a 4 × 4 homogeneous matrix whose rotation block is a rotation.

    Raises:
        ShapeError, NonFiniteError, InvalidValueError: not such a transform.
    """
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


def whole_body_model(name: str, base: PlanarBase, arm: Arm, mount: pin.SE3) -> pin.Model:
    """The whole-body model (see the module docstring) named ``name``.

    Raises:
        ValueError: an arm joint is named like a base joint.
    """
    model = pin.Model()
    model.name = name
    big = np.array([1e10])
    parent = 0
    for joint_name, joint in zip(
        BASE_JOINTS, (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelRZ()), strict=True
    ):
        parent = model.addJoint(parent, joint, pin.SE3.Identity(), joint_name, big, big, -big, big)
    model.appendBodyToJoint(parent, base.spatial_inertia(), pin.SE3.Identity())
    base_frame = model.addFrame(
        pin.Frame("base", parent, 0, pin.SE3.Identity(), pin.FrameType.BODY)
    )
    mount_frame = model.addFrame(
        pin.Frame("mount", parent, base_frame, mount, pin.FrameType.OP_FRAME)
    )
    arm_model = pin.Model(arm.model)
    ee_name = arm.ee_frame
    for index in range(1, len(arm_model.frames)):
        frame = arm_model.frames[index]
        if frame.name in _RESERVED_FRAMES:
            new_name = "arm_" + frame.name
            if frame.name == ee_name:
                ee_name = new_name
            frame.name = new_name
            arm_model.frames[index] = frame
    for joint_name in list(arm_model.names)[1:]:
        if joint_name in BASE_JOINTS:
            raise ValueError(f"arm joint name {joint_name!r} is reserved for the base")
    whole = pin.appendModel(model, arm_model, mount_frame, pin.SE3.Identity())
    ee_id = whole.getFrameId(ee_name)
    ee = whole.frames[ee_id]
    whole.addFrame(pin.Frame("ee", ee.parentJoint, ee_id, ee.placement, pin.FrameType.OP_FRAME))
    whole.name = name
    return whole
