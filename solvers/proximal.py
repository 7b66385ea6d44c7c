"""Proximal-point iterations: a convex QP with a positive *semi*-definite (even zero) Hessian,
solved through a solver that needs a positive-definite one.

Each iteration solves the regularised problem

    minimise 1/2 x' (H + mu I) x + (g - mu x_k)' x   subject to the original constraints,

whose minimiser ``x_{k+1}`` is the proximal step from ``x_k``; the iterates converge to a
minimiser of the original QP (linearly, at the rate ``mu / (mu + lambda)`` along each curvature
``lambda`` of ``H``; an LP terminates finitely), and the last solve's multipliers satisfy the
original KKT conditions up to ``mu * |x_{k+1} - x_k|``. On degenerate problems (a singular
``H`` with the optimum at a vertex of the bounds, as in the levels after a task-scaling LP) the
linear rate can be 0.98; so whenever a step is more than half the previous one, ``mu`` is divided
by 10, down to ``mu_min`` (each division costs conditioning: ``||H|| / mu``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import lapack


def is_positive_definite(H: np.ndarray, rcond: float = 1e-12) -> bool:
    """Whether ``H`` has a Cholesky factor whose pivots all exceed ``rcond * max(diag(H))``.

    The pivot test runs on Python floats: on a matrix of a few dozen entries, ``np.diagonal`` and
    numpy's reductions cost about a microsecond each, more than the factorisation.
    """
    factor, info = lapack.dpotrf(H)  # LAPACK directly: numpy's cholesky costs 5x more here
    # info == 0: the factor's diagonal is positive, so its smallest square is the smallest pivot.
    return info == 0 and min(factor.diagonal().tolist()) ** 2 > rcond * max(H.diagonal().tolist())


OPTION_NAMES = ("prox_mu", "prox_tol", "prox_max_iter")
"""Backend options that set the :class:`ProximalPoint` fields ``mu``, ``tol``, ``max_iter``."""


@dataclass(frozen=True)
class ProximalPoint:
    """Settings of the proximal-point iterations.

    Attributes:
        mu: regularisation relative to the data: the absolute value is
            ``mu * max(||H||_inf, ||g||_inf)`` (in the units of ``H``, taking a length
            scale of 1 for ``x`` when ``H = 0``). Smaller converges in fewer iterations but each
            regularised QP is worse conditioned (``||H|| / mu``).
        tol: stop when ``max|x_{k+1} - x_k| <= tol * max(1, max|x_{k+1}|)``.
        max_iter: iteration limit.
        mu_min: floor of ``mu`` (relative, like ``mu``) when slow convergence shrinks it.
    """

    mu: float = 1e-3
    tol: float = 1e-10
    max_iter: int = 100
    mu_min: float = 1e-7

    @classmethod
    def from_options(cls, options: dict) -> ProximalPoint:
        """Settings from the ``prox_*`` entries of a backend's options (others are ignored)."""
        return cls(mu=options.get("prox_mu", cls.mu), tol=options.get("prox_tol", cls.tol),
                   max_iter=options.get("prox_max_iter", cls.max_iter))

    def run(
        self,
        solve: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, Any]],
        H: np.ndarray,
        g: np.ndarray,
        x0: np.ndarray,
    ) -> tuple[np.ndarray, Any, int, bool]:
        """Iterate from ``x0``.

        Args:
            solve: ``solve(H_reg, g_k) -> (x, extra)`` solves the regularised QP under the
                original constraints (it raises on failure; the exception propagates).
            H: PSD Hessian, ``(n, n)``.
            g: linear term, ``(n,)``.
            x0: starting point, ``(n,)``.

        Returns:
            ``(x, extra, iterations, converged)`` of the last solve.
        """
        scale = max(float(np.abs(H).sum(axis=1).max(initial=0.0)), float(np.abs(g).max()))
        scale = scale if scale > 0.0 else 1.0
        mu, mu_min = self.mu * scale, self.mu_min * scale
        H_reg = H + mu * np.eye(len(g))
        x = np.asarray(x0, dtype=float)
        extra, previous = None, np.inf
        for iteration in range(1, self.max_iter + 1):
            x_next, extra = solve(H_reg, g - mu * x)
            step = np.abs(x_next - x).max(initial=0.0)
            x = x_next
            if step <= self.tol * max(1.0, np.abs(x).max(initial=0.0)):
                return x, extra, iteration, True
            if step > 0.5 * previous and mu > mu_min:  # slow: a smaller mu converges faster
                mu = max(mu / 10.0, mu_min)
                H_reg = H + mu * np.eye(len(g))
            previous = step
        return x, extra, self.max_iter, False
