"""`BodySphericalBarrier`: keep two frames at least ``d_min`` apart (a control barrier).

Pink's ``BodySphericalBarrier`` (pink 4.4, ``pink/barriers/body_spherical_barrier.py``) at the
velocity level, with the barrier machinery of :mod:`wbc.tasks.position_barrier`. One row::

    h(q)  = ‖p₁ − p₂‖² − d_min²                       [m²]
    J_h   = 2 (p₁ − p₂)ᵀ (J₁ − J₂)                      [m² per unit v]
    α(h)  = h / (1 + |h|)                               (pink's class-K function)
    hard:   J_h v >= −γ α(h)

with ``p_i`` the frames' world positions (``"pose[<frame>]"``) and ``J_i`` the linear rows of
their world-aligned Jacobians (``"J[<frame>]"``). ``α`` saturates at 1, so far from the
sphere the row allows ``ḣ`` down to ``−γ`` [m²/s] whatever the distance. Pink's default
safe-displacement gain is 3 (a cost ``1/2 · 3 / ‖J_h‖² · ‖v‖²``, see
:meth:`~wbc.tasks.position_barrier.Barrier.safe_displacement`); here it is a separate task, so
the default of this class is pink's but the cost is in the stack only if added.
"""

from __future__ import annotations

import casadi as ca

from wbc.checks import check_frame, check_robot, checked_name, checked_number
from wbc.errors import InvalidValueError

from .position_barrier import Barrier

__all__ = ["BodySphericalBarrier"]


class BodySphericalBarrier(Barrier):
    """Keep the origins of two frames at least ``d_min`` [m] apart (module docstring); add it
    with ``stack.constrain``, and ``barrier.safe_displacement()`` with ``stack.add`` for pink's
    full formulation.

    Args:
        robot: the robot (``nv``, frame names).
        frames: the two frame names ``(frame_1, frame_2)``, distinct.
        d_min: the smallest distance [m], ``>= 0``; the default of the parameter
            ``"<name>.d_min"`` (1,), settable per tick.
        gain: barrier gain ``γ > 0`` [1/s].
        safe_displacement_gain: pink's ``r >= 0`` (pink's default 3).
        name: task name. block: the joint-velocity block of the decision vector.

    Quantities it declares: ``"pose[<frame>]"`` and ``"J[<frame>]"`` of both frames.
    """

    rows = 1

    def __init__(self, robot, frames, d_min: float, gain: float = 1.0,
                 safe_displacement_gain: float = 3.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"BodySphericalBarrier {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        if isinstance(frames, (str, bytes)) or not hasattr(frames, "__len__") or len(
                frames) != 2:
            raise InvalidValueError(f"frames of {what} must be two frame names, got {frames!r}")
        self.frames = tuple(checked_name(f, f"frames of {what}", optional=False)
                            for f in frames)
        if self.frames[0] == self.frames[1]:
            raise InvalidValueError(f"frames of {what} must differ, got {self.frames}")
        for frame in self.frames:
            check_frame(robot, frame, what)
        self.d_min = checked_number(d_min, f"d_min [m] of {what}")
        self._init_gains(gain, safe_displacement_gain, what)
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def _difference(self, stack) -> tuple[ca.SX, ca.SX]:
        """``(p₁ − p₂, J_h)``."""
        poses = [stack.quantity(f"pose[{f}]", (4, 4)) for f in self.frames]
        jacobians = [stack.quantity(f"J[{f}]", (6, self.nv)) for f in self.frames]
        delta = poses[0][:3, 3] - poses[1][:3, 3]
        return delta, 2 * delta.T @ (jacobians[0][:3, :] - jacobians[1][:3, :])

    def barrier(self, stack):
        delta, J_h = self._difference(stack)
        d_min = stack.parameter(f"{self.name}.d_min", 1, self.d_min)
        return ca.sumsqr(delta) - d_min * d_min, J_h

    def jacobian(self, stack):
        return self._difference(stack)[1]

    def class_k(self, h):
        """Pink's ``α(h) = h / (1 + |h|)``."""
        return h / (1 + ca.fabs(h))

    def __repr__(self) -> str:
        return (f"BodySphericalBarrier(frames={self.frames}, d_min={self.d_min}, "
                f"name={self.name!r})")
