"""`LowAccelerationTask`: penalise the change of the command from one tick to the next.

The cost, over the joint velocities ``v`` [rad/s or m/s], with ``v_prev`` the previous command
(parameter ``"<name>.target"``, ``nv`` entries, default 0, set every tick with
``ctrl.step(q, <name>=v_prev)``)::

    cost = 1/2 Σ_i w_i (v_i − v_prev,i)²  =  1/2 Σ_i w_i dt² a_i²,    a = (v − v_prev) / dt

so it penalises the joint acceleration ``a`` [rad/s²] the new command implies. The caller sets
``v_prev`` (usually the command it sent last tick); the task keeps no state of its own, so
resets, skipped ticks and a measured velocity instead of the command are the caller's choice.
It does not dissipate energy: pair it with a :class:`~wbc.tasks.damping.DampingTask` to avoid
oscillations, as pink advises.

Peer. Pink's ``LowAccelerationTask(cost)`` with ``set_last_integration(v_prev, dt)`` has error
``−v_prev · dt``, Jacobian ``I`` and gain 1: it minimises ``1/2 c² ‖Δq − v_prev dt‖²`` over
``Δq = v · dt``; divided by ``dt²`` that is the cost above with ``w = c²``. Before the first
``set_last_integration`` pink uses ``v_prev = 0``, as the default here.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import check_robot, checked_name, checked_weights
from wbc.terms import Cost, Task

from .frame import velocity_block


class LowAccelerationTask(Task):
    """``1/2 Σ_i w_i (v_i − v_prev,i)²`` (see the module docstring).

    Args:
        robot: the robot (``nv``); see :class:`wbc.Controller`.
        weight: ``w``, a scalar or one per velocity coordinate (``>= 0``), or a CasADi SX
            expression of the stack's parameters [cost / (rad/s)²]; equals pink's ``cost²``.
        name: task name (default: the stack names it); ``v_prev`` is ``"<name>.target"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"<name>.target"`` (nv,), the previous command ``v_prev``
    [rad/s or m/s] (default 0).
    """

    def __init__(self, robot, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"LowAccelerationTask {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.weight = checked_weights(weight, self.nv, f"weight of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"LowAccelerationTask {self.name!r}")
        v_prev = stack.parameter(f"{self.name}.target", self.nv, np.zeros(self.nv))
        return [Cost(v, v_prev, self.weight, self.name)]

    def __repr__(self) -> str:
        return f"LowAccelerationTask(weight={self.weight}, name={self.name!r})"
