"""Differential-drive base (PAL Robotics PMB2, the base of Tiago).

Velocity coordinates: the base's own inputs ``(v [m/s], ω [rad/s])`` — forward speed of the
base frame's origin along its x axis and yaw rate. The body twist is ``(v, 0, ω)``; the
nonholonomic constraint (no lateral slip) is ``−sin θ ẋ + cos θ ẏ = 0``
(:meth:`PlanarBase.constraint_matrix`). A whole-body model with this base therefore has
``nv = nq − 1``.

Wheel kinematics, wheels ordered (left, right), separation ``b`` and radius ``r``::

    φ̇_left  = (v − ω b / 2) / r,     v = r (φ̇_right + φ̇_left) / 2,
    φ̇_right = (v + ω b / 2) / r,     ω = r (φ̇_right − φ̇_left) / b.
"""

from __future__ import annotations

import numpy as np

from wbc.checks import checked_number, checked_vector

from .planar_base import UNICYCLE_MAP, PlanarBase

__all__ = ["DifferentialDriveBase", "tiago_base"]


class DifferentialDriveBase(PlanarBase):
    """Two driven wheels on a common axle through the base origin.

    Args:
        separation: distance ``b`` [m] between the wheels' contact points.
        radius: wheel radius ``r`` [m].
        name: model name.
        mass: base body mass [kg]; ``com`` [m] and ``inertia`` [kg m²] in the base frame.
        v_max: limits of ``(v [m/s], ω [rad/s])``.
        a_max: acceleration limits ``(v̇ [m/s²], ω̇ [rad/s²])``.
    """

    velocity_names = ("v", "omega")
    holonomic = False
    body_map = UNICYCLE_MAP

    def __init__(
        self,
        separation: float,
        radius: float,
        *,
        name: str = "differential",
        mass: float,
        com,
        inertia,
        v_max,
        a_max,
    ) -> None:
        separation = checked_number(separation, "separation", strict=True)
        radius = checked_number(radius, "radius", strict=True)
        self.separation = float(separation)
        self.radius = float(radius)
        super().__init__(name, mass, com, inertia, v_max, a_max)
        half = 0.5 * self.separation
        # wheel rates = jacobian @ (v, ω)
        self.jacobian = np.array([[1.0, -half], [1.0, half]]) / self.radius

    n_wheels = 2

    def inverse(self, base_velocity) -> np.ndarray:
        """Wheel rates ``(φ̇_left, φ̇_right)`` [rad/s] for ``(v [m/s], ω [rad/s])``."""
        return self.jacobian @ checked_vector(base_velocity, 2, "base_velocity", broadcast=False)

    def forward(self, wheel_rates) -> np.ndarray:
        """``(v [m/s], ω [rad/s])`` from wheel rates ``(φ̇_left, φ̇_right)`` [rad/s]."""
        left, right = checked_vector(wheel_rates, 2, "wheel_rates", broadcast=False)
        return np.array(
            [0.5 * self.radius * (right + left), self.radius * (right - left) / self.separation]
        )


def tiago_base() -> DifferentialDriveBase:
    """The PMB2 base of PAL Robotics' Tiago, from example-robot-data's ``tiago.urdf``.

    Wheel radius 0.0985 m (height of ``base_link`` over ``base_footprint``), wheel separation
    0.4044 m (wheel joints at y = ±0.2022 m), base link mass 28.26649 kg with the URDF's inertia,
    its centre of mass at the wheel axle height. The base frame is ``base_footprint`` (on the
    floor). Limits: ``|v| ≤ 1.0`` m/s (the URDF's wheel speed limit 10.15 rad/s × 0.0985 m),
    ``|ω| ≤ 1.0`` rad/s and accelerations 1.0 m/s², 1.0 rad/s² (Petrič & Žlajpah's ωmax = 1,
    Δvmax = Δωmax = 1).
    """
    inertia = np.array(
        [
            [0.465408937, 0.002160024, -0.001760255],
            [0.002160024, 0.483193291, -0.000655952],
            [-0.001760255, -0.000655952, 0.550939703],
        ]
    )
    return DifferentialDriveBase(
        separation=0.4044,
        radius=0.0985,
        name="pmb2",
        mass=28.26649,
        com=[0.0, 0.0, 0.0985],
        inertia=inertia,
        v_max=[1.0, 1.0],
        a_max=[1.0, 1.0],
    )
