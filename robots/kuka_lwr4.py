"""KUKA LWR-IV (7 DoF), built in code from its published kinematic parameters.

Kinematics: the standard LWR-IV geometry — base to shoulder ``d_bs = 0.31`` m, shoulder to
elbow ``d_se = 0.40`` m, elbow to wrist ``d_ew = 0.39`` m, wrist to flange ``d_wf = 0.078`` m,
all link offsets ``a = 0`` — in Craig's modified Denavit–Hartenberg form, with the twists used
throughout the LWR literature (e.g. Jubien, Gautier & Janot, "Dynamic identification of the
Kuka LWR robot using motor torques and joint torque sensors data", IFAC 2014)::

    i   α_{i−1}   a_{i−1}   d_i
    1     0         0       0.31
    2    π/2        0       0
    3   −π/2        0       0.40
    4   −π/2        0       0
    5    π/2        0       0.39
    6    π/2        0       0
    7   −π/2        0       0
    flange: 0.078 along z7

At ``q = 0`` the arm stands straight up (flange at 1.178 m) and the joint axes are
z, −y, z, +y, z, −y, z of the arm's base frame.

Limits (KUKA LWR 4+ specification): positions ±170° (A1, A3, A5, A7), ±120° (A2, A4, A6);
velocities 110, 110, 128, 128, 204, 184, 184 °/s. Acceleration limits are not published:
assumed 10 rad/s².

Inertia: KUKA publishes only the total mass (16 kg). The split used here is an approximation
(fixed base 2.0 kg; links 2.7, 2.7, 2.5, 2.5, 1.7, 1.6, 0.3 kg), each link a solid cylinder of
radius 0.07 m along its segment. It serves the whole-system centre of mass, not dynamics.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .arms import Arm, Segment, build_serial_arm, rotation_x
from .planar_base import cylinder_inertia

__all__ = ["kuka_lwr4"]

#: (α_{i−1} [rad], a_{i−1} [m], d_i [m]) of Craig's modified DH table.
MDH = (
    (0.0, 0.0, 0.31),
    (math.pi / 2, 0.0, 0.0),
    (-math.pi / 2, 0.0, 0.40),
    (-math.pi / 2, 0.0, 0.0),
    (math.pi / 2, 0.0, 0.39),
    (math.pi / 2, 0.0, 0.0),
    (-math.pi / 2, 0.0, 0.0),
)
FLANGE = 0.078

#: per link: mass [kg], z of the centre of mass at q = 0 [m], cylinder length [m]
_LINKS = (
    (2.7, 0.21, 0.20),
    (2.7, 0.41, 0.20),
    (2.5, 0.61, 0.20),
    (2.5, 0.81, 0.20),
    (1.7, 1.00, 0.19),
    (1.6, 1.10, 0.12),
    (0.3, 1.14, 0.08),
)
_BASE = (2.0, 0.055, 0.11)
_RADIUS = 0.07


def _inertia_at_zero(mass: float, com_z: float, length: float, pose: pin.SE3) -> pin.Inertia:
    """A vertical cylinder given in the arm base frame at q = 0, expressed in frame ``pose``."""
    rot = pose.rotation
    com_local = rot.T @ (np.array([0.0, 0.0, com_z]) - pose.translation)
    inertia_local = rot.T @ cylinder_inertia(mass, _RADIUS, length) @ rot
    return pin.Inertia(mass, com_local, inertia_local)


def kuka_lwr4() -> Arm:
    """The KUKA LWR-IV arm; end effector ``lwr_flange`` (no tool)."""
    placements = []
    for alpha, a, d in MDH:
        placements.append(
            pin.SE3(rotation_x(alpha), np.array([a, 0.0, 0.0]))
            * pin.SE3(np.eye(3), np.array([0.0, 0.0, d]))
        )
    pose = pin.SE3.Identity()
    segments = []
    for k, (placement, (mass, com_z, length)) in enumerate(zip(placements, _LINKS, strict=True)):
        pose = pose * placement
        segments.append(
            Segment(
                f"lwr_joint_{k + 1}",
                placement,
                f"lwr_link_{k + 1}",
                _inertia_at_zero(mass, com_z, length, pose),
            )
        )
    deg = math.pi / 180.0
    q_max = np.array([170, 120, 170, 120, 170, 120, 170]) * deg
    return build_serial_arm(
        "kuka_lwr4",
        segments,
        base_body="lwr_link_0",
        base_inertia=_inertia_at_zero(*_BASE, pin.SE3.Identity()),
        tool_frame="lwr_flange",
        tool_placement=pin.SE3(np.eye(3), np.array([0.0, 0.0, FLANGE])),
        q_lower=-q_max,
        q_upper=q_max,
        v_max=np.array([110, 110, 128, 128, 204, 184, 184]) * deg,
        a_max=np.full(7, 10.0),
        home=np.array([0.0, -0.4, 0.0, 1.4, 0.0, -1.0, 0.0]),
        source="modified DH of the KUKA LWR-IV (d = 0.31, 0.40, 0.39, 0.078 m); "
        "approximate inertia",
    )
