"""`DampingTask`: penalise joint velocities, with a weight per velocity coordinate.

The cost, over the joint velocities ``v`` [rad/s or m/s]::

    cost = 1/2 Σ_i w_i v_i²

It brings the robot to rest when nothing else drives it and picks the least-motion answer among
equally good ones. Unlike the stack's ``damping`` (one ``ρ²`` on every variable and level), it is
a task: it lives at the level it is added to, with its own weight per coordinate, and competes
with that level's other tasks.

Peers. Pink's ``DampingTask(cost)`` (one scalar) and mink's ``DampingTask(model, cost)`` (one
per degree of freedom) both minimise ``1/2 Σ_i c_i² Δq_i²`` over ``Δq = v · dt``; dividing the
whole objective by ``dt²`` (as for every wbc task) gives the cost above with ``w_i = c_i²``.
Both peers leave the coordinates of a floating base (a free root joint) undamped; wbc's base
coordinates are actuated velocities and are damped like the joints unless their weight is 0.
"""

from __future__ import annotations

from wbc.checks import check_robot, checked_name, checked_weights
from wbc.terms import Cost, Task

from .frame import velocity_block


class DampingTask(Task):
    """``1/2 Σ_i w_i v_i²`` over every velocity coordinate (see the module docstring).

    Args:
        robot: the robot (``nv``); see :class:`wbc.Controller`.
        weight: ``w``, a scalar or one per velocity coordinate (``nv`` entries, ``>= 0``;
            0 leaves a coordinate free), or a CasADi SX expression of the stack's parameters
            (see :func:`wbc.checks.checked_weights`) [cost / (rad/s)²]; equals pink's and mink's
            ``cost²``.
        name: task name (default: the stack names it).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    The task declares no parameter; its residual is ``v`` [rad/s or m/s].
    """

    def __init__(self, robot, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"DampingTask {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.weight = checked_weights(weight, self.nv, f"weight of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"DampingTask {self.name!r}")
        return [Cost(v, 0.0, self.weight, self.name)]

    def __repr__(self) -> str:
        return f"DampingTask(weight={self.weight}, name={self.name!r})"
