"""`JointCouplingTask`: hold a linear relation between joint positions, ``Σ_i c_i q_i = r``.

A one-row linear holonomic task: with ``c`` the ratios of the coupled joints (0 elsewhere),
``r`` the target [rad or m] (parameter ``"<name>.target"``, default 0) and ``q`` the
configuration, the error is ``e = r − cᵀq`` and the cost, over the joint velocities ``v``::

    cost = 1/2 w (cᵀv − gain · (r − cᵀq) / dt)²

so that with gain 1 the relation holds after one tick of ``q ← q + v · dt`` (dead-beat), e.g.
``q_1 − q_2 = 0`` (ratios ``(1, −1)``) makes two joints move as one.

Peer. Pink's ``JointCouplingTask(joint_names, ratios, cost, configuration, lm_damping, gain)``
is a ``LinearHolonomicTask`` ``A (q ⊖ q_0) = b`` with ``A = cᵀ``, ``b = 0`` and ``q_0`` the
model's neutral configuration (0 for revolute and prismatic joints), so its error is ``cᵀq``
and its Jacobian ``cᵀ``; it minimises ``1/2 c_p² (cᵀΔq + gain · cᵀq)²`` (plus its
Levenberg–Marquardt term) over ``Δq = v · dt``. Divided by ``dt²`` that is the cost above with
``r = 0`` and ``w = c_p²``; ``lm_damping`` carries over unchanged (``μ = lm_damping · w ·
(gain · e)²`` on every velocity coordinate). The target ``r`` is wbc's addition (pink's ``b``
of the general task).

The coupled joints are named as in ``robot.joint_names`` — the arm's 1-DoF joints, which are
the last entries of ``q`` and of ``v`` (see :mod:`wbc.tasks.posture`), so ``q_i ⊖ q_0,i`` is
``q_i`` there.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import (
    check_robot,
    checked_name,
    checked_number,
    checked_vector,
    checked_weights,
)
from wbc.errors import InvalidValueError, ShapeError, UnknownNameError
from wbc.terms import Task

from .frame import tracking_terms, velocity_block
from .posture import arm_size


class JointCouplingTask(Task):
    """``Σ_i c_i q_i = r`` as a cost on ``v`` (see the module docstring).

    Args:
        robot: the robot (``nq``, ``nv``, ``joint_names``); see :class:`wbc.Controller`.
        joints: names of the coupled joints (from ``robot.joint_names``, each once).
        ratios: one ratio ``c_i`` per joint [-], not all zero.
        gain: task gain ``α >= 0`` [-] (1 = dead-beat).
        weight: ``w >= 0`` (a number, or a 1 × 1 CasADi SX expression of the stack's
            parameters) [cost / rad²]; equals pink's ``cost²``.
        lm_damping: pink's Levenberg–Marquardt damping: adds ``μ/2 ‖v‖²`` with
            ``μ = lm_damping · w · (α e)²`` (0: no rows added).
        name: task name (default: the stack names it); the target is ``"<name>.target"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"q"`` (nq,), ``"dt"`` (1,), ``"<name>.target"`` (1,), ``r``
    [rad or m] (default 0).
    """

    def __init__(self, robot, joints, ratios, gain: float = 1.0, weight=1.0,
                 lm_damping: float = 0.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"JointCouplingTask {name!r}"
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        names = getattr(robot, "joint_names", None)
        if names is None:
            raise InvalidValueError(f"robot of {what} must have joint_names (see wbc.robots)")
        names = list(names)
        n_arm = arm_size(robot)
        if len(names) != n_arm:
            raise ShapeError(f"{what}: the robot names {len(names)} joints but has {n_arm} "
                             "arm joints")
        if isinstance(joints, str) or not hasattr(joints, "__len__") or len(joints) == 0:
            raise InvalidValueError(f"joints of {what} must be a non-empty list of joint "
                                    f"names, got {joints!r}")
        for joint in joints:
            checked_name(joint, f"joint of {what}", optional=False)
            if joint not in names:
                raise UnknownNameError(f"{what}: unknown joint {joint!r}; joints are {names}")
        if len(set(joints)) != len(joints):
            raise InvalidValueError(f"{what}: a joint is listed twice in {list(joints)}")
        self.joints = tuple(joints)
        self.ratios = checked_vector(ratios, len(self.joints), f"ratios of {what}",
                                     broadcast=False).copy()
        if not self.ratios.any():
            raise InvalidValueError(f"ratios of {what} are all zero: the task would be empty")
        # the ratios as rows over q and over v (the arm joints are the last entries of both)
        self.row_q, self.row_v = np.zeros(self.nq), np.zeros(self.nv)
        for joint, ratio in zip(self.joints, self.ratios, strict=True):
            i = names.index(joint)
            self.row_q[self.nq - n_arm + i] = ratio
            self.row_v[self.nv - n_arm + i] = ratio
        self.gain = checked_number(gain, f"gain of {what}")
        self.weight = checked_weights(weight, 1, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.error: ca.SX | None = None  # symbolic error r − cᵀq, set by terms()

    def terms(self, stack):
        what = f"JointCouplingTask {self.name!r}"
        v = velocity_block(stack, self.block, self.nv, what)
        q = stack.quantity("q", self.nq)
        dt = stack.quantity("dt", 1)
        target = stack.parameter(f"{self.name}.target", 1, np.zeros(1))
        e = target - ca.DM(self.row_q).T @ q
        self.error = e
        expr = ca.DM(self.row_v).T @ v
        # reported residual, as FrameTask's: 0 when the row holds, e when nothing moves [rad]
        return tracking_terms(self.name, expr, e, v, dt, self.gain, self.weight,
                              self.lm_damping)

    def __repr__(self) -> str:
        return (f"JointCouplingTask(joints={list(self.joints)}, ratios={self.ratios.tolist()}, "
                f"gain={self.gain}, weight={self.weight}, name={self.name!r})")
