"""SO(3) and SE(3) logarithms and their Jacobians, symbolic (CasADi SX).

Pure math on ``(3, 3)`` rotations and ``(4, 4)`` homogeneous transforms given as SX (or
anything ``casadi.SX`` accepts). It imports casadi and numpy only — nothing of the core, tasks,
robots or solvers — so any module can build on it: :class:`wbc.tasks.FrameTask`, the Xing
study's orientation error (``tests/test_architecture.py`` keeps it so).

* :func:`so3_log`, :func:`so3_jlog` — ``log3(R)`` (the rotation vector ``θ u``) and its right
  Jacobian ``d log3(R exp(δ)) / dδ`` at 0;
* :func:`se3_log`, :func:`se3_jlog` — ``log6(T)`` (the twist ``[v; ω]``) and its right Jacobian,
  twists ordered ``[linear; angular]``;
* :func:`pose_error`, :func:`pose_error_world_jacobian` — pink's frame error
  ``e = log6(T_b⁻¹ T_t)`` with ``Jlog6(T_t⁻¹ T_b)``, the latter multiplied out with a
  world-aligned frame Jacobian (the rows of :class:`wbc.tasks.FrameTask`).

The conventions are pinocchio's (``log6`` = ``[v; ω]``, ``Jlog`` = right Jacobian of the log).
Near zero the closed forms switch to Taylor expansions with ``casadi.if_else``, so they are exact
to machine precision at and around the identity; near a half-turn the rotation axis is read from
the symmetric part of ``R`` (largest component first, so that the relative signs of the
components stay exact up to θ = π).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["pose_error", "pose_error_world_jacobian", "se3_jlog", "se3_log", "so3_jlog",
           "so3_log"]

# Below these angles [rad] the closed forms are replaced by their Taylor series.
_SMALL = 1e-4  # for θ / sin θ and θ/2 · cot(θ/2): no cancellation, only 0/0 at θ = 0
_SMALL_CANCEL = 5e-2  # for β, β'/θ, whose closed forms cancel large terms
_NEAR_PI = np.pi - 1e-2  # axis read from the diagonal of R above this angle


# ---------------------------------------------------------------------------- helpers
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
