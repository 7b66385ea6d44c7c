"""Four-mecanum-wheel base (Xing et al., eq. 16).

Wheels ordered front-left, front-right, rear-left, rear-right, at ``(±d1, ±d2)`` [m] from the
base origin (``d1`` half the wheelbase along x, ``d2`` half the track along y), rollers at 45°
in the usual "X" arrangement (seen from above, the rollers touching the floor form an X).
Wheel rates ``θ̇`` [rad/s] from the body twist ``(v_x, v_y, ω)`` in the base frame::

    θ̇ = (1/R) [[1, −1, −(d1 + d2)],
               [1,  1,  (d1 + d2)],
               [1,  1, −(d1 + d2)],
               [1, −1,  (d1 + d2)]] (v_x, v_y, ω)

(each row is the contact point's velocity projected on the direction perpendicular to the
wheel's bottom roller, divided by R). The forward map is the pseudo-inverse
``(R/4) [[1, 1, 1, 1], [−1, 1, 1, −1], [−1, 1, −1, 1]/(d1 + d2)]``.

Velocity coordinates: body twist ``(v_x, v_y, ω)`` in the base frame.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_number, checked_vector

from .planar_base import HOLONOMIC_MAP, PlanarBase, box_inertia

__all__ = ["MecanumBase", "mecanum_base"]


class MecanumBase(PlanarBase):
    """Four mecanum wheels on a rectangle.

    Args:
        radius: wheel radius ``R`` [m].
        half_wheelbase: ``d1`` [m], wheel x offset from the base origin.
        half_track: ``d2`` [m], wheel y offset from the base origin.
        name: model name.
        mass: base body mass [kg]; ``com`` [m] and ``inertia`` [kg m²] in the base frame.
        v_max: limits of ``(v_x [m/s], v_y [m/s], ω [rad/s])``.
        a_max: acceleration limits [m/s², m/s², rad/s²].
    """

    velocity_names = ("vx", "vy", "omega")
    holonomic = True
    body_map = HOLONOMIC_MAP
    n_wheels = 4

    def __init__(
        self,
        radius: float,
        half_wheelbase: float,
        half_track: float,
        *,
        name: str = "mecanum",
        mass: float,
        com,
        inertia,
        v_max,
        a_max,
    ) -> None:
        radius = checked_number(radius, "radius", strict=True)
        half_wheelbase = checked_number(half_wheelbase, "half_wheelbase", strict=True)
        half_track = checked_number(half_track, "half_track", strict=True)
        self.radius = float(radius)
        self.half_wheelbase = float(half_wheelbase)
        self.half_track = float(half_track)
        super().__init__(name, mass, com, inertia, v_max, a_max)
        k = self.half_wheelbase + self.half_track
        self.jacobian = (
            np.array([[1.0, -1.0, -k], [1.0, 1.0, k], [1.0, 1.0, -k], [1.0, -1.0, k]]) / self.radius
        )
        self._jacobian_pinv = np.linalg.pinv(self.jacobian)

    @property
    def wheel_positions(self) -> np.ndarray:
        """Wheel centres ``(x, y)`` [m] in the base frame, order FL, FR, RL, RR, shape (4, 2)."""
        d1, d2 = self.half_wheelbase, self.half_track
        return np.array([[d1, d2], [d1, -d2], [-d1, d2], [-d1, -d2]])

    def inverse(self, base_velocity) -> np.ndarray:
        """Wheel rates [rad/s] (FL, FR, RL, RR) for the body twist (base frame)."""
        return self.jacobian @ checked_vector(base_velocity, 3, "base_velocity", broadcast=False)

    def forward(self, wheel_rates) -> np.ndarray:
        """Body twist from wheel rates (least squares, exact for consistent rates)."""
        return self._jacobian_pinv @ checked_vector(wheel_rates, 4, "wheel_rates", broadcast=False)


def mecanum_base() -> MecanumBase:
    """The mecanum platform carrying the Kinova Gen3 of Xing et al.

    Xing et al. do not give the platform's dimensions; chosen here for a compact platform
    that carries a 7-DoF arm of 8 kg: ``R = 0.076`` m (6-inch mecanum wheels), ``d1 = 0.25`` m,
    ``d2 = 0.20`` m, body mass 40 kg.

    The base frame of this model lies **on the arm's mounting plane**, 0.30 m above the floor
    (so that Xing et al.'s start position [0.65, −0.0246, 0.4921] m is expressed in it, see
    :mod:`wbc.robots.catalogue`); the body is a box 0.64 × 0.50 × 0.30 m filling the space
    below it.

    Limits: Xing et al.'s Table 1, joints 1–3 (the base). The paper models the base as
    prismatic x, y and revolute θ joints with ±0.25 m/s, ±0.25 m/s, ±1.0 rad/s and ±0.025 m/s²,
    ±0.025 m/s², ±1.5 rad/s² (positions unbounded). Our base velocity coordinates are the
    body twist ``(v_x, v_y, ω)`` in the base frame, not the world rates ``(ẋ, ẏ, θ̇)``: the
    paper's x / y numbers are applied to ``v_x`` / ``v_y``. Both boxes coincide at θ = 0 (the
    paper's start, where its base frame is the world frame) and for ω; at other headings the
    body box is the world box rotated by θ (the paper's bounds on ẋ, ẏ allow up to √2 · 0.25 m/s
    along a diagonal of the world, ours along a diagonal of the base).
    """
    return MecanumBase(
        radius=0.076,
        half_wheelbase=0.25,
        half_track=0.20,
        name="mecanum",
        mass=40.0,
        com=[0.0, 0.0, -0.15],
        inertia=box_inertia(40.0, 0.64, 0.50, 0.30),
        v_max=[0.25, 0.25, 1.0],  # Xing et al., Table 1, joints 1-3
        a_max=[0.025, 0.025, 1.5],
    )
