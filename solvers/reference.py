r"""Closed-form controllers from the literature, used as test oracles and as solvers.

Everything here is plain numpy (float64 in, float64 out) and units-agnostic: a Jacobian maps
whatever the decision vector is (joint velocities [rad/s, m/s], accelerations, ...) to whatever
the task is. No function keeps state.

Contents
--------
* :func:`pinv` -- truncated-SVD Moore-Penrose pseudo-inverse ``J⁺``.
* :func:`damped_pinv` -- damped least squares ``Jᵀ(JJᵀ + ρ²I)⁻¹``.
* :func:`weighted_damped_pinv` -- ``M Jᵀ(J M Jᵀ + ρ²I)⁻¹`` for a PSD *mobility* ``M = W⁻¹``
  that may be singular (zero-mobility joints do not move).
* :func:`nullspace_projector` -- ``N = I − J⁺J``.
* :func:`hierarchy` -- strict priorities by recursive null-space projection.
* :func:`sns_velocity`, :func:`sns_acceleration` -- Saturation in the Null Space (Flacco,
  De Luca, Khatib, ICRA 2012 / IEEE T-RO 2015), single task, with task scaling.

Tolerances
----------
Singular values ``σ_i`` are kept when ``σ_i > max(tol, rtol·σ_max)``. :func:`pinv` and
:func:`nullspace_projector` default to ``tol = 1e-12`` (absolute, in the units of ``J``) and
``rtol = max(m, n)·eps`` (numpy's / MATLAB's rank convention). Functions that take pseudo-inverses
of *derived* matrices (``J_k N_{k−1}`` in :func:`hierarchy`, column subsets of ``J`` in SNS) use
``rtol = 1e-10`` relative to the norm of the *original* Jacobian instead, because round-off in a
product such as ``J_k N_{k−1}`` is of the order of ``eps·‖J_k‖``, not of ``eps·‖J_k N_{k−1}‖``:
measuring it against the (possibly tiny) projected matrix would turn round-off into huge gains.
Pass ``tol=0`` to make any cutoff purely relative.

Errors
------
:class:`~wbc.errors.ShapeError` for wrong shapes, :class:`~wbc.errors.NonFiniteError` for NaN
(or inf where inf is meaningless: everywhere except in bounds),
:class:`~wbc.errors.BoundsOrderError` for ``lower > upper`` (and, for :func:`sns_velocity`,
bounds that do not contain 0), and ``ValueError`` for values outside a parameter's domain
(negative damping, non-symmetric or indefinite mobility).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wbc.errors import BoundsOrderError, InvalidValueError, NonFiniteError, ShapeError
from wbc.qp import Status

__all__ = [
    "DEFAULT_TOL",
    "DERIVED_RTOL",
    "HierarchyLevel",
    "SNSInfo",
    "damped_pinv",
    "hierarchy",
    "nullspace_projector",
    "pinv",
    "sns_acceleration",
    "sns_velocity",
    "weighted_damped_pinv",
]

DEFAULT_TOL = 1e-12
"""Default absolute singular-value cutoff (in the units of the matrix)."""

DERIVED_RTOL = 1e-10
"""Default relative cutoff for pseudo-inverses of derived matrices (hierarchy, SNS)."""

_EPS = np.finfo(np.float64).eps


# --------------------------------------------------------------------------------------------
# input checking
# --------------------------------------------------------------------------------------------


def _matrix(J, name: str = "J") -> np.ndarray:
    J = np.asarray(J, dtype=np.float64)
    if J.ndim != 2:
        raise ShapeError(f"{name} must be a 2-D array (m, n), got shape {J.shape}")
    if not np.all(np.isfinite(J)):
        raise NonFiniteError(f"{name} holds NaN or inf")
    return J


def _vector(v, size: int, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    if v.shape != (size,):
        raise ShapeError(f"{name} must have shape ({size},), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise NonFiniteError(f"{name} holds NaN or inf")
    return v


def _nonneg_scalar(x, name: str) -> float:
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape != ():
        raise ShapeError(f"{name} must be a scalar, got shape {arr.shape}")
    x = float(arr)
    if not np.isfinite(x):
        raise NonFiniteError(f"{name} must be finite, got {x}")
    if x < 0.0:
        raise InvalidValueError(f"{name} must be >= 0, got {x}")
    return x


def _bounds(lower, upper, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of shape (n,) (scalars broadcast); ±inf means "no bound", NaN is refused."""
    out = []
    for name, b in (("lower", lower), ("upper", upper)):
        b = np.asarray(b, dtype=np.float64)
        if b.ndim == 0:
            b = np.full(n, float(b))
        if b.shape != (n,):
            raise ShapeError(f"{name} must have shape ({n},) or be a scalar, got {b.shape}")
        if np.any(np.isnan(b)):
            raise NonFiniteError(f"{name} holds NaN")
        out.append(b.copy())
    lo, up = out
    if np.any(lo == np.inf) or np.any(up == -np.inf):
        raise NonFiniteError("a lower bound is +inf or an upper bound is -inf")
    bad = np.flatnonzero(lo > up)
    if bad.size:
        i = int(bad[0])
        raise BoundsOrderError(
            f"lower > upper at index {i} (lower={lo[i]}, upper={up[i]}); {bad.size} such entries"
        )
    return lo, up


# --------------------------------------------------------------------------------------------
# SVD helpers (shared so that one SVD serves rank, pinv and damped pinv)
# --------------------------------------------------------------------------------------------


def _svd(J: np.ndarray):
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
    J = _matrix(J)
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
    J = _matrix(J)
    rho = _nonneg_scalar(rho, "rho")
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
    (design math note 1); for invertible ``M`` that is ``‖J x − v‖² + ρ² ‖x‖²_W``. Directions of
    zero mobility never move: with ``M = diag(m_i)`` and ``m_j = 0`` joint ``j`` is pinned to 0
    and the other joints solve the same problem on their own (with ``ρ²/m_i`` as damping of the
    weighted coordinates). With ``ρ = 0`` and a non-full-rank ``J M^{1/2}`` it is the
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
    J = _matrix(J)
    rho = _nonneg_scalar(rho, "rho")
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
    J = _matrix(J)
    m, n = J.shape
    if m == 0 or n == 0:
        return np.eye(n)
    _, s, Vt = np.linalg.svd(J, full_matrices=True)
    c = _cutoff(s[0], J.shape, tol, rtol)
    r = int(np.count_nonzero(s > c))
    V0 = Vt[r:].T
    N = V0 @ V0.T
    return 0.5 * (N + N.T)


# --------------------------------------------------------------------------------------------
# strict hierarchy by null-space projection
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HierarchyLevel:
    """What one level of :func:`hierarchy` did.

    Attributes:
        x: the solution after this level, ``x_k``.
        projector: ``N_{k−1}``, the projector onto the null space of all *earlier* levels
            (identity for the first level).
        rank: rank of ``J_k N_{k−1}``: how many task directions this level could still act on.
        residual: ``v_k − J_k x`` for the *final* ``x`` (zero when the level is achieved).
    """

    x: np.ndarray
    projector: np.ndarray
    rank: int
    residual: np.ndarray


def hierarchy(
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    rho: float | Sequence[float] = 0.0,
    tol: float | None = None,
    rtol: float | None = None,
    *,
    return_info: bool = False,
):
    r"""Strict task priorities by recursive null-space projection.

    Levels ``(J_k, v_k)`` are ordered from highest to lowest priority. With ``x_0 = 0``,
    ``N_0 = I``::

        x_k = x_{k−1} + (J_k N_{k−1})^# (v_k − J_k x_{k−1}),
        N_k = I − [J_1; …; J_k]⁺ [J_1; …; J_k]            (exact stacked projector)

    where ``^#`` is :func:`damped_pinv` with ``ρ_k`` (the plain truncated pseudo-inverse when
    ``ρ_k = 0``). The projectors are never damped (design math note 2), so the increment of level
    ``k`` never disturbs levels ``< k``.

    With every ``ρ_k = 0`` the result is the minimum-norm solution of the lexicographic
    least-squares problem (each level minimises ``‖J_k x − v_k‖`` among the optima of the
    earlier levels): every increment lies in the row space of the stack, so no extra
    "minimum-norm" level is needed.

    Cutoffs: the pseudo-inverse of ``J_k N_{k−1}`` drops singular values at or below
    ``max(tol, rtol·‖J_k‖₂)`` (defaults ``1e-12`` and :data:`DERIVED_RTOL` = 1e-10), i.e. relative
    to the level's own Jacobian. The stacked projector is computed from the stack with every
    block scaled to unit spectral norm (same null space, but levels in different units count
    alike) and cutoff ``rtol``.

    Args:
        levels: sequence of ``(J_k, v_k)``, ``J_k`` of shape ``(m_k, n)``, ``v_k`` of ``(m_k,)``.
        rho: damping, one for all levels or one per level.
        tol, rtol: cutoffs (see above).
        return_info: also return one :class:`HierarchyLevel` per level.

    Returns:
        ``x`` of shape ``(n,)``, or ``(x, [HierarchyLevel, ...])`` with ``return_info``.
    """
    levels = list(levels)
    if not levels:
        raise ShapeError("hierarchy needs at least one level (J, v)")
    Js, vs = [], []
    n = None
    for k, lvl in enumerate(levels):
        try:
            Jk, vk = lvl
        except (TypeError, ValueError):
            raise ShapeError(f"level {k} must be a pair (J, v)") from None
        Jk = _matrix(Jk, f"J of level {k}")
        if n is None:
            n = Jk.shape[1]
        if Jk.shape[1] != n:
            raise ShapeError(f"J of level {k} has {Jk.shape[1]} columns, level 0 has {n}")
        Js.append(Jk)
        vs.append(_vector(vk, Jk.shape[0], f"v of level {k}"))
    if np.ndim(rho) == 0:
        rhos = [_nonneg_scalar(rho, "rho")] * len(levels)
    else:
        if len(rho) != len(levels):
            raise ShapeError(f"rho has {len(rho)} entries for {len(levels)} levels")
        rhos = [_nonneg_scalar(r, f"rho[{k}]") for k, r in enumerate(rho)]
    rtol = DERIVED_RTOL if rtol is None else float(rtol)

    x = np.zeros(n)
    N = np.eye(n)
    blocks: list[np.ndarray] = []
    xs, Ns, ranks = [], [], []
    for Jk, vk, rk in zip(Js, vs, rhos, strict=True):
        U, s, Vt = _svd(Jk @ N)
        norm_k = float(np.linalg.norm(Jk, 2)) if Jk.size else 0.0
        c = _cutoff(norm_k, Jk.shape, tol, rtol)
        if rk == 0.0:
            A_sharp = _pinv_svd(U, s, Vt, c)
        else:
            A_sharp = _damped_svd(U, s, Vt, rk)
        Ns.append(N)
        ranks.append(int(np.count_nonzero(s > c)))
        x = x + A_sharp @ (vk - Jk @ x)
        xs.append(x)
        # Exact projector of the stack so far (rows scaled per level; null space unchanged).
        if norm_k > 0.0:
            blocks.append(Jk / norm_k)
        if blocks:
            N = nullspace_projector(np.vstack(blocks), tol=0.0, rtol=rtol)
    if not return_info:
        return x
    info = [
        HierarchyLevel(x=xk, projector=Nk, rank=r, residual=vk - Jk @ x)
        for xk, Nk, r, Jk, vk in zip(xs, Ns, ranks, Js, vs, strict=True)
    ]
    return x, info


# --------------------------------------------------------------------------------------------
# Saturation in the Null Space (SNS)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SNSInfo:
    """Diagnostics of an SNS solve.

    Attributes:
        status: ``Status.SOLVED`` when the returned command satisfies the bounds *and* the scaled
            task; ``Status.INFEASIBLE`` when no scale in [0, 1] was found (acceleration level
            only; see :func:`sns_acceleration`).
        saturated: indices of the joints held at a bound in the returned solution, in the order
            they were saturated.
        iterations: number of pseudo-inverses computed.
    """

    status: Status
    saturated: tuple[int, ...]
    iterations: int


def _scale_intervals(a, b, lo, up):
    """Per joint, the interval of scales ``s`` with ``lo <= s·a + b <= up``.

    Returns ``(s_min, s_max)``; an empty interval is ``(+inf, -inf)``.
    """
    s_min = np.full(a.shape, -np.inf)
    s_max = np.full(a.shape, np.inf)
    pos, neg, zero = a > 0, a < 0, a == 0
    with np.errstate(invalid="ignore", over="ignore"):
        s_min[pos] = (lo[pos] - b[pos]) / a[pos]
        s_max[pos] = (up[pos] - b[pos]) / a[pos]
        s_min[neg] = (up[neg] - b[neg]) / a[neg]
        s_max[neg] = (lo[neg] - b[neg]) / a[neg]
    # a_i = 0: the joint does not depend on s; either always or never within its bounds.
    out = zero & ((b < lo) | (b > up))
    s_min[out], s_max[out] = np.inf, -np.inf
    return s_min, s_max


def _sns(J, task, offset, lower, upper, tol, rtol, feas_tol):
    r"""SNS core for ``J q = s·task + offset``, ``lower <= q <= upper``.

    Returns ``(q, s, saturated, iterations)`` or ``(None, None, saturated, iterations)`` when no
    scale in [0, 1] was found.
    """
    m, n = J.shape
    U, sv, Vt = _svd(J)
    smax = sv[0] if sv.size else 0.0
    cutoff = _cutoff(smax, J.shape, tol, DERIVED_RTOL if rtol is None else rtol)
    rank_J = int(np.count_nonzero(sv > cutoff))

    if feas_tol is None:
        finite = np.abs(np.concatenate([lower, upper]))
        finite = finite[np.isfinite(finite)]
        mag = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
        feas_tol = 1e-10 * mag
    # Round-off must not make a joint that sits on its bound look violated, so feasibility and
    # scale intervals are judged against bounds widened by feas_tol; the result is clipped.
    lo_b, up_b = lower - feas_tol, upper + feas_tol

    free = np.ones(n, dtype=bool)  # joints still moved by the pseudo-inverse
    q_sat = np.zeros(n)  # values of saturated joints (0 on free ones): the paper's q̇_N
    saturated: list[int] = []
    best = None  # (scale, q, saturated) of the largest feasible scale found so far
    it = 0
    while True:
        it += 1
        idx = np.flatnonzero(free)
        if it == 1:
            Uf, sf, Vtf = U, sv, Vt
        else:
            Uf, sf, Vtf = _svd(J[:, idx])
            # Paper's stopping rule, generalised to rank-deficient J: once the free joints no
            # longer span the task space of J, the task cannot be kept by them; stop and return
            # the best scaled solution found so far.
            if int(np.count_nonzero(sf > cutoff)) < rank_J:
                break
        P = _pinv_svd(Uf, sf, Vtf, cutoff)
        # q(s) = s·a + b: the minimum-norm motion of the free joints that achieves the scaled
        # task given the saturated joints' contribution J q_sat (the paper's
        # q̇ = q̇_N + (J W)^# (s ẋ − J q̇_N) with W the selection of free joints).
        a = np.zeros(n)
        b = q_sat.copy()
        a[idx] = P @ task
        b[idx] = P @ (offset - J @ q_sat)
        s_min, s_max = _scale_intervals(a[idx], b[idx], lo_b[idx], up_b[idx])
        violated = (s_min > 1.0) | (s_max < 1.0)
        if not violated.any():
            # The unscaled task is feasible with the current saturation set: done, s = 1.
            return a + b, 1.0, saturated, it
        # Largest feasible scale for this saturation set (paper: getTaskScalingFactor).
        s_hi = min(1.0, float(s_max.min()))
        s_lo = max(0.0, float(s_min.max()))
        if s_lo <= s_hi and (best is None or s_hi > best[0]):
            best = (s_hi, s_hi * a + b, tuple(saturated))
        # Most critical joint: the one whose feasible scale interval is farthest from s = 1.
        # When an interval containing some s <= 1 exists this is the paper's argmin s_max (the
        # joint that limits the scale first); otherwise (acceleration bounds that exclude the
        # drift compensation) it is the joint that blocks s = 1 the most.
        with np.errstate(invalid="ignore"):
            gap = np.maximum(np.maximum(1.0 - s_max, s_min - 1.0), 0.0)
        j = int(idx[int(np.argmax(gap))])
        # Saturate it at the bound it violates in the unscaled solution.
        q1 = a[j] + b[j]
        q_sat[j] = upper[j] if (q1 - upper[j]) > (lower[j] - q1) else lower[j]
        free[j] = False
        saturated.append(j)
        if not free.any():
            break
    if best is None:
        return None, None, saturated, it
    s, q, sat = best
    return q, s, list(sat), it


def _sns_prepare(J, target, name):
    J = _matrix(J)
    target = _vector(target, J.shape[0], name)
    return J, target


def sns_velocity(
    J,
    xd,
    lower,
    upper,
    *,
    tol: float | None = None,
    rtol: float | None = None,
    feas_tol: float | None = None,
    return_info: bool = False,
):
    r"""Saturation in the Null Space at velocity level (Flacco, De Luca, Khatib), one task.

    Finds joint velocities ``q̇`` and a task scale ``s ∈ [0, 1]`` with::

        J q̇ = s ẋ_d,      lower <= q̇ <= upper,

    ``s = 1`` whenever the minimum-norm solution ``J⁺ ẋ_d`` is within the bounds (and then
    ``q̇ = J⁺ ẋ_d``). Otherwise the algorithm repeatedly

    1. computes ``q̇(s) = s a + b`` with ``a = (J W)⁺ ẋ_d``, ``b = q̇_N − (J W)⁺ J q̇_N``, where
       ``W`` selects the joints not yet saturated and ``q̇_N`` holds the saturated joints at
       their bounds (they are "saturated in the null space" of the task);
    2. computes the largest ``s ∈ [0, 1]`` for which ``q̇(s)`` is within the bounds and keeps the
       best ``(s, q̇)`` seen;
    3. saturates the most critical joint (the one limiting ``s``) at the bound it violates;

    until the unscaled task becomes feasible (``s = 1``) or the free joints lose rank with
    respect to ``J`` (the task can no longer be kept), in which case the best scaled solution
    is returned. Basic SNS never unsaturates a joint, so its scale can fall short of the largest
    feasible one (the LP optimum) in a few percent of problems; see Opt-SNS in the paper.

    Within its saturation set the returned ``q̇`` is minimum-norm. If ``ẋ_d`` is not in the range
    of a rank-deficient ``J`` the task holds in the least-squares sense:
    ``J q̇ = s·P ẋ_d`` with ``P`` the projector onto ``range(J)``.

    Args:
        J: task Jacobian, shape ``(m, n)``.
        xd: desired task velocity ``ẋ_d``, shape ``(m,)``.
        lower, upper: joint velocity bounds, shape ``(n,)`` or scalars, ``lower <= 0 <= upper``
            (so ``q̇ = 0``, ``s = 0`` is always feasible); ``±inf`` for unbounded joints.
        tol, rtol: singular-value cutoff ``max(tol, rtol·σ_max(J))`` used for every
            pseudo-inverse and rank test (defaults 1e-12 and :data:`DERIVED_RTOL`).
        feas_tol: bound-violation tolerance, default ``1e-10·max|finite bound|``; the returned
            ``q̇`` is clipped into the exact bounds (a change of at most ``feas_tol``).
        return_info: also return an :class:`SNSInfo`.

    Returns:
        ``(qd, scale)``, or ``(qd, scale, info)`` with ``return_info``.

    Raises:
        BoundsOrderError: ``lower > upper`` somewhere, or a bound excludes 0.
    """
    J, xd = _sns_prepare(J, xd, "xd")
    lower, upper = _bounds(lower, upper, J.shape[1])
    bad = np.flatnonzero((lower > 0) | (upper < 0))
    if bad.size:
        i = int(bad[0])
        raise BoundsOrderError(
            f"sns_velocity needs lower <= 0 <= upper; joint {i} has [{lower[i]}, {upper[i]}] "
            "(use sns_acceleration with drift=0 for bounds that exclude 0)"
        )
    q, s, sat, it = _sns(J, xd, np.zeros(J.shape[0]), lower, upper, tol, rtol, feas_tol)
    # With 0 in the bounds the very first iterate is feasible at s = 0, so q is never None.
    assert q is not None
    q = np.clip(q, lower, upper)
    if return_info:
        return q, s, SNSInfo(Status.SOLVED, tuple(sat), it)
    return q, s


def sns_acceleration(
    J,
    xdd,
    drift,
    lower,
    upper,
    *,
    tol: float | None = None,
    rtol: float | None = None,
    feas_tol: float | None = None,
    return_info: bool = False,
):
    r"""Saturation in the Null Space at acceleration level, one task.

    Finds joint accelerations ``q̈`` and a scale ``s ∈ [0, 1]`` with::

        J q̈ + J̇q̇ = s ẍ_d,     lower <= q̈ <= upper,

    i.e. only the commanded task acceleration ``ẍ_d`` is scaled, never the drift ``J̇q̇``
    (design math note 4). The iteration is that of :func:`sns_velocity` with
    ``q̈(s) = s a + b``, ``a = (J W)⁺ ẍ_d``, ``b = q̈_N + (J W)⁺ (−J̇q̇ − J q̈_N)``.

    Acceleration bounds derived from position and velocity limits need not contain 0, so
    ``s = 0`` need not be feasible; the feasible scales of a saturation set form an interval
    ``[s_lo, s_hi]`` and SNS keeps the largest ``s_hi ∈ [0, 1]`` found. When a joint blocks
    every ``s ≤ 1`` it is saturated first (the one farthest from admitting ``s = 1``).

    If no saturation set admits a scale in [0, 1] (typically: the bounds cannot compensate the
    drift at all), the result is ``scale = 0.0`` and the bounded least-squares
    ``q̈ = argmin ‖J q̈ + J̇q̇‖ s.t. lower <= q̈ <= upper`` (scipy ``lsq_linear``; bounds hold, the
    task equation does not, and ``q̈`` is not minimum-norm). ``info.status`` is then
    ``Status.INFEASIBLE`` unless that least-squares residual is zero within tolerance (SNS
    missed a feasible ``s = 0``), in which case it is ``Status.SOLVED``.

    Args:
        J: task Jacobian, shape ``(m, n)``.
        xdd: commanded task acceleration ``ẍ_d``, shape ``(m,)``.
        drift: ``J̇ q̇``, shape ``(m,)``.
        lower, upper: joint acceleration bounds, shape ``(n,)`` or scalars, ``lower <= upper``.
        tol, rtol, feas_tol, return_info: as in :func:`sns_velocity`.

    Returns:
        ``(qdd, scale)``, or ``(qdd, scale, info)`` with ``return_info``.
    """
    J, xdd = _sns_prepare(J, xdd, "xdd")
    drift = _vector(drift, J.shape[0], "drift")
    lower, upper = _bounds(lower, upper, J.shape[1])
    q, s, sat, it = _sns(J, xdd, -drift, lower, upper, tol, rtol, feas_tol)
    if q is not None:
        q = np.clip(q, lower, upper)
        status = Status.SOLVED
    else:
        from scipy.optimize import lsq_linear

        s = 0.0
        if J.size:
            q = lsq_linear(J, -drift, bounds=(lower, upper), method="bvls").x
        else:
            q = np.clip(np.zeros(J.shape[1]), lower, upper)
        q = np.clip(q, lower, upper)
        res = float(np.linalg.norm(J @ q + drift))
        ref = max(float(np.linalg.norm(drift)), float(np.linalg.norm(J, 2) if J.size else 0), 1.0)
        status = Status.SOLVED if res <= 1e-9 * ref else Status.INFEASIBLE
        sat = [int(i) for i in np.flatnonzero((q <= lower) | (q >= upper))]
    if return_info:
        return q, s, SNSInfo(status, tuple(sat), it)
    return q, s
from .reference_xing import AMPInfo, amp, auxiliary_projector, base_transition, manipulability_acceleration, manipulability_gradient, manipulability_hessian, manipulability_hessian_product, scaling_factor, traditional  # noqa: E402, E501, I001

__all__ += ["AMPInfo", "amp", "auxiliary_projector", "base_transition", "manipulability_acceleration", "manipulability_gradient", "manipulability_hessian", "manipulability_hessian_product", "scaling_factor", "traditional"]  # noqa: E501
from .reference_sorour import arm_compensation, sharing_mobility, task_sharing_factor, task_sharing_velocity  # noqa: E402, E501, I001
__all__ += ["arm_compensation", "sharing_mobility", "task_sharing_factor", "task_sharing_velocity"]  # noqa: E501
from .reference_omni import DISTRIBUTION_METHODS, friction_utilisation, torque_distribution, torque_null_space  # noqa: E402, E501, I001
__all__ += ["DISTRIBUTION_METHODS", "friction_utilisation", "torque_distribution", "torque_null_space"]  # noqa: E501
from .reference_petric_arm import PETRIC_LAMBDA, damped_projector, dls_arm_velocity, projector_leak  # noqa: E402, E501, I001
__all__ += ["PETRIC_LAMBDA", "damped_projector", "dls_arm_velocity", "projector_leak"]  # noqa: E501
from .reference_petric import rate_limit_interval, rate_limited_twist  # noqa: E402, I001
__all__ += ["rate_limit_interval", "rate_limited_twist"]
