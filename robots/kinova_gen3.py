"""Kinova Gen3 (7 DoF, spherical wrist), built in code from Kinova's published parameters.

Kinematics and inertia: the joint origins and link inertial parameters Kinova publishes in its
``ros_kortex`` description of the Gen3 7-DoF arm (all joints turn about their local z; ``Rx(φ)``
is a rotation about x)::

    joint   parent -> joint translation [m]       rotation
    1       (0, 0, 0.15643)                        Rx(π)
    2       (0, 0.005375, −0.12838)                Rx(π/2)
    3       (0, −0.21038, −0.006375)               Rx(−π/2)
    4       (0, 0.006375, −0.21038)                Rx(π/2)
    5       (0, −0.20843, −0.006375)               Rx(−π/2)
    6       (0, 0.00017505, −0.10593)              Rx(π/2)
    7       (0, −0.10593, −0.00017505)             Rx(−π/2)
    tool    (0, 0, −0.061525)                      Rx(π)       (interface / flange, no gripper)

They agree to 0.2 mm with the classic Denavit–Hartenberg table of Kinova's Gen3 user guide
(d = −0.2848, −0.0118, −0.4208, −0.0128, −0.3143, 0, −0.1674 m; θ offsets π on joints 2–7;
base twist π), which the tests check. At Xing et al.'s ``q = [0, π/6, 0, π/2, 0, −π/6, 0]`` the
flange is at (0.65, −0.0246, 0.4921) m in the arm's base frame — the paper's start position.

Limits: Xing et al.'s Table 1, joints 4–10 (the arm's joints 1–7), the limits their planner
used on this arm: positions ±∞, ±2.2, ±∞, ±2.5, ±∞, ±2.0, ±∞ rad (joints 2, 4, 6 a little
inside the user guide's ±128.9°, ±147.8°, ±120.3° = ±2.25, ±2.58, ±2.10 rad; joints 1, 3, 5,
7 continuous); velocities ±1.75 rad/s (joints 1–4) and ±3.14 rad/s (joints 5–7); accelerations
±3.0 rad/s² (joints 1–4) and ±5.0 rad/s² (joints 5–7). The user guide gives lower velocity
limits (1.3963 and 1.2218 rad/s); the paper's are what its planner enforced, so they are the
ones this model carries.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .arms import Arm, Segment, build_serial_arm, rotation_x

__all__ = ["kinova_gen3", "XING_Q0_ARM"]

#: Xing et al.'s initial arm configuration [rad].
XING_Q0_ARM = (0.0, math.pi / 6, 0.0, math.pi / 2, 0.0, -math.pi / 6, 0.0)

# (joint translation [m], rotation about x [rad]) of the parent -> joint transforms
_JOINTS = (
    ((0.0, 0.0, 0.15643), math.pi),
    ((0.0, 0.005375, -0.12838), math.pi / 2),
    ((0.0, -0.21038, -0.006375), -math.pi / 2),
    ((0.0, 0.006375, -0.21038), math.pi / 2),
    ((0.0, -0.20843, -0.006375), -math.pi / 2),
    ((0.0, 0.00017505, -0.10593), math.pi / 2),
    ((0.0, -0.10593, -0.00017505), -math.pi / 2),
)
_TOOL = ((0.0, 0.0, -0.061525), math.pi)

# link name, mass [kg], centre of mass [m], inertia about the centre of mass [kg m²]
# (ixx, iyy, izz, ixy, ixz, iyz), all in the link's frame
_LINKS = (
    (
        "shoulder_link",
        1.3773,
        (-2.3e-05, -0.010364, -0.07336),
        (0.00457, 0.004831, 0.001409, 1e-06, 2e-06, 0.000448),
    ),
    (
        "half_arm_1_link",
        1.1636,
        (-4.4e-05, -0.09958, -0.013278),
        (0.011088, 0.001072, 0.011255, 5e-06, 0.0, -0.000691),
    ),
    (
        "half_arm_2_link",
        1.1636,
        (-4.4e-05, -0.006641, -0.117892),
        (0.010932, 0.011127, 0.001043, 0.0, -7e-06, 0.000606),
    ),
    (
        "forearm_link",
        0.9302,
        (-1.8e-05, -0.075478, -0.015006),
        (0.008147, 0.000631, 0.008316, -1e-06, 0.0, -0.0005),
    ),
    (
        "spherical_wrist_1_link",
        0.6781,
        (1e-06, -0.009432, -0.063883),
        (0.001596, 0.001607, 0.000399, 0.0, 0.0, 0.000256),
    ),
    (
        "spherical_wrist_2_link",
        0.6781,
        (1e-06, -0.045483, -0.00965),
        (0.001641, 0.00041, 0.001641, 0.0, 0.0, -0.000278),
    ),
    (
        "bracelet_link",
        0.5006,
        (-0.000281, -0.011402, -0.029798),
        (0.000587, 0.000369, 0.000609, 3e-06, 3e-06, 0.000118),
    ),
)
_BASE_LINK = (
    "base_link",
    1.697,
    (-0.000648, -0.000166, 0.084487),
    (0.004622, 0.004495, 0.002079, 9e-06, 6e-05, 9e-06),
)


def _inertia(mass: float, com, moments) -> pin.Inertia:
    ixx, iyy, izz, ixy, ixz, iyz = moments
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    return pin.Inertia(mass, np.array(com, dtype=float), tensor)


def _placement(translation, angle: float) -> pin.SE3:
    return pin.SE3(rotation_x(angle), np.array(translation, dtype=float))


def kinova_gen3() -> Arm:
    """The Kinova Gen3 7-DoF arm; end effector ``gen3_end_effector`` (flange, no gripper)."""
    segments = [
        Segment(
            f"gen3_joint_{k + 1}", _placement(*joint), f"gen3_{link}", _inertia(mass, com, moments)
        )
        for k, (joint, (link, mass, com, moments)) in enumerate(zip(_JOINTS, _LINKS, strict=True))
    ]
    q_max = np.array([np.inf, 2.2, np.inf, 2.5, np.inf, 2.0, np.inf])  # Xing et al., Table 1
    name, mass, com, moments = _BASE_LINK
    return build_serial_arm(
        "kinova_gen3",
        segments,
        base_body=f"gen3_{name}",
        base_inertia=_inertia(mass, com, moments),
        tool_frame="gen3_end_effector",
        tool_placement=_placement(*_TOOL),
        q_lower=-q_max,
        q_upper=q_max,
        v_max=[1.75] * 4 + [3.14] * 3,
        a_max=[3.0] * 4 + [5.0] * 3,
        home=np.array(XING_Q0_ARM),
        source="Kinova Gen3 7-DoF joint origins and inertias (Kinova ros_kortex description)",
    )
