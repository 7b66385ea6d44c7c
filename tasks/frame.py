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

The logarithms and their Jacobians (:func:`so3_log`, :func:`so3_jlog`, :func:`se3_log`,
:func:`se3_jlog`) follow pinocchio's conventions (``log6`` = ``[v; ω]``, ``Jlog`` = right
Jacobian of the log) and switch to Taylor expansions near zero with ``casadi.if_else``, so
they are exact to machine precision at and around the identity; near a half-turn the rotation
axis is read from the symmetric part of ``R`` (largest component first, so that the relative
signs of the components stay exact up to θ = π).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import check_robot, checked_name, checked_number, checked_weights
from wbc.controller import check_frame
from wbc.errors import InvalidValueError, ShapeError
from wbc.terms import Cost, Task

# Below these angles [rad] the closed forms are replaced by their Taylor series.
_SMALL = 1e-4  # for θ / sin θ and θ/2 · cot(θ/2): no cancellation, only 0/0 at θ = 0
_SMALL_CANCEL = 5e-2  # for β, β'/θ, whose closed forms cancel large terms
_NEAR_PI = np.pi - 1e-2  # axis read from the diagonal of R above this angle


# ---------------------------------------------------------------------------- Lie helpers
def _skew(w) -> ca.SX:
    return ca.vertcat(ca.horzcat(0, -w[2], w[1]),
                      ca.horzcat(w[2], 0, -w[0]),
                      ca.horzcat(-w[1], w[0], 0))


def _angle(R) -> tuple[ca.SX, ca.SX]:
    """``(θ, vee(R − Rᵀ))``: the rotation angle in ``[0, π]`` by ``atan2`` (accurate at every
    angle, unlike ``acos`` near 0) and the axis vector ``2 sin θ · u``."""
    axis = ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    cos_t = (R[0, 0] + R[1, 1] + R[2, 2] - 1) / 2
    sin_t = ca.sqrt(ca.sumsqr(axis)) / 2
    return ca.atan2(sin_t, cos_t), axis


def so3_log(R) -> ca.SX:
    """``log3(R)``: the rotation vector ``θ u`` of a ``(3, 3)`` rotation (SX)."""
    return _so3_log(R)[1]


def _so3_log(R) -> tuple[ca.SX, ca.SX]:
    R = ca.SX(R)
    theta, axis = _angle(R)
    t2 = theta * theta
    # generic: θ / (2 sin θ) · vee(R − Rᵀ), with 2 sin θ = |vee|
    safe = ca.if_else(theta < _SMALL, 1.0, theta)
    factor = ca.if_else(theta < _SMALL, 0.5 + t2 / 12 + 7 * t2 * t2 / 720,
                        safe / (2 * ca.sin(safe)))
    generic = factor * axis
    # near π: R + Rᵀ = 2 cos θ I + 2 (1 − cos θ) u uᵀ. The largest |u_k| comes from the
    # diagonal, its sign from the skew part (2 sin θ u_k, reliable unless θ = π exactly, where
    # both signs are valid), the other components from the symmetric off-diagonal terms, so
    # that their relative signs are exact.
    cos_t = ca.cos(theta)
    one_minus_cos = 1 - cos_t
    diag = [(R[i, i] - cos_t) / one_minus_cos for i in range(3)]  # u_i²
    candidates = []
    for k in range(3):
        uk = ca.if_else(axis[k] >= 0, 1.0, -1.0) * ca.sqrt(ca.fmax(diag[k], 1e-300))
        u = [(R[i, k] + R[k, i]) / (2 * one_minus_cos * uk) if i != k else uk
             for i in range(3)]
        candidates.append(ca.vertcat(*u))
    d0, d1, d2 = diag
    u = ca.if_else(ca.logic_and(d0 >= d1, d0 >= d2), candidates[0],
                   ca.if_else(d1 >= d2, candidates[1], candidates[2]))
    near_pi = theta * u / ca.norm_2(u)
    w = ca.if_else(theta > _NEAR_PI, near_pi, generic)
    return theta, w


def _alpha_beta(theta) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``α = θ/2 · cot(θ/2)``, ``β = 1/θ² − cot(θ/2)/(2θ)`` and ``β'(θ)/θ``, with their Taylor
    series near 0 (``1 − cos θ`` is written ``2 sin²(θ/2)`` to avoid cancellation)."""
    t2 = theta * theta
    safe = ca.if_else(theta < _SMALL, 1.0, theta)
    alpha = ca.if_else(theta < _SMALL, 1 - t2 / 12 - t2 * t2 / 720,
                       safe / 2 / ca.tan(safe / 2))
    safe_c = ca.if_else(theta < _SMALL_CANCEL, 1.0, theta)
    half_cot = 1 / ca.tan(safe_c / 2)  # = sin θ / (1 − cos θ)
    one_minus_cos = 2 * ca.sin(safe_c / 2) ** 2
    beta = ca.if_else(theta < _SMALL_CANCEL,
                      1 / 12 + t2 / 720 + t2 * t2 / 30240 + t2 ** 3 / 1209600,
                      1 / safe_c ** 2 - half_cot / (2 * safe_c))
    beta_dot = ca.if_else(theta < _SMALL_CANCEL,
                          1 / 360 + t2 / 7560 + t2 * t2 / 201600,
                          -2 / safe_c ** 4 + (1 + ca.sin(safe_c) / safe_c)
                          / (2 * safe_c ** 2 * one_minus_cos))
    return alpha, beta, beta_dot


def so3_jlog(R) -> ca.SX:
    """``Jlog3(R)``: the right Jacobian of ``log3``, ``d log3(R exp(δ)) / dδ`` at 0 (SX 3×3)."""
    theta, w = _so3_log(R)
    alpha, beta, _ = _alpha_beta(theta)
    return _jlog3(w, alpha, beta)


def _jlog3(w, alpha, beta) -> ca.SX:
    return alpha * ca.SX.eye(3) + beta * (w @ w.T) + 0.5 * _skew(w)


def se3_log(T) -> ca.SX:
    """``log6(T)`` of a ``(4, 4)`` homogeneous transform: the twist ``[v; ω]`` (SX 6×1)."""
    T = ca.SX(T)
    R, p = T[:3, :3], T[:3, 3]
    theta, w = _so3_log(R)
    alpha, beta, _ = _alpha_beta(theta)
    return ca.vertcat(_vinv(w, p, alpha, beta), w)


def _vinv(w, p, alpha, beta) -> ca.SX:
    """``V(ω)⁻¹ p`` (the translation part of ``log6``) with ``V⁻¹ = α I + β ω ωᵀ − ½ [ω]×``."""
    return alpha * p + beta * w * (w.T @ p) - 0.5 * ca.cross(w, p)


def se3_jlog(T) -> ca.SX:
    """``Jlog6(T)``: the right Jacobian of ``log6``, ``d log6(T exp(δ)) / dδ`` at 0 (SX 6×6),
    with twists ordered ``[linear; angular]`` as in pinocchio."""
    T = ca.SX(T)
    R, p = T[:3, :3], T[:3, 3]
    theta, w = _so3_log(R)
    return _jlog6(theta, w, p)


def _jlog6(theta, w, p) -> ca.SX:
    A, CA = _jlog6_blocks(theta, w, p)
    return ca.vertcat(ca.horzcat(A, CA), ca.horzcat(ca.SX.zeros(3, 3), A))


def _jlog6_blocks(theta, w, p) -> tuple[ca.SX, ca.SX]:
    """The non-zero blocks of ``Jlog6 = [[A, C A], [0, A]]`` (pinocchio's closed form)."""
    alpha, beta, beta_dot = _alpha_beta(theta)
    A = _jlog3(w, alpha, beta)
    wtp = w.T @ p
    tmp = (beta_dot * wtp) * w - (theta * theta * beta_dot + 2 * beta) * p
    C = tmp @ w.T + beta * (w @ p.T) + wtp * beta * ca.SX.eye(3) + _skew(0.5 * p)
    return A, C @ A


def pose_error(pose, target) -> tuple[ca.SX, ca.SX]:
    """Pink's frame error and its log Jacobian, from the frame pose ``T_b`` and target ``T_t``.

    Returns:
        ``(e, Jlog)`` with ``e = log6(T_b⁻¹ T_t)`` (a body twist [m, rad]) and
        ``Jlog = Jlog6(T_t⁻¹ T_b)``, such that ``de/dt = −Jlog · ν_b`` for the body twist
        ``ν_b`` of the frame.
    """
    e, theta, w_tb, p_tb, _ = _pose_error(pose, target)
    return e, _jlog6(theta, w_tb, p_tb)


def _pose_error(pose, target):
    pose, target = ca.SX(pose), ca.SX(target)
    Rb, pb = pose[:3, :3], pose[:3, 3]
    Rt, pt = target[:3, :3], target[:3, 3]
    R_bt = Rb.T @ Rt
    p_bt = Rb.T @ (pt - pb)
    theta, w_bt = _so3_log(R_bt)
    alpha, beta, _ = _alpha_beta(theta)
    e = ca.vertcat(_vinv(w_bt, p_bt, alpha, beta), w_bt)
    # T_tb = T_bt⁻¹ has the opposite rotation vector and translation −R_btᵀ p_bt
    return e, theta, -w_bt, -(R_bt.T @ p_bt), Rb


def pose_error_world_jacobian(pose, target, J) -> tuple[ca.SX, ca.SX]:
    """``(e, J_e)``: pink's frame error and ``J_e = Jlog6(T_t⁻¹ T_b) · blockdiag(R_bᵀ, R_bᵀ) · J``
    for a world-aligned Jacobian ``J`` (6 × n), so that ``de/dt = −J_e v``.

    Multiplied out block-wise (``Jlog6 = [[A, C A], [0, A]]``): ``M = A R_bᵀ`` and ``C M`` are
    3 × 3, then ``J_e = [M J_lin + C M J_ang; M J_ang]`` — fewer operations than the 6 × 6
    products, which matters for the compiled function's evaluation time.
    """
    e, theta, w_tb, p_tb, Rb = _pose_error(pose, target)
    A, CA = _jlog6_blocks(theta, w_tb, p_tb)
    M = A @ Rb.T
    CM = CA @ Rb.T
    J = ca.SX(J)
    J_lin, J_ang = J[:3, :], J[3:, :]
    return e, ca.vertcat(M @ J_lin + CM @ J_ang, M @ J_ang)


# ---------------------------------------------------------------------------- the task
def weight_root(weight) -> ca.SX | ca.DM | float:
    """``√w`` of a weight checked by :func:`wbc.checks.checked_weights`, for CasADi products."""
    if isinstance(weight, ca.SX):
        return ca.sqrt(weight)
    return ca.DM(np.sqrt(weight)) if np.ndim(weight) else float(np.sqrt(weight))


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
        # reported residual: the error the command leaves, to first order, in m and rad
        # (0 when the row holds; e itself when nothing moves towards the target)
        residual = e - dt / self.gain * (J_e @ v) if self.gain > 0 else None
        terms = [Cost(J_e @ v, self.gain / dt * e, self.weight, self.name, residual)]
        if self.lm_damping > 0:
            mu = self.lm_damping * ca.sumsqr(weight_root(self.weight) * self.gain * e)
            terms.append(Cost(v, 0.0, mu, f"{self.name} (lm damping)"))
        return terms

    def __repr__(self) -> str:
        return (f"FrameTask(frame={self.frame!r}, gain={self.gain}, weight={self.weight}, "
                f"position_only={self.position_only}, name={self.name!r})")

