r"""Closed forms of the omni platform's wheel-torque distribution (torque-redundancy paper).

A platform with ``N`` omni wheels (``N = 4`` in the paper) and wheel Jacobian ``J`` (``N × 3``,
eq. 1: ``Δθ = J Δx``) turns wheel torques ``τ`` [N m] into the platform wrench ``f = Jᵀ τ``
(eq. 5). For ``N > 3`` the torques realising a desired wrench ``f_d`` form the affine set
``τ = (Jᵀ)⁺ f_d + (I − (Jᵀ)⁺ Jᵀ) a`` (eq. 7); with four wheels its direction is one unit
vector ``n`` (eq. 10): ``τ(α) = (Jᵀ)⁺ f_d + α n`` (eq. 11). :func:`torque_distribution` picks
one member:

* ``"min_norm"`` — ``a = 0``: ``τ = (Jᵀ)⁺ f_d``, the least-norm torques (eq. 7's first term).
* ``"proportional"`` — eqs. 10–13 with the criterion ``H(α)`` of eq. 12, whose formula is lost
  from the paper's text. **Reconstruction** (documented decision): wheel ``i`` can transmit at
  most ``μ_i f_i`` of traction (eq. 9; ``f_i`` its normal force), so its *friction utilisation*
  is ``u_i = |τ_i| / (μ_i f_i r)``; the paper asks that the driving forces be proportional to the
  normal forces. We maximise ``H(α) = −Σ_i (τ_i(α) / (μ_i f_i))²`` (``r`` is a common factor and
  dropped), i.e. minimise the sum of squared utilisations, which spreads the traction over the
  wheels in proportion to what each can carry. Each ``τ_i(α) = τ0_i + α n_i`` is affine in
  ``α``, so ``H`` is a concave quadratic in ``α`` (the paper: "a quadratic equation in α") and
  ``dH/dα = 0`` gives, with ``w_i = 1/(μ_i f_i)``::

      α_opt = − Σ w_i² τ0_i n_i / Σ w_i² n_i²          (eq. 13: τ_opt = τ0 + α_opt n)

  Exact proportionality ``τ_i = c μ_i f_i`` is generally out of reach (one free parameter, four
  ratios); ``H`` is its least-squares relaxation. Equivalently ``τ_opt`` is the weighted least-
  norm solution ``argmin ||W τ||² s.t. Jᵀ τ = f_d`` with ``W = diag(w)``, which is how the QP
  form (:mod:`wbc.papers.omni.distribution_tasks`) states it; for ``N − 3 > 1`` redundant
  torques the same formula holds with ``α`` a vector (normal equations in the null-space
  basis). Being a sum of squares, ``H`` usually lowers the *largest* utilisation against
  ``"min_norm"`` but not always (measured over 865 random arm configurations of ``omni4_arm6``
  where no wheel lifts, μ = 0.5, random wrenches: lower in 85 %, median ratio 0.56, above 1.1
  in the worst 5 %).
* ``"minmax"`` (beyond the paper) — minimise the largest utilisation ``max_i |τ_i| w_i`` (an LP
  over ``(τ, t)``). It is the exact no-slip criterion: no wheel slips iff ``max_i u_i ≤ 1``, so
  if any distribution avoids slip, this one does. Closed form on the one-dimensional null
  space: ``g(α) = max_i |a_i + α b_i|`` (``a = W τ0``, ``b = W n``) is convex and piecewise
  linear; its minimum lies where two of the lines ``±(a_i + α b_i)`` cross (or where one
  crosses zero), so the candidates are enumerated and the best taken. When the minimum is
  attained on an interval of ``α`` (a wheel with ``n_i = 0`` carries the largest utilisation),
  the least-norm member is returned (``α = 0`` clipped to the interval, as ``τ0 ⟂ n``): the
  answer is unique and equals the QP form's (a damped level, see
  :mod:`wbc.papers.omni.distribution_tasks`). Only ``N − 3 ≤ 1`` is supported.

The functions are plain numpy, the oracles of the QP forms and usable as controllers.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_2d, checked_vector
from wbc.errors import InvalidValueError, ShapeError
from wbc.solvers.linalg import pinv

__all__ = ["DISTRIBUTION_METHODS", "friction_utilisation", "torque_distribution",
           "torque_null_space"]

#: the methods of :func:`torque_distribution`.
DISTRIBUTION_METHODS = ("min_norm", "proportional", "minmax")


def checked_wheel_jacobian(J) -> np.ndarray:
    """``J`` checked as the ``(N, 3)`` wheel Jacobian of eq. 1 (wheel rates [rad/s] per platform
    twist) of ``N >= 3`` wheels, of full column rank (every platform wrench producible); else a
    :class:`~wbc.WbcError` naming ``J``."""
    J = checked_2d(J, "J")
    if J.shape[1] != 3 or J.shape[0] < 3:
        raise ShapeError(f"J must be the (N, 3) wheel Jacobian with N >= 3 wheels, got shape "
                         f"{J.shape}")
    if np.linalg.matrix_rank(J) < 3:
        raise InvalidValueError("J must have full column rank 3 (otherwise some platform "
                                "wrenches cannot be produced by the wheels)")
    return J


def _capacity(normal_forces, mu, n: int) -> np.ndarray:
    """``μ_i f_i`` [N]: the largest traction each wheel can transmit, validated."""
    forces = checked_vector(normal_forces, n, "normal_forces", broadcast=False)
    if np.any(forces <= 0.0):
        raise InvalidValueError(f"normal_forces must be > 0 [N] (a wheel without load transmits "
                                f"no traction), got {forces}")
    mu = checked_vector(mu, n, "mu")
    if np.any(mu <= 0.0):
        raise InvalidValueError(f"mu must be > 0, got {mu}")
    return mu * forces


def torque_null_space(J) -> np.ndarray:
    """Orthonormal basis ``(N, N − 3)`` of the null space of ``Jᵀ`` (eq. 10's ``n`` for N = 4).

    Each column's sign is fixed (its largest-magnitude entry positive), so the basis is
    deterministic.
    """
    J = checked_wheel_jacobian(J)
    basis = np.linalg.svd(J.T)[2][3:].T
    signs = np.sign(basis[np.abs(basis).argmax(axis=0), np.arange(basis.shape[1])])
    return basis * signs


def friction_utilisation(tau, normal_forces, radius: float, mu=1.0) -> np.ndarray:
    """``u_i = |τ_i| / (μ_i f_i r)``: wheel ``i``'s traction over its friction limit (eq. 9).

    A wheel slips when ``u_i > 1``.

    Args:
        tau: wheel torques [N m], shape (N,).
        normal_forces: ``f_i`` [N], shape (N,), > 0.
        radius: wheel radius ``r`` [m], > 0.
        mu: friction coefficients, scalar or (N,), > 0.
    """
    tau = np.asarray(tau, dtype=float)
    tau = checked_vector(tau, tau.size, "tau", broadcast=False)
    if not (np.isfinite(radius) and radius > 0):
        raise InvalidValueError(f"radius must be > 0 [m], got {radius!r}")
    return np.abs(tau) / (_capacity(normal_forces, mu, tau.size) * radius)


def torque_distribution(J, f_d, normal_forces, mu=1.0, method: str = "proportional"
                        ) -> np.ndarray:
    """Wheel torques ``τ`` [N m] with ``Jᵀ τ = f_d``, chosen by ``method`` (module docstring).

    Args:
        J: wheel Jacobian (N, 3), eq. 1 (wheel rates [rad/s] per platform twist), full rank.
        f_d: desired platform wrench ``(f_x [N], f_y [N], m_z [N m])`` in the platform frame.
        normal_forces: ``f_i`` [N], shape (N,), > 0 (:func:`wbc.robots.normal_forces`).
        mu: friction coefficients ``μ_i``, scalar or (N,), > 0.
        method: ``"min_norm"`` (eq. 7, a = 0), ``"proportional"`` (eqs. 10–13, reconstructed
            ``H``) or ``"minmax"`` (least largest friction utilisation).

    Returns:
        ``τ``, shape (N,).

    Raises:
        ShapeError, NonFiniteError, InvalidValueError: bad input (non-positive normal forces or
        friction coefficients, rank-deficient ``J``, unknown method, ``"minmax"`` with more
        than one redundant torque).
    """
    if method not in DISTRIBUTION_METHODS:
        raise InvalidValueError(f"method must be one of {DISTRIBUTION_METHODS}, got {method!r}")
    J = checked_wheel_jacobian(J)
    f_d = checked_vector(f_d, 3, "f_d", broadcast=False)
    w = 1.0 / _capacity(normal_forces, mu, J.shape[0])
    tau0 = pinv(J.T) @ f_d
    if method == "min_norm":
        return tau0
    null = torque_null_space(J)
    if null.shape[1] == 0:  # three wheels: no redundancy, every method gives τ0
        return tau0
    # maximiser of H: normal equations of min ||W (τ0 + N α)||² in α
    wn = w[:, None] * null
    alpha = -np.linalg.solve(wn.T @ wn, wn.T @ (w * tau0))
    if method == "proportional":
        return tau0 + null @ alpha
    if null.shape[1] > 1:
        raise InvalidValueError(f"method 'minmax' is implemented for one redundant torque "
                                f"(4 wheels), got {null.shape[1]}")
    return tau0 + null[:, 0] * _minmax_alpha(w * tau0, wn[:, 0])


def _minmax_alpha(a: np.ndarray, b: np.ndarray) -> float:
    """A minimiser of ``g(α) = max_i |a_i + α b_i|``: the one nearest to 0.

    The minimum of this convex piecewise-linear function lies at a crossing of two lines
    ``±(a_i + α b_i)`` or at a zero of one; every candidate is evaluated.
    """
    scale = np.abs(b).max()
    i, j = np.triu_indices(a.size, k=1)
    candidates = [-a[b != 0] / b[b != 0]]
    for sign in (1.0, -1.0):  # a_i + α b_i = sign · (a_j + α b_j)
        den = b[i] - sign * b[j]
        ok = np.abs(den) > 1e-12 * scale
        candidates.append((sign * a[j][ok] - a[i][ok]) / den[ok])
    alphas = np.concatenate(candidates)
    values = np.abs(a[None, :] + alphas[:, None] * b[None, :]).max(axis=1)
    best = values.min()
    # the minimisers: |a_i + α b_i| <= best for all i, an interval in α
    moving = np.abs(b) > 1e-12 * scale
    ends = np.sort(np.stack([(-best - a[moving]) / b[moving], (best - a[moving]) / b[moving]]),
                   axis=0)
    lo, hi = ends[0].max(), ends[1].min()
    if lo > hi:  # round-off at a single minimiser
        return float(alphas[values.argmin()])
    return float(np.clip(0.0, lo, hi))
