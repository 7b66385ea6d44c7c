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

The paper's masses and the wheels' load:

* :data:`PLATFORM_MASS` (15 kg) and :data:`ARM_MASS` (30 kg) are the paper's; the catalogue's
  ``"omni4_arm6"`` carries a UR10 stand-in (about 32.7 kg). :func:`system_com` gives the whole
  system's mass (45 kg) and centre of mass with the paper's masses, the arm's 30 kg distributed
  like the stand-in's links, so that the centre of mass moves with the arm.
* :func:`normal_forces` splits the weight over the wheels (minimum-norm solution of the three
  equilibrium equations, i.e. an equal-stiffness suspension).
"""

from __future__ import annotations

import math
import weakref

import numpy as np
import pinocchio as pin

from wbc.checks import checked_number, checked_vector
from wbc.errors import InvalidValueError, ShapeError

from .planar_base import (
    HOLONOMIC_MAP,
    PlanarBase,
    cylinder_inertia,
)

__all__ = ["ARM_MASS", "PLATFORM_MASS", "OmniBase", "normal_forces", "omni4_octagon",
           "system_com"]

#: mass of the paper's platform [kg] ("about 15 kg").
PLATFORM_MASS = 15.0
#: mass of the paper's arm, a Mitsubishi RV-E3 [kg] ("about 30 kg").
ARM_MASS = 30.0
#: standard gravity [m/s²].
GRAVITY = 9.81


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
        distance = checked_number(distance, "distance", strict=True)
        radius = checked_number(radius, "radius", strict=True)
        self.distance = float(distance)
        self.radius = float(radius)
        super().__init__(name, mass, com, inertia, v_max, a_max)
        s, c = np.sin(self.angles), np.cos(self.angles)
        self.jacobian = np.column_stack([-s, c, np.full_like(s, self.distance)]) / self.radius
        self._jacobian_pinv = np.linalg.pinv(self.jacobian)

    @property
    def n_wheels(self) -> int:
        return self.angles.size

    @property
    def wheel_positions(self) -> np.ndarray:
        """Contact points ``L (cos α_i, sin α_i)`` [m] in the base frame, shape (N, 2)."""
        return self.distance * np.column_stack([np.cos(self.angles), np.sin(self.angles)])

    def inverse(self, base_velocity) -> np.ndarray:
        """Wheel rates ``J ξ`` [rad/s] for the body twist ξ (base frame)."""
        return self.jacobian @ checked_vector(base_velocity, 3, "base_velocity", broadcast=False)

    def forward(self, wheel_rates) -> np.ndarray:
        """Body twist ``J⁺ θ̇`` (least squares, exact for consistent wheel rates)."""
        rates = checked_vector(wheel_rates, self.n_wheels, "wheel_rates", broadcast=False)
        return self._jacobian_pinv @ rates

    def wrench(self, wheel_torques) -> np.ndarray:
        """Base wrench ``Jᵀ τ``: force (f_x, f_y) [N] in the base frame and torque [N m]."""
        torques = checked_vector(wheel_torques, self.n_wheels, "wheel_torques", broadcast=False)
        return self.jacobian.T @ torques


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


def normal_forces(wheel_xy, com_xy, mass: float, g: float = GRAVITY) -> np.ndarray:
    """Normal (vertical) contact forces ``f_i`` [N] of wheels on flat ground, at rest.

    Static equilibrium of the whole system gives three equations in the N forces: the vertical
    forces carry the weight (``Σ f_i = m g``, the paper's eq. 8 with weight ``m g``) and their
    moments about the base's x and y axes balance the weight's (``Σ f_i x_i = m g x_c``,
    ``Σ f_i y_i = m g y_c``). With four wheels the system is statically indeterminate (one
    force combination is free). We take the minimum-norm solution ``f = A⁺ b``: it is the one
    of a rigid platform on N equally stiff suspensions (the deflections, hence the forces, are
    an affine function of the contact position — exactly the row space of ``A``), the standard
    choice when nothing is known about the springs.

    Args:
        wheel_xy: contact points ``(x_i, y_i)`` [m], shape (N, 2), N ≥ 3, not all on one line
            (e.g. :attr:`OmniBase.wheel_positions`).
        com_xy: horizontal position of the centre of mass [m], shape (2,) (or (3,): z is
            ignored), in the same frame as ``wheel_xy``.
        mass: total mass [kg], > 0.
        g: gravity [m/s²], > 0.

    Returns:
        ``f`` [N], shape (N,), all ≥ 0.

    Raises:
        ShapeError, NonFiniteError: malformed input.
        InvalidValueError: ``mass`` or ``g`` not positive; contacts on one line; a force of the
            minimum-norm solution is negative — the ground would have to pull a wheel down:
            that wheel lifts (with four wheels this happens once the centre of mass leaves the
            diamond spanned by the contacts' mid-edges, before the platform tips over). We raise
            rather than return a meaningless split.
    """
    wheel_xy = np.asarray(wheel_xy, dtype=float)
    if wheel_xy.ndim != 2 or wheel_xy.shape[1] != 2 or wheel_xy.shape[0] < 3:
        raise ShapeError(f"wheel_xy must have shape (N, 2) with N >= 3, got {wheel_xy.shape}")
    com = np.asarray(com_xy, dtype=float)
    if com.shape not in ((2,), (3,)):
        raise ShapeError(f"com_xy must have shape (2,) (or (3,)), got {com.shape}")
    checked_vector(wheel_xy.ravel(), wheel_xy.size, "wheel_xy", broadcast=False)
    com = checked_vector(com[:2], 2, "com_xy", broadcast=False)
    if not (np.isfinite(mass) and mass > 0):
        raise InvalidValueError(f"mass must be a positive number [kg], got {mass!r}")
    if not (np.isfinite(g) and g > 0):
        raise InvalidValueError(f"g must be a positive number [m/s²], got {g!r}")
    A = np.vstack([np.ones(len(wheel_xy)), wheel_xy.T])
    # A has full row rank iff the contacts are not collinear; then A⁺ = Aᵀ (A Aᵀ)⁻¹, a 3 × 3
    # solve (a tenth of the cost of an SVD-based rank test and pinv, this runs every tick)
    gram = A @ A.T
    if np.linalg.det(gram) <= 1e-12 * np.trace(gram) ** 3:
        raise InvalidValueError("wheel_xy: the contact points lie on one line, the platform is "
                                "not supported")
    weight = mass * g
    forces = A.T @ np.linalg.solve(gram, weight * np.array([1.0, com[0], com[1]]))
    if forces.min() < -1e-9 * weight:
        raise InvalidValueError(
            f"com_xy = {com}: the minimum-norm normal forces {forces.round(3)} N include a "
            "negative one — a wheel would lift (the centre of mass is too far out)")
    return np.maximum(forces, 0.0)


#: pinocchio data of each robot's arm model, made once (system_com runs every tick)
_ARM_DATA: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def system_com(robot, q, frame: str = "world") -> tuple[float, np.ndarray]:
    """Mass [kg] and centre of mass [m] of the paper's platform + arm in configuration ``q``.

    The platform weighs :data:`PLATFORM_MASS` with its centre of mass where the robot's base
    model puts it (``robot.base.com``); the arm weighs :data:`ARM_MASS`, its centre of mass that
    of the robot's arm model (all its links, its fixed root link included) for the arm joints of
    ``q`` — i.e. the paper's 30 kg distributed like the stand-in arm's links.

    Args:
        robot: a :class:`~wbc.robots.MobileManipulator` on an omni base (``"omni4_arm6"``).
        q: configuration ``[x, y, θ, arm joints]``, shape (nq,).
        frame: ``"world"`` or ``"base"`` (the frame of :func:`normal_forces`' ``wheel_xy``).

    Returns:
        ``(mass, com)``: 45.0 kg and the (3,) centre of mass.
    """
    if frame not in ("world", "base"):
        raise InvalidValueError(f"frame must be 'world' or 'base', got {frame!r}")
    q = checked_vector(q, robot.nq, "q", broadcast=False)
    arm = robot.arm.model
    data = _ARM_DATA.get(robot)
    if data is None:
        data = _ARM_DATA[robot] = arm.createData()
    # pinocchio's centre of mass leaves out the root link (the universe joint's inertia, fixed
    # in the arm's frame); every body of the arm counts here
    moving = pin.centerOfMass(arm, data, q[3:])
    root = arm.inertias[0]
    arm_mass = data.mass[0] + root.mass
    arm_com = robot.mount.act((data.mass[0] * moving + root.mass * root.lever) / arm_mass)
    mass = PLATFORM_MASS + ARM_MASS
    com = (PLATFORM_MASS * np.asarray(robot.base.com, dtype=float) + ARM_MASS * arm_com) / mass
    if frame == "world":
        c, s = math.cos(q[2]), math.sin(q[2])
        com = np.array([q[0] + c * com[0] - s * com[1], q[1] + s * com[0] + c * com[1], com[2]])
    return mass, com
