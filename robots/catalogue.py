"""The robot catalogue: named mobile manipulators of the four papers, and user URDFs on a base.

=================  ==========================  ======================  =========================
name               base (velocity coordinates)  arm                     mount (in the base frame)
=================  ==========================  ======================  =========================
``mpo700_lwr4``    MPO700, 4 steerable wheels  KUKA LWR-IV (7)         (0.30, 0, 0.36) m
                   ``(v_x, v_y, ω)``
``tiago_panda``    Tiago's PMB2, differential  Franka Panda (7)        (−0.062, 0, 0.2915) m
                   ``(v, ω)``
``omni4_arm6``     4 omni wheels, octagon      UR10 stand-in (6)       (0, 0, 0.15) m
                   ``(v_x, v_y, ω)``
``mecanum_gen3``   mecanum, 4 wheels           Kinova Gen3 (7)         identity
                   ``(v_x, v_y, ω)``
=================  ==========================  ======================  =========================

All mounts are pure translations (arm upright, facing the base's x axis). The base frames of
the first three robots lie on the floor; the mounts are assumed (top front of the MPO700's
deck; the place of Tiago's torso on the PMB2, 0.193 m above ``base_link``; the centre of the
omni platform's top). For ``mecanum_gen3`` the base frame lies on the arm's mounting plane and
the mount is the identity: Xing et al.'s start position [0.65, −0.0246, 0.4921] m is the Gen3's
flange at their ``q0`` expressed in the arm's own base frame, so their world frame is the
mounting plane's (the floor is 0.30 m below). ``load("mecanum_gen3").neutral()`` is that ``q0``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from wbc.checks import as_float_array, checked_name
from wbc.errors import InvalidValueError, UnknownNameError

from .arms import Arm, arm_from_urdf, panda, ur10
from .differential import tiago_base
from .kinova_gen3 import XING_Q0_ARM, kinova_gen3
from .kuka_lwr4 import kuka_lwr4
from .manipulator import MobileManipulator
from .mecanum import mecanum_base
from .omni import omni4_octagon
from .pinocchio_robot import PinocchioRobot
from .planar_base import PlanarBase
from .steerable import mpo700

__all__ = ["names", "load", "from_urdf", "make_base", "base_names"]


def _translation(x: float, y: float, z: float) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array([x, y, z]))


def _mpo700_lwr4() -> MobileManipulator:
    return MobileManipulator(
        mpo700(), kuka_lwr4(), _translation(0.30, 0.0, 0.36), name="mpo700_lwr4"
    )


def _tiago_panda() -> MobileManipulator:
    return MobileManipulator(
        tiago_base(), panda(), _translation(-0.062, 0.0, 0.2915), name="tiago_panda"
    )


def _omni4_arm6() -> MobileManipulator:
    return MobileManipulator(
        omni4_octagon(), ur10(), _translation(0.0, 0.0, 0.15), name="omni4_arm6"
    )


def _mecanum_gen3() -> MobileManipulator:
    home = np.concatenate([np.zeros(3), XING_Q0_ARM])
    return MobileManipulator(mecanum_base(), kinova_gen3(), None, name="mecanum_gen3", home=home)


_CATALOGUE: dict[str, Callable[[], MobileManipulator]] = {
    "mpo700_lwr4": _mpo700_lwr4,
    "tiago_panda": _tiago_panda,
    "omni4_arm6": _omni4_arm6,
    "mecanum_gen3": _mecanum_gen3,
}

_BASES: dict[str, Callable[[], PlanarBase]] = {
    "steerable": mpo700,
    "mpo700": mpo700,
    "differential": tiago_base,
    "tiago": tiago_base,
    "omni": omni4_octagon,
    "omni4": omni4_octagon,
    "mecanum": mecanum_base,
}


def names() -> list[str]:
    """Names of the catalogue's robots."""
    return list(_CATALOGUE)


def load(name: str) -> MobileManipulator:
    """A new instance of the catalogue robot ``name`` (its own pinocchio ``Data``).

    Raises:
        UnknownNameError: ``name`` is not in the catalogue (the message lists it).
    """
    try:
        factory = _CATALOGUE[checked_name(name, "robot name", optional=False)]
    except (KeyError, InvalidValueError):
        raise UnknownNameError(f"unknown robot {name!r}; the catalogue has {names()}") from None
    return factory()


def base_names() -> list[str]:
    """Names accepted by :func:`make_base` and :func:`from_urdf`."""
    return list(_BASES)


def make_base(name: str) -> PlanarBase:
    """A base model by name: ``"steerable"``/``"mpo700"``, ``"differential"``/``"tiago"``,
    ``"omni"``/``"omni4"``, ``"mecanum"``."""
    try:
        factory = _BASES[checked_name(name, "base name", optional=False)]
    except (KeyError, InvalidValueError):
        raise UnknownNameError(f"unknown base {name!r}; bases: {base_names()}") from None
    return factory()


class _DefaultBase(str):
    """from_urdf's default base name: a distinct object, so that ``base is _DEFAULT_BASE``
    tells "not given" from an explicit ``base="mecanum"``."""


_DEFAULT_BASE = _DefaultBase("mecanum")


def from_urdf(
    urdf: str | os.PathLike[str] | Arm,
    base: str | PlanarBase = _DEFAULT_BASE,
    *,
    root: str | PlanarBase | None = None,
    ee_frame: str | None = None,
    mount=None,
    name: str | None = None,
    locked_joints: Sequence[str] = (),
    v_max=None,
    a_max=None,
    home=None,
) -> PinocchioRobot:
    """Put an arm of your own (a URDF file) on one of the bases — or, with ``root``, load a
    whole robot (a humanoid, a quadruped, a mobile manipulator with its wheels) on any root.

    Two uses:

    * ``from_urdf(arm_urdf, base="mecanum", ee_frame=..., mount=...)`` — an arm URDF mounted on
      a base (default ``"mecanum"``): a :class:`MobileManipulator`;
    * ``from_urdf(robot_urdf, root=..., ee_frame=None, ...)`` — a whole-robot URDF with
      ``root`` one of ``"fixed"``, ``"free_flyer"``, ``"planar"`` or a base name: see
      :func:`wbc.robots.whole_body.robot_from_urdf` (wheels recognised as the base's, continuous
      joints accepted; ``home`` is then a whole configuration; ``mount`` is not used).

    Every robot loaded from a file records it as ``robot.urdf_path``.

    Args:
        urdf: path of the arm's URDF (or an already built :class:`~wbc.robots.arms.Arm`).
        base: a base name (see :func:`base_names`) or a base model (default ``"mecanum"``;
            not with ``root``).
        root: the root of a whole-robot URDF (see above).
        ee_frame: the URDF frame (link or joint name) used as ``"ee"``; when a link and a joint
            share the name, ``"link:<name>"`` or ``"joint:<name>"`` (see
            :mod:`wbc.robots.arms`).
        mount: pose of the arm's root in the base frame (SE3 or 4 × 4; default identity).
        name: robot name.
        locked_joints: URDF joints to remove (e.g. gripper fingers).
        v_max, a_max: arm velocity / acceleration limits (default: URDF velocities, no
            acceleration limit).
        home: the arm's home configuration.

    Example::

        import numpy as np
        import wbc.robots as robots
        from wbc.robots.resources import urdf_path
        mount = np.eye(4); mount[2, 3] = 0.4                 # arm root 0.4 m above the base
        robot = robots.from_urdf(urdf_path("ur_description/urdf/ur5_robot.urdf"),
                                 base="omni", ee_frame="tool0", mount=mount)
        robot.frame_pose(robot.neutral(), "ee")
    """
    if root is not None:
        from .whole_body import ROOTS, robot_from_urdf  # loaded when first needed

        if base is not _DEFAULT_BASE or mount is not None:
            raise InvalidValueError("from_urdf: give either root= (a whole-robot URDF) or "
                                    "base= / mount= (an arm on a base), not both")
        if isinstance(urdf, Arm):
            raise InvalidValueError("from_urdf: root= needs a URDF path, got an Arm")
        if isinstance(root, str) and root in _BASES:
            root_model: str | PlanarBase = make_base(root)
        elif isinstance(root, PlanarBase) or (isinstance(root, str) and root in ROOTS):
            root_model = root
        else:
            raise UnknownNameError(f"unknown root {root!r}; use one of "
                                   f"{[*ROOTS, *base_names()]} or a PlanarBase"[:300])
        return robot_from_urdf(urdf, root_model, root_name=root if isinstance(root, str)
                               else None, ee_frame=ee_frame, name=name,
                               locked_joints=locked_joints, home=home, v_max=v_max,
                               a_max=a_max)
    if not isinstance(base, (str, PlanarBase)):
        raise InvalidValueError(f"base must be a base name ({base_names()}) or a PlanarBase, "
                                f"got {base!r}"[:160])
    base_model = make_base(base) if isinstance(base, str) else base
    checked_name(name, "name")
    checked_name(ee_frame, "ee_frame")
    if mount is not None and not isinstance(mount, pin.SE3):
        mount = as_float_array(mount, "mount")
    if isinstance(urdf, Arm):
        arm = urdf
    else:
        if ee_frame is None:
            raise InvalidValueError("ee_frame is required: name the URDF frame to use as the "
                                    "end effector")
        arm = arm_from_urdf(
            urdf, ee_frame, locked_joints=locked_joints, v_max=v_max, a_max=a_max, home=home
        )
        from .whole_body import wheel_joints  # loaded when first needed

        wheels = wheel_joints(arm.model)[0]
        if wheels:  # a whole robot: its wheels would become arm joints the base never turns
            raise InvalidValueError(
                f"from_urdf: {os.fspath(urdf)!r} has wheel joints {wheels} on its root link: it "
                f"describes a whole robot, not an arm; load it with root= (e.g. "
                f"from_urdf(path, root={base if isinstance(base, str) else 'planar'!r}, "
                f"ee_frame=...)) so the base's wheels replace them, or lock them "
                f"(locked_joints=...)")
    robot = MobileManipulator(base_model, arm, mount, ee_frame=ee_frame, name=name)
    if not isinstance(urdf, Arm):
        robot.urdf_path = os.fspath(urdf)
        robot.locked_joints = tuple(locked_joints)
    return robot
