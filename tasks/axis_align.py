"""`AxisAlignTask`: align a frame's axis with a world direction (e.g. a tool pointing down).

Mink's ``AxisAlignTask`` (mink 1.3, ``mink/tasks/axis_align_task.py``) as an affine cost over
``v``. With ``a`` the unit axis in the frame's own coordinates, ``t`` the unit target
direction in the world (parameter ``"<name>.target"``, normalised inside the compiled
function), ``R`` the frame's rotation (``"pose[<frame>]"``) and ``J_ω = Rᵀ J[3:]`` the angular
rows of the frame's Jacobian in its own axes (``"J[<frame>]"`` is world-aligned)::

    d    = Rᵀ t                          the target direction in the frame [-]
    e    = a − d                         error (3 rows, rank 2: the roll about a is free)
    J_e  = −[d]× J_ω                     so that  ė = J_e v   (ḋ = [d]× ω_body)
    cost = 1/2 w ‖J_e v + gain · e / dt‖²

Mink minimises ``1/2 ‖c (J_e Δq + gain · e)‖² + μ/2 ‖Δq‖²`` over ``Δq = v · dt`` with
``μ = lm_damping · ‖c · gain · e‖²``; divided by ``dt²`` that is the cost above with
``w = c²`` and the same ``μ`` on ``1/2 ‖v‖²``: the same minimiser. The error is mink's
three-row difference of unit vectors, not the two-row cross product ``a × d``: the two agree to
first order at alignment (``a × d = −[a]× e`` there) and differ away from it (they ask for
different rates); mink's is kept so that the two controllers agree exactly. ``‖e‖ = 2 sin(θ/2)``
for the angle ``θ`` between ``a`` and ``Rᵀ t`` (what :attr:`wbc.Solution.residuals` reports, to
first order after the tick). Anti-aligned (``d = −a``) the error is largest and ``J_e`` still
rank 2; ``lm_damping`` keeps the step bounded, as in mink.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import (
    check_frame,
    check_robot,
    checked_name,
    checked_number,
    checked_vector,
    checked_weights,
)
from wbc.errors import InvalidValueError
from wbc.terms import Cost, Task

from .frame import lm_damping_terms, velocity_block

__all__ = ["AxisAlignTask", "unit_axis"]

#: norm [-] below which a target direction or point offset counts as zero (mink's float64 ε)
EPSILON = 1e-10


def unit_axis(axis, what: str) -> np.ndarray:
    """``axis`` (3,) normalised; a zero or non-finite vector raises naming ``what``."""
    axis = checked_vector(axis, 3, what, broadcast=False)
    norm = float(np.linalg.norm(axis))
    if norm < EPSILON:
        raise InvalidValueError(f"{what} must be a non-zero vector, got {axis}")
    return axis / norm


class AxisAlignTask(Task):
    """Align the frame axis ``axis`` with the world direction ``"<name>.target"`` (module
    docstring).

    Args:
        robot: the robot (``nv``, frame names).
        frame: the frame whose axis is aligned (e.g. ``"ee"``).
        axis: the axis in the frame's own coordinates (3,), normalised here (default ``+z``).
        gain: task gain ``α >= 0`` [-] (1 = dead-beat, as mink's).
        weight: ``w`` (scalar or 3 rows, ``>= 0``); equals mink's ``cost²``.
        lm_damping: mink's Levenberg–Marquardt damping [-].
        name: task name; the target direction is ``"<name>.target"`` (3,) in world axes (need
            not be normalised; no default: set it before the first solve, as mink's
            ``TargetNotSet``).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Quantities it declares: ``"pose[<frame>]"``, ``"J[<frame>]"``, ``"dt"``.
    """

    def __init__(self, robot, frame: str, axis=(0.0, 0.0, 1.0), gain: float = 1.0,
                 weight=1.0, lm_damping: float = 0.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"{type(self).__name__} {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.frame = checked_name(frame, f"frame of {what}", optional=False)
        check_frame(robot, frame, what)
        self.axis = unit_axis(axis, f"axis of {what}")
        self.gain = checked_number(gain, f"gain of {what}")
        self.weight = checked_weights(weight, 3, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.error: ca.SX | None = None
        self.jacobian: ca.SX | None = None

    def error_and_jacobian(self, stack) -> tuple[ca.SX, ca.SX]:
        """``(e, J_e)`` as SX of the stack's quantities (module docstring)."""
        pose = stack.quantity(f"pose[{self.frame}]", (4, 4))
        J = stack.quantity(f"J[{self.frame}]", (6, self.nv))
        target = stack.parameter(f"{self.name}.target", 3)  # no default: must be set
        R = pose[:3, :3]
        t = target / ca.fmax(ca.norm_2(target), EPSILON)
        d = R.T @ t
        return ca.DM(self.axis) - d, -ca.skew(d) @ (R.T @ J[3:, :])

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"{type(self).__name__} {self.name!r}")
        dt = stack.quantity("dt", 1)
        e, J_e = self.error_and_jacobian(stack)
        self.error, self.jacobian = e, J_e
        # reported residual: the error left after the tick, to first order [-]
        residual = e + dt * (J_e @ v)
        return [Cost(J_e @ v, -self.gain / dt * e, self.weight, self.name, residual),
                *lm_damping_terms(self.name, v, self.weight, self.gain, self.lm_damping, e)]

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(frame={self.frame!r}, axis={self.axis.tolist()}, "
                f"gain={self.gain}, name={self.name!r})")
