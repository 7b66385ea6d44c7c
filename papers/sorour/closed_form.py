"""Closed forms of Sorour, Cherubini & Fraisse's task-sharing redundancy resolution.

* :func:`task_sharing_factor` — eq. 11: ψ from the end-tip position error.
* :func:`sharing_mobility` — the mobility ``M = diag((1 − ψ) I_base, ψ I_arm)`` of eq. 10 read
  with the erratum (docs/DESIGN.md, section "Sorour et al."): as printed, eq. 10 *weights* the
  base by ``1 − ψ``, so that ``W⁻¹`` moves only the base at ψ = 1, the opposite of the text and
  Fig. 2. We read ``diag((1 − ψ) I, ψ I)`` as the mobility ``W⁻¹``: ψ = 1 moves the arm only,
  ψ = 0 the base only, and both extremes are singular (a zero mobility pins those joints).
* :func:`task_sharing_velocity` — eq. 9: ``M Jᵀ(J M Jᵀ + ρ²I)⁻¹ v + λ(I − J⁺J) z``.
* :func:`arm_compensation` — eq. 14's correction ``J_arm^# J_base (q̇_b,ref − q̇_b,feasible)``
  (``J_arm^#`` damped by μ; the pseudo-inverse for μ = 0).

They are the oracles of the QP forms in :mod:`wbc.papers.sorour.task_sharing` and usable as
controllers.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_2d, checked_scalar, checked_vector
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError
from wbc.solvers.linalg import (
    damped_pinv,
    nullspace_projector,
    weighted_damped_pinv,
)

__all__ = ["arm_compensation", "sharing_mobility", "task_sharing_factor",
           "task_sharing_velocity"]


def task_sharing_factor(error_norm: float, r_fm: float = 0.25, r_mm: float = 0.9) -> float:
    """Sorour eq. 11: the task-sharing factor ψ from the end-tip position error.

    Args:
        error_norm: ``||e_pos||₂`` [m], the norm of the position part of the pose error.
        r_fm: fine-manipulation range [m] (Table I: 0.25).
        r_mm: mobile-manipulation range [m] (Table I: 0.9), ``> r_fm``.

    Returns:
        1.0 (fine manipulation, arm only) if ``error_norm <= r_fm``; 0.5 (mobile manipulation)
        if ``r_fm < error_norm <= r_mm``; 0.0 (gross motion, base only) beyond ``r_mm``.
    """
    e = checked_scalar(error_norm, "error_norm")
    r_fm = checked_scalar(r_fm, "r_fm")
    r_mm = checked_scalar(r_mm, "r_mm")
    if not r_fm < r_mm:
        raise InvalidValueError(f"r_fm must be < r_mm, got r_fm = {r_fm}, r_mm = {r_mm}")
    if e <= r_fm:
        return 1.0
    return 0.5 if e <= r_mm else 0.0


def sharing_mobility(psi: float, n_base: int, n: int) -> np.ndarray:
    """Diagonal ``(n,)`` of ``M = diag((1 − ψ) I_{n_base}, ψ I_{n − n_base})`` (eq. 10 read
    with the erratum, see the module docstring).

    Raises:
        InvalidValueError: ψ outside ``[0, 1]`` or ``n_base`` outside ``[0, n]``.
    """
    psi = float(psi)
    if not np.isfinite(psi):
        raise NonFiniteError(f"psi must be finite, got {psi}")
    if not 0.0 <= psi <= 1.0:
        raise InvalidValueError(f"psi must lie in [0, 1], got {psi}")
    if not 0 <= int(n_base) <= n:
        raise InvalidValueError(f"n_base must lie in [0, {n}], got {n_base}")
    return np.r_[np.full(int(n_base), 1.0 - psi), np.full(n - int(n_base), psi)]


def task_sharing_velocity(J, v, psi: float, rho: float, n_base: int, lam: float = 0.0,
                          z=None) -> np.ndarray:
    """Sorour eq. 9 with the corrected ψ: ``M Jᵀ(J M Jᵀ + ρ²I)⁻¹ v + λ(I − J⁺J) z``.

    Args:
        J: ``(m, n)`` task Jacobian (Sorour's ``J_mm``), the first ``n_base`` columns the
            base's.
        v: ``(m,)`` task velocity (``ṗ_ref`` of eq. 12).
        psi: task-sharing factor in ``[0, 1]`` (1: arm only; 0: base only).
        rho: damping ``ρ >= 0``.
        n_base: number of base columns of ``J``.
        lam: gain ``λ >= 0`` of the null-space term (``λ_dex``).
        z: ``(n,)`` null-space velocity (eq. 13's ``z_dex``); ``None``: no null-space term.

    Returns:
        ``q̇`` of shape ``(n,)``. The projector ``I − J⁺J`` is undamped (docs/DESIGN.md,
        math note 2).
    """
    J = checked_2d(J, "J")
    m, n = J.shape
    v = checked_vector(v, m, "v", broadcast=False)
    mobility = sharing_mobility(psi, n_base, n)
    qd = weighted_damped_pinv(J, rho, mobility) @ v
    if z is not None:
        lam = checked_scalar(lam, "lam")
        qd = qd + lam * (nullspace_projector(J) @ checked_vector(z, n, "z", broadcast=False))
    return qd


def arm_compensation(J_arm, J_base, qd_base_ref, qd_base_feasible,
                     damping: float = 0.0) -> np.ndarray:
    """Sorour eq. 14's correction of the arm's joint velocities,
    ``J_arm^# J_base (q̇_b,ref − q̇_b,feasible)``: the arm makes up for the end-tip velocity the
    base will miss when it moves at its feasible velocity instead of the reference.

    Args:
        J_arm: ``(m, n_arm)`` arm columns of the task Jacobian.
        J_base: ``(m, n_base)`` base columns of the task Jacobian (``M_RPY H J_b``).
        qd_base_ref: ``(n_base,)`` base velocity the redundancy resolution asked for.
        qd_base_feasible: ``(n_base,)`` base velocity the base's controller will produce.
        damping: μ >= 0 of ``J_arm^# = J_armᵀ (J_arm J_armᵀ + μ² I)⁻¹``.

    Returns:
        ``Δq̇_arm`` of shape ``(n_arm,)``, to add to the arm's reference (μ = 0: the Moore–Penrose
        pseudo-inverse, the least-squares, minimum-norm correction when ``J_arm`` is
        rank-deficient).
    """
    J_arm = checked_2d(J_arm, "J_arm")
    J_base = checked_2d(J_base, "J_base")
    if J_base.shape[0] != J_arm.shape[0]:
        raise ShapeError(f"J_arm and J_base must have the same rows, got {J_arm.shape} and "
                         f"{J_base.shape}")
    nb = J_base.shape[1]
    missed = (checked_vector(qd_base_ref, nb, "qd_base_ref", broadcast=False)
              - checked_vector(qd_base_feasible, nb, "qd_base_feasible", broadcast=False))
    damping = checked_scalar(damping, "damping")
    if damping < 0.0:
        raise InvalidValueError(f"damping must be >= 0, got {damping}")
    return damped_pinv(J_arm, damping) @ (J_base @ missed)
