"""Joint limits as velocity bounds: `ConfigurationLimit` and `VelocityLimit`.

Both are :class:`~wbc.VariableBounds` (hard, passed to the QP backends as bounds, never as rows)
over the joint velocities ``v``; add them with ``stack.constrain(...)``.

* ``ConfigurationLimit`` — pink's ``ConfigurationLimit`` at the velocity level: the next
  configuration ``q + v · dt`` stays within ``[q_min, q_max]``, approached with a gain::

      gain · (q_min − q) / dt  <=  v  <=  gain · (q_max − q) / dt

  on the arm joints (base coordinates and joints without finite limits are unbounded; see
  :mod:`wbc.tasks.posture` for which coordinates are the arm's). Pink's gain default is 0.5.
* ``VelocityLimit`` — ``v_min <= v <= v_max`` from ``robot.limits``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import check_robot, checked_name, checked_number
from wbc.errors import ShapeError
from wbc.terms import Task, VariableBounds

from .frame import velocity_block
from .linear import Bounds
from .posture import arm_size


class ConfigurationLimit(Task):
    """Position limits as velocity bounds (see the module docstring).

    Args:
        robot: the robot (``nq``, ``nv``, ``limits.q_lower``, ``limits.q_upper``).
        gain: ``0 < gain <= 1`` [-]; 1 lets a joint reach its limit in one tick.
        name: task name; the limits are parameters ``"<name>.lower"``, ``"<name>.upper"``
            (``(nq,)``, defaults from the robot).
        joints: number of trailing arm joints (default: as :class:`~wbc.tasks.PostureTask`).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"q"`` (nq,), ``"dt"`` (1,), ``"<name>.lower"``,
    ``"<name>.upper"``.
    """

    def __init__(self, robot, gain: float = 0.5, name: str | None = None,
                 joints: int | None = None, block: str | None = None) -> None:
        what = f"ConfigurationLimit {name!r}"
        self.gain = checked_number(gain, f"gain of {what}", 0.0, strict=True, high=1.0)
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        self.n_arm = arm_size(robot, joints)
        self.lower = np.asarray(robot.limits.q_lower, dtype=float).reshape(-1).copy()
        self.upper = np.asarray(robot.limits.q_upper, dtype=float).reshape(-1).copy()
        if self.lower.shape != (self.nq,) or self.upper.shape != (self.nq,):
            raise ShapeError(f"{what}: robot.limits.q_lower/q_upper must have shape "
                             f"({self.nq},)")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        velocity_block(stack, self.block, self.nv, f"ConfigurationLimit {self.name!r}")
        q = stack.quantity("q", self.nq)
        dt = stack.quantity("dt", 1)
        lo = stack.parameter(f"{self.name}.lower", self.nq, self.lower, allow_inf=True)
        up = stack.parameter(f"{self.name}.upper", self.nq, self.upper, allow_inf=True)
        k, base = self.n_arm, self.nv - self.n_arm
        arm = slice(self.nq - k, self.nq)
        inf = ca.SX(ca.DM.ones(base) * np.inf)
        lower = ca.vertcat(-inf, self.gain * (lo[arm] - q[arm]) / dt)
        upper = ca.vertcat(inf, self.gain * (up[arm] - q[arm]) / dt)
        return [VariableBounds(lower, upper, self.block, self.name)]

    def __repr__(self) -> str:
        return f"ConfigurationLimit(gain={self.gain}, name={self.name!r})"


class VelocityLimit(Bounds):
    """``v_min <= v <= v_max`` from ``robot.limits.v_lower`` / ``v_upper`` (bounds).

    Args:
        robot: the robot (``limits.v_lower``, ``limits.v_upper``, ``nv`` entries).
        scale: multiplies both limits, ``> 0`` [-] (e.g. 0.5 for half speed).
        name: task name; the bounds are parameters ``"<name>.lower"``, ``"<name>.upper"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).
    """

    def __init__(self, robot, scale: float = 1.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"VelocityLimit {name!r}"
        scale = checked_number(scale, f"scale of {what}", 0.0, strict=True)
        check_robot(robot, f"robot of {what}")
        lower = scale * np.asarray(robot.limits.v_lower, dtype=float)
        upper = scale * np.asarray(robot.limits.v_upper, dtype=float)
        super().__init__(lower, upper, name=name, block=block)
