"""What every wheeled base has in common: a planar pose and its own velocity coordinates.

Conventions shared by every base model:

* **Pose** ``(x, y, θ)``: position [m] of the base frame's origin in the world's horizontal plane
  and its heading θ [rad] about the world's vertical axis. The base frame has its x axis
  forward, z axis up; where its origin sits (floor or mounting plate) is stated per robot.
* **Velocity coordinates** ``v_b`` (size ``nv``): the base's own inputs, always expressed in the
  **base frame**. Holonomic bases (steerable, omni, mecanum) use the body twist
  ``(v_x [m/s], v_y [m/s], ω [rad/s])``; the differential drive uses ``(v [m/s], ω [rad/s])``,
  i.e. the body twist ``(v, 0, ω)``. A constant matrix ``B`` (3 × nv) maps ``v_b`` to the body
  twist.
* ``H(θ) = Rz(θ) B`` maps ``v_b`` to the pose rates ``(ẋ, ẏ, θ̇)`` in the world.
* ``J_b(r)`` maps pose rates to the twist of a frame whose origin lies at ``r`` [m] (world axes)
  from the base origin, with rows ``[linear; angular]`` (origin velocity and angular velocity in
  world axes). The product ``J_b(r) H(θ)`` — Sorour et al.'s ``H J_b`` — is
  :meth:`PlanarBase.twist_matrix`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np
import pinocchio as pin

__all__ = ["PlanarBase", "PlanarRoot", "HOLONOMIC_MAP", "UNICYCLE_MAP"]

#: body map ``B`` of holonomic bases: the velocity coordinates are the body twist.
HOLONOMIC_MAP = np.eye(3)
HOLONOMIC_MAP.setflags(write=False)
#: body map ``B`` of the differential drive: ``(v, ω) -> (v, 0, ω)``.
UNICYCLE_MAP = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
UNICYCLE_MAP.setflags(write=False)


class PlanarBase(ABC):
    """Abstract wheeled base moving in the plane.

    Subclasses set the class attributes and implement the wheel kinematics
    (:meth:`forward`, :meth:`inverse`).

    Attributes:
        name: short name of the base model.
        velocity_names: names of the velocity coordinates, e.g. ``("vx", "vy", "omega")``.
        holonomic: whether any body twist is feasible.
        body_map: ``B`` (3 × nv), base velocity coordinates -> body twist ``(v_x, v_y, ω)``.
        mass: mass of the base body [kg].
        com: centre of mass of the base body in the base frame [m], shape (3,).
        inertia: rotational inertia about the centre of mass, base axes [kg m²], (3, 3).
        v_max: symmetric velocity limits of the velocity coordinates, shape (nv,).
        a_max: symmetric acceleration limits of the velocity coordinates, shape (nv,).
    """

    name: str
    velocity_names: tuple[str, ...]
    holonomic: bool
    body_map: np.ndarray
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray

    def __init__(self, name: str, mass: float, com, inertia, v_max, a_max) -> None:
        """Store the physical data every base has (see the class attributes for units)."""
        self.name = name
        self.mass = float(mass)
        self.com = np.array(com, dtype=float)
        self.inertia = np.array(inertia, dtype=float)
        self.v_max = np.array(v_max, dtype=float)
        self.a_max = np.array(a_max, dtype=float)

    @property
    def nv(self) -> int:
        """Number of velocity coordinates of the base (3 holonomic, 2 differential drive)."""
        return len(self.velocity_names)

    # ------------------------------------------------------------------ planar maps
    def pose_rate_matrix(self, theta: float, out: np.ndarray | None = None) -> np.ndarray:
        """``H(θ)`` (3 × nv): base velocity coordinates -> world pose rates ``(ẋ, ẏ, θ̇)``."""
        c, s = math.cos(theta), math.sin(theta)
        if out is None:
            out = np.empty((3, self.nv))
        # filled from Python floats: one assignment, no temporary arrays (hot path)
        if self.nv == 3 and self.body_map is HOLONOMIC_MAP:
            out[:] = ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))
        elif self.nv == 2 and self.body_map is UNICYCLE_MAP:
            out[:] = ((c, 0.0), (s, 0.0), (0.0, 1.0))
        else:
            np.matmul(
                np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), self.body_map, out=out
            )
        return out

    def pose_rate_drift(self, theta: float, base_velocity) -> np.ndarray:
        """``Ḣ v_b`` (3,): the pose acceleration at constant base velocity coordinates.

        With ``ṗ = H(θ) v_b`` and θ̇ = ω, ``p̈ = H v̇_b + ω (dH/dθ) v_b``; this returns the
        second term [m/s², m/s², rad/s²].
        """
        twist = self.body_map @ np.asarray(base_velocity, dtype=float)
        c, s = math.cos(theta), math.sin(theta)
        omega = twist[2]
        return np.array(
            [
                omega * (-s * twist[0] - c * twist[1]),
                omega * (c * twist[0] - s * twist[1]),
                0.0,
            ]
        )

    def twist_matrix(self, theta: float, offset) -> np.ndarray:
        """``J_b(r) H(θ)`` (6 × nv): base velocity coordinates -> twist of a frame on the robot.

        Args:
            theta: base heading [rad].
            offset: ``r`` [m], position of the frame's origin minus the base origin, world axes
                (only its x and y matter), shape (2,) or (3,).

        Returns:
            Rows ``[linear; angular]`` of the frame's twist, world axes (the whole-body
            Jacobian's base columns with ``reference="world"``).
        """
        r = np.asarray(offset, dtype=float)
        jb = np.zeros((6, 3))
        jb[0, 0] = jb[1, 1] = jb[5, 2] = 1.0
        jb[0, 2] = -r[1]
        jb[1, 2] = r[0]
        return jb @ self.pose_rate_matrix(theta)

    def constraint_matrix(self, theta: float) -> np.ndarray:
        """Kinematic constraints ``A(θ) (ẋ, ẏ, θ̇) = 0``, shape ``(3 − nv, 3)``.

        Empty for holonomic bases; the no-lateral-slip row for the differential drive.
        """
        if self.nv == 3:
            return np.zeros((0, 3))
        h = self.pose_rate_matrix(theta)
        # rows spanning the left null space of H(θ)
        u, _, _ = np.linalg.svd(h)
        return u[:, self.nv :].T.copy()

    def integrate_pose(self, pose, base_velocity, dt: float) -> np.ndarray:
        """Exact pose after ``dt`` [s] at constant base velocity coordinates.

        The body twist is constant, so the motion is the SE(2) exponential: an arc of a circle
        (or a straight line when ω = 0).

        Args:
            pose: ``(x, y, θ)`` [m, m, rad].
            base_velocity: base velocity coordinates ``v_b``.
            dt: duration [s].

        Returns:
            ``(x, y, θ)`` after ``dt``; θ is not wrapped.
        """
        x, y, theta = pose
        vx, vy, omega = self.body_map @ np.asarray(base_velocity, dtype=float)
        angle = omega * dt
        if abs(angle) < 1e-9:
            # series of sin(a)/a and (1 - cos(a))/a
            sa, ca = 1.0 - angle * angle / 6.0, angle / 2.0
        else:
            sa, ca = math.sin(angle) / angle, (1.0 - math.cos(angle)) / angle
        dx_body = (sa * vx - ca * vy) * dt
        dy_body = (ca * vx + sa * vy) * dt
        c, s = math.cos(theta), math.sin(theta)
        return np.array(
            [x + c * dx_body - s * dy_body, y + s * dx_body + c * dy_body, theta + angle]
        )

    # ------------------------------------------------------------------ limits, inertia
    @property
    def v_lower(self) -> np.ndarray:
        return -np.asarray(self.v_max, dtype=float)

    @property
    def v_upper(self) -> np.ndarray:
        return np.asarray(self.v_max, dtype=float)

    @property
    def a_lower(self) -> np.ndarray:
        return -np.asarray(self.a_max, dtype=float)

    @property
    def a_upper(self) -> np.ndarray:
        return np.asarray(self.a_max, dtype=float)

    def spatial_inertia(self) -> pin.Inertia:
        """The base body's inertia as a pinocchio ``Inertia`` in the base frame."""
        return pin.Inertia(
            float(self.mass), np.asarray(self.com, float), np.asarray(self.inertia, float)
        )

    # ------------------------------------------------------------------ wheel kinematics
    @abstractmethod
    def forward(self, *args, **kwargs) -> np.ndarray:
        """Wheel rates -> base velocity coordinates (least squares when over-determined)."""

    @abstractmethod
    def inverse(self, base_velocity, *args, **kwargs):
        """Base velocity coordinates -> wheel rates."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, velocity={self.velocity_names})"


class PlanarRoot(PlanarBase):
    """A holonomic planar root without wheels and without velocity or acceleration limits:
    what ``wbc.robots.from_urdf(path, root="planar")`` puts under a whole-robot URDF.

    Its velocity coordinates are the body twist ``(v_x [m/s], v_y [m/s], ω [rad/s])`` in the
    base frame (``B = I``). It has no wheel kinematics: :meth:`forward` and :meth:`inverse` are
    the identity on the body twist. The body (mass [kg], centre of mass [m] and rotational
    inertia [kg m²] in the base frame) is the URDF's root link's.
    """

    velocity_names = ("vx", "vy", "omega")
    holonomic = True
    body_map = HOLONOMIC_MAP
    n_wheels = 0

    def __init__(self, name: str = "planar", mass: float = 0.0, com=(0.0, 0.0, 0.0),
                 inertia=None) -> None:
        inertia = np.zeros((3, 3)) if inertia is None else inertia
        inf = np.full(3, np.inf)
        super().__init__(name, mass, com, inertia, inf, inf.copy())

    def forward(self, body_twist) -> np.ndarray:  # type: ignore[override]
        """The body twist ``(v_x, v_y, ω)`` itself (no wheels)."""
        return np.array(body_twist, dtype=float)

    def inverse(self, base_velocity) -> np.ndarray:  # type: ignore[override]
        """The body twist ``(v_x, v_y, ω)`` itself (no wheels)."""
        return np.array(base_velocity, dtype=float)


def box_inertia(mass: float, size_x: float, size_y: float, size_z: float) -> np.ndarray:
    """Rotational inertia [kg m²] of a solid box about its centre, axes along its edges."""
    return (mass / 12.0) * np.diag(
        [size_y**2 + size_z**2, size_x**2 + size_z**2, size_x**2 + size_y**2]
    )


def cylinder_inertia(mass: float, radius: float, height: float) -> np.ndarray:
    """Rotational inertia [kg m²] of a solid vertical cylinder about its centre."""
    side = mass * (3.0 * radius**2 + height**2) / 12.0
    return np.diag([side, side, 0.5 * mass * radius**2])
