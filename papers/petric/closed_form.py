r"""Closed form of Petrič & Žlajpah's two-stage rate limiter (eqs. 16–18).

The smoothed base command ``û_k`` (eqs. 14–15) is limited against the previous applied command
``u_{k−1}`` per component: first its change, then its value,

    ũ_k = ψ_{u_max}(u_{k−1} + ψ_{Δu_max}(û_k − u_{k−1})),      ψ_r(x) = clip(x, −r, r).

docs/DESIGN.md, math note 5: for 1-D intervals with a common point, clipping into one interval
and then into the other is the projection onto their intersection, so eqs. 16–17 are the QP

    min ½||u − û_k||²   s.t.   lower ≤ u ≤ upper,
    lower = clip(u_{k−1} − Δu_max, −u_max, u_max),   upper = clip(u_{k−1} + Δu_max, −u_max, u_max).

Clipping the rate interval's ends into ``[−u_max, u_max]`` keeps the QP feasible — and equal to
the two-stage clip — when the intervals do not meet (``|u_{k−1}| > u_max + Δu_max``, which the
field never produces since its ``u_{k−1}`` is itself saturated): then both give ``±u_max``.
This is the oracle of :meth:`wbc.tasks.VelocityField.rate_limit_level` and the limiter that
:meth:`wbc.tasks.VelocityField.step` applies.

Units follow the command: ``(v [m/s], ω [rad/s])``; the rate limits are changes per control
tick (``[m/s]``, ``[rad/s]`` per tick), as eqs. 16–17 print them.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import as_float_array, checked_vector
from wbc.errors import InvalidValueError, ShapeError

__all__ = ["rate_limit_interval", "rate_limited_twist"]


def _prepare(target, previous, limit, rate_limit):
    target = as_float_array(target, "target")
    if target.ndim != 1:
        raise ShapeError(f"target must be a vector, got shape {target.shape}")
    n = target.shape[0]
    limit, rate_limit = checked_vector(limit, n, "limit"), checked_vector(rate_limit, n,
                                                                            "rate_limit")
    for name, value in (("limit", limit), ("rate_limit", rate_limit)):
        if np.any(value <= 0.0):
            raise InvalidValueError(f"{name} must be > 0, got {value}")
    return (checked_vector(target, n, "target"), checked_vector(previous, n, "previous"),
            limit, rate_limit)


def rate_limited_twist(target, previous, limit, rate_limit) -> np.ndarray:
    """Eqs. 16–17: ``clip(previous + clip(target − previous, ±rate_limit), ±limit)``.

    Args:
        target: ``(n,)`` smoothed command ``û_k`` (for the base ``(v̂ [m/s], ω̂ [rad/s])``).
        previous: ``(n,)`` command applied at the previous tick ``u_{k−1}`` (or a scalar).
        limit: ``u_max > 0``, scalar or ``(n,)`` (``(v_max, ω_max)``).
        rate_limit: ``Δu_max > 0`` per tick, scalar or ``(n,)`` (``(Δv_max, Δω_max)``).

    Returns:
        ``(n,)`` limited command ``ũ_k``.
    """
    target, previous, limit, rate = _prepare(target, previous, limit, rate_limit)
    return np.clip(previous + np.clip(target - previous, -rate, rate), -limit, limit)


def rate_limit_interval(previous, limit, rate_limit) -> tuple[np.ndarray, np.ndarray]:
    """The QP's bounds ``(lower, upper)``, each ``(n,)``: the rate interval around ``previous``
    with its ends clipped into ``[−limit, limit]`` (see the module docstring).

    Args: as :func:`rate_limited_twist` (``previous`` must be a vector here).
    """
    previous = np.asarray(previous, dtype=np.float64)
    _, previous, limit, rate = _prepare(previous, previous, limit, rate_limit)
    return (np.clip(previous - rate, -limit, limit), np.clip(previous + rate, -limit, limit))
