"""`LookAtTask`: point a frame's axis at a world point (a camera, a head).

Mink's ``LookAtTask`` (mink 1.3, ``mink/tasks/look_at_task.py``) as an affine cost over ``v``.
With ``a`` the unit gaze axis in the frame's own coordinates, ``p*`` the target point in the
world (parameter ``"<name>.target"``, (3,) [m]), ``R``, ``p`` the frame's rotation and
position (``"pose[<frame>]"``) and ``[J_v; J_ω] = [Rᵀ J[:3]; Rᵀ J[3:]]`` the frame's Jacobian
in its own axes (``"J[<frame>]"`` is world-aligned)::

    r    = Rᵀ (p* − p),   n = max(‖r‖, 1e-10),   d = r / n       line of sight [m], [-]
    e    = a − d                                                  error [-], rank 2
    J_e  = (I − d dᵀ) (J_v − [r]× J_ω) / n                        so that  ė = J_e v
    cost = 1/2 w ‖J_e v + gain · e / dt‖²

(``ṙ = [r]× ω_b − v_b`` for the body twist ``(v_b, ω_b)``, and ``ḋ = (I − d dᵀ) ṙ / n``.) The
translation rows make the frame move, not only turn, to keep the target in view. Mink's cost
``c``, gain and Levenberg–Marquardt damping map as for :class:`~wbc.tasks.axis_align.AxisAlignTask`
(``w = c²``, the same ``μ``): the same minimiser. Degenerate when the target is at the frame
origin (``n → 0``) or straight behind the axis (``d = −a``); ``lm_damping`` keeps the step
bounded there, as in mink.
"""

from __future__ import annotations

import casadi as ca

from .axis_align import EPSILON, AxisAlignTask

__all__ = ["LookAtTask"]


class LookAtTask(AxisAlignTask):
    """Point the frame axis ``axis`` at the world point ``"<name>.target"`` (module docstring).

    Args:
        robot: the robot (``nv``, frame names).
        frame: the frame that looks (e.g. a camera frame).
        axis: the gaze axis in the frame's own coordinates (3,), normalised here (default
            ``+z``).
        gain: task gain ``α >= 0`` [-] (1 = dead-beat, as mink's).
        weight: ``w`` (scalar or 3 rows, ``>= 0``); equals mink's ``cost²``.
        lm_damping: mink's Levenberg–Marquardt damping [-].
        name: task name; the target point is ``"<name>.target"`` (3,) [m], world (no default:
            set it before the first solve).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Quantities it declares: ``"pose[<frame>]"``, ``"J[<frame>]"``, ``"dt"``. The cost and
    its residual are :class:`~wbc.tasks.axis_align.AxisAlignTask`'s with this error.
    """

    def error_and_jacobian(self, stack) -> tuple[ca.SX, ca.SX]:
        """``(e, J_e)`` as SX of the stack's quantities (module docstring)."""
        pose = stack.quantity(f"pose[{self.frame}]", (4, 4))
        J = stack.quantity(f"J[{self.frame}]", (6, self.nv))
        target = stack.parameter(f"{self.name}.target", 3)  # no default: must be set
        R = pose[:3, :3]
        r = R.T @ (target - pose[:3, 3])
        n = ca.fmax(ca.norm_2(r), EPSILON)
        d = r / n
        J_v, J_w = R.T @ J[:3, :], R.T @ J[3:, :]
        J_e = (ca.SX.eye(3) - d @ d.T) @ (J_v - ca.skew(r) @ J_w) / n
        return ca.DM(self.axis) - d, J_e

