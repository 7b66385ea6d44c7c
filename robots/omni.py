"""Four-omni-wheel base on an octagonal platform (torque-redundancy paper).

Geometry: wheel ``i`` (i = 0..3) sits on the platform's radius at angle ``α_i = π/4 + i π/2``
[rad] from the base x axis, its contact point at distance ``L`` [m] from the centre, and drives
tangentially along ``u_i = (−sin α_i, cos α_i)`` (the 12 passive rollers let it slide freely
along the radius). Wheel ``i`` turns at ``θ̇_i = u_i · (velocity of its contact point) / r``, so
for a base displacement ``Δx = (Δx, Δy, Δφ)`` expressed in the base frame::

    Δθ = J Δx,    J = (1/r) [[−sin α_i, cos α_i, L]]_i    (4 × 3)

and, by virtual work, wheel torques ``τ`` [N m] produce the base wrench ``Jᵀ τ`` (force [N] in
the base frame, torque [N m]). ``J`` has full column rank; ``Jᵀ`` has a one-dimensional null
space — the torque redundancy the paper exploits.

Velocity coordinates: body twist ``(v_x, v_y, ω)`` in the base frame.
"""

from __future__ import annotations

import math

import numpy as np

from wbc.errors import InvalidValueError

from .planar_base import (
    HOLONOMIC_MAP,
    PlanarBase,
    as_vector,
    cylinder_inertia,
    require_positive,
)

__all__ = ["OmniBase", "omni4_octagon"]


class OmniBase(PlanarBase):
    """Omni wheels tangent to a circle of radius ``L`` around the base origin.

    Args:
        angles: wheel placement angles ``α_i`` [rad], shape (N,), N ≥ 3.
        distance: ``L`` [m], centre-to-contact distance.
        radius: wheel radius ``r`` [m].
        name: model name.
        mass: base body mass [kg]; ``com`` [m] and ``inertia`` [kg m²] in the base frame.
        v_max: limits of ``(v_x [m/s], v_y [m/s], ω [rad/s])``.
        a_max: acceleration limits [m/s², m/s², rad/s²].
    """

    velocity_names = ("vx", "vy", "omega")
    holonomic = True
    body_map = HOLONOMIC_MAP

    def __init__(
        self,
        angles,
        distance: float,
        radius: float,
        *,
        name: str = "omni",
        mass: float,
        com,
        inertia,
        v_max,
        a_max,
    ) -> None:
        self.angles = np.array(angles, dtype=float)
        if self.angles.ndim != 1 or self.angles.size < 3:
            raise InvalidValueError(
                f"an omni base needs at least 3 wheel angles, got {self.angles}")
        require_positive(distance=distance, radius=radius)
        self.distance = float(distance)
        self.radius = float(radius)
        super().__init__(name, mass, com, inertia, v_max, a_max)
        s, c = np.sin(self.angles), np.cos(self.angles)
        self.jacobian = np.column_stack([-s, c, np.full_like(s, self.distance)]) / self.radius
        self._jacobian_pinv = np.linalg.pinv(self.jacobian)

    @property
    def n_wheels(self) -> int:
        return self.angles.size

    def inverse(self, base_velocity) -> np.ndarray:
        """Wheel rates ``J ξ`` [rad/s] for the body twist ξ (base frame)."""
        return self.jacobian @ as_vector(base_velocity, 3, "base_velocity")

    def forward(self, wheel_rates) -> np.ndarray:
        """Body twist ``J⁺ θ̇`` (least squares, exact for consistent wheel rates)."""
        return self._jacobian_pinv @ as_vector(wheel_rates, self.n_wheels, "wheel_rates")

    def wrench(self, wheel_torques) -> np.ndarray:
        """Base wrench ``Jᵀ τ``: force (f_x, f_y) [N] in the base frame and torque [N m]."""
        return self.jacobian.T @ as_vector(wheel_torques, self.n_wheels, "wheel_torques")


def omni4_octagon() -> OmniBase:
    """The paper's platform: four omni wheels (12 rollers each), octagon 500 mm wide, 15 kg.

    Given by the paper: wheel diameter 0.2 m (r = 0.1 m), platform width 0.5 m, mass 15 kg.
    Assumed here: wheels on alternate faces of the octagon at ``α = 45°, 135°, 225°, 315°``
    with their contact points ``L = 0.225`` m from the centre (the face's apothem 0.25 m minus
    half a 50 mm wheel width); the platform body is a cylinder of radius 0.26 m and 0.1 m
    height centred 0.1 m above the floor (base frame on the floor); limits 1.0 m/s, 1.0 rad/s,
    1.0 m/s², 1.0 rad/s².
    """
    return OmniBase(
        [math.pi / 4 + k * math.pi / 2 for k in range(4)],
        distance=0.225,
        radius=0.1,
        name="omni4_octagon",
        mass=15.0,
        com=[0.0, 0.0, 0.1],
        inertia=cylinder_inertia(15.0, 0.26, 0.1),
        v_max=[1.0, 1.0, 1.0],
        a_max=[1.0, 1.0, 1.0],
    )
