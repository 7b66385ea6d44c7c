"""Petrič & Žlajpah's reduced arm: the translational point that drives the Tiago base.

The velocity-field controller of Petrič & Žlajpah moves the differential-drive base from the
position of one point of a *reduced* model of the Franka Panda: a vertical segment ``l0`` (arm
root to shoulder), an upper arm ``l1`` (shoulder to elbow) and a forearm ``l2``, with the
Panda's small offsets folded into straight segments:

* ``l0 = 0.333`` m — height of the shoulder ``S`` (origin of joint 2) over the arm root;
* ``l1 = |(0.0825, 0.316)| ≈ 0.3267`` m — shoulder to elbow ``E`` (origin of joint 4), exact
  for every configuration;
* ``l2 = |(0.088, 0.384)| ≈ 0.3940`` m — the forearm, from the Panda's parameters ``d5 = 0.384``
  and ``a7 = 0.088`` as the paper folds them.

All three are read from the pinocchio model (``l0`` and ``l1`` as distances between joint
origins, ``d5 = sqrt(|t5|² − |t4|²)`` and ``a7 = |t7|`` from the joint placements ``t_i``).

**Reduced translational end-effector point.** ``W = E + l2 (C − E)/|C − E|`` where ``C`` is the
wrist centre (origin of joints 5 and 6). ``W`` lies on the forearm's axis, at the paper's forearm
length from the elbow: 1.2 mm beyond the true wrist centre (``|C − E| = |(0.0825, 0.384)|``), a
difference inherited from the paper's ``l2``. With ``q3 = 0`` the reduced arm is planar and
``W = S + l1 u(q2 + γ1) + l2 u(q2 − q4 − γ2)`` in the vertical plane at azimuth ``q1``, with
``u(φ) = (sin φ, cos φ)`` (horizontal, vertical), ``γ1 = atan2(0.0825, 0.316)`` and
``γ2 = atan2(0.0825, 0.384)``.
"""

from __future__ import annotations

import math

import numpy as np

from wbc.errors import UnknownNameError

from .manipulator import MobileManipulator

__all__ = ["ReducedPanda"]


class ReducedPanda:
    """Reduced model of a Panda arm mounted on a mobile base.

    Args:
        robot: a mobile manipulator whose arm is a Franka Panda (e.g. ``load("tiago_panda")``).
        prefix: prefix of the Panda's joint names.

    Attributes:
        lengths: ``(l0, l1, l2)`` [m].
    """

    def __init__(self, robot: MobileManipulator, prefix: str = "panda_joint") -> None:
        model = robot.model
        names = [f"{prefix}{k}" for k in range(1, 8)]
        missing = [n for n in names if not model.existJointName(n)]
        if missing:
            raise UnknownNameError(
                f"robot {robot.name!r} has no Panda joints {missing}; "
                f"joints: {list(model.names)[1:]}"
            )
        self.robot = robot
        self._joints = [model.getJointId(n) for n in names]
        arm_model = robot.arm.model  # placements relative to the arm's root, without the mount
        m = [arm_model.jointPlacements[arm_model.getJointId(n)] for n in names]
        t = [placement.translation for placement in m]
        l0 = float(np.linalg.norm((m[0] * m[1]).translation))
        l1 = float(np.linalg.norm((m[2] * m[3]).translation))  # at q3 = 0; constant in q3
        d5 = math.sqrt(float(np.dot(t[4], t[4]) - np.dot(t[3], t[3])))
        a7 = float(np.linalg.norm(t[6]))
        self.lengths = (l0, l1, math.hypot(a7, d5))

    def _points(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.robot._ensure(q)
        omi = self.robot.data.oMi
        shoulder = omi[self._joints[1]].translation
        elbow = omi[self._joints[3]].translation
        wrist = omi[self._joints[5]].translation
        return shoulder, elbow, wrist

    def _to_frame(self, point: np.ndarray, frame: str) -> np.ndarray:
        if frame == "world":
            return point.copy()
        if frame == "base":
            pose = self.robot.data.oMf[self.robot.frame_id("base")]
            return pose.rotation.T @ (point - pose.translation)
        raise UnknownNameError(f"unknown frame {frame!r}; use 'world' or 'base'")

    def point(self, q=None, frame: str = "world") -> np.ndarray:
        """Reduced translational end-effector point ``W`` (3,) [m], world or base frame."""
        _, elbow, wrist = self._points(q)
        forearm = wrist - elbow
        w = elbow + self.lengths[2] * forearm / np.linalg.norm(forearm)
        return self._to_frame(w, frame)

    def shoulder(self, q=None, frame: str = "world") -> np.ndarray:
        """The shoulder ``S`` (3,) [m] — origin of joint 2 — in the world or base frame."""
        return self._to_frame(self._points(q)[0], frame)

    def elbow(self, q=None, frame: str = "world") -> np.ndarray:
        """The elbow ``E`` (3,) [m] — origin of joint 4 — in the world or base frame."""
        return self._to_frame(self._points(q)[1], frame)
