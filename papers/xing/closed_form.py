r"""Xing et al.'s adaptive motion planning (AMP) in closed form, and its building blocks.

H. Xing et al., "Enhancing kinematic accuracy of redundant wheeled mobile manipulators via
adaptive motion planning" (mecanum base + Kinova Gen3, acceleration level). Plain numpy, no
state; the QP form of the same method is ``wbc.experiments.xing.amp_stack``.

* :func:`amp` — one tick of AMP (eqs. 9–15, Figs. 3–4).
* :func:`traditional` — the paper's comparison planner, ``q̈ = J⁺(ẍ − J̇q̇) + (I − J⁺J) q̈_sa``.
* :func:`scaling_factor` — Fig. 4 (the factor α of the task or β of the tertiary objective).
* :func:`auxiliary_projector` — eq. (10), ``P_A = [I − ((I − S) P_N)⁺] P_N``.
* :func:`manipulability_gradient`, :func:`manipulability_hessian` (and
  :func:`manipulability_hessian_product`, ``∇²H d``) — appendices A and B, for
  ``H = det(J_m J_mᵀ)``; :func:`manipulability_acceleration` — eqs. (12)–(13).
* :func:`base_transition` — eq. (15), the base stopping at its maximal deceleration.

Reading of the paper (where its text leaves a choice):

* **The SNS loop** (§3.2, Fig. 3) is Flacco et al.'s SNS at acceleration level
  (:func:`wbc.solvers.reference.sns_acceleration`'s core: the most critical joint is saturated
  first, the best scale is kept). AMP runs it first on the arm alone, the base's acceleration
  held at the transition value (eq. 15; zero when the base is at rest). If that succeeds with
  α = 1 the base stays disabled. Otherwise — the arm's unsaturated joints lost rank (the paper's
  "rank(JS) < r") before the task became feasible — the base is enabled and SNS runs again on
  all joints, saturations reset (the paper: "the joints' accelerations need to be adjusted
  again"); its scale is α. When ``σ_min(J_m) < σ_thr`` the base is enabled from the start.
* **Scaling** applies to the commanded task acceleration only, not to the drift ``J̇q̇``
  (docs/DESIGN.md, math note 4).
* **The tertiary objective** is ``β P_A q̈_sa`` with ``S`` the joints that are still free after
  the SNS loop (saturated joints and a disabled base have ``S_ii = 0``); ``P_N = I − J⁺J`` uses
  the whole robot's task Jacobian. As printed, ``[I − ((I − S)P_N)⁺] P_N`` is the orthogonal
  projector onto ``null(J) ∩ {q̈_i = 0 for S_ii = 0}`` because ``I − S`` is a selection
  (``(CP_N)⁺ = (CP_N)⁺ C`` for an orthogonal projector ``C``), so the tertiary motion moves
  neither the task nor the disabled joints.
* **The transition function** (eq. 15) decelerates each base coordinate at its maximal rate
  until it stops. Sampled at the period ``T`` it is ``clip(−v_b/T, A_min, A_max)``: the maximal
  deceleration while ``|v_b| > A T``, then the one step that lands exactly on zero (eq. 15's
  continuous switch time ``t_f`` falls inside that step). Written so, it needs no memory of
  the switching time ``t_0``; it is 0 for a base at rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wbc.checks import checked_2d, checked_bounds, checked_vector
from wbc.errors import InvalidValueError, ShapeError
from wbc.solvers.linalg import _svd, pinv
from wbc.solvers.sns import _scale_intervals, _sns

__all__ = [
    "AMPInfo",
    "amp",
    "auxiliary_projector",
    "base_transition",
    "manipulability_acceleration",
    "manipulability_gradient",
    "manipulability_hessian",
    "manipulability_hessian_product",
    "scaling_factor",
    "traditional",
]


@dataclass(frozen=True)
class AMPInfo:
    """What one AMP tick decided.

    Attributes:
        alpha: the task's scaling factor α ∈ [0, 1] (1: the commanded acceleration holds).
        beta: the tertiary objective's scaling factor β ∈ [0, 1].
        base_enabled: whether the base was enabled (S_base = I).
        reason: ``"arm"`` (base disabled, the arm alone did it), ``"saturation"`` (the arm could
            not, the base was enabled) or ``"singularity"`` (σ_min < σ_thr).
        free: boolean (n,), the joints the pseudo-inverse still moved (``S_ii = 1``).
    """

    alpha: float
    beta: float
    base_enabled: bool
    reason: str
    free: np.ndarray


# ------------------------------------------------------------------------------ pieces
def base_transition(v_base, a_min, a_max, dt: float) -> np.ndarray:
    """Eq. (15), sampled: the base acceleration that stops it at its maximal deceleration.

    Args:
        v_base: base velocity coordinates (n_b,) [m/s, rad/s].
        a_min, a_max: their acceleration limits (n_b,) [m/s², rad/s²], ``a_min < 0 < a_max``.
        dt: the period ``T`` [s].

    Returns:
        ``clip(−v_base/T, a_min, a_max)`` (see the module docstring).
    """
    if not dt > 0:
        raise InvalidValueError(f"base_transition: dt must be > 0 [s], got {dt!r}")
    return np.clip(-np.asarray(v_base, dtype=float) / dt, a_min, a_max)


def scaling_factor(demand, offset, lower, upper) -> float:
    """Fig. 4: the largest factor ``f ∈ [0, 1]`` with ``lower <= offset + f·demand <= upper``.

    ``demand`` is the paper's ``A`` (the joint acceleration the task asks for), ``offset`` its
    ``E`` (what is already committed). Joints with ``demand = 0`` do not limit ``f``. If the
    offset itself violates a bound the factor is 0.
    """
    demand, offset = np.asarray(demand, float), np.asarray(offset, float)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    s_min, s_max = _scale_intervals(demand, offset, lower, upper)
    largest = float(s_max.min(initial=np.inf))
    if s_min.max(initial=-np.inf) > 1e-12 or largest < -1e-12:  # round-off on a bound is no
        return 0.0  # violation
    return min(max(largest, 0.0), 1.0)


def auxiliary_projector(J, free) -> np.ndarray:
    """Eq. (10): ``P_A = [I − ((I − S) P_N)⁺] P_N`` with ``P_N = I − J⁺J`` and ``S =
    diag(free)``: the projector onto the task's null space with the non-free joints still."""
    J = checked_2d(J, "J")
    n = J.shape[1]
    P_N = np.eye(n) - pinv(J) @ J
    C = np.diag(~np.asarray(free, dtype=bool)).astype(float)
    return (np.eye(n) - pinv(C @ P_N)) @ P_N


def _psi_terms(J, dJ):
    J = checked_2d(J, "J_m")
    dJ = np.asarray(dJ, dtype=float)
    r, m = J.shape
    if dJ.shape != (m, r, m):
        raise ShapeError(f"dJ must have shape ({m}, {r}, {m}) (∂J/∂q_k stacked on k), got "
                         f"{dJ.shape}")
    psi = J @ J.T
    d_psi = dJ @ J.T + J @ dJ.transpose(0, 2, 1)  # ∂_k Ψ = ∂_k J Jᵀ + J ∂_k Jᵀ, (m, r, r)
    psi_inv = np.linalg.inv(psi)
    return J, dJ, psi, psi_inv, psi_inv @ d_psi


def manipulability_gradient(J, dJ) -> np.ndarray:
    """Appendix A, eq. (17): ``∇H = det Ψ · tr(Ψ⁻¹ ∂_k Ψ)`` with ``Ψ = J_m J_mᵀ``.

    Args:
        J: the arm's task Jacobian ``J_m`` (r, m), ``r <= m`` and full rank.
        dJ: ``∂J_m/∂q_k`` stacked on ``k``, shape (m, r, m).

    Returns:
        ``∂H/∂q_k`` (m,) [units of H per rad].
    """
    _, _, psi, _, M = _psi_terms(J, dJ)
    return np.linalg.det(psi) * np.trace(M, axis1=1, axis2=2)


def manipulability_hessian_product(J, dJ, dJ_dot, direction) -> np.ndarray:
    """Appendix B, eqs. (18)–(20), applied to a direction ``d``: ``∇²H d``, with
    ``(∇²H)_pq = det Ψ [tr(Ψ⁻¹∂_pΨ) tr(Ψ⁻¹∂_qΨ) − tr(Ψ⁻¹∂_qΨ Ψ⁻¹∂_pΨ) + tr(Ψ⁻¹ ∂_pqΨ)]``
    and ``∂_pqΨ = ∂_pqJ Jᵀ + ∂_qJ ∂_pJᵀ + ∂_pJ ∂_qJᵀ + J ∂_pqJᵀ``. Contracted with ``d``,
    ``Σ_q ∂_pqΨ d_q = ∂_p Ψ̇`` for ``Ψ̇ = J̇Jᵀ + JJ̇ᵀ``, ``J̇ = Σ_q ∂_qJ d_q``: so only
    ``∂_p J̇`` is needed, not the whole second derivative of ``J`` (eq. 13 needs
    ``∇²H q̇_m``).

    Args:
        J, dJ: as in :func:`manipulability_gradient`.
        dJ_dot: ``∂J̇/∂q_p = Σ_q ∂²J_m/∂q_p∂q_q d_q`` stacked on ``p``, shape (m, r, m).
        direction: ``d`` (m,), e.g. ``q̇_m`` [rad/s].

    Returns:
        ``∇²H d`` (m,).
    """
    J, dJ, psi, psi_inv, M = _psi_terms(J, dJ)
    m, r = J.shape[1], J.shape[0]
    dJ_dot = np.asarray(dJ_dot, dtype=float)
    if dJ_dot.shape != (m, r, m):
        raise ShapeError(f"dJ_dot must have shape ({m}, {r}, {m}), got {dJ_dot.shape}")
    d = checked_vector(direction, m, "direction", broadcast=False)
    traces = np.trace(M, axis1=1, axis2=2)
    J_dot = np.tensordot(d, dJ, axes=1)
    d_psi_dot = (dJ_dot @ J.T + J_dot @ dJ.transpose(0, 2, 1) + dJ @ J_dot.T
                 + J @ dJ_dot.transpose(0, 2, 1))  # ∂_p Ψ̇, (m, r, r)
    cross = np.einsum("qij,pji->pq", M, M) @ d  # Σ_q tr(Ψ⁻¹∂_qΨ Ψ⁻¹∂_pΨ) d_q
    second = np.einsum("ij,pji->p", psi_inv, d_psi_dot)
    return np.linalg.det(psi) * (traces * (traces @ d) - cross + second)


def manipulability_hessian(J, dJ, ddJ) -> np.ndarray:
    """Appendix B: the Hessian ``∇²H`` (m, m), column by column with
    :func:`manipulability_hessian_product` (``d = e_k``, ``∂J̇/∂q_p = ∂²J/∂q_p∂q_k``).

    Args:
        J, dJ: as in :func:`manipulability_gradient`.
        ddJ: ``∂²J_m/∂q_p∂q_q``, shape (m, m, r, m).
    """
    J = checked_2d(J, "J_m")
    r, m = J.shape
    ddJ = np.asarray(ddJ, dtype=float)
    if ddJ.shape != (m, m, r, m):
        raise ShapeError(f"ddJ must have shape ({m}, {m}, {r}, {m}), got {ddJ.shape}")
    return np.column_stack([manipulability_hessian_product(J, dJ, ddJ[:, k], np.eye(m)[k])
                            for k in range(m)])


def manipulability_acceleration(gradient, hessian_qd, qd_arm, gamma1: float = 5.0,
                                gamma2: float = 0.5) -> np.ndarray:
    """Eq. (13): ``q̈_sa = γ1 ∇²H q̇_m + γ2 (γ1 ∇H − q̇_m)`` on the arm joints — the derivative
    of eq. (12)'s velocity ``q̇_sa = γ1 ∇H`` plus a term that pulls ``q̇_m`` towards it.

    Args:
        gradient: ``∇H`` (m,); hessian_qd: ``∇²H q̇_m`` (m,); qd_arm: ``q̇_m`` (m,) [rad/s].
        gamma1, gamma2: the paper's γ1 = 5, γ2 = 0.5 [1/s].
    """
    return (gamma1 * np.asarray(hessian_qd, float)
            + gamma2 * (gamma1 * np.asarray(gradient, float) - np.asarray(qd_arm, float)))


# ------------------------------------------------------------------------------ planners
def traditional(J, xdd, drift, qdd_sa) -> np.ndarray:
    """§4.3's traditional planner: ``q̈ = J⁺(ẍ − J̇q̇) + (I − J⁺J) q̈_sa`` (no joint limits)."""
    J = checked_2d(J, "J")
    r, n = J.shape
    P = pinv(J)
    qdd_sa = checked_vector(qdd_sa, n, "qdd_sa", broadcast=False)
    xdd = checked_vector(xdd, r, "xdd", broadcast=False)
    drift = checked_vector(drift, r, "drift", broadcast=False)
    return P @ (xdd - drift) + qdd_sa - P @ (J @ qdd_sa)


def amp(J, xdd, drift, lower, upper, n_base: int, *, qdd_sa=None, transition=None,
        sigma_min: float = np.inf, sigma_thr: float = 0.15) -> tuple[np.ndarray, AMPInfo]:
    """One tick of AMP (see the module docstring for the reading of the paper).

    Args:
        J: the whole robot's task Jacobian (r, n), base columns first (``n_base`` of them).
        xdd: commanded task acceleration ``ẍ_d + K_d ė + K_p e`` (r,) (scaled by α).
        drift: ``J̇ q̇`` (r,) (never scaled).
        lower, upper: joint acceleration bounds (n,) (eqs. 6–8).
        n_base: number of base coordinates.
        qdd_sa: the tertiary objective's acceleration (n,) (eq. 13, zero on the base), or
            ``None`` for none.
        transition: base acceleration (n_base,) while the base is disabled (eq. 15, see
            :func:`base_transition`); zeros if ``None``.
        sigma_min: ``σ_min`` of the arm's task Jacobian; below ``sigma_thr`` the base is
            enabled from the start.

    Returns:
        ``(qdd, info)``: the command ``q̈_c = q̈_amp + β P_A q̈_sa`` (eq. 14) and an
        :class:`AMPInfo`.
    """
    J = checked_2d(J, "J")
    r, n = J.shape
    xdd = checked_vector(xdd, r, "xdd", broadcast=False)
    drift = checked_vector(drift, r, "drift", broadcast=False)
    lower, upper = checked_bounds(lower, upper, n, "bounds")
    if not 0 <= n_base < n:
        raise ShapeError(f"n_base must be in 0..{n - 1}, got {n_base}")
    qdd_sa = np.zeros(n) if qdd_sa is None else checked_vector(qdd_sa, n, "qdd_sa", broadcast=False)
    transition = (np.zeros(n_base) if transition is None
                  else checked_vector(transition, n_base, "transition", broadcast=False))
    return _amp(J, xdd, drift, lower, upper, n_base, qdd_sa, transition, sigma_min, sigma_thr)


def _amp(J, xdd, drift, lower, upper, n_base, qdd_sa, transition, sigma_min, sigma_thr):
    """:func:`amp` on arguments it has checked (float arrays of the right shapes, finite,
    ``lower <= upper``, ``0 <= n_base < n``; ``qdd_sa`` and ``transition`` arrays): for
    callers that guarantee as much themselves."""
    n = J.shape[1]
    base = slice(0, n_base)
    qdd = None
    if sigma_min >= sigma_thr:  # the arm alone, the base at its transition value
        arm = slice(n_base, n)
        J_arm = J[:, arm]
        svd = _svd(J_arm)  # SNS's first pseudo-inverse, the rank test's and P_A's
        q_arm, alpha, saturated, _ = _sns(J_arm, xdd, -drift - J[:, base] @ transition,
                                          lower[arm], upper[arm], None, None, None, svd)
        # "rank(JS) < r": an arm that cannot span the task's directions fails however SNS
        # ends (SNS itself only compares against the rank of the columns it was given)
        if q_arm is not None and alpha == 1.0 and _spans(J, J_arm, svd[1]):
            qdd = np.concatenate([transition, np.clip(q_arm, lower[arm], upper[arm])])
            free = np.ones(n, dtype=bool)
            free[base] = False
            free[[n_base + j for j in saturated]] = False
            reason = "arm"
        else:
            reason = "saturation"
    else:
        reason = "singularity"
    if qdd is None:  # the base enabled: SNS again over every joint
        svd = _svd(J)
        qdd, alpha, saturated, _ = _sns(J, xdd, -drift, lower, upper, None, None, None, svd)
        if qdd is None:  # no scale in [0, 1]: the bounds cannot even absorb the drift
            qdd, alpha, saturated = np.clip(np.zeros(n), lower, upper), 0.0, []
        qdd = np.clip(qdd, lower, upper)
        free = np.ones(n, dtype=bool)
        free[list(saturated)] = False
    # svd is that of J[:, free] when SNS saturated nothing
    tertiary = _tertiary(J, free, qdd_sa, qdd, lower, upper, None if saturated else svd)
    beta = scaling_factor(tertiary, qdd, lower, upper)
    info = AMPInfo(float(alpha), beta, reason != "arm", reason, free)
    return qdd + beta * tertiary, info


def _spans(J, J_arm, s_arm) -> bool:
    """``rank(J_arm) == rank(J)`` as :func:`numpy.linalg.matrix_rank` decides it, given
    ``s_arm``, the singular values of ``J_arm`` (columns of ``J``).

    Where ``σ_r(J_arm)`` (``r`` = rows) is far above both rank tolerances (``max(r, m)·eps``
    times ``σ_max``) the answer is certain without ``J``'s SVD: both ranks are ``r``
    (``σ_r(J) >= σ_r(J_arm)`` for a column subset, ``σ_max(J) <= ‖J‖_F``). Otherwise it is
    decided as ever, by two ``matrix_rank`` calls."""
    if s_arm.size == J.shape[0] and s_arm.min(initial=np.inf) > 1e-8 * np.linalg.norm(J):
        return True
    return bool(np.linalg.matrix_rank(J_arm) == np.linalg.matrix_rank(J))


def _tertiary(J, free, qdd_sa, qdd, lower, upper, svd=None) -> np.ndarray:
    """``P_A q̈_sa`` of eq. (10) with exact zeros on the still joints (``free`` False), for the
    command ``qdd`` (within ``[lower, upper]`` on the free joints) that β will scale it from.

    ``P_A`` is the orthogonal projector onto ``null(J) ∩ {q̈_i = 0 where not free}`` (module
    docstring), i.e. ``I − J_F⁺ J_F`` on the free joints ``F`` and 0 elsewhere. That form —
    ``q̈_sa,F − V Vᵀ q̈_sa,F`` with ``V`` the right singular vectors of ``J_F``, whose SVD the
    caller may pass in ``svd`` — is used where it agrees with :func:`auxiliary_projector` to
    round-off and β with it:

    * ``J_F`` has full row rank ``r`` with ``σ_r(J_F) > max(1e-4 ‖J‖_F, 1e-6)``. Then ``J``
      keeps all ``r`` singular values in ``pinv(J)`` and ``(I − S) P_N`` has full row rank with
      ``σ_min >= σ_r(J_F) / (2‖J‖_F)`` (a unit ``u`` on the still joints is at least that far
      from ``range(Jᵀ)``): neither pseudo-inverse sits near its cutoff or amplifies round-off
      by more than ``2·10⁴``.
    * No free joint could limit β on round-off alone: none has a small ``|t_j| < 1e-4
      ‖q̈_sa‖_∞`` and a margin to a bound ``<= |t_j| + 1e-12 ‖q̈_sa‖_∞`` (e.g. a joint on its
      bound whose exact ``t_j`` is 0: the sign of the round-off decides β = 0 or not).

    Otherwise eq. (10) as printed (:func:`auxiliary_projector`), rounding as it always did.
    """
    _, s, Vt = _svd(J[:, free]) if svd is None else svd
    if s.size == J.shape[0] and s.min(initial=np.inf) > max(1e-4 * np.linalg.norm(J), 1e-6):
        x = qdd_sa[free]
        t = x - Vt.T @ (Vt @ x)
        scale = np.abs(qdd_sa).max(initial=0.0)
        small = np.abs(t) < 1e-4 * scale
        if small.any():  # are they on or near a bound?
            q, t_small = qdd[free][small], np.abs(t[small])
            margin = np.minimum(upper[free][small] - q, q - lower[free][small])
            small = margin <= t_small + 1e-12 * scale
        if not small.any():
            tertiary = np.zeros(J.shape[1])
            tertiary[free] = t
            return tertiary
    tertiary = auxiliary_projector(J, free) @ qdd_sa
    tertiary[~free] = 0.0  # exactly: P_A's rows of still joints are zero up to round-off
    return tertiary
