"""Petrič & Žlajpah's arm controller (eq. 22) as a stack (:func:`arm_stack`), and beyond the
paper the same task as one whole-body QP (:func:`whole_body_stack`); the gains and control
period the study uses (:data:`DT`, :data:`KP`, :data:`K_POSTURE`).

Why these values (``K_p·dt < 1`` at the velocity level; the posture towards the centre of the
joint range): the study's docstring, :mod:`wbc.experiments.studies.petric`.
"""

from __future__ import annotations

import math

import numpy as np

import wbc
from wbc.tasks import FrameTask, LinearTask, PostureTask, VelocityLimit

from .closed_form_arm import PETRIC_LAMBDA

__all__ = ["DT", "KP", "K_POSTURE", "arm_stack", "posture_target", "whole_body_stack"]

DT = 0.02
"""Control period [s]."""
KP = 10.0
"""Task-space gain ``K_p`` of eq. 22 [1/s]."""
K_POSTURE = 1.0
"""Gain ``K_n`` of the null-space posture velocity [1/s]."""


def arm_stack(robot, lam: float = PETRIC_LAMBDA, kp: float = KP, k_posture: float = K_POSTURE,
              dt: float = DT, projector: str = "exact") -> wbc.Stack:
    """Eq. 22 as a stack over all ``nv`` velocities, the base's pinned (mobility 0), the TCP
    position task named ``"ee"`` (``FrameTask``, gain ``K_p·dt``) and ``PostureTask``
    ``"posture"`` (gain ``K_n·dt``) towards the centre of the arm's joint range.

    ``projector="exact"``: two levels — the task damped by ``ρ² = λ``, then the posture under
    the task's rows (docs/DESIGN.md, math note 3: the cascade adds exactly ``(I − J⁺J) q̇_n``).
    ``projector="damped"`` (eq. 26 as printed): one level, the task plus the posture weighted
    by ``λ`` — ``min ||J q̇ − u||² + λ||q̇ − q̇_n||²``, whose minimiser is
    ``J#u + (I − J#J) q̇_n`` (see :mod:`wbc.solvers.reference_petric_arm`)."""
    nb = int(robot.nv_base)
    mobility = np.r_[np.zeros(nb), np.ones(robot.nv - nb)]
    exact = projector == "exact"
    if not exact and projector != "damped":
        raise wbc.InvalidValueError(f"projector must be 'exact' or 'damped', got {projector!r}")
    stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping={0: math.sqrt(lam)} if exact else 0.0,
                      mobility=mobility, min_norm=False)
    stack.add(FrameTask(robot, "ee", gain=kp * dt, position_only=True, name="ee"), priority=0)
    _add_posture(stack, robot, k_posture * dt, priority=1 if exact else 0,
                 weight=1.0 if exact else lam)
    return stack


def _add_posture(stack, robot, gain: float, priority: int, weight: float = 1.0) -> None:
    posture = PostureTask(robot, gain=gain, name="posture")
    stack.add(posture, priority=priority, weight=weight)
    stack.parameter("posture.target", robot.nq, posture_target(robot))


def posture_target(robot) -> np.ndarray:
    """``robot.neutral()`` with the arm joints at the centre of their range [rad]."""
    arm = slice(robot.nq - robot.n_arm, robot.nq)
    target = robot.neutral()
    target[arm] = 0.5 * (robot.limits.q_lower[arm] + robot.limits.q_upper[arm])
    return target


def whole_body_stack(robot, lam: float = PETRIC_LAMBDA, kp: float = KP,
                     k_posture: float = K_POSTURE, dt: float = DT) -> wbc.Stack:
    """The same task as one QP cascade over base (v, ω) and arm joints: level 0 the damped TCP
    task with every column, level 1 the field's ``(v, ω)`` as a soft reference (parameter
    ``"base.b"``), level 2 the posture; the robot's velocity limits are hard bounds."""
    nb = int(robot.nv_base)
    stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping={0: math.sqrt(lam)}, min_norm=False)
    stack.add(FrameTask(robot, "ee", gain=kp * dt, position_only=True, name="ee"), priority=0)
    stack.add(LinearTask(np.eye(nb, robot.nv), np.zeros(nb), name="base"), priority=1)
    _add_posture(stack, robot, k_posture * dt, priority=2)
    stack.constrain(VelocityLimit(robot, name="limits"))
    return stack
