"""The MJCF (MuJoCo) model of a wbc robot: its links with pinocchio's inertias, on real wheels.

:func:`build_mjcf` writes the model :class:`~wbc.sim.mujoco_plant.MujocoPlant` simulates. It
reads the robot by duck typing (``robot.model``, a pinocchio model; ``robot.root``;
``robot.base``, the planar base model with its wheel geometry) — ``wbc.sim`` does not import
``wbc.robots``.

The arm (any chain of 1-dof revolute or prismatic joints)
    One MuJoCo body per pinocchio joint, placed by ``model.jointPlacements``, with
    ``model.inertias`` (mass [kg], centre of mass [m], rotational inertia [kg m²] — the fixed
    links pinocchio merged into each joint included), the joint's position limits, and
    ``model.damping`` / ``model.armature`` (0 for example-robot-data's URDFs except the
    Panda's 0.003 N m s/rad damping; a real geared joint's rotor inertia is not in the URDFs and
    is therefore not added). Bodies lighter than :data:`MIN_MASS` get that mass (MuJoCo needs a
    positive mass for a moving body). Links have no collision geometry: the arm collides with
    nothing (the plant is for the base's contacts and the arm's dynamics).

Torque limits [N m]
    ``model.effortLimit`` where the URDF gives one; for the arms whose URDFs do not,
    :data:`DATASHEET_TORQUES` (KUKA LWR4+ and Kinova Gen3 datasheets, see there).

The base (planar robots: ``robot.root == "planar"``)
    A free body (6 dof: it can tip, bounce and slide) whose frame is wbc's base frame, at
    :data:`BASE_HEIGHT` above the floor (0 except the mecanum base, whose frame is the arm's
    mounting plane 0.30 m up, see ``wbc.robots.catalogue``). Its inertia is the base joint's of
    the pinocchio model (the base body and the arm's fixed root link) minus the wheel
    assemblies, which are separate bodies: the base model's mass is the whole platform's, wheels
    included (as the omni paper's 15 kg); where that difference is not a physical inertia its
    principal moments are lifted to one (:func:`_physical`). Wheel data: :data:`WHEELS`
    (mass, inertia, roller count, torque limit, each with where it comes from).

    * differential (``robot.base.separation``): two drive wheels on the axle through the base
      origin, and PMB2's four casters as free balls (ball joints) of 0.025 m radius at its
      caster contact points (example-robot-data's ``tiago.urdf``: x = 0.1535 and −0.1895 m,
      y = ±0.102 m) — a swivel caster's wheel and fork are simplified to a ball;
    * steerable (``robot.base.hips``): per wheel a steer joint (vertical, at the hip) carrying a
      drive joint whose wheel trails the steer axis by the offset ``d`` (or sits beside it, the
      paper's model: ``steer_offset``, :data:`STEER_OFFSETS`);
    * the tyres of both are rounded: ellipsoids of the wheel's radius and 0.04 m wide (the
      PMB2's wheel width in ``tiago.urdf``), touching the floor at one point as a tyre's
      narrow patch does (a flat cylinder touches at its two edges, which scrub when the base
      turns: measured 1.7 % of the yaw rate lost on the PMB2, with 20 ms contacts);
    * omni (``robot.base.angles``) and mecanum (``robot.base.half_wheelbase``): each wheel
      carries :data:`WHEELS`' ``rollers`` passive rollers on hinge joints about their own
      axes — tangent to the wheel (omni) or at the angle the base's wheel Jacobian gives
      (mecanum: 45°) — so a wheel drives along one direction and rolls freely across it.
      Each roller is an ellipsoid of revolution about its axis (so its spin does not move its
      surface), its centre ``r − b`` from the wheel axis; ``b = 0.28 r`` (a typical roller's
      middle radius for its wheel) and the semi-axis along the roller chosen so that the
      rollers' envelope is the wheel's circle (:func:`roller_shape`: the mean rolling radius is
      ``r`` within 0.001 %, the ripple 0.04 mm on the omni wheels, 0.03 mm on the mecanum
      ones). Rollers touch only the floor. Neighbouring rollers overlap (they do not collide
      with each other), so near a hand-over two rollers touch the floor at once.

    Every ground contact (wheel or caster) sits on a vertical spring joint of the same
    stiffness, deflecting :data:`SUSPENSION_DEFLECTION` under its mean load, critically damped:
    the model behind ``wbc.robots.normal_forces`` (a rigid platform on equally stiff
    supports). Without it the load of a platform on four or more contacts — statically
    indeterminate — splits as MuJoCo's soft contacts split it, by each contact's effective
    mass (measured on the omni platform, arm out, no springs and 20 ms contacts: 225/95/27/95 N
    where the statics give 209/110/12/110; with the springs, within 2.4 % in three poses).

The floor and contacts
    A plane with friction ``mu`` (Coulomb, ``condim=3``: sliding friction, no torsional or
    rolling friction) against the wheels, rollers and casters; an **elliptic** friction cone so
    a contact's traction is bounded by exactly ``μ f_n``; contacts critically damped with a
    time constant :data:`CONTACT_TIMECONST` of 2 ms, the stiffest MuJoCo allows (``solref``;
    MuJoCo's default 20 ms lets loaded contacts creep, see there) and MuJoCo's default
    ``solimp = (0.9, 0.95, 0.001)``.
    Solver: Newton, ``implicitfast`` integration (the actuators' velocity gains implicit), time
    step :data:`TIMESTEP` (1 ms: the servo period of the omni paper's wheel drives), 100
    iterations, tolerance 1e-10. MuJoCo's no-slip solver (another cure for creep) is off:
    tried with 10 iterations and the default contacts, it cut the mecanum base's creep less
    than stiffer contacts do (sideways 3.7 → 2.4 %) and made every base roll straight
    0.4–0.8 % short of its odometry (0.05 % without).

Actuators (by command kind; gains are stated estimates, see :data:`SERVO_BANDWIDTH_HZ`)
    * ``"velocity"``: each arm joint an integrating velocity servo (MuJoCo ``intvelocity``:
      the commanded rate is integrated into a position reference followed by a PD loop,
      ``kp = I ω²``, ``kv = 2 I ω`` with ``I`` the joint's inertia at the home configuration
      and ``ω = 2π·SERVO_BANDWIDTH_HZ``), plus a gravity and Coriolis feedforward the plant
      applies as joint torques (``qfrc_bias`` at each period's start; not counted against the
      servo's limit); each drive wheel and each steer joint an integrating servo like the arm's
      (a drive's PI velocity loop: without the integral a proportional loop lags the command
      by what the rollers' rolling resistance needs), ``I`` for a drive wheel the robot's mass
      reflected on it (``m r² / n_wheels``) plus its armature;
    * ``"acceleration"``: arm joints torque motors (the plant computes inverse dynamics), wheels
      as above (the base's acceleration integrated into a velocity target);
    * ``"torque"``: drive wheels torque motors, arm joints and steer joints servos as for
      ``"velocity"`` (omni force control: the wheels take torques, the arm its own servos);
    * ``"joints"``: the actuators of ``"velocity"``, commanded joint by joint (a controller that
      drives the wheels itself: a steering controller's steer and drive rates, wheel angle
      servos).
    Every actuator is clipped to its torque limit. ``passive_wheels``: those drive wheels get no
    actuator and roll freely (an unpowered motor: its rotor still turns with the wheel, the
    armature stays; the omni paper's two-motor experiment).
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import checked_number
from ..errors import InvalidValueError, WbcError

__all__ = ["BASE_HEIGHT", "COMMANDS", "CONTACT_TIMECONST", "DATASHEET_TORQUES", "DEFAULT_MU",
           "MjcfModel", "PAPER_MASSES", "SERVO_BANDWIDTH_HZ", "STEER_OFFSETS",
           "SUSPENSION_DEFLECTION", "TIMESTEP", "WHEELS", "base_kind", "build_mjcf", "roller_shape"]

#: the command kinds a model's actuators can be built for (see the module docstring)
COMMANDS = ("velocity", "acceleration", "torque", "joints")
#: where a steered wheel's contact sits from its steer axis, by the distance ``d`` of the base
#: model: ``"trailing"`` — behind it along the rolling direction, a caster
#: (``wbc.robots.SteerableBase``'s model, the default); ``"sideways"`` — beside it along the
#: wheel's axle, to the right of the rolling direction (Sorour et al.'s inverse actuation model
#: ``r φ̇ = f(β) ξ + d β̇``, ``f = [cos β, sin β, d − h_y cos β + h_x sin β]``: the contact at
#: ``h + d (sin β, −cos β)``).
STEER_OFFSETS = ("trailing", "sideways")
#: physics time step [s] (the omni paper's servo period, 1 ms).
TIMESTEP = 0.001
#: smallest body mass [kg] MuJoCo is given (massless pinocchio bodies, e.g. a flange).
MIN_MASS = 1e-3
#: joint and wheel servo bandwidth [Hz] (stated estimate: industrial joint position loops run
#: at 5–20 Hz; 10 Hz, critically damped).
SERVO_BANDWIDTH_HZ = 10.0
#: time constant [s] of the contacts (MuJoCo's ``solref``, critically damped): 2 time steps,
#: the stiffest contact MuJoCo integrates (its documentation asks for ``timeconst`` ≥ 2 time
#: steps, and its ``refsafe`` flag clamps smaller values to that). The rule, fixed before the
#: studies ran on this plant: the wheels, rollers and floor are rigid in every model this plant
#: is compared with (the base models, ``wbc.robots.normal_forces``), so the contacts are as
#: rigid as MuJoCo allows. (History: a first choice of 5 ms was made after seeing the mecanum
#: base's validation results, against this project's rule; it was replaced by this rule. The
#: effect, measured then: with MuJoCo's default 20 ms the mecanum base moved 3.7 % slower
#: sideways than its wheels' odometry, 1.4 % with 5 ms, 1.2 % with 2 ms.)
CONTACT_TIMECONST = 2.0 * TIMESTEP
#: standard gravity [m/s²].
GRAVITY = 9.81
#: static deflection [m] of the ground contacts' springs under a contact's mean load. The springs
#: exist for the statics (a rigid platform on equally stiff supports: ``wbc.robots.normal_forces``'
#: model), so they are made as stiff as they can be integrated accurately: MuJoCo integrates
#: joint springs explicitly (``implicitfast`` treats damping implicitly, not stiffness), and a
#: spring loaded by its share of the robot's mass has ω = √(g/δ); the rule ω·dt ≤ 0.1 (about 60
#: steps per period) gives δ = g·(10·dt)² = 0.98 mm at dt = 1 ms. Fixed by that rule before the
#: studies ran on this plant (a first 1 mm had been picked after seeing the load-split results).
SUSPENSION_DEFLECTION = GRAVITY * (10.0 * TIMESTEP) ** 2
#: default wheel-floor friction coefficient (stated estimate: rubber on a hard floor 0.6–1.0).
DEFAULT_MU = 0.8

#: height [m] of the base frame above the floor, by base kind (0: the frame lies on the floor).
BASE_HEIGHT = {"differential": 0.0, "steerable": 0.0, "omni": 0.0, "mecanum": 0.30}

#: the papers' masses [kg] (platform with its wheels, arm), by catalogue robot name: the omni
#: paper's 15 kg platform and 30 kg arm (``wbc.robots.omni.PLATFORM_MASS`` / ``ARM_MASS``).
PAPER_MASSES = {"omni4_arm6": (15.0, 30.0)}

#: joint torque limits [N m] of arms whose URDF gives none: KUKA LWR4+ (datasheet: 176, 176,
#: 100, 100, 100, 38, 38) and Kinova Gen3 7-dof (user guide: large actuators 39, small 9).
DATASHEET_TORQUES = {"kuka_lwr4": (176.0, 176.0, 100.0, 100.0, 100.0, 38.0, 38.0),
                     "kinova_gen3": (39.0, 39.0, 39.0, 39.0, 9.0, 9.0, 9.0)}

#: wheel data by base kind: ``mass`` [kg] of a wheel (hub and rollers), ``rollers`` per wheel,
#: ``roller_mass`` [kg] each (part of ``mass``), ``armature`` [kg m²] (motor and gear reflected
#: to the wheel axis), ``torque`` [N m] drive limit, ``width`` [m] of a cylinder wheel,
#: ``steer_mass`` [kg] of a steering fork. Sources: the omni paper (12 rollers, r = 0.1 m);
#: example-robot-data's ``tiago.urdf`` (wheel mass 1.82 kg); the rest stated estimates:
#: masses of commercial wheels of these sizes (6-inch mecanum wheels: 9–12 rollers, ≈ 1.2 kg),
#: armatures and torque limits sized so that the bases' ``a_max`` needs a fraction of them.
WHEELS = {
    "omni": {"mass": 1.0, "rollers": 12, "roller_mass": 0.03, "armature": 0.02, "torque": 10.0},
    "mecanum": {"mass": 1.2, "rollers": 12, "roller_mass": 0.04, "armature": 0.02,
                "torque": 10.0},
    "differential": {"mass": 1.82362, "armature": 0.02, "torque": 20.0, "width": 0.04},
    "steerable": {"mass": 2.0, "steer_mass": 1.0, "armature": 0.02, "torque": 20.0,
                  "width": 0.04},
}
#: PMB2's caster contact points (x, y) [m] in the base frame and their radius [m]
#: (example-robot-data's tiago.urdf).
CASTERS = ((0.1535, 0.102), (0.1535, -0.102), (-0.1895, 0.102), (-0.1895, -0.102))
CASTER_RADIUS = 0.025
CASTER_MASS = 0.05

_REVOLUTE = {"JointModelRX": (1, 0, 0), "JointModelRY": (0, 1, 0), "JointModelRZ": (0, 0, 1)}
_PRISMATIC = {"JointModelPX": (1, 0, 0), "JointModelPY": (0, 1, 0), "JointModelPZ": (0, 0, 1)}


@dataclass
class MjcfModel:
    """An MJCF model and how its joints map to the robot's coordinates.

    Attributes:
        xml: the MJCF text.
        kind: ``"fixed"`` or the base kind (``"differential"``, ``"steerable"``, ``"omni"``,
            ``"mecanum"``).
        arm_joints: MuJoCo joint names in the robot's arm velocity order.
        wheel_joints: drive joints in the base model's wheel order.
        steer_joints: steer joints (steerable base), same order.
        wheel_bodies: the body of each wheel (its rollers are its children).
        base_height: height [m] of the base frame above the floor.
        arm_torque: arm joint torque limits [N m] (``inf``: none).
        wheel_torque: drive torque limit [N m].
        mu: floor friction coefficient.
        command: the command kind the actuators were made for.
        passive_wheels: indices (base model's wheel order) of the drive wheels without an
            actuator.
        steer_offset: where a steered wheel sits from its steer axis (see :data:`STEER_OFFSETS`).
        offset: that distance ``d`` [m] (the base model's ``offset``; 0 without steering).
    """

    xml: str
    kind: str
    arm_joints: tuple[str, ...]
    wheel_joints: tuple[str, ...] = ()
    steer_joints: tuple[str, ...] = ()
    wheel_bodies: tuple[str, ...] = ()
    base_height: float = 0.0
    arm_torque: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wheel_torque: float = math.inf
    mu: float = DEFAULT_MU
    command: str = "velocity"
    passive_wheels: tuple[int, ...] = ()
    steer_offset: str = "trailing"
    offset: float = 0.0

    def wheel_offset_vector(self) -> np.ndarray:
        """A steered wheel's centre [m] in its steer frame (x: the rolling direction)."""
        if self.steer_offset == "trailing":
            return np.array([-self.offset, 0.0, 0.0])
        return np.array([0.0, -self.offset, 0.0])


def base_kind(robot) -> str:
    """``"fixed"`` or the kind of the robot's wheeled base, told by its geometry attributes.

    Raises:
        WbcError: a free-flyer root or a base without wheel geometry (not simulated yet).
    """
    root = getattr(robot, "root", "fixed")
    if root == "fixed":
        return "fixed"
    if root != "planar":
        raise WbcError(f"MujocoPlant: a {root!r} root is not supported yet (fixed and wheeled "
                       "planar bases are)")
    base = robot.base
    for attribute, kind in (("hips", "steerable"), ("angles", "omni"),
                            ("half_wheelbase", "mecanum"), ("separation", "differential")):
        if hasattr(base, attribute):
            return kind
    raise WbcError(f"MujocoPlant: base {type(base).__name__} has no wheels to simulate (a "
                   "differential, steerable, omni or mecanum base is needed)")


@functools.lru_cache(maxsize=64)  # pure geometry, 0.03 s a call: once per wheel kind
def roller_shape(radius: float, rollers: int, tilt: float) -> tuple[float, float, float]:
    """``(c, b, a)`` [m]: a roller ellipsoid's centre distance from the wheel axis, its radius
    across its axis and its semi-axis along it, for a wheel of ``radius`` with ``rollers``
    rollers tilted by ``tilt`` [rad] (0 omni, π/4 mecanum).

    ``b = 0.28 r``; ``a`` minimises the ripple of the rollers' envelope (the height of the wheel
    axis over the floor as the wheel turns, a 1-D search over a grid of 400 values), and ``c``
    makes its mean ``r``. Geometry only: no simulation is involved.
    """
    b = 0.28 * radius
    phases = np.linspace(0.0, 2.0 * math.pi / rollers, 41)
    angles = 2.0 * math.pi * np.arange(rollers) / rollers
    slope = math.cos(tilt) * np.sin(angles[None, :] + phases[:, None])
    depth = np.cos(angles[None, :] + phases[:, None])

    def envelope(a: float) -> np.ndarray:
        return ((radius - b) * depth + np.sqrt(b * b + (a * a - b * b) * slope**2)).max(axis=1)

    candidates = np.linspace(b, 1.5 * radius, 400)
    ripples = [float(np.ptp(envelope(a))) for a in candidates]
    a = float(candidates[int(np.argmin(ripples))])
    c = radius - b - (float(envelope(a).mean()) - radius)
    return c, b, a


def _fmt(values) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.ravel(values))


def _quat(rotation: np.ndarray) -> str:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix."""
    import pinocchio as pin  # pinocchio is a core dependency of wbc's robots

    q = pin.Quaternion(np.asarray(rotation, dtype=float)).coeffs()  # x, y, z, w
    return _fmt([q[3], q[0], q[1], q[2]])


def _skew(c: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])


def _spatial(mass: float, com, inertia) -> np.ndarray:
    """6 × 6 spatial inertia (linear first) about the frame origin: additive across bodies."""
    c = np.asarray(com, dtype=float)
    s = _skew(c)
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[:3, 3:] = -mass * s
    out[3:, :3] = mass * s
    out[3:, 3:] = np.asarray(inertia, dtype=float) + mass * s @ s.T
    return out


def _from_spatial(matrix: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    mass = float(matrix[0, 0])
    s = matrix[3:, :3] / mass
    c = np.array([s[2, 1], s[0, 2], s[1, 0]])
    inertia = matrix[3:, 3:] - mass * _skew(c) @ _skew(c).T
    return mass, c, 0.5 * (inertia + inertia.T)


def _inertial(body: ET.Element, mass: float, com, inertia) -> None:
    inertia = np.asarray(inertia, dtype=float)
    if mass < MIN_MASS:
        scale = MIN_MASS / max(mass, 1e-300)
        mass, inertia = MIN_MASS, inertia * scale if mass > 0 else np.eye(3) * 1e-6
    # MuJoCo rejects inertias violating the triangle inequality by rounding: lift them a little
    inertia = inertia + np.eye(3) * 1e-9
    ET.SubElement(body, "inertial", pos=_fmt(com), mass=f"{mass:.12g}",
                  fullinertia=_fmt([inertia[0, 0], inertia[1, 1], inertia[2, 2],
                                    inertia[0, 1], inertia[0, 2], inertia[1, 2]]))


def _physical(inertia: np.ndarray) -> np.ndarray:
    """``inertia`` [kg m²] with its principal moments lifted, where needed, to satisfy the
    triangle inequality ``A + B >= C`` of a real body (MuJoCo refuses others). A chassis is the
    base model's platform minus its wheel assemblies; the catalogue's platforms are thin discs
    (``C ≈ A + B``), so taking the wheels at the rim out can leave ``A + B`` short of ``C``
    (omni4_arm6 with pinocchio 3.8's model of the arm's root link: A + B = 0.200, C = 0.304
    kg m²). The two smaller moments are raised by half the shortfall each — the least change
    in the sum that makes the body physical; nothing changes for a valid inertia."""
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    shortfall = moments[2] - moments[0] - moments[1]
    if shortfall <= 0:
        return inertia
    moments[:2] += 0.5 * shortfall
    return axes @ np.diag(moments) @ axes.T


def _arm_torques(robot, model, first: int) -> np.ndarray:
    effort = np.array(model.effortLimit[first:], dtype=float)
    effort[~np.isfinite(effort) | (effort <= 0) | (effort >= 1e9)] = np.inf
    arm = getattr(getattr(robot, "arm", None), "name", None) or getattr(robot, "name", "")
    table = DATASHEET_TORQUES.get(str(arm))
    if table is not None and len(table) == effort.size:
        effort = np.where(np.isfinite(effort), effort, np.array(table))
    return effort


def _joint_inertias(model, q, first: int, armature: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    data = model.createData()
    mass_matrix = pin.crba(model, data, np.asarray(q, dtype=float))
    return np.maximum(np.diag(mass_matrix)[first:] + armature, 1e-4)


def build_mjcf(robot, command: str = "velocity", mu: float = DEFAULT_MU, *,
               masses: tuple[float, float] | None = None,
               base_height: float | None = None,
               passive_wheels: tuple[int, ...] = (),
               steer_offset: str = "trailing") -> MjcfModel:
    """The MJCF model of ``robot`` with actuators for ``command`` (see the module docstring).

    Args:
        robot: a wbc robot (fixed base, or a wheeled planar base).
        command: ``"velocity"``, ``"acceleration"``, ``"torque"`` or ``"joints"``.
        mu: wheel-floor friction coefficient (> 0).
        masses: ``(platform, arm)`` masses [kg] to scale the base and arm inertias to
            (default :data:`PAPER_MASSES` for the robot's name, else the model's own).
        base_height: height [m] of the base frame above the floor (default
            :data:`BASE_HEIGHT`).
        passive_wheels: indices of drive wheels (the base model's wheel order) that get no
            actuator and roll freely (default none).
        steer_offset: ``"trailing"`` or ``"sideways"`` (:data:`STEER_OFFSETS`; steerable bases).
    """
    if command not in COMMANDS:
        raise InvalidValueError(f"command must be one of {COMMANDS}, got {command!r}")
    mu = checked_number(mu, "mu", strict=True)
    if steer_offset not in STEER_OFFSETS:
        raise InvalidValueError(f"steer_offset must be one of {STEER_OFFSETS}, got "
                                f"{steer_offset!r}")
    kind = base_kind(robot)
    passive = tuple(sorted({int(i) for i in passive_wheels}))
    if passive and (kind == "fixed" or passive[0] < 0 or passive[-1] >= robot.base.n_wheels):
        raise InvalidValueError(f"passive_wheels must index the base's drive wheels, got "
                                f"{tuple(passive_wheels)!r}")
    model = robot.model
    planar = kind != "fixed"
    first_joint = 4 if planar else 1  # pinocchio joints 1..3: base_x, base_y, base_theta
    for j in range(first_joint, model.njoints):
        if model.joints[j].nv != 1:
            raise WbcError(f"MujocoPlant: joint {model.names[j]!r} has {model.joints[j].nv} "
                           "dof; only 1-dof joints are supported")
    first_v = model.joints[first_joint].idx_v if model.njoints > first_joint else model.nv
    if masses is None:
        masses = PAPER_MASSES.get(getattr(robot, "name", ""))

    root = ET.Element("mujoco", model=str(getattr(robot, "name", "robot")))
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", timestep=f"{TIMESTEP}", integrator="implicitfast",
                  cone="elliptic", solver="Newton", iterations="100", tolerance="1e-10")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0", condim="3",
                  friction=f"{mu:.12g} 0.005 0.0001", solref=f"{CONTACT_TIMECONST:.12g} 1")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "geom", name="floor", type="plane", size="0 0 0.05",
                  contype="1", conaffinity="1", friction=f"{mu:.12g} 0.005 0.0001")
    actuators = ET.SubElement(root, "actuator")

    arm_scale = 1.0
    arm_root = np.zeros((6, 6))
    base: Any = robot.base if planar else None
    if planar:
        base_matrix = _spatial(base.mass, base.com, base.inertia)
        arm_root = _spatial(model.inertias[3].mass, model.inertias[3].lever,
                            model.inertias[3].inertia) - base_matrix
        if masses is not None:
            arm_total = arm_root[0, 0] + sum(model.inertias[j].mass
                                             for j in range(first_joint, model.njoints))
            arm_scale = float(masses[1]) / arm_total
            base_matrix = base_matrix * (float(masses[0]) / base.mass)

    # the arm's bodies, one per pinocchio joint
    torque = _arm_torques(robot, model, first_v)
    armature = np.array(model.armature[first_v:], dtype=float)
    inertias = _joint_inertias(model, robot.neutral(), first_v, armature)
    omega = 2.0 * math.pi * SERVO_BANDWIDTH_HZ
    bodies: dict[int, ET.Element] = {}
    arm_joints = []
    height = 0.0
    if planar:
        height = BASE_HEIGHT[kind] if base_height is None else float(base_height)
        base_body = ET.SubElement(world, "body", name="base", pos=f"0 0 {height:.12g}")
        ET.SubElement(base_body, "freejoint", name="base")
        bodies[3] = base_body
    for j in range(first_joint, model.njoints):
        parent = bodies.get(int(model.parents[j]), world)
        placement = model.jointPlacements[j]
        name = model.names[j]
        body = ET.SubElement(parent, "body", name=f"link_{name}", pos=_fmt(placement.translation),
                             quat=_quat(placement.rotation))
        inertia = model.inertias[j]
        _inertial(body, inertia.mass * arm_scale, inertia.lever, inertia.inertia * arm_scale)
        shortname = model.joints[j].shortname()
        if shortname in _REVOLUTE or "Revolute" in shortname:
            jtype, axis = "hinge", _REVOLUTE.get(shortname)
        elif shortname in _PRISMATIC or "Prismatic" in shortname:
            jtype, axis = "slide", _PRISMATIC.get(shortname)
        else:
            raise WbcError(f"MujocoPlant: joint {name!r} of type {shortname} is not supported")
        if axis is None:
            axis = tuple(model.joints[j].extract().axis)
        iv = model.joints[j].idx_v - first_v
        attributes = {"name": name, "type": jtype, "axis": _fmt(axis),
                      "damping": f"{float(model.damping[model.joints[j].idx_v]):.12g}",
                      "armature": f"{armature[iv]:.12g}"}
        iq = model.joints[j].idx_q
        lower, upper = model.lowerPositionLimit[iq], model.upperPositionLimit[iq]
        if np.isfinite(lower) and np.isfinite(upper) and upper - lower < 1e6:
            attributes["range"] = f"{lower:.12g} {upper:.12g}"
        limit = torque[iv]
        if np.isfinite(limit):
            attributes["actuatorfrcrange"] = f"{-limit:.12g} {limit:.12g}"
        ET.SubElement(body, "joint", **attributes)
        arm_joints.append(name)
        bodies[j] = body
        actuator = {"joint": name}
        if np.isfinite(limit):
            actuator["forcerange"] = f"{-limit:.12g} {limit:.12g}"
        if command != "acceleration":
            kp, kv = inertias[iv] * omega**2, 2.0 * inertias[iv] * omega
            actuator.update(name=f"servo_{name}", kp=f"{kp:.12g}", kv=f"{kv:.12g}",
                            actrange="-1e6 1e6")
            ET.SubElement(actuators, "intvelocity", attrib=actuator)
        else:
            ET.SubElement(actuators, "motor", attrib={**actuator, "name": f"motor_{name}"})

    result = MjcfModel(xml="", kind=kind, arm_joints=tuple(arm_joints), arm_torque=torque,
                       mu=float(mu), command=command, base_height=height,
                       passive_wheels=passive, steer_offset=steer_offset,
                       offset=float(robot.base.offset) if kind == "steerable" else 0.0)
    if planar:
        links = sum(model.inertias[j].mass for j in range(first_joint, model.njoints))
        platform = base_matrix + arm_root * arm_scale
        _wheels(robot, kind, command, bodies[3], actuators, platform,
                float(platform[0, 0]) + links * arm_scale, height, result)
    result.xml = ET.tostring(root, encoding="unicode")
    return result


def _cylinder_inertia(mass: float, radius: float, width: float) -> np.ndarray:
    """About the centre, symmetry axis along y [kg m²]."""
    side = mass * (3.0 * radius**2 + width**2) / 12.0
    return np.diag([side, 0.5 * mass * radius**2, side])


def _tyred_wheel(body: ET.Element, name: str, mass: float, radius: float, width: float,
                 armature: float, limit: float) -> np.ndarray:
    """Make ``body`` a drive wheel: its inertia (a cylinder of ``mass`` [kg], ``radius`` and
    ``width`` [m], axle along y), a hinge ``name`` about the axle with ``armature`` [kg m²] and
    torque range ``±limit`` [N m], and a rounded tyre (an ellipsoid: see the module docstring).
    Returns the inertia [kg m²] about the wheel's centre."""
    inertia = _cylinder_inertia(mass, radius, width)
    _inertial(body, mass, np.zeros(3), inertia)
    ET.SubElement(body, "joint", name=name, type="hinge", axis="0 1 0",
                  armature=f"{armature:.12g}", actuatorfrcrange=f"{-limit:.12g} {limit:.12g}")
    ET.SubElement(body, "geom", type="ellipsoid",
                  size=f"{radius:.12g} {width / 2:.12g} {radius:.12g}", contype="2",
                  conaffinity="1", mass="0")
    return inertia


def _suspension(parent: ET.Element, name: str, position, stiffness: float,
                damping: float, preload: float) -> ET.Element:
    """A body at ``position`` on a vertical spring joint (see :data:`SUSPENSION_DEFLECTION`):
    at ``preload`` [N] its joint is at 0, the wheel at its nominal height."""
    body = ET.SubElement(parent, "body", name=f"suspension_{name}", pos=_fmt(position))
    _inertial(body, MIN_MASS, np.zeros(3), np.eye(3) * 1e-6)
    ET.SubElement(body, "joint", name=f"suspension_{name}", type="slide", axis="0 0 1",
                  stiffness=f"{stiffness:.12g}", damping=f"{damping:.12g}",
                  springref=f"{-preload / stiffness:.12g}", range="-0.05 0.05")
    return body


def _wheels(robot, kind: str, command: str, base_body: ET.Element, actuators: ET.Element,
            platform: np.ndarray, robot_mass: float, height: float, result: MjcfModel) -> None:
    """Add the wheels (and casters) of the base on their suspensions, their actuators, and the
    chassis inertia (the platform's spatial inertia ``platform`` minus the wheel assemblies);
    ``robot_mass`` [kg] is the whole robot's."""
    base = robot.base
    data = WHEELS[kind]
    r = float(base.radius)
    n = int(base.n_wheels)
    wheel_mass = float(data["mass"])
    total_mass = robot_mass
    contacts = n + (len(CASTERS) if kind == "differential" else 0)
    preload = robot_mass * GRAVITY / contacts  # the mean load of a ground contact [N]
    stiffness = preload / SUSPENSION_DEFLECTION
    spring_damping = 2.0 * math.sqrt(stiffness * robot_mass / contacts)  # critical

    def suspended(name, position):
        return _suspension(base_body, name, position, stiffness, spring_damping, preload)

    # the platform's mass reflected on one wheel's axis: what a wheel servo accelerates
    reflected = total_mass * r * r / n + float(data["armature"])
    omega = 2.0 * math.pi * SERVO_BANDWIDTH_HZ
    limit = float(data["torque"])
    result.wheel_torque = limit
    assemblies = np.zeros((6, 6))
    wheels, steers, wheel_bodies = [], [], []
    z = r - height  # wheel centres in the base frame
    if kind in ("omni", "mecanum"):
        rows = np.asarray(base.jacobian, dtype=float) * r
        centres = base.wheel_positions  # the wheels' centres above their contacts
        rollers = int(data["rollers"])
        roller_mass = float(data["roller_mass"])
        hub = wheel_mass - rollers * roller_mass
        for i in range(n):
            u = rows[i, :2] / np.linalg.norm(rows[i, :2])  # bottom roller's axis (ground)
            t = u if kind == "omni" else np.array([1.0, 0.0])  # rolling direction
            t3 = np.array([t[0], t[1], 0.0])
            axle = np.cross([0.0, 0.0, 1.0], t3)
            rotation = np.column_stack([t3, axle, [0.0, 0.0, 1.0]])
            tilt = math.atan2(float(u @ axle[:2]), float(u @ t))
            centre = np.array([centres[i][0], centres[i][1], z])
            body = ET.SubElement(suspended(f"wheel{i}", centre), "body", name=f"wheel{i}",
                                 quat=_quat(rotation))
            _inertial(body, hub, np.zeros(3), _cylinder_inertia(hub, 0.8 * r, 0.04))
            ET.SubElement(body, "joint", name=f"wheel{i}", type="hinge", axis="0 1 0",
                          armature=f"{data['armature']:.12g}",
                          actuatorfrcrange=f"{-limit:.12g} {limit:.12g}")
            c, b, a = roller_shape(r, rollers, abs(tilt))
            for k in range(rollers):
                psi = 2.0 * math.pi * k / rollers
                ry = np.array([[math.cos(psi), 0.0, math.sin(psi)], [0.0, 1.0, 0.0],
                               [-math.sin(psi), 0.0, math.cos(psi)]])
                frame = ry @ np.array([[math.cos(tilt), -math.sin(tilt), 0.0],
                                       [math.sin(tilt), math.cos(tilt), 0.0],
                                       [0.0, 0.0, 1.0]])
                roller = ET.SubElement(body, "body", name=f"wheel{i}_roller{k}",
                                       pos=_fmt(ry @ np.array([0.0, 0.0, -c])),
                                       quat=_quat(frame))
                _inertial(roller, roller_mass, np.zeros(3), np.diag(
                    [0.4 * roller_mass * b * b, 0.2 * roller_mass * (a * a + b * b),
                     0.2 * roller_mass * (a * a + b * b)]))
                ET.SubElement(roller, "joint", name=f"wheel{i}_roller{k}", type="hinge",
                              axis="1 0 0", damping="1e-4", armature="1e-5")
                ET.SubElement(roller, "geom", type="ellipsoid", size=_fmt([a, b, b]),
                              contype="2", conaffinity="1", mass="0")
            assemblies += _spatial(wheel_mass, centre, _cylinder_inertia(wheel_mass, r, 0.04))
            wheels.append(f"wheel{i}")
            wheel_bodies.append(f"wheel{i}")
    elif kind == "differential":
        width = float(data["width"])
        half = 0.5 * float(base.separation)
        for i, y in enumerate((half, -half)):  # (left, right)
            centre = np.array([0.0, y, z])
            body = ET.SubElement(suspended(f"wheel{i}", centre), "body", name=f"wheel{i}")
            inertia = _tyred_wheel(body, f"wheel{i}", wheel_mass, r, width,
                                   float(data["armature"]), limit)
            assemblies += _spatial(wheel_mass, centre, inertia)
            wheels.append(f"wheel{i}")
            wheel_bodies.append(f"wheel{i}")
        for k, (x, y) in enumerate(CASTERS):
            centre = np.array([x, y, CASTER_RADIUS - height])
            body = ET.SubElement(suspended(f"caster{k}", centre), "body", name=f"caster{k}")
            inertia = np.eye(3) * 0.4 * CASTER_MASS * CASTER_RADIUS**2
            _inertial(body, CASTER_MASS, np.zeros(3), inertia)
            ET.SubElement(body, "joint", name=f"caster{k}", type="ball", damping="1e-4")
            ET.SubElement(body, "geom", type="sphere", size=f"{CASTER_RADIUS:.12g}",
                          contype="2", conaffinity="1", mass="0")
            assemblies += _spatial(CASTER_MASS, centre, inertia)
    else:  # steerable
        width = float(data["width"])
        d = float(base.offset)
        steer_mass = float(data["steer_mass"])
        for i, (hx, hy) in enumerate(np.asarray(base.hips, dtype=float)):
            hip = np.array([hx, hy, z])
            offset = result.wheel_offset_vector()  # the wheel's centre in the steer frame
            steer = ET.SubElement(suspended(f"wheel{i}", hip), "body", name=f"steer{i}")
            fork = np.eye(3) * steer_mass * 0.05**2
            _inertial(steer, steer_mass, 0.5 * offset, fork)
            ET.SubElement(steer, "joint", name=f"steer{i}", type="hinge", axis="0 0 1",
                          armature=f"{data['armature']:.12g}", damping="0.1",
                          actuatorfrcrange=f"{-limit:.12g} {limit:.12g}")
            wheel = ET.SubElement(steer, "body", name=f"wheel{i}", pos=_fmt(offset))
            inertia = _tyred_wheel(wheel, f"wheel{i}", wheel_mass, r, width,
                                   float(data["armature"]), limit)
            # steering inertia: the fork and the wheel about the steer axis, plus the armature
            steer_inertia = (steer_mass * (0.05**2 + 0.25 * d * d) + wheel_mass * d * d
                             + inertia[0, 0] + float(data["armature"]))
            kp, kv = steer_inertia * omega**2, 2.0 * steer_inertia * omega
            ET.SubElement(actuators, "intvelocity", name=f"servo_steer{i}", joint=f"steer{i}",
                          kp=f"{kp:.12g}", kv=f"{kv:.12g}", actrange="-1e6 1e6",
                          forcerange=f"{-limit:.12g} {limit:.12g}")
            assemblies += _spatial(steer_mass, hip + 0.5 * offset, fork)
            assemblies += _spatial(wheel_mass, hip + offset, inertia)
            wheels.append(f"wheel{i}")
            steers.append(f"steer{i}")
            wheel_bodies.append(f"wheel{i}")
    for i, name in enumerate(wheels):
        if i in result.passive_wheels:  # unpowered: rolls freely
            continue
        if command == "torque":
            ET.SubElement(actuators, "motor", name=f"motor_{name}", joint=name,
                          forcerange=f"{-limit:.12g} {limit:.12g}")
        else:
            ET.SubElement(actuators, "intvelocity", name=f"servo_{name}", joint=name,
                          kp=f"{reflected * omega**2:.12g}", kv=f"{2.0 * reflected * omega:.12g}",
                          actrange="-1e9 1e9", forcerange=f"{-limit:.12g} {limit:.12g}")
    chassis = platform - assemblies
    mass, com, inertia = _from_spatial(chassis)
    if mass <= 0 or np.linalg.eigvalsh(inertia).min() <= 0:
        raise WbcError(f"MujocoPlant: the base's mass {platform[0, 0]:.3g} kg does not leave a "
                       "positive chassis once its wheels are taken out")
    inertia = _physical(inertia)
    # the chassis is the base body itself: its inertial element goes first (MJCF's order)
    _inertial(base_body, mass, com, inertia)
    element = base_body.findall("inertial")[-1]
    base_body.remove(element)
    base_body.insert(0, element)
    result.wheel_joints, result.steer_joints = tuple(wheels), tuple(steers)
    result.wheel_bodies = tuple(wheel_bodies)
