"""`DofFreezing`: hold listed velocity coordinates at zero.

For the listed coordinates ``F`` of the joint velocities ``v`` (indices into ``v``, or names
from ``robot.velocity_names``)::

    v_i = 0    for i ∈ F

Two forms:

* ``form="bounds"`` (the default): ``0 <= v_i <= 0`` as variable bounds (``±inf`` on the other
  coordinates), added with ``stack.constrain(...)`` — hard at every level, handed to the QP
  backends as bounds, never as rows. The other coordinates then solve the same problem as if the
  frozen ones were deleted from the robot: a frozen column contributes nothing to any task.
* ``form="equality"``: the rows ``v_F = 0`` as an :class:`~wbc.terms.Equality`. Constrained
  (``stack.constrain``) they are hard rows, the same solution as the bounds; added
  (``stack.add(..., weight=w)``) they are a soft cost ``w/2 ‖v_F‖²`` at that level.

Peer. Mink's ``DofFreezingTask(model, dof_indices)`` has Jacobian rows of the identity at the
frozen degrees of freedom, error 0 and cost 1. Passed to ``mink.solve_ik(..., constraints=[...])``
it is the equality ``Δq_F = 0`` — the same set as ``v_F = 0`` (``Δq = v · dt``), so both
hard forms here give mink's answer; passed as a task it is the cost ``1/2 ‖Δq_F‖²``, i.e.
``1/2 ‖v_F‖²`` over ``v`` once divided by ``dt²``: ``form="equality"`` added with weight 1.
As mink, an empty list, an index out of range and a repeated coordinate are refused.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import check_robot, checked_integer, checked_name
from wbc.errors import InvalidValueError, UnknownNameError
from wbc.terms import Equality, Task, VariableBounds

from .frame import velocity_block

FORMS = ("bounds", "equality")
"""The forms of :class:`DofFreezing` (see the module docstring)."""


class DofFreezing(Task):
    """Listed velocity coordinates held at zero (see the module docstring).

    Args:
        robot: the robot (``nv``; ``velocity_names`` when coordinates are given by name).
        dofs: the frozen coordinates: indices into ``v`` (``0 <= i < nv``) or names from
            ``robot.velocity_names``, each once, at least one.
        form: ``"bounds"`` (hard, ``stack.constrain``) or ``"equality"`` (hard rows with
            ``stack.constrain``, a soft cost with ``stack.add``).
        name: task name (default: the stack names it).
        block: the joint-velocity block of the decision vector (``None``: all of it); the
            indices count from the start of the block.

    The task declares no parameter. :attr:`indices` holds the frozen indices, sorted.
    """

    def __init__(self, robot, dofs, form: str = "bounds", name: str | None = None,
                 block: str | None = None) -> None:
        what = f"DofFreezing {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        if isinstance(dofs, (str, int, np.integer)):
            dofs = [dofs]
        if not hasattr(dofs, "__len__") or len(dofs) == 0:
            raise InvalidValueError(f"dofs of {what} must be a non-empty list of indices or "
                                    f"velocity names, got {dofs!r}")
        names = getattr(robot, "velocity_names", None)
        indices = []
        for dof in dofs:
            if isinstance(dof, str):
                if names is None or dof not in list(names):
                    known = f"; velocity names are {list(names)}" if names is not None else (
                        " (the robot has no velocity_names: give indices)")
                    raise UnknownNameError(f"{what}: unknown velocity coordinate {dof!r}"
                                           + known)
                indices.append(list(names).index(dof))
            else:
                indices.append(checked_integer(dof, f"dof of {what}", 0, self.nv - 1))
        if len(set(indices)) != len(indices):
            raise InvalidValueError(f"{what}: a coordinate is listed twice in {list(dofs)}")
        self.indices = tuple(sorted(indices))
        if not isinstance(form, str) or form not in FORMS:  # `in` on an array is ambiguous
            raise InvalidValueError(f"form of {what} must be one of {list(FORMS)}, got "
                                    f"{form!r}")
        self.form = form
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"DofFreezing {self.name!r}")
        if self.form == "equality":
            rows = ca.vertcat(*[v[i] for i in self.indices])
            return [Equality(rows, 0.0, self.name)]
        frozen = np.zeros(self.nv, dtype=bool)
        frozen[list(self.indices)] = True
        lower, upper = np.where(frozen, 0.0, -np.inf), np.where(frozen, 0.0, np.inf)
        return [VariableBounds(lower, upper, self.block, self.name)]

    def __repr__(self) -> str:
        return (f"DofFreezing(indices={list(self.indices)}, form={self.form!r}, "
                f"name={self.name!r})")
