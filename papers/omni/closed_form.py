r"""Closed forms of the omni platform's wheel-torque distribution (torque-redundancy paper).

A platform with ``N`` omni wheels (``N = 4`` in the paper) and wheel Jacobian ``J`` (``N × 3``,
eq. 1: ``Δθ = J Δx``) turns wheel torques ``τ`` [N m] into the platform wrench ``f = Jᵀ τ``
(eq. 5). For ``N > 3`` the torques realising a desired wrench ``f_d`` form the affine set
``τ = (Jᵀ)⁺ f_d + (I − (Jᵀ)⁺ Jᵀ) a`` (eq. 7); with four wheels its direction is one unit
vector ``n`` (eq. 10): ``τ(α) = (Jᵀ)⁺ f_d + α n`` (eq. 11). :func:`torque_distribution` picks
one member:

* ``"min_norm"`` — ``a = 0``: ``τ = (Jᵀ)⁺ f_d``, the least-norm torques (eq. 7's first term).
* ``"proportional"`` — eqs. 10–13 with the criterion ``H(α)`` of eq. 12, whose formula is lost
  from the paper's text. What the text keeps: wheel ``i`` can transmit at most ``μ_i f_i`` of
  traction (eq. 9; ``f_i`` its normal force), "for avoiding the slippage, the desirable driving
  forces should be proportional to the reaction forces", α is chosen "so that the value of H
  becomes maximum", and "the optimal α can easily be obtained by solving a quadratic equation
  in α". Two reconstructions (``criterion=``), both documented decisions:

  - ``"utilisation"`` (default, the study's main reading) — maximise
    ``H(α) = −Σ_i (τ_i(α) / (μ_i f_i))²`` (``r`` is a common factor and dropped), i.e.
    minimise the sum of squared *friction utilisations* ``u_i = |τ_i| / (μ_i f_i r)``: the
    least-squares relaxation of "proportional" (``u_i`` all equal is generally out of reach,
    one free parameter for four ratios), which also penalises the torques' size. ``H`` is a
    concave quadratic in ``α``, so ``dH/dα = 0`` is a *linear* equation — not the paper's
    quadratic one. With ``w_i = 1/(μ_i f_i)``::

        α_opt = − Σ w_i² τ0_i n_i / Σ w_i² n_i²          (eq. 13: τ_opt = τ0 + α_opt n)

    Equivalently ``τ_opt`` is the weighted least-norm solution ``argmin ||W τ||² s.t.
    Jᵀ τ = f_d`` with ``W = diag(w)``, which is how the QP form
    (:mod:`wbc.papers.omni.distribution_tasks`) states it; for ``N − 3 > 1`` redundant torques
    the same formula holds with ``α`` a vector (normal equations in the null-space basis).
    Being a sum of squares, it usually lowers the *largest* utilisation against
    ``"min_norm"`` but not always (measured over 865 random arm configurations of
    ``omni4_arm6`` where no wheel lifts, μ = 0.5, random wrenches: lower in 85 %, median ratio
    0.56, above 1.1 in the worst 5 %).
  - ``"ratios"`` — the text read literally: the driving forces proportional to the normal
    forces means every wheel using the same fraction of its friction, ``u_i`` all equal, and
    ``H(α)`` measures how nearly they are, as the squared cosine of the angle between the
    vector of ``|u_i(α)|`` and ``(1, …, 1)``::

        H(α) = (Σ_i |u_i(α)|)² / (N Σ_i u_i(α)²)        ∈ [0, 1], 1 iff every |u_i| is equal

    (``u_i = w_i τ_i(α)``; ``1 / H − 1`` is the squared coefficient of variation of the
    ``|u_i|``). Where no ``τ_i`` changes sign (signs ``s_i``), ``Σ |u_i| = A + B α`` and
    ``Σ u_i² = P + 2 Q α + R α²`` (``a = W τ0``, ``b = W n``: ``A = sᵀa``, ``B = sᵀb``,
    ``P = aᵀa``, ``Q = aᵀb``, ``R = bᵀb``), so ``dH/dα = 0`` is the quadratic equation
    ``(A + B α) ((B P − A Q) + (B Q − A R) α) = 0``: one root makes ``H = 0``, the other is the
    maximum — the paper's "solving a quadratic equation in α" and keeping the root that
    maximises ``H``. ``H`` is scale-free: it asks for equal utilisations, not for small ones,
    so it may load a lightly loaded wheel that ``"utilisation"`` leaves nearly idle. Exact on
    the one-dimensional null space: the roots of each sign pattern's quadratic and the
    breakpoints ``τ_i = 0`` are the candidates, the best is taken (the least ``|α|`` among
    equals). Should ``H``'s supremum lie at ``|α| → ∞`` (``W n`` itself more nearly uniform
    than any finite member) it is not attained, and the best finite candidate is returned
    (unbounded internal torques serve nothing; not met on 3000 random instances). A zero wrench
    gives zero torques. Only ``N − 3 ≤ 1``. (A first literal reading, the cosine between
    ``|τ|`` and ``μ f``, weighs each wheel by its capacity, so it overloads the light wheels
    it barely counts — 10 to 20 times min-norm's slip in the study's runs: dropped.)

  Consequences on the study's claims: ``wbc study omni`` runs both readings
  (``"proportional"`` and ``"proportional_ratios"``) and reports both.
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

from functools import lru_cache

import numpy as np

from wbc.checks import checked_2d, checked_vector
from wbc.errors import InvalidValueError, ShapeError
from wbc.solvers.linalg import pinv

__all__ = ["DISTRIBUTION_METHODS", "H_CRITERIA", "equal_ratios", "friction_utilisation",
           "torque_distribution", "torque_null_space"]

#: the methods of :func:`torque_distribution`.
DISTRIBUTION_METHODS = ("min_norm", "proportional", "minmax")
#: the reconstructions of eq. 12's ``H(α)`` for ``"proportional"`` (module docstring).
H_CRITERIA = ("utilisation", "ratios")


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


@lru_cache(maxsize=32)
def _wheel_basis(shape: tuple[int, int], data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``((Jᵀ)⁺, null space of Jᵀ)`` of the float64 ``J`` given by its shape and bytes, checked
    (:func:`checked_wheel_jacobian`) — computed once per Jacobian: a controller or a study
    calls :func:`torque_distribution` with the same ``J`` every tick. Read-only arrays."""
    J = checked_wheel_jacobian(np.frombuffer(data).reshape(shape))
    pseudo_inverse, null = pinv(J.T), torque_null_space(J)
    pseudo_inverse.flags.writeable = null.flags.writeable = False
    return pseudo_inverse, null


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


def torque_distribution(J, f_d, normal_forces, mu=1.0, method: str = "proportional",
                        criterion: str = "utilisation") -> np.ndarray:
    """Wheel torques ``τ`` [N m] with ``Jᵀ τ = f_d``, chosen by ``method`` (module docstring).

    Args:
        J: wheel Jacobian (N, 3), eq. 1 (wheel rates [rad/s] per platform twist), full rank.
        f_d: desired platform wrench ``(f_x [N], f_y [N], m_z [N m])`` in the platform frame.
        normal_forces: ``f_i`` [N], shape (N,), > 0 (:func:`wbc.robots.normal_forces`).
        mu: friction coefficients ``μ_i``, scalar or (N,), > 0.
        method: ``"min_norm"`` (eq. 7, a = 0), ``"proportional"`` (eqs. 10–13, reconstructed
            ``H``) or ``"minmax"`` (least largest friction utilisation).
        criterion: the reconstruction of ``H`` for ``"proportional"``: ``"utilisation"``
            (least squared friction utilisations) or ``"ratios"`` (the utilisations most
            nearly equal; one redundant torque only); ignored by the other methods.

    Returns:
        ``τ``, shape (N,).

    Raises:
        ShapeError, NonFiniteError, InvalidValueError: bad input (non-positive normal forces or
        friction coefficients, rank-deficient ``J``, unknown method or criterion, ``"minmax"``
        or ``"ratios"`` with more than one redundant torque).
    """
    if method not in DISTRIBUTION_METHODS:
        raise InvalidValueError(f"method must be one of {DISTRIBUTION_METHODS}, got {method!r}")
    if criterion not in H_CRITERIA:
        raise InvalidValueError(f"criterion must be one of {H_CRITERIA}, got {criterion!r}")
    J = checked_2d(J, "J")
    pseudo_inverse, null = _wheel_basis(J.shape, J.tobytes())
    f_d = checked_vector(f_d, 3, "f_d", broadcast=False)
    w = 1.0 / _capacity(normal_forces, mu, J.shape[0])
    tau0 = pseudo_inverse @ f_d
    if method == "min_norm":
        return tau0
    if null.shape[1] == 0:  # three wheels: no redundancy, every method gives τ0
        return tau0
    if method == "proportional" and criterion == "ratios":
        if null.shape[1] > 1:
            raise InvalidValueError(f"criterion 'ratios' is implemented for one redundant "
                                    f"torque (4 wheels), got {null.shape[1]}")
        return tau0 + null[:, 0] * equal_ratios(w * tau0, w * null[:, 0])[0]
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


def equal_ratios(a, b) -> tuple[float, float]:
    """The maximiser ``α`` of the ``"ratios"`` criterion and its value (module docstring):
    ``H(α) = (Σ |a_i + α b_i|)² / (N Σ (a_i + α b_i)²)``, the utilisations ``u(α) = a + α b``.

    Args:
        a: ``W τ0``, the least-norm torques' utilisations (N,) (any common scale).
        b: ``W n``, the null-space direction's (N,).

    Returns:
        ``(α, H [-])``; ``(0, 0)`` for a zero ``a`` (a zero wrench: zero torques).
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    P, Q, R = float(a @ a), float(a @ b), float(b @ b)
    if P == 0.0:
        return 0.0, 0.0
    moving = b != 0.0
    breaks = np.unique(-a[moving] / b[moving])  # where a utilisation changes sign
    # one sign pattern per interval between breakpoints (and beyond the outer ones)
    probes = np.concatenate([breaks[:1] - 1.0, 0.5 * (breaks[1:] + breaks[:-1]),
                             breaks[-1:] + 1.0]) if breaks.size else np.zeros(1)
    candidates = [breaks]
    for probe in probes:
        s = np.sign(a + probe * b)
        A, B = float(s @ a), float(s @ b)
        den = B * Q - A * R
        if den != 0.0:  # the maximising root of (A + B α)((B P − A Q) + (B Q − A R) α) = 0
            candidates.append(np.array([(A * Q - B * P) / den]))
    alphas = np.concatenate(candidates)
    u = a[None, :] + alphas[:, None] * b[None, :]
    values = np.abs(u).sum(axis=1) ** 2 / (a.size * np.einsum("ij,ij->i", u, u))
    best = values.max()
    # among (round-off) equals, the least |α|: the least-norm member
    ties = np.flatnonzero(values >= best - 1e-12 * best)
    i = ties[np.argmin(np.abs(alphas[ties]))]
    return float(alphas[i]), float(values[i])
