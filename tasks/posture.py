"""`PostureTask`: regulate the arm joints towards a reference configuration (velocity level).

Pink's ``PostureTask`` (stephane-caron/pink) as an affine term over joint velocities ``v``::

    cost = 1/2 Σ_i w_i (v_i − gain · (q*_i − q_i) / dt)²        over the arm joints i

Pink minimises ``1/2 ||W (Δq + gain · (q ⊖ q*))||²`` over ``Δq = v · dt``; dividing by ``dt²``
gives the cost above with ``w = cost²``.

Base coordinates. The robots order coordinates base first, then arm joints (docs/DESIGN.md,
section "Robots and tasks"), and a mobile base's velocity coordinates need not match its
configuration (a differential drive has ``q_base = (x, y, θ)`` but ``v_base = (v, ω)``). The
posture therefore acts on the *arm* only:
the last ``n_arm`` entries of ``v`` and of ``q``, where the arm joints are 1-DoF (revolute or
prismatic, so ``q_i ⊖ q*_i = q_i − q*_i``). ``n_arm`` is, in order: the ``joints`` argument,
``robot.n_arm``, ``robot.nv − robot.base.nv``, or ``robot.nv`` when ``robot.nq == robot.nv``
and the robot has no ``base`` (a fixed-base arm). The target is a full configuration (``nq``
entries, as pink's); its base coordinates are ignored.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import (
    check_robot,
    checked_integer,
    checked_name,
    checked_number,
    checked_weights,
)
from wbc.errors import ShapeError, WbcError
from wbc.terms import Cost, Task

from .frame import lm_damping_terms, velocity_block


def arm_size(robot, joints: int | None = None) -> int:
    """Number of trailing arm joints of ``robot`` (see the module docstring)."""
    nq, nv = check_robot(robot, "robot")
    if joints is None:
        if getattr(robot, "n_arm", None) is not None:
            joints = int(robot.n_arm)
        elif getattr(getattr(robot, "base", None), "nv", None) is not None:
            joints = nv - int(robot.base.nv)
        elif nq == nv:
            joints = nv
        else:
            raise WbcError(f"cannot tell the arm joints of a robot with nq = {nq} != nv = "
                           f"{nv}: pass joints=<number of trailing arm joints>")
    joints = checked_integer(joints, "joints")
    if not 0 < joints <= min(nq, nv):
        raise ShapeError(f"joints must be in 1..{min(nq, nv)}, got {joints}")
    return joints


class PostureTask(Task):
    """Posture regulation of the arm joints (see the module docstring).

    Args:
        robot: the robot (``nq``, ``nv``, ``neutral()``; see :class:`wbc.Controller`).
        gain: task gain ``α`` [-] (1 = dead-beat).
        weight: ``w``, scalar or one per arm joint (``>= 0``, or a CasADi SX expression of the
            stack's parameters, see :func:`wbc.checks.checked_weights`); equals pink's
            ``cost²``.
        lm_damping: pink's Levenberg–Marquardt damping (adds ``μ/2 ||v||²``,
            ``μ = lm_damping · Σ w_i (α e_i)²``).
        name: task name; the target is ``"<name>.target"`` (``(nq,)``, default
            ``robot.neutral()``).
        joints: number of trailing arm joints regulated (default: see module docstring).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"q"`` (nq,), ``"dt"`` (1,), ``"<name>.target"`` (nq,).
    """

    def __init__(self, robot, gain: float = 1.0, weight=1.0, lm_damping: float = 0.0,
                 name: str | None = None, joints: int | None = None,
                 block: str | None = None) -> None:
        what = f"PostureTask {name!r}"
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        self.n_arm = arm_size(robot, joints)
        self.gain = checked_number(gain, f"gain of {what}")
        self.weight = checked_weights(weight, self.n_arm, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.default_target = np.asarray(robot.neutral(), dtype=float).reshape(-1)
        if self.default_target.shape != (self.nq,):
            raise ShapeError(f"{what}: robot.neutral() has shape "
                             f"{self.default_target.shape}, expected ({self.nq},)")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.error = None

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"PostureTask {self.name!r}")
        q = stack.quantity("q", self.nq)
        dt = stack.quantity("dt", 1)
        target = stack.parameter(f"{self.name}.target", self.nq, self.default_target)
        k = self.n_arm
        e = target[self.nq - k:] - q[self.nq - k:]
        self.error = e
        return [Cost(v[self.nv - k:], self.gain / dt * e, self.weight, self.name),
                *lm_damping_terms(self.name, v, self.weight, self.gain, self.lm_damping, e)]

    def __repr__(self) -> str:
        return f"PostureTask(gain={self.gain}, weight={self.weight}, name={self.name!r})"

