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

Modules
-------
This module is the catalogue: it re-exports the shared linear algebra
(:mod:`wbc.solvers.linalg`), SNS (:mod:`wbc.solvers.sns`) and each paper's closed forms, which
live in the paper's package (``wbc.papers.xing.closed_form``, ``wbc.papers.sorour.closed_form``,
``wbc.papers.omni.closed_form``, ``wbc.papers.petric.closed_form`` and ``closed_form_arm``)
and import from the first two only: imports point one way. The papers' names are imported on
first access (PEP 562), so ``import wbc.solvers.reference`` loads no paper; the old modules
``wbc.solvers.reference_<paper>`` are aliases of the new ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from wbc.aliases import moved_names
from wbc.checks import checked_2d, checked_scalar, checked_vector
from wbc.errors import ShapeError

from .linalg import (
    DEFAULT_TOL,
    DERIVED_RTOL,
    _cutoff,
    _damped_svd,
    _pinv_svd,
    _svd,
    damped_pinv,
    nullspace_projector,
    pinv,
    weighted_damped_pinv,
)
from .sns import SNSInfo, sns_acceleration, sns_velocity

__all__ = [
    # shared linear algebra (linalg) and SNS (sns)
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
]  # + each paper's closed forms (_MOVED, at the end: imported on first access)


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
    ``ρ_k = 0``). The projectors are never damped (docs/DESIGN.md, math note 2), so the
    increment of level ``k`` never disturbs levels ``< k``.

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
    n = 0  # the columns of level 0's J, which every level must have
    for k, lvl in enumerate(levels):
        try:
            Jk, vk = lvl
        except (TypeError, ValueError):
            raise ShapeError(f"level {k} must be a pair (J, v)") from None
        Jk = checked_2d(Jk, f"J of level {k}")
        if k == 0:
            n = Jk.shape[1]
        if Jk.shape[1] != n:
            raise ShapeError(f"J of level {k} has {Jk.shape[1]} columns, level 0 has {n}")
        Js.append(Jk)
        vs.append(checked_vector(vk, Jk.shape[0], f"v of level {k}", broadcast=False))
    if np.ndim(rho) == 0:
        rhos = [checked_scalar(rho, "rho")] * len(levels)
    else:
        rho = cast(Sequence[float], rho)  # not a scalar: one per level
        if len(rho) != len(levels):
            raise ShapeError(f"rho has {len(rho)} entries for {len(levels)} levels")
        rhos = [checked_scalar(r, f"rho[{k}]") for k, r in enumerate(rho)]
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
# the papers' closed forms, imported on first access
# --------------------------------------------------------------------------------------------

_PAPERS = {
    "AMPInfo": "xing", "amp": "xing", "auxiliary_projector": "xing", "base_transition": "xing",
    "manipulability_acceleration": "xing", "manipulability_gradient": "xing",
    "manipulability_hessian": "xing", "manipulability_hessian_product": "xing",
    "scaling_factor": "xing", "traditional": "xing",
    "arm_compensation": "sorour", "sharing_mobility": "sorour", "task_sharing_factor": "sorour",
    "task_sharing_velocity": "sorour",
    "DISTRIBUTION_METHODS": "omni", "friction_utilisation": "omni",
    "torque_distribution": "omni", "torque_null_space": "omni",
    "PETRIC_LAMBDA": "petric.closed_form_arm", "damped_projector": "petric.closed_form_arm",
    "dls_arm_velocity": "petric.closed_form_arm", "projector_leak": "petric.closed_form_arm",
    "rate_limit_interval": "petric", "rate_limited_twist": "petric",
}
#: ``name -> module`` of each paper's closed form re-exported here
_MOVED = {name: f"wbc.papers.{where}" if where.endswith("_arm") else
          f"wbc.papers.{where}.closed_form" for name, where in _PAPERS.items()}
__all__ += list(_MOVED)


__getattr__, __dir__ = moved_names(__name__, _MOVED)
