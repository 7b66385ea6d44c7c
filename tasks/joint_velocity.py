"""`JointVelocityTask`: track a joint-velocity reference.

The cost, over the joint velocities ``v`` [rad/s or m/s], with the reference ``v_ref``
(parameter ``"<name>.target"``, ``nv`` entries, set with ``ctrl.step(q, <name>=v_ref)``)::

    cost = 1/2 Σ_i w_i (v_i − v_ref,i)²

Alone (stack damping ``ρ``) the answer is ``v_i = w_i v_ref,i / (w_i + ρ²)``; among other tasks
it pulls the command towards the reference, e.g. a teleoperated joint-velocity stream.

Peer. Pink's ``JointVelocityTask(cost)`` (pink 4.4) means to minimise ``‖v_ref − v‖`` but, as
released, drives the command to ``−v_ref``: its error is ``e = +v_ref · dt`` with Jacobian ``I``
and gain 1, and pink's task dynamics ``J Δq = −gain · e`` make its objective
``1/2 c² ‖Δq + v_ref dt‖²`` (over ``Δq = v · dt``; pink alone returns ``v = −v_ref``). wbc
tracks ``+v_ref``, the task's documented intent: its answer equals pink's given the reference
``−v_ref`` (tested at random states), and dividing pink's objective by ``dt²`` gives the cost
above with ``w = c²``. Pink skips a floating base's coordinates (its reference has ``nv − 6``
entries there); wbc's base coordinates are actuated velocities, tracked like the joints unless
their weight is 0. The reference has no default: solving before it is set raises (pink's
``TargetNotSet``).
"""

from __future__ import annotations

from wbc.checks import check_robot, checked_name, checked_weights
from wbc.terms import Cost, Task

from .frame import velocity_block


class JointVelocityTask(Task):
    """``1/2 Σ_i w_i (v_i − v_ref,i)²`` (see the module docstring).

    Args:
        robot: the robot (``nv``); see :class:`wbc.Controller`.
        weight: ``w``, a scalar or one per velocity coordinate (``>= 0``), or a CasADi SX
            expression of the stack's parameters [cost / (rad/s)²]; equals pink's ``cost²``.
        name: task name (default: the stack names it); the reference is ``"<name>.target"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"<name>.target"`` (nv,), the reference velocity [rad/s or m/s]
    (no default).
    """

    def __init__(self, robot, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"JointVelocityTask {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.weight = checked_weights(weight, self.nv, f"weight of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"JointVelocityTask {self.name!r}")
        target = stack.parameter(f"{self.name}.target", self.nv)  # no default: must be set
        return [Cost(v, target, self.weight, self.name)]

    def __repr__(self) -> str:
        return f"JointVelocityTask(weight={self.weight}, name={self.name!r})"
