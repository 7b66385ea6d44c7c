"""Steerable wheeled base: N steered and driven off-centred wheels (Neobotix MPO700).

Wheel model (Sorour, Cherubini, Fraisse; Table I gives the MPO700 values):

* wheel ``i`` steers about a vertical axis through its *hip* ``h_i = (h_x, h_y)`` [m] (base
  frame); its steering angle ``β_i`` [rad] is the angle from the base x axis to the wheel's
  rolling direction ``e_i = (cos β_i, sin β_i)``;
* the wheel is off-centred like a caster: its ground contact point trails the steering axis by
  the offset ``d`` [m], ``c_i = h_i − d e_i``;
* it rolls without slipping with radius ``r_w`` [m]; its drive rate ``φ̇_i`` [rad/s] is positive
  when it rolls along ``+e_i``.

Velocity coordinates: the body twist ``ξ = (v_x, v_y, ω)`` in the base frame. For a twist ``ξ``
and steering angles ``β`` the no-slip conditions at each contact point give the wheel rates
uniquely (the offset makes the steering rates a function of ``ξ``)::

    r_w φ̇_i = [cos β_i,  sin β_i,  h_x sin β_i − h_y cos β_i] ξ          (rolling)
    d   β̇_i = [−sin β_i, cos β_i,  h_x cos β_i + h_y sin β_i − d] ξ      (no lateral slip)

:meth:`SteerableBase.inverse` evaluates these, :meth:`SteerableBase.forward` solves them for ξ
in the least-squares sense (exact when the rates are consistent).

Instantaneous centre of rotation (ICR): for a twist, the point ``(−v_y/ω, v_x/ω)`` [m] of the
base frame, or homogeneously the unit vector ``X ∝ (−v_y, v_x, ω)`` (finite also for pure
translations, ``X₃ = 0``). For steering angles, the common point of the wheels' axle lines (each
through its contact point, perpendicular to ``e_i``), in the least-squares sense.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wbc.checks import checked_number, checked_vector
from wbc.errors import InvalidValueError, ShapeError

from .planar_base import HOLONOMIC_MAP, PlanarBase, box_inertia

__all__ = ["SteerableBase", "SteerableRates", "mpo700"]


class SteerableRates(NamedTuple):
    """Joint rates of a steerable base's wheels.

    Attributes:
        steer_rates: ``β̇`` [rad/s], shape (N,).
        drive_rates: ``φ̇`` [rad/s], shape (N,).
    """

    steer_rates: np.ndarray
    drive_rates: np.ndarray


class SteerableBase(PlanarBase):
    """N steerable, driven, off-centred wheels.

    Args:
        hips: hip positions ``(h_x, h_y)`` [m] in the base frame, shape (N, 2).
        offset: steering offset ``d`` [m] (> 0) between steering axis and contact point.
        radius: wheel radius ``r_w`` [m].
        name: model name.
        mass: base body mass [kg]; ``com`` [m] and ``inertia`` [kg m²] in the base frame.
        v_max: velocity limits of ``(v_x [m/s], v_y [m/s], ω [rad/s])``.
        a_max: acceleration limits of the same coordinates [m/s², m/s², rad/s²].
    """

    velocity_names = ("vx", "vy", "omega")
    holonomic = True
    body_map = HOLONOMIC_MAP

    def __init__(
        self,
        hips,
        offset: float,
        radius: float,
        *,
        name: str = "steerable",
        mass: float,
        com,
        inertia,
        v_max,
        a_max,
    ) -> None:
        hips = np.array(hips, dtype=float)
        if hips.ndim != 2 or hips.shape[1] != 2 or hips.shape[0] < 2:
            raise ShapeError(f"hips must have shape (N, 2) with N >= 2, got {hips.shape}")
        offset = checked_number(offset, "offset", strict=True)
        radius = checked_number(radius, "radius", strict=True)
        self.hips = hips
        self.offset = float(offset)
        self.radius = float(radius)
        super().__init__(name, mass, com, inertia, v_max, a_max)

    @property
    def n_wheels(self) -> int:
        """Number of wheels N."""
        return self.hips.shape[0]

    # ------------------------------------------------------------------ geometry
    def _steering(self, steering) -> np.ndarray:
        return checked_vector(steering, self.n_wheels, "steering", broadcast=False)

    def contact_points(self, steering) -> np.ndarray:
        """Ground contact points ``c_i = h_i − d e(β_i)`` [m] in the base frame, shape (N, 2)."""
        beta = self._steering(steering)
        return self.hips - self.offset * np.column_stack([np.cos(beta), np.sin(beta)])

    def no_slip_matrices(self, steering) -> tuple[np.ndarray, np.ndarray]:
        """Rolling and lateral rows of the no-slip conditions, each of shape (N, 3).

        Returns:
            ``(P, L)`` with ``r_w φ̇ = P ξ`` and ``d β̇ = L ξ`` for the body twist ξ.
        """
        beta = self._steering(steering)
        c, s = np.cos(beta), np.sin(beta)
        hx, hy = self.hips[:, 0], self.hips[:, 1]
        rolling = np.column_stack([c, s, hx * s - hy * c])
        lateral = np.column_stack([-s, c, hx * c + hy * s - self.offset])
        return rolling, lateral

    # ------------------------------------------------------------------ wheel kinematics
    def inverse(self, base_velocity, steering) -> SteerableRates:
        """Wheel rates that realise a body twist without slipping.

        Args:
            base_velocity: body twist ``(v_x [m/s], v_y [m/s], ω [rad/s])``, base frame.
            steering: current steering angles ``β`` [rad], shape (N,).

        Returns:
            :class:`SteerableRates` ``(β̇, φ̇)`` [rad/s].
        """
        twist = checked_vector(base_velocity, 3, "base_velocity", broadcast=False)
        rolling, lateral = self.no_slip_matrices(steering)
        return SteerableRates(lateral @ twist / self.offset, rolling @ twist / self.radius)

    def forward(self, drive_rates, steering, steer_rates) -> np.ndarray:
        """Body twist from measured wheel rates (least squares over the 2N no-slip rows).

        Args:
            drive_rates: ``φ̇`` [rad/s], shape (N,).
            steering: steering angles ``β`` [rad], shape (N,).
            steer_rates: ``β̇`` [rad/s], shape (N,).

        Returns:
            ``(v_x [m/s], v_y [m/s], ω [rad/s])`` in the base frame.
        """
        phi_dot = checked_vector(drive_rates, self.n_wheels, "drive_rates", broadcast=False)
        beta_dot = checked_vector(steer_rates, self.n_wheels, "steer_rates", broadcast=False)
        rolling, lateral = self.no_slip_matrices(steering)
        a = np.vstack([rolling, lateral])
        b = np.concatenate([self.radius * phi_dot, self.offset * beta_dot])
        return np.linalg.lstsq(a, b, rcond=None)[0]

    def contact_velocities(self, base_velocity, steering, steer_rates) -> np.ndarray:
        """Velocities [m/s] of the wheels' contact points (base axes), shape (N, 2).

        Computed geometrically from the rigid motion of the base and the steering rates:
        ``ċ_i = v + ω ẑ × c_i − d β̇_i ẑ × e_i``. Under no slip it is ``r_w φ̇_i e_i``.
        """
        vx, vy, omega = checked_vector(base_velocity, 3, "base_velocity", broadcast=False)
        beta = self._steering(steering)
        beta_dot = checked_vector(steer_rates, self.n_wheels, "steer_rates", broadcast=False)
        c = self.contact_points(beta)
        e_perp = np.column_stack([-np.sin(beta), np.cos(beta)])
        rigid = np.column_stack([vx - omega * c[:, 1], vy + omega * c[:, 0]])
        return rigid - self.offset * beta_dot[:, None] * e_perp

    # ------------------------------------------------------------------ ICR
    @staticmethod
    def icr_of_twist(base_velocity, homogeneous: bool = False) -> np.ndarray:
        """ICR of a body twist.

        Args:
            base_velocity: ``(v_x, v_y, ω)``, base frame.
            homogeneous: return the unit vector ``X ∝ (−v_y, v_x, ω)`` instead of the point.

        Returns:
            The point ``(−v_y/ω, v_x/ω)`` [m] in the base frame (``inf`` entries when ω = 0), or
            the unit 3-vector. A zero twist has no ICR: ``ValueError``.
        """
        vx, vy, omega = checked_vector(base_velocity, 3, "base_velocity", broadcast=False)
        h = np.array([-vy, vx, omega])
        norm = float(np.linalg.norm(h))
        if norm == 0.0:
            raise InvalidValueError("a zero twist has no instantaneous centre of rotation")
        if homogeneous:
            return h / norm
        if omega == 0.0:
            return np.full(2, np.inf)
        return h[:2] / omega

    def icr_of_steering(self, steering, homogeneous: bool = False) -> np.ndarray:
        """ICR of a steering configuration: least-squares common point of the axle lines.

        Each axle line passes through the contact point ``c_i`` perpendicular to ``e_i``:
        ``e_i · (p − c_i) = 0``. Homogeneously, ``X`` is the unit right singular vector of the
        rows ``[cos β_i, sin β_i, −e_i · c_i]`` with the smallest singular value, signed so that
        ``X₃ ≥ 0``.

        Returns:
            The point [m] (base frame; ``inf`` for parallel axles) or the unit 3-vector.
        """
        beta = self._steering(steering)
        e = np.column_stack([np.cos(beta), np.sin(beta)])
        c = self.contact_points(beta)
        rows = np.column_stack([e, -np.sum(e * c, axis=1)])
        x = np.linalg.svd(rows)[2][-1]
        if x[2] < 0.0 or (x[2] == 0.0 and x[0] < 0.0):
            x = -x
        if homogeneous:
            return x
        if abs(x[2]) < 1e-12:
            return np.full(2, np.inf)
        return x[:2] / x[2]

    def steering_for_twist(self, base_velocity, current=None) -> np.ndarray:
        """Steering angles at which the wheels can follow a constant twist without steering.

        With ``β̇ = 0`` the contact point ``c_i`` is fixed to the base, so its velocity must lie
        along ``e_i``: ``m sin(ψ − β) = d ω`` where ``m, ψ`` are the magnitude and direction of
        the hip velocity ``v + ω ẑ × h_i``. Of the two solutions (rolling forwards or backwards)
        the forward one is returned, or, when ``current`` is given, the one nearest to
        ``current`` (in angle, then expressed within π of it).

        When a hip lies within ``d`` of the ICR (``m < d |ω|``) no steady angle exists; the
        limiting angle ``ψ ∓ π/2`` is returned. A zero twist returns ``current`` (or zeros).

        Args:
            base_velocity: ``(v_x, v_y, ω)``, base frame.
            current: current steering angles [rad], shape (N,), optional.

        Returns:
            Steering angles [rad], shape (N,).
        """
        vx, vy, omega = checked_vector(base_velocity, 3, "base_velocity", broadcast=False)
        if current is not None:
            current = self._steering(current)
        hip_v = np.column_stack([vx - omega * self.hips[:, 1], vy + omega * self.hips[:, 0]])
        m = np.linalg.norm(hip_v, axis=1)
        if not np.any(m > 0.0):
            return np.zeros(self.n_wheels) if current is None else current.copy()
        psi = np.arctan2(hip_v[:, 1], hip_v[:, 0])
        ratio = np.clip(self.offset * omega / np.where(m > 0.0, m, 1.0), -1.0, 1.0)
        forward = psi - np.arcsin(ratio)
        if current is None:
            return _wrap(forward)
        backward = psi + math.pi + np.arcsin(ratio)
        d_fwd = np.abs(_wrap(forward - current))
        d_bwd = np.abs(_wrap(backward - current))
        chosen = np.where(d_fwd <= d_bwd, forward, backward)
        return current + _wrap(chosen - current)

    def steering_for_icr(self, icr, current=None) -> np.ndarray:
        """Steering angles whose axle lines meet at the ICR ``icr`` (homogeneous, (3,)).

        Same as :meth:`steering_for_twist` for the twist direction ``(X₂, −X₁, X₃)``.
        """
        x = checked_vector(icr, 3, "icr", broadcast=False)
        return self.steering_for_twist(np.array([x[1], -x[0], x[2]]), current)


def _wrap(angle):
    """Wrap angles [rad] to (−π, π]."""
    return -np.remainder(-np.asarray(angle) + math.pi, 2.0 * math.pi) + math.pi


def mpo700() -> SteerableBase:
    """Neobotix MPO700 with Sorour et al.'s Table I geometry.

    Wheels (order front-left, rear-left, rear-right, front-right) at hips
    ``(±0.24, ±0.19)`` m, steering offset ``d = 0.045`` m, radius ``r_w = 0.09`` m.

    Not in the paper, assumed here: body mass 70 kg, modelled as a solid box
    0.99 × 0.65 × 0.30 m centred 0.21 m above the floor (base frame origin on the floor,
    below the platform centre); limits ``|v_x|, |v_y| ≤ 0.9`` m/s, ``|ω| ≤ 1.0`` rad/s,
    accelerations 1.0 m/s² and 1.0 rad/s².
    """
    hx, hy = 0.24, 0.19
    return SteerableBase(
        [[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]],
        offset=0.045,
        radius=0.09,
        name="mpo700",
        mass=70.0,
        com=[0.0, 0.0, 0.21],
        inertia=box_inertia(70.0, 0.99, 0.65, 0.30),
        v_max=[0.9, 0.9, 1.0],
        a_max=[1.0, 1.0, 1.0],
    )
