"""`ComTask`: move the robot's centre of mass towards a target point (velocity level).

Pink's ``ComTask`` (stephane-caron/pink) as an affine term over the velocity ``v``, with ``c``
the centre of mass (model quantity ``"com"``, world [m]), ``J_com`` its Jacobian (quantity
``"J_com"``, ``ċ = J_com v``) and ``c*`` the target (parameter ``"<name>.target"``)::

    cost = 1/2 Σ_i w_i (J_com v − gain · (c* − c) / dt)_i²        i = x, y, z (world axes)

Pink minimises ``1/2 ||W (J_com Δq + gain · (c − c*))||²`` over ``Δq = v · dt``; dividing by
``dt²`` gives the cost above with ``w = cost²`` (per axis). ``v`` is the robot's velocity, so
with a free-flyer root ``J_com`` includes the root's six columns (pinocchio's, root twist in
the root body's axes) and the task moves the whole body.

Keeping the centre of mass over a support polygon is the usual use: a target inside the
polygon at a high priority, or a target whose horizontal coordinates are weighted (``weight =
(w_x, w_y, 0)`` leaves the height free).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import check_robot, checked_name, checked_number, checked_weights
from wbc.errors import ShapeError
from wbc.terms import Task

from .frame import tracking_terms, velocity_block


class ComTask(Task):
    """Centre-of-mass tracking (see the module docstring).

    Args:
        robot: the robot (``nv``; ``com(q)`` and ``neutral()`` for the default target); see
            :class:`wbc.Controller`.
        gain: task gain ``α >= 0`` [-] (1 = dead-beat).
        weight: ``w``, scalar or one per world axis (``>= 0``, or a CasADi SX expression of
            the stack's parameters, see :func:`wbc.checks.checked_weights`); equals pink's
            ``cost²``.
        lm_damping: pink's Levenberg–Marquardt damping (adds ``μ/2 ||v||²``,
            ``μ = lm_damping · Σ w_i (α e_i)²``, ``e = c* − c``; 0: no rows added).
        name: task name (default ``None``: the stack names it — never ``"com"``, the model
            quantity); the target is ``"<name>.target"`` (``(3,)`` [m], world; default the
            robot's centre of mass at ``robot.neutral()``).
        block: the velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"com"`` (3, 1), ``"J_com"`` (3, nv), ``"dt"`` (1,),
    ``"<name>.target"`` (3,).
    """

    def __init__(self, robot, gain: float = 1.0, weight=1.0, lm_damping: float = 0.0,
                 name: str | None = None, block: str | None = None) -> None:
        what = f"ComTask {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.gain = checked_number(gain, f"gain of {what}")
        self.weight = checked_weights(weight, 3, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        com = getattr(robot, "com", None)
        if com is None:
            raise ShapeError(f"{what}: the robot has no com(q) (the centre of mass) for the "
                             f"default target")
        self.default_target = np.asarray(com(robot.neutral()), dtype=float).reshape(-1).copy()
        if self.default_target.shape != (3,):
            raise ShapeError(f"{what}: robot.com(q) has shape {self.default_target.shape}, "
                             f"expected (3,)")
        self.error: ca.SX | None = None  # c* − c, set by terms()

    def terms(self, stack):
        what = f"ComTask {self.name!r}"
        v = velocity_block(stack, self.block, self.nv, what)
        com = stack.quantity("com", (3, 1))
        J_com = stack.quantity("J_com", (3, self.nv))
        dt = stack.quantity("dt", 1)
        target = stack.parameter(f"{self.name}.target", 3, self.default_target)
        e = target - com
        self.error = e
        # reported residual: the error the command leaves, to first order [m]
        return tracking_terms(self.name, J_com @ v, e, v, dt, self.gain, self.weight,
                              self.lm_damping)

    def __repr__(self) -> str:
        return f"ComTask(gain={self.gain}, weight={self.weight}, name={self.name!r})"
