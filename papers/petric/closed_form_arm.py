r"""Closed forms of Petrič & Žlajpah's arm controller (eqs. 22–26): damped least squares plus a
null-space posture velocity.

Eq. 22 commands the arm joints with

    q̇ = J# (K_p e + ẋ_d) + N q̇_n,        J# = Jᵀ (J Jᵀ + λ I)⁻¹        (eq. 25)

where ``λ`` enters as ``J Jᵀ + λ I`` — the damping ``ρ`` of :func:`damped_pinv` is ``√λ``
(``ρ² = λ = 0.05`` in the paper). Eq. 26 prints the projector ``N = I − J# J`` with the *damped*
inverse. That matrix is not a projector (``N² ≠ N``) and its range is not the null space of
``J``: ``J (I − J# J) = λ (J Jᵀ + λ I)⁻¹ J``, so the "secondary" velocity leaks into the primary
task. Per singular value ``σ`` of ``J`` the leak gain is ``λ σ / (σ² + λ) ≤ √λ / 2``
(0.112 for λ = 0.05, at ``σ = √λ``). Both readings are offered:

* ``projector="exact"`` — ``N = I − J⁺ J`` (docs/DESIGN.md, math note 2: never damp the
  projector). Its QP form is the two-level cascade "level 0: ``½||J x − u||² + ½ λ ||x||²``;
  level 1: ``½||x − q̇_n||²`` keeping ``J x = J x₀*``" (docs/DESIGN.md, math note 3: ``J# u``
  lies in the row space of ``J``, so the cascade adds exactly ``(I − J⁺J) q̇_n``).
* ``projector="damped"`` — eq. 26 as printed. Then eq. 22 is exactly the *single* regularised
  least-squares problem ``min ||J x − u||² + λ ||x − q̇_n||²``: since
  ``J# = (JᵀJ + λI)⁻¹ Jᵀ`` and ``I − J# J = λ (JᵀJ + λI)⁻¹``, its minimiser
  ``(JᵀJ + λI)⁻¹ (Jᵀ u + λ q̇_n)`` is eq. 22. The paper's controller is damped least squares
  whose damping pulls towards the posture velocity instead of towards zero; the primary task
  is traded against the posture, not strictly above it.

Everything is plain numpy; units follow ``J`` (joint velocities [rad/s], task velocities
[m/s]).
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_2d, checked_scalar, checked_vector
from wbc.errors import InvalidValueError
from wbc.solvers.linalg import damped_pinv, nullspace_projector

__all__ = ["PETRIC_LAMBDA", "damped_projector", "dls_arm_velocity", "projector_leak"]

PETRIC_LAMBDA = 0.05
"""λ of eq. 25 (the paper's example value, used in its experiments)."""

_PROJECTORS = ("exact", "damped")


def damped_projector(J, lam: float = PETRIC_LAMBDA) -> np.ndarray:
    """Eq. 26 as printed: ``I − J# J`` with the damped inverse ``J# = Jᵀ(JJᵀ + λI)⁻¹``,
    ``(n, n)``. Not idempotent for ``λ > 0``: see the module docstring.

    Args:
        J: ``(m, n)`` arm Jacobian.
        lam: ``λ >= 0`` of eq. 25 (``λ = 0`` gives the exact projector ``I − J⁺J``).
    """
    J = checked_2d(J, "J")
    lam = checked_scalar(lam, "lam")
    return np.eye(J.shape[1]) - damped_pinv(J, np.sqrt(lam)) @ J


def dls_arm_velocity(J, task_velocity, qd_null=None, lam: float = PETRIC_LAMBDA,
                     projector: str = "exact") -> np.ndarray:
    """Eq. 22: ``J# u + N q̇_n`` with ``J# = Jᵀ(JJᵀ + λI)⁻¹`` and ``u = K_p e + ẋ_d``.

    Args:
        J: ``(m, n)`` arm Jacobian (the paper's ``J_m``; position rows: ``m = 3``).
        task_velocity: ``(m,)`` the commanded task velocity ``u = K_p e + ẋ_d`` [m/s].
        qd_null: ``(n,)`` the secondary joint velocity ``q̇_n`` [rad/s]; ``None``: none.
        lam: ``λ >= 0`` of eq. 25 (default 0.05, the paper's).
        projector: ``"exact"`` — ``N = I − J⁺J``; ``"damped"`` — eq. 26 as printed,
            ``N = I − J#J`` (see the module docstring).

    Returns:
        ``q̇`` of shape ``(n,)``.

    Raises:
        InvalidValueError: an unknown ``projector`` or a negative ``lam``.
    """
    if projector not in _PROJECTORS:
        raise InvalidValueError(f"projector must be one of {_PROJECTORS}, got {projector!r}")
    J = checked_2d(J, "J")
    m, n = J.shape
    u = checked_vector(task_velocity, m, "task_velocity", broadcast=False)
    lam = checked_scalar(lam, "lam")
    qd = damped_pinv(J, np.sqrt(lam)) @ u
    if qd_null is None:
        return qd
    z = checked_vector(qd_null, n, "qd_null", broadcast=False)
    N = nullspace_projector(J) if projector == "exact" else damped_projector(J, lam)
    return qd + N @ z


def projector_leak(J, qd_null, lam: float = PETRIC_LAMBDA) -> np.ndarray:
    """The task velocity the paper's damped projector lets through: ``J (I − J#J) q̇_n =
    λ (JJᵀ + λI)⁻¹ J q̇_n``, ``(m,)`` [m/s] (zero for the exact projector). Its norm is at
    most ``√λ/2 · ||q̇_n||`` (module docstring).

    Args:
        J: ``(m, n)`` arm Jacobian.
        qd_null: ``(n,)`` secondary joint velocity [rad/s].
        lam: ``λ >= 0`` of eq. 25.
    """
    J = checked_2d(J, "J")
    m, n = J.shape
    z = checked_vector(qd_null, n, "qd_null", broadcast=False)
    lam = checked_scalar(lam, "lam")
    return lam * np.linalg.solve(J @ J.T + lam * np.eye(m), J @ z) if lam > 0 else np.zeros(m)
