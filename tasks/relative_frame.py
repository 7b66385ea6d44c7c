"""`RelativeFrameTask`: track the pose of a robot frame relative to another robot frame.

The pose of frame ``f`` in a *root* frame ``r`` of the same robot — both may move — tracks a
target ``T_t`` given in the root frame (parameter ``"<name>.target"``, ``(4, 4)``), at the
velocity level. With the world poses ``T_f``, ``T_r`` (parameters ``"pose[<frame>]"``,
``"pose[<root>]"``) and their world-aligned Jacobians ``J_f``, ``J_r`` (``"J[<frame>]"``,
``"J[<root>]"``, rows ``[linear; angular]``)::

    P     = T_r⁻¹ T_f = (R, p)                          the frame's pose in the root [m]
    J_rel = blockdiag(R_rᵀ, R_rᵀ) [J_f,lin − J_r,lin + [p_f − p_r]× J_r,ang ; J_f,ang − J_r,ang]
    e, J_e = the frame error of P towards T_t, as FrameTask's with pose P and Jacobian J_rel
    cost  = 1/2 Σ_i w_i (J_e v − gain · e / dt)_i²

``J_rel v`` is the velocity of ``P``: its origin's velocity ``d p / dt`` and its angular
velocity, both in the root's axes (the relative velocity of the two origins, less the part the
root's rotation sweeps, ``ω_r × (p_f − p_r)``). Written so, the error and its Jacobian are
:func:`wbc.lie.pose_error_world_jacobian` of ``(P, T_t, J_rel)`` — the frame task's own math,
with the root in the place of the world: ``e = log6(P⁻¹ T_t)`` is a twist in the frame's axes
[m, rad] and ``J_e = Jlog6(T_t⁻¹ P) · blockdiag(Rᵀ, Rᵀ) · J_rel``, so ``de/dt = −J_e v``.

Peers. Pink's and mink's ``RelativeFrameTask(frame, root, position_cost, orientation_cost,
gain, lm_damping)`` have the error ``e_p = log6(T_t⁻¹ P) = −e`` and the Jacobian
``Jlog6(T_t⁻¹ P) (ᶠJ_f − Ad(T_fr) ʳJ_r)`` (body Jacobians) — the same ``J_e`` — and minimise
``1/2 ‖W (J_e Δq + gain · e_p)‖²`` (``W = diag(cost)``) over ``Δq = v · dt``; divided by
``dt²`` that is the cost above with ``w = cost²`` (per row: position, then orientation, in the
frame's axes). ``lm_damping`` carries over as in :class:`~wbc.tasks.frame.FrameTask`.
"""

from __future__ import annotations

import casadi as ca

from wbc.checks import check_frame, check_robot, checked_name, checked_number, checked_weights
from wbc.errors import InvalidValueError
from wbc.lie import pose_error_world_jacobian
from wbc.terms import Task

from .frame import tracking_terms, velocity_block


def relative_pose_and_jacobian(pose_f, pose_r, J_f, J_r) -> tuple[ca.SX, ca.SX]:
    """``(P, J_rel)``: the pose ``T_r⁻¹ T_f`` (4 × 4) of frame ``f`` in frame ``r`` and the
    Jacobian (6 × n) of its velocity — origin velocity [m/s] and angular velocity [rad/s] in the
    root's axes — from the world poses and world-aligned Jacobians of both (see the module
    docstring)."""
    pose_f, pose_r, J_f, J_r = (ca.SX(x) for x in (pose_f, pose_r, J_f, J_r))
    R_r, p_r = pose_r[:3, :3], pose_r[:3, 3]
    R_f, p_f = pose_f[:3, :3], pose_f[:3, 3]
    d = p_f - p_r
    P = ca.SX.eye(4)
    P[:3, :3] = R_r.T @ R_f
    P[:3, 3] = R_r.T @ d
    # −ω_r × d = [d]× ω_r: what the root's rotation sweeps is not relative motion
    d_cross = ca.vertcat(ca.horzcat(0, -d[2], d[1]), ca.horzcat(d[2], 0, -d[0]),
                         ca.horzcat(-d[1], d[0], 0))
    lin = J_f[:3, :] - J_r[:3, :] + d_cross @ J_r[3:, :]
    ang = J_f[3:, :] - J_r[3:, :]
    return P, ca.vertcat(R_r.T @ lin, R_r.T @ ang)


class RelativeFrameTask(Task):
    """Pose of ``frame`` in ``root`` tracking a target (see the module docstring).

    Args:
        robot: the robot (for ``nv`` and the frame name checks); see :class:`wbc.Controller`.
        frame: the regulated frame, as the robot knows it (e.g. ``"ee"``).
        root: the frame the pose is taken in (another frame of the robot).
        gain: task gain ``α >= 0`` [-]: the cost asks for ``α · e / dt`` per tick (1 =
            dead-beat).
        weight: ``w``, a scalar or 6 per-row weights (position, then orientation, in the
            frame's axes; ``>= 0``), or a CasADi SX expression of the stack's parameters;
            equals pink's and mink's ``cost²``.
        lm_damping: pink's Levenberg–Marquardt damping: adds ``μ/2 ‖v‖²`` with
            ``μ = lm_damping · Σ w_i (α e_i)²`` (0: no rows added).
        name: task name (default: the stack names it); the target is ``"<name>.target"``.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"pose[<frame>]"``, ``"pose[<root>]"`` (4, 4), ``"J[<frame>]"``,
    ``"J[<root>]"`` (6, nv), ``"dt"`` (1,), and ``"<name>.target"`` (4, 4), the target pose of
    ``frame`` in ``root`` (no default: solving before it is set raises, as the peers'
    ``TargetNotSet``).
    """

    def __init__(self, robot, frame: str, root: str, gain: float = 1.0, weight=1.0,
                 lm_damping: float = 0.0, name: str | None = None,
                 block: str | None = None) -> None:
        self.name = checked_name(name, "name of a RelativeFrameTask")
        what = f"RelativeFrameTask {name or frame!r}"
        self.frame = checked_name(frame, f"frame of {what}", optional=False)
        self.root = checked_name(root, f"root of {what}", optional=False)
        self.nv = check_robot(robot, f"robot of {what}")[1]
        check_frame(robot, frame, what)
        check_frame(robot, root, what)
        if frame == root:
            raise InvalidValueError(f"{what}: frame and root are the same frame {frame!r}")
        self.gain = checked_number(gain, f"gain of {what}")
        self.weight = checked_weights(weight, 6, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.error: ca.SX | None = None  # symbolic error and Jacobian, set by terms()
        self.jacobian: ca.SX | None = None

    def terms(self, stack):
        what = f"RelativeFrameTask {self.name!r}"
        v = velocity_block(stack, self.block, self.nv, what)
        pose_f = stack.quantity(f"pose[{self.frame}]", (4, 4))
        pose_r = stack.quantity(f"pose[{self.root}]", (4, 4))
        J_f = stack.quantity(f"J[{self.frame}]", (6, self.nv))
        J_r = stack.quantity(f"J[{self.root}]", (6, self.nv))
        dt = stack.quantity("dt", 1)
        target = stack.parameter(f"{self.name}.target", (4, 4))  # no default: must be set
        P, J_rel = relative_pose_and_jacobian(pose_f, pose_r, J_f, J_r)
        e, J_e = pose_error_world_jacobian(P, target, J_rel)
        self.error, self.jacobian = e, J_e
        # reported residual, as FrameTask's: the relative pose error the command leaves [m, rad]
        return tracking_terms(self.name, J_e @ v, e, v, dt, self.gain, self.weight,
                              self.lm_damping)

    def __repr__(self) -> str:
        return (f"RelativeFrameTask(frame={self.frame!r}, root={self.root!r}, gain={self.gain}, "
                f"weight={self.weight}, name={self.name!r})")
