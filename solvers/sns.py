r"""Saturation in the Null Space (SNS; Flacco, De Luca, Khatib, ICRA 2012 / IEEE T-RO 2015),
single task, with task scaling: :func:`sns_velocity`, :func:`sns_acceleration`, and the core
:func:`_sns` that :mod:`wbc.papers.xing.closed_form` builds on. Plain numpy; tolerances and
errors as in :mod:`wbc.solvers.linalg`. Re-exported by :mod:`wbc.solvers.reference`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wbc.checks import checked_2d, checked_bounds, checked_vector
from wbc.errors import BoundsOrderError
from wbc.qp import Status

from .linalg import DERIVED_RTOL, _cutoff, _pinv_svd, _svd

__all__ = ["SNSInfo", "sns_acceleration", "sns_velocity"]


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
    # both quotients on every joint, picked by the sign of a_i (fewer numpy calls than masked
    # assignments, the same IEEE operations on the joints that use them)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        to_lo = (lo - b) / a
        to_up = (up - b) / a
    pos = a > 0
    s_min, s_max = np.where(pos, to_lo, to_up), np.where(pos, to_up, to_lo)
    zero = a == 0
    if zero.any():  # the joint does not depend on s; either always or never within its bounds
        out = zero & ((b < lo) | (b > up))
        inside = zero & ~out
        s_min[inside], s_max[inside] = -np.inf, np.inf
        s_min[out], s_max[out] = np.inf, -np.inf
    return s_min, s_max


def _sns(J, task, offset, lower, upper, tol, rtol, feas_tol, svd=None):
    r"""SNS core for ``J q = s·task + offset``, ``lower <= q <= upper``; ``svd``: ``J``'s
    ``(U, s, Vt)`` as :func:`~wbc.solvers.linalg._svd` gives it, if the caller has it.

    Returns ``(q, s, saturated, iterations)`` or ``(None, None, saturated, iterations)`` when no
    scale in [0, 1] was found.
    """
    m, n = J.shape
    U, sv, Vt = _svd(J) if svd is None else svd
    smax = sv[0] if sv.size else 0.0
    cutoff = _cutoff(smax, J.shape, tol, DERIVED_RTOL if rtol is None else rtol)
    rank_J = int(np.count_nonzero(sv > cutoff))

    if feas_tol is None:
        bounds = np.abs(np.concatenate([lower, upper]))
        mag = float(np.max(bounds, where=np.isfinite(bounds), initial=0.0))
        feas_tol = 1e-10 * (mag if mag > 0 else 1.0)
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
        if it == 1:  # every joint free, none saturated (q_sat = 0)
            a, b = P @ task, P @ offset
            s_min, s_max = _scale_intervals(a, b, lo_b, up_b)
        else:
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
    J = checked_2d(J, "J")
    target = checked_vector(target, J.shape[0], name, broadcast=False)
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
    lower, upper = checked_bounds(lower, upper, J.shape[1], "bounds")
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
    (docs/DESIGN.md, math note 4). The iteration is that of :func:`sns_velocity` with
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
    drift = checked_vector(drift, J.shape[0], "drift", broadcast=False)
    lower, upper = checked_bounds(lower, upper, J.shape[1], "bounds")
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
