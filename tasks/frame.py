"""`FrameTask`: track a world pose (or position) of a robot frame at the velocity level.

The task is pink's ``FrameTask`` (stephane-caron/pink, ``pink/tasks/frame_task.py``) written as
an affine term over joint velocities ``v`` and compiled with the rest of the stack — the SE(3)
error and its Jacobian are computed *inside* the compiled CasADi function from model-quantity
parameters, so a tick runs no per-task numpy.

Formulation (full pose). With ``T_b`` the frame's world pose (parameter ``"pose[<frame>]"``),
``T_t`` the target (parameter ``"<name>.target"``), ``J`` the frame Jacobian with rows
``[linear; angular]`` in world-aligned axes (parameter ``"J[<frame>]"``, pinocchio's
``LOCAL_WORLD_ALIGNED``) and ``R_b`` the frame's rotation::

    e      = log6(T_b⁻¹ T_t)                        body-frame error twist [m, rad]
    J_b    = blockdiag(R_bᵀ, R_bᵀ) J                 body (LOCAL) Jacobian
    J_e    = Jlog6(T_t⁻¹ T_b) J_b                   so that  de/dt = −J_e v
    cost   = 1/2 Σ_i w_i (J_e v − gain · e / dt)_i²

Pink minimises ``1/2 ||W (J_p Δq + gain · e)||² + damping/2 ||Δq||²`` over ``Δq = v · dt`` with
``J_p = −J_e`` and ``W = diag(cost)``; dividing by ``dt²`` gives the cost above with
``w = cost²`` and a stack damping ``ρ² = damping``: the same minimiser, tick for tick.
Per-row weights act on the body-frame rows ``[linear; angular]``, as pink's anisotropic costs do.

Position only (``position_only=True``): ``e = p_t − p_b`` in world axes and ``J_e = J[:3]``,
so the cost is ``1/2 Σ w_i (J_lin v − gain · e / dt)_i²``. This is *not* pink's FrameTask with
a zero orientation cost (the linear part of the SE(3) log couples position and rotation); it is
the usual point-position task. The target stays a ``(4, 4)`` pose; only its translation is used.

The logarithms and their Jacobians (``so3_log``, ``so3_jlog``, ``se3_log``, ``se3_jlog``,
``pose_error``, ``pose_error_world_jacobian``) live in :mod:`wbc.lie` (pinocchio's conventions,
exact at the identity and up to a half-turn); this module re-exports them under their old names
(``wbc.tasks.frame.so3_log`` ...).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import check_frame, check_robot, checked_name, checked_number, checked_weights
from wbc.errors import InvalidValueError, ShapeError
from wbc.lie import pose_error as pose_error
from wbc.lie import pose_error_world_jacobian
from wbc.lie import se3_jlog as se3_jlog
from wbc.lie import se3_log as se3_log
from wbc.lie import so3_jlog as so3_jlog
from wbc.lie import so3_log as so3_log
from wbc.terms import Cost, Task


# ---------------------------------------------------------------------------- the task
def weight_root(weight) -> ca.SX | ca.DM | float:
    """``√w`` of a weight checked by :func:`wbc.checks.checked_weights`, for CasADi products."""
    if isinstance(weight, ca.SX):
        return ca.sqrt(weight)
    return ca.DM(np.sqrt(weight)) if np.ndim(weight) else float(np.sqrt(weight))


def lm_damping_terms(name: str, v: ca.SX, weight, gain, lm_damping: float,
                     error) -> list[Cost]:
    """Pink's (and mink's) Levenberg–Marquardt term ``μ/2 ||v||²`` with ``μ = lm_damping ·
    Σ w_i (gain · e_i)²`` [same units as the task's cost] — none when ``lm_damping`` is 0."""
    if lm_damping <= 0:
        return []
    mu = lm_damping * ca.sumsqr(weight_root(weight) * gain * error)
    return [Cost(v, 0.0, mu, f"{name} (lm damping)")]


def tracking_terms(name: str, rate: ca.SX, error: ca.SX, v: ca.SX, dt: ca.SX, gain: float,
                   weight, lm_damping: float) -> list[Cost]:
    """The velocity-level tracking cost ``1/2 Σ w_i (rate − gain · e / dt)_i²`` of an error
    ``e`` whose rate the command makes ``rate = J_e v`` (``de/dt = −J_e v``), reporting as its
    residual the error the command leaves, to first order (``e − dt/gain · J_e v``: 0 when the
    row holds, ``e`` when nothing moves towards the target), plus :func:`lm_damping_terms`."""
    residual = error - dt / gain * rate if gain > 0 else None
    return [Cost(rate, gain / dt * error, weight, name, residual),
            *lm_damping_terms(name, v, weight, gain, lm_damping, error)]


def velocity_block(stack, block: str | None, nv: int, what: str) -> ca.SX:
    """The symbol of the joint velocities in the stack's decision vector (checked: ``nv``
    entries)."""
    xs = stack.variables.symbol[stack.variables.slice(block)]
    if xs.shape[0] != nv:
        where = f"block {block!r}" if block else "the decision vector"
        raise ShapeError(f"{what}: the robot has nv = {nv} velocity coordinates but {where} "
                         f"has {xs.shape[0]} entries; pass block=<joint-velocity block>")
    return xs


class FrameTask(Task):
    """Pose (or position) tracking of a robot frame, at the velocity level (see module doc).

    Args:
        robot: the robot (for ``nv`` and the frame name check); see :class:`wbc.Controller`.
        frame: frame name as the robot knows it (e.g. ``"ee"``).
        gain: task gain ``α >= 0`` [-]: the cost asks for ``α · e / dt`` per tick (1 = dead-beat).
        weight: ``w`` (scalar or one per row: 6 for a pose, 3 for a position; ``>= 0``, or a
            CasADi SX expression of the stack's parameters, see
            :func:`wbc.checks.checked_weights`); equals pink's ``cost²``.
        position_only: track the position only (3 rows, world axes).
        lm_damping: pink's Levenberg–Marquardt damping: adds ``μ/2 ||v||²`` with
            ``μ = lm_damping · Σ w_i (α e_i)²`` (0: no rows added).
        name: task name (default: the stack names it); the target is ``"<name>.target"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"pose[<frame>]"`` (4, 4), ``"J[<frame>]"`` (6, nv), ``"dt"``
    (1,), and ``"<name>.target"`` (4, 4), the target's world pose (no default: solving before
    it is set raises, as pink's ``TargetNotSet``).
    """

    def __init__(self, robot, frame: str, gain: float = 1.0, weight=1.0,
                 position_only: bool = False, lm_damping: float = 0.0,
                 name: str | None = None, block: str | None = None) -> None:
        self.name = checked_name(name, "name of a FrameTask")
        self.frame = checked_name(frame, f"frame of FrameTask {name!r}", optional=False)
        what = f"FrameTask {name or frame!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        check_frame(robot, frame, what)
        self.gain = checked_number(gain, f"gain of {what}")
        if not isinstance(position_only, (bool, np.bool_)):
            raise InvalidValueError(f"position_only of {what} must be True or False, got "
                                    f"{position_only!r}")
        self.position_only = bool(position_only)
        self.rows = 3 if self.position_only else 6
        self.weight = checked_weights(weight, self.rows, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.error: ca.SX | None = None  # symbolic error and Jacobian, set by terms()
        self.jacobian: ca.SX | None = None

    def terms(self, stack):
        what = f"FrameTask {self.name!r}"
        v = velocity_block(stack, self.block, self.nv, what)
        pose = stack.quantity(f"pose[{self.frame}]", (4, 4))
        J = stack.quantity(f"J[{self.frame}]", (6, self.nv))
        dt = stack.quantity("dt", 1)
        target = stack.parameter(f"{self.name}.target", (4, 4))  # no default: must be set
        if self.position_only:
            e = target[:3, 3] - pose[:3, 3]
            J_e = J[:3, :]
        else:
            e, J_e = pose_error_world_jacobian(pose, target, J)
        self.error, self.jacobian = e, J_e
        # the reported residual is the pose error the command leaves, in m and rad
        return tracking_terms(self.name, J_e @ v, e, v, dt, self.gain, self.weight,
                              self.lm_damping)

    def __repr__(self) -> str:
        return (f"FrameTask(frame={self.frame!r}, gain={self.gain}, weight={self.weight}, "
                f"position_only={self.position_only}, name={self.name!r})")

