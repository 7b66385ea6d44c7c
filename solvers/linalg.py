r"""Linear algebra shared by the closed forms of :mod:`wbc.solvers.reference`: SVD-based
pseudo-inverses and null-space projectors (plain numpy, float64 in and out; the arguments are
checked with :mod:`wbc.checks`).

* :func:`pinv` -- truncated-SVD Moore-Penrose pseudo-inverse ``J⁺``.
* :func:`damped_pinv` -- damped least squares ``Jᵀ(JJᵀ + ρ²I)⁻¹``.
* :func:`weighted_damped_pinv` -- ``M Jᵀ(J M Jᵀ + ρ²I)⁻¹`` for a PSD *mobility* ``M = W⁻¹``
  that may be singular (zero-mobility joints do not move).
* :func:`nullspace_projector` -- ``N = I − J⁺J``.

Every ``reference*`` module imports its helpers from here (and :mod:`wbc.solvers.sns`), never
from :mod:`wbc.solvers.reference`, which re-exports them: imports point one way.

Cutoffs (``tol``, ``rtol``, :data:`DEFAULT_TOL`, :data:`DERIVED_RTOL`) and the errors raised
are described in :mod:`wbc.solvers.reference`.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_2d, checked_scalar
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError

__all__ = [
    "DEFAULT_TOL",
    "DERIVED_RTOL",
    "damped_pinv",
    "nullspace_projector",
    "pinv",
    "weighted_damped_pinv",
]

DEFAULT_TOL = 1e-12
"""Default absolute singular-value cutoff (in the units of the matrix)."""

DERIVED_RTOL = 1e-10
"""Default relative cutoff for pseudo-inverses of derived matrices (hierarchy, SNS)."""

_EPS = np.finfo(np.float64).eps


# --------------------------------------------------------------------------------------------
# SVD helpers (shared so that one SVD serves rank, pinv and damped pinv)
# --------------------------------------------------------------------------------------------


def _svd(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m, n = J.shape
    if m == 0 or n == 0:
        k = min(m, n)
        return np.zeros((m, k)), np.zeros(k), np.zeros((k, n))
    return np.linalg.svd(J, full_matrices=False)


def _cutoff(smax: float, shape: tuple[int, int], tol, rtol) -> float:
    tol = DEFAULT_TOL if tol is None else float(tol)
    rtol = max(shape) * _EPS if rtol is None else float(rtol)
    if not (np.isfinite(tol) and np.isfinite(rtol)) or tol < 0 or rtol < 0:
        raise InvalidValueError(f"tol and rtol must be finite and >= 0, got tol={tol}, rtol={rtol}")
    return max(tol, rtol * smax)


def _pinv_svd(U, s, Vt, cutoff: float) -> np.ndarray:
    keep = s > cutoff
    return (Vt[keep].T / s[keep]) @ U[:, keep].T


def _damped_svd(U, s, Vt, rho: float) -> np.ndarray:
    # Filter factors σ/(σ² + ρ²), written as 1/(σ + ρ²/σ) so that neither σ² nor ρ² can
    # overflow or underflow on their own; σ = 0 gives 0 (that direction is unreachable).
    f = np.zeros_like(s)
    pos = s > 0
    f[pos] = 1.0 / (s[pos] + rho * rho / s[pos])
    return (Vt.T * f) @ U.T


# --------------------------------------------------------------------------------------------
# pseudo-inverses and projectors
# --------------------------------------------------------------------------------------------


def pinv(J, tol: float | None = None, rtol: float | None = None) -> np.ndarray:
    r"""Moore-Penrose pseudo-inverse by truncated SVD.

    With ``J = U Σ Vᵀ``, ``J⁺ = Σ_{σ_i > c} v_i u_iᵀ / σ_i`` where the cutoff is
    ``c = max(tol, rtol·σ_max)``: singular values at or below ``c`` are treated as zero.

    Args:
        J: matrix, shape ``(m, n)``.
        tol: absolute cutoff, default :data:`DEFAULT_TOL` (1e-12).
        rtol: relative cutoff, default ``max(m, n)·eps``.

    Returns:
        ``J⁺``, shape ``(n, m)``. ``x = J⁺ v`` is the minimum-norm least-squares solution of
        ``J x ≈ v``.
    """
    J = checked_2d(J, "J")
    U, s, Vt = _svd(J)
    c = _cutoff(s[0] if s.size else 0.0, J.shape, tol, rtol)
    return _pinv_svd(U, s, Vt, c)


def damped_pinv(J, rho: float, tol: float | None = None, rtol: float | None = None) -> np.ndarray:
    r"""Damped least-squares inverse ``J^# = Jᵀ(JJᵀ + ρ²I)⁻¹``.

    Computed from ``J = U Σ Vᵀ`` as ``J^# = Σ_i σ_i/(σ_i² + ρ²) v_i u_iᵀ`` (no normal equations,
    so the conditioning is that of ``J``, not of ``JJᵀ``). ``x = J^# v`` is the unique minimiser
    of ``‖J x − v‖² + ρ²‖x‖²``. With ``ρ = 0`` this is :func:`pinv` (``tol``, ``rtol`` are passed
    on; they are not used when ``ρ > 0``: the filter factors need no truncation).

    Args:
        J: matrix, shape ``(m, n)``.
        rho: damping ``ρ >= 0``, in the units of ``J``'s singular values.

    Returns:
        ``J^#``, shape ``(n, m)``.
    """
    J = checked_2d(J, "J")
    rho = checked_scalar(rho, "rho")
    if rho == 0.0:
        return pinv(J, tol=tol, rtol=rtol)
    return _damped_svd(*_svd(J), rho)


def _mobility_sqrt(mobility, n: int) -> np.ndarray:
    """Symmetric PSD square root ``M^{1/2}`` of the mobility (1-D input means a diagonal)."""
    M = np.asarray(mobility, dtype=np.float64)
    if M.ndim == 1:
        M = np.diag(M)
    if M.shape != (n, n):
        raise ShapeError(f"mobility must have shape ({n}, {n}) or ({n},), got {M.shape}")
    if not np.all(np.isfinite(M)):
        raise NonFiniteError("mobility holds NaN or inf")
    scale = float(np.max(np.abs(M))) if M.size else 0.0
    if not np.allclose(M, M.T, rtol=0.0, atol=1e-12 * max(scale, 1e-300)):
        raise InvalidValueError("mobility must be symmetric")
    d = np.diag(M)
    if np.count_nonzero(M - np.diag(d)) == 0:
        # Diagonal: exact, no eigen-decomposition round-off (zero mobility stays exactly 0).
        if np.any(d < 0):
            raise InvalidValueError(
                f"mobility must be positive semi-definite, diagonal has {d.min()}")
        return np.diag(np.sqrt(d))
    M = 0.5 * (M + M.T)
    w, Q = np.linalg.eigh(M)
    wmax = max(float(w[-1]), 0.0)
    if w[0] < -1e-8 * wmax:
        raise InvalidValueError(f"mobility must be positive semi-definite, eigenvalue {w[0]:.3e}")
    # Eigenvalues within round-off of zero are exactly zero: otherwise sqrt would turn a 1e-16
    # round-off into a 1e-8 leak of motion into zero-mobility directions.
    w = np.where(w > 10.0 * n * _EPS * wmax, w, 0.0)
    S = (Q * np.sqrt(w)) @ Q.T
    return 0.5 * (S + S.T)


def weighted_damped_pinv(
    J, rho: float, mobility, tol: float | None = None, rtol: float | None = None
) -> np.ndarray:
    r"""Damped pseudo-inverse weighted by a PSD *mobility* ``M = W⁻¹`` (``M`` may be singular).

    ``J^#_M = M Jᵀ (J M Jᵀ + ρ² I)⁻¹``, computed as ``M^{1/2} (J M^{1/2})^#`` with
    :func:`damped_pinv`; for ``ρ = 0`` this is ``M^{1/2} (J M^{1/2})⁺``.

    ``x = J^#_M v`` is the minimiser of ``‖J x − v‖² + ρ² xᵀ M⁺ x`` over ``x ∈ range(M)``
    (docs/DESIGN.md, math note 1); for invertible ``M`` that is ``‖J x − v‖² + ρ² ‖x‖²_W``.
    Directions of zero mobility never move: with ``M = diag(m_i)`` and ``m_j = 0`` joint ``j``
    is pinned to 0 and the other joints solve the same problem on their own (with ``ρ²/m_i`` as
    damping of the weighted coordinates). With ``ρ = 0`` and a non-full-rank ``J M^{1/2}`` it is the
    minimum-``‖x‖_{M⁺}`` least-squares solution within ``range(M)``.

    Args:
        J: matrix, shape ``(m, n)``.
        rho: damping ``ρ >= 0``.
        mobility: symmetric PSD ``(n, n)`` matrix, or its diagonal ``(n,)``. Eigenvalues below
            ``10·n·eps·λ_max`` are treated as exactly zero.
        tol, rtol: cutoffs for the ``ρ = 0`` pseudo-inverse (see :func:`pinv`).

    Returns:
        ``J^#_M``, shape ``(n, m)``.
    """
    J = checked_2d(J, "J")
    rho = checked_scalar(rho, "rho")
    S = _mobility_sqrt(mobility, J.shape[1])
    return S @ damped_pinv(J @ S, rho, tol=tol, rtol=rtol)


def nullspace_projector(J, tol: float | None = None, rtol: float | None = None) -> np.ndarray:
    r"""Orthogonal projector onto the null space of ``J``: ``N = I − J⁺J``.

    Built from the full SVD as ``N = V₀ V₀ᵀ`` where ``V₀`` spans the right singular vectors whose
    singular values are at or below ``max(tol, rtol·σ_max)`` (same cutoff as :func:`pinv`), so it
    is symmetric, idempotent and ``J N`` equals the dropped singular values only.

    Returns:
        ``N``, shape ``(n, n)``; the identity for a matrix with no rows.
    """
    J = checked_2d(J, "J")
    m, n = J.shape
    if m == 0 or n == 0:
        return np.eye(n)
    _, s, Vt = np.linalg.svd(J, full_matrices=True)
    c = _cutoff(s[0], J.shape, tol, rtol)
    r = int(np.count_nonzero(s > c))
    V0 = Vt[r:].T
    N = V0 @ V0.T
    return 0.5 * (N + N.T)
