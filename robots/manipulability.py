"""Yoshikawa's manipulability ``det(J Jᵀ)`` of an arm and its analytic gradient.

``J`` (6 × n) is the arm's columns of a frame's geometric Jacobian (origin velocity [m/s] and
angular velocity [rad/s] per unit joint rate, world axes). The gradient with respect to the arm
joints needs ``∂J/∂q_k``, computed here in closed form from pinocchio's spatial Jacobian: with
``S_i`` the spatial twist (at the world origin) of joint ``i``, ``∂S_i/∂q_k = ad(S_k) S_i`` when
joint ``k`` is a strict ancestor of joint ``i``, and zero otherwise. The functions read a
pinocchio ``Data`` after ``computeJointJacobians`` and ``updateFramePlacements`` (one robot
``update``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = ["ancestor_mask", "arm_jacobian_derivatives", "manipulability",
           "manipulability_gradient"]


def ancestor_mask(model: pin.Model, first: int, n: int) -> np.ndarray:
    """``mask[k, i]``: the joint of velocity index ``first + k`` is a strict ancestor of the
    joint of velocity index ``first + i`` (``n`` scalar arm joints from ``first`` on)."""
    joint_of = {model.joints[j].idx_v: j for j in range(1, model.njoints)}
    arm_joints = [joint_of[first + k] for k in range(n)]
    mask = np.zeros((n, n), dtype=bool)
    for i, ji in enumerate(arm_joints):
        supports = set(model.supports[ji])
        for k, jk in enumerate(arm_joints):
            mask[k, i] = jk != ji and jk in supports
    return mask


def arm_jacobian_derivatives(model: pin.Model, data: pin.Data, frame_id: int, first: int,
                             ancestors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arm Jacobian ``J`` (6 × n, LOCAL_WORLD_ALIGNED) of a frame and ``∂J/∂q_k`` (n × 6 × n)
    [m/rad, 1/rad per rad], for the ``n`` arm joints of velocity indices ``first`` on."""
    spatial = pin.getFrameJacobian(model, data, frame_id, pin.ReferenceFrame.WORLD)[:, first:]
    point = data.oMf[frame_id].translation
    v0, w = spatial[:3].T, spatial[3:].T  # (n, 3): spatial twists at the world origin
    linear = v0 + np.cross(w, point)  # velocity of the frame's origin
    mask = ancestors[:, :, None]
    # ∂S_i/∂q_k = ad(S_k) S_i for k an ancestor of i (spatial, world origin)
    d_w = np.cross(w[:, None, :], w[None, :, :]) * mask
    d_v0 = (np.cross(w[:, None, :], v0[None, :, :]) + np.cross(v0[:, None, :], w[None, :, :])
            ) * mask
    # origin velocity column: v0_i + w_i × p, with ∂p/∂q_k = linear_k
    d_linear = d_v0 + np.cross(d_w, point) + np.cross(w[None, :, :], linear[:, None, :])
    jac = np.vstack([linear.T, w.T])
    d_jac = np.concatenate([d_linear, d_w], axis=2).transpose(0, 2, 1)
    return jac, d_jac


def manipulability(jac: np.ndarray) -> float:
    """``det(J Jᵀ)`` of an arm Jacobian ``J`` (6 × n) (units of ``J`` squared, per row)."""
    return float(np.linalg.det(jac @ jac.T))


def manipulability_gradient(jac: np.ndarray, d_jac: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``∂ det(A)/∂q_k = 2 tr(adj(A) J (∂J/∂q_k)ᵀ)`` with ``A = J Jᵀ``, written into ``out``
    (n,); the adjugate (from the eigen-decomposition of ``A``) keeps it finite at
    singularities."""
    eigenvalues, vectors = np.linalg.eigh(jac @ jac.T)
    others = np.where(np.eye(6, dtype=bool), 1.0, eigenvalues[None, :]).prod(axis=1)
    adjugate = (vectors * others) @ vectors.T
    weights = adjugate @ jac
    out[:] = 2.0 * np.einsum("ri,kri->k", weights, d_jac)
    return out
