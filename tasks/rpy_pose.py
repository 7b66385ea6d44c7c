"""`RpyPoseTask`: Sorour et al.'s pose tracking with the analytic RPY Jacobian (eqs. 5–7, 12).

Task coordinates ``p = (position [m], roll γ, pitch β, yaw α [rad])`` of a frame in the world,
``R = Rz(α) Ry(β) Rx(γ)``. The angular velocity is ``ω = Ω(p) d(γ, β, α)/dt`` with::

    Ω = [[cos α cos β, −sin α, 0],
         [sin α cos β,  cos α, 0],
         [−sin β,       0,     1]]

(the matrix the paper prints as ``Ω_RPY``; its ``M_RPY = blockdiag(I, Ω)`` must be read
``blockdiag(I, Ω⁻¹)`` to map twists to RPY rates — the paper's remark that the inverse is singular
at β = π/2 is about ``Ω``).

Decisions where the paper is ambiguous (documented here and in the study):

* Eq. 12 commands ``ṗ_ref = λ_p ᵇT_w e_p`` with ``e_p = ʷp* − ʷp`` (world RPY differences,
  wrapped to (−π, π]) rotated into the base frame, while eqs. 5–7 write the Jacobian in the
  base frame. We take the rows ``J_mm = ᵇT_w M_RPY(ʷp) J_w`` with ``J_w = [H J_b, J_a]`` in world
  axes (``"J[frame]"``): then ``J_mm q̇ = ᵇT_w dʷp/dt`` exactly, and the task ``J_mm q̇ = ṗ_ref``
  is the exact first-order loop ``dʷp/dt = λ_p e_p`` (``ᵇT_w`` is a rotation, so the damped
  least-squares solution is the same as in world axes). With ``Ω`` evaluated at the frame's
  base-frame angles instead, the loop would not be exact once the base has turned.
* The base's velocity coordinates are its body twist ``(v_x, v_y, ω)``; the base heading is
  ``q[2]`` (planar bases of :mod:`wbc.robots`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import (
    check_frame,
    check_robot,
    checked_name,
    checked_number,
    checked_weights,
)
from wbc.terms import Cost, Task

from .frame import velocity_block

__all__ = ["RpyPoseTask", "pose_error", "rpy", "rpy_jacobian"]


def rpy(R) -> np.ndarray | ca.SX:
    """``(roll, pitch, yaw)`` [rad] of a rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)``; numpy or
    CasADi (the same formula: pitch in [−π/2, π/2])."""
    lib = ca if isinstance(R, (ca.SX, ca.MX)) else np
    yaw = lib.arctan2(R[1, 0], R[0, 0])
    pitch = lib.arctan2(-R[2, 0], lib.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2))
    roll = lib.arctan2(R[2, 1], R[2, 2])
    return ca.vertcat(roll, pitch, yaw) if lib is ca else np.array([roll, pitch, yaw])


def _wrap(angle, lib):
    return lib.arctan2(lib.sin(angle), lib.cos(angle))


def pose_error(pose, target):
    """``e_p = p* − p`` (6,): position difference [m] and RPY differences wrapped to
    (−π, π] [rad], world frame. ``pose``: (4, 4) homogeneous transform; ``target``: (6,)."""
    lib = ca if isinstance(pose, (ca.SX, ca.MX)) or isinstance(target, (ca.SX, ca.MX)) else np
    angles = rpy(pose[:3, :3])
    if lib is ca:
        return ca.vertcat(target[:3] - pose[:3, 3], _wrap(target[3:] - angles, ca))
    target = np.asarray(target, dtype=float)
    return np.concatenate([target[:3] - pose[:3, 3], _wrap(target[3:] - angles, np)])


def rpy_jacobian(J_world, R, heading: float):
    """``J_mm = ᵇT_w M_RPY J_w`` (6 × nv; numpy or CasADi): rows ``ᵇT_w dp/dt`` in base axes.

    Args:
        J_world: (6, nv) frame Jacobian, rows ``[linear; angular]`` in world axes.
        R: (3, 3) frame rotation in the world.
        heading: base heading θ [rad] (``ᵇR_w = Rz(θ)ᵀ``).
    """
    lib = ca if any(isinstance(a, (ca.SX, ca.MX)) for a in (J_world, R, heading)) else np
    roll, pitch, yaw = (rpy(R)[i] for i in range(3))
    ca_, sa, cb, sb = lib.cos(yaw), lib.sin(yaw), lib.cos(pitch), lib.sin(pitch)
    # Ω⁻¹: d(γ, β, α)/dt = Ω⁻¹ ω
    rows = [[ca_ / cb, sa / cb, 0.0], [-sa, ca_, 0.0], [ca_ * sb / cb, sa * sb / cb, 1.0]]
    c, s = lib.cos(heading), lib.sin(heading)
    Rbw = [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]
    if lib is ca:
        omega_inv = ca.vertcat(*[ca.horzcat(*r) for r in rows])
        rot = ca.vertcat(*[ca.horzcat(*r) for r in Rbw])
        return ca.vertcat(rot @ J_world[:3, :], rot @ omega_inv @ J_world[3:, :])
    omega_inv, rot = np.array(rows, dtype=float), np.array(Rbw, dtype=float)
    return np.vstack([rot @ J_world[:3], rot @ omega_inv @ J_world[3:]])


def base_rotation_6(heading, lib=np):
    """``ᵇT_w = blockdiag(Rz(θ)ᵀ, Rz(θ)ᵀ)`` as a function applied to a 6-vector."""
    c, s = lib.cos(heading), lib.sin(heading)

    def apply(e):
        if lib is ca:
            return ca.vertcat(c * e[0] + s * e[1], -s * e[0] + c * e[1], e[2],
                              c * e[3] + s * e[4], -s * e[3] + c * e[4], e[5])
        return np.array([c * e[0] + s * e[1], -s * e[0] + c * e[1], e[2],
                         c * e[3] + s * e[4], -s * e[3] + c * e[4], e[5]])
    return apply


class RpyPoseTask(Task):
    """Cost ``1/2 ||J_mm q̇ − λ_p ᵇT_w e_p||²`` (Sorour eqs. 7 and 12; see the module docstring).

    Args:
        robot: a mobile manipulator of :mod:`wbc.robots` (planar base, heading ``q[2]``).
        frame: the controlled frame.
        gain: ``λ_p > 0`` [1/s] (Table I: 1.7).
        name: task name; the target is parameter ``"<name>.target"``, shape (6,):
            ``(x, y, z [m], roll, pitch, yaw [rad])`` in the world.
        block: the joint-velocity block of the decision vector (``None``: all of it).
        weight: ``w`` of the cost ``w/2 ||J_mm q̇ − λ_p ᵇT_w e_p||²`` (the paper's is 1): a
            number, one per row (6, ``[m/s]`` rows then ``[rad/s]`` rows), or a CasADi SX
            expression of the stack's parameters, set every tick (see
            :func:`wbc.checks.checked_weights`).

    After :meth:`terms` (i.e. once added to a stack) the CasADi expressions ``error`` (``e_p``),
    ``jacobian`` (``J_mm``) and ``position_error_norm`` (``||e_pos||``) are attributes, for
    the task-sharing mobility (:func:`wbc.tasks.share_task`).
    """

    def __init__(self, robot, frame: str = "ee", gain: float = 1.7, name: str | None = None,
                 block: str | None = None, weight=1.0) -> None:
        what = f"RpyPoseTask {name!r}"
        check_robot(robot, f"robot of {what}")
        checked_name(frame, f"frame of {what}", optional=False)
        check_frame(robot, frame, what)
        self.gain = checked_number(gain, f"gain of {what}", 0.0, strict=True)
        self.robot, self.frame = robot, frame
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.weight = checked_weights(weight, 6, f"weight of {what}")
        self.error = self.jacobian = self.position_error_norm = None

    def terms(self, stack):
        nv = int(self.robot.nv)
        qd = velocity_block(stack, self.block, nv, f"RpyPoseTask {self.name!r}")
        pose = stack.quantity(f"pose[{self.frame}]", (4, 4))
        J = stack.quantity(f"J[{self.frame}]", (6, nv))
        q = stack.quantity("q", int(self.robot.nq))
        target = stack.parameter(f"{self.name}.target", 6)
        self.error = pose_error(pose, target)
        self.jacobian = rpy_jacobian(J, pose[:3, :3], q[2])
        self.position_error_norm = ca.norm_2(self.error[:3])
        command = self.gain * base_rotation_6(q[2], ca)(self.error)
        return [Cost(self.jacobian @ qd, command, self.weight, self.name)]
