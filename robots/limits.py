"""Position, velocity and acceleration limits of a robot as plain arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wbc.errors import BoundsOrderError, NonFiniteError, ShapeError

__all__ = ["Limits"]


@dataclass(frozen=True)
class Limits:
    """Position, velocity and acceleration limits.

    Position limits are over the configuration ``q`` (size ``nq``); velocity and acceleration
    limits are over the velocity coordinates ``v`` (size ``nv``) — for a mobile base its own
    velocity coordinates first (see the base model), then the arm joints. Units follow the
    coordinates: [m] and [rad] for positions, [m/s] and [rad/s] for velocities, [m/s²] and
    [rad/s²] for accelerations. Unbounded entries are ``±inf`` (a base pose x, y, θ always;
    continuous arm joints too).

    Attributes:
        q_lower, q_upper: position limits, shape ``(nq,)``.
        v_lower, v_upper: velocity limits, shape ``(nv,)``.
        a_lower, a_upper: acceleration limits, shape ``(nv,)``.
    """

    q_lower: np.ndarray
    q_upper: np.ndarray
    v_lower: np.ndarray
    v_upper: np.ndarray
    a_lower: np.ndarray
    a_upper: np.ndarray

    def __post_init__(self) -> None:
        for lower, upper, label in (
            ("q_lower", "q_upper", "position"),
            ("v_lower", "v_upper", "velocity"),
            ("a_lower", "a_upper", "acceleration"),
        ):
            lo = np.array(getattr(self, lower), dtype=float)
            hi = np.array(getattr(self, upper), dtype=float)
            if lo.ndim != 1 or lo.shape != hi.shape:
                raise ShapeError(
                    f"{label} limits must be two 1-D arrays of equal size, got {lower} "
                    f"{lo.shape} and {upper} {hi.shape}"
                )
            if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
                raise NonFiniteError(f"{label} limits hold NaN")
            if np.any(lo > hi):
                bad = np.flatnonzero(lo > hi).tolist()
                raise BoundsOrderError(f"{label} lower limit exceeds upper at indices {bad}")
            lo.setflags(write=False)
            hi.setflags(write=False)
            object.__setattr__(self, lower, lo)
            object.__setattr__(self, upper, hi)
        if self.v_lower.shape != self.a_lower.shape:
            raise ShapeError(
                f"velocity limits {self.v_lower.shape} and acceleration limits "
                f"{self.a_lower.shape} must have the same size nv"
            )

    @property
    def nq(self) -> int:
        """Size of the position limits."""
        return self.q_lower.shape[0]

    @property
    def nv(self) -> int:
        """Size of the velocity and acceleration limits."""
        return self.v_lower.shape[0]
