"""A mobile manipulator: a planar wheeled base carrying an arm, as one pinocchio model.

:class:`MobileManipulator` assembles the whole-body model (:mod:`wbc.robots.model_assembly`:
scalar root joints ``base_x``, ``base_y``, ``base_theta``, the arm appended at the frame
``"mount"``, its end effector aliased ``"ee"``) and inherits every getter from
:class:`~wbc.robots.pinocchio_robot.PinocchioRobot`, which documents the coordinates
(``q = [x, y, θ, q_arm]``, ``v`` = the base's own velocity coordinates in the base frame, then
the arm rates), the Jacobian conventions (``reference="world" | "base" | "local"``), the
one-update-per-tick pattern, the symbolic forms and the sharing between clones. This module adds
what only a robot with a base has: the mount, the base / arm column split of the Jacobian
(Sorour et al.'s ``H J_b``) and the catalogue-style constructor from an arm URDF or model.

Frames: every frame of the whole-body model, at least ``"base"`` (origin at the base pose, x
forward, z up), ``"mount"`` and ``"ee"``; arm frames whose names clash with these are renamed
``"arm_<name>"``.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pinocchio as pin

from .arms import Arm, arm_from_model, arm_from_urdf
from .limits import Limits
from .model_assembly import as_se3, whole_body_model
from .pinocchio_robot import PinocchioRobot
from .planar_base import PlanarBase

__all__ = ["MobileManipulator"]


class MobileManipulator(PinocchioRobot):
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

    Raises:
        WbcError: the arm has a joint the kinematics do not support
            (:func:`wbc.robots.symbolic.check_joints`).

    Example — a UR5 of your own on the mecanum base, 0.1 m ahead of its centre::

        import numpy as np
        from wbc.robots import MobileManipulator, mecanum_base
        mount = np.eye(4); mount[0, 3] = 0.1
        robot = MobileManipulator(mecanum_base(), "/path/to/ur5_robot.urdf", mount,
                                  ee_frame="tool0", name="mecanum_ur5")
        J = robot.frame_jacobian(robot.neutral(), "ee")      # (6, 9)

    (:func:`wbc.robots.from_urdf` does the same with a base given by name.)
    """

    base: PlanarBase  # never None here (a fixed-base PinocchioRobot's is)

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

        name = name or f"{base.name}_{arm.name}"
        self.arm = arm
        self._mount = as_se3(mount)
        limits = Limits(
            q_lower=np.concatenate([np.full(3, -np.inf), arm.q_lower]),
            q_upper=np.concatenate([np.full(3, np.inf), arm.q_upper]),
            v_lower=np.concatenate([base.v_lower, -arm.v_max]),
            v_upper=np.concatenate([base.v_upper, arm.v_max]),
            a_lower=np.concatenate([base.a_lower, -arm.a_max]),
            a_upper=np.concatenate([base.a_upper, arm.a_max]),
        )
        if home is None:
            home = np.concatenate([np.zeros(3), arm.home])
        super().__init__(whole_body_model(name, base, arm, self._mount), name=name,
                         limits=limits, home=home, base=base)

    @property
    def mount(self) -> pin.SE3:
        """Pose of the arm's root in the base frame."""
        return pin.SE3(self._mount)

    def base_jacobian(
        self, q=None, frame: str | int = "ee", reference: str = "world"
    ) -> np.ndarray:
        """Base columns (6 × base.nv) of :meth:`frame_jacobian`: Sorour et al.'s ``H J_b``."""
        return self.frame_jacobian(q, frame, reference)[:, : self.nv_base].copy()

    def arm_jacobian(self, q=None, frame: str | int = "ee", reference: str = "world") -> np.ndarray:
        """Arm columns (6 × n_arm) of :meth:`frame_jacobian`."""
        return self.frame_jacobian(q, frame, reference)[:, self.nv_base :].copy()

    def __repr__(self) -> str:
        return (
            f"MobileManipulator(name={self.name!r}, base={self.base.name!r}, "
            f"arm={self.arm.name!r}, nq={self.nq}, nv={self.nv})"
        )
