"""Whole-robot URDFs with any root: fixed, free flyer, planar, or one of the wheeled bases.

:func:`robot_from_urdf` (reached as ``wbc.robots.from_urdf(path, root=...)``) loads a URDF that
describes the whole robot — a humanoid, a quadruped, a mobile manipulator with its wheels —
and puts it on one of four roots:

=================  ==========================================================================
``root``           the robot
=================  ==========================================================================
``"fixed"``        the URDF's root link fixed in the world
                   (:class:`~wbc.robots.fixed_base.FixedBaseRobot`; ``q`` = the joints)
``"free_flyer"``   a free-floating root body
                   (:class:`~wbc.robots.floating_base.FloatingBaseRobot`; ``q = [x, y, z,
                   quaternion, joints]``, ``v = [v, ω, joint rates]`` with ``v, ω`` in the
                   root body's axes)
``"planar"``       the root link on a holonomic planar root without velocity limits
                   (:class:`~wbc.robots.planar_base.PlanarRoot`: ``q = [x, y, θ, joints]``,
                   ``v = [v_x, v_y, ω, joint rates]`` in the base frame)
a base name        the root link on one of the bases of :func:`wbc.robots.base_names`
                   (``"differential"``, ``"mecanum"``, …), whose wheel kinematics and limits
                   replace the URDF's wheels
=================  ==========================================================================

The URDF's root link sits at the base frame (``"base"``, for the planar roots and the free
flyer) and keeps its inertia: on a planar root or a base the base body *is* the root link (the
base model's own mass, centre of mass and inertia are replaced by the URDF's).

Continuous joints become plain revolute joints with infinite position limits
(:mod:`wbc.robots.arms`). Frames sharing a name become ``"link:<name>"`` / ``"joint:<name>"``.

Wheels. The joints attached to the root link whose names contain ``wheel`` or ``caster``
(case-insensitive) are the base's wheels when the root is ``"planar"`` or a base: they are
locked (pinocchio ``buildReducedModel``, at their neutral angle) — the base's velocity
coordinates replace them — and listed in ``robot.wheel_joints`` (and ``robot.locked_joints``).
For a base, the *drive* wheels (continuous joints named like wheels, casters excluded) must be
as many as the base model has (two for ``"differential"``, four for ``"mecanum"``, ...);
otherwise the URDF is refused with a message naming what was found. With ``"fixed"`` and
``"free_flyer"`` wheels stay ordinary joints.

Every robot built here records its file as ``robot.urdf_path``.
"""

from __future__ import annotations

import copy
import os
import re
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from wbc.checks import as_float_array, check_finite, checked_name, checked_vector
from wbc.errors import InvalidValueError, ShapeError, UnknownNameError

from .arms import _unambiguous_frames, _with_scalar_joints, arm_from_model, load_urdf_model
from .fixed_base import FixedBaseRobot
from .floating_base import FloatingBaseRobot, default_limits
from .limits import Limits
from .manipulator import MobileManipulator
from .pinocchio_robot import PinocchioRobot
from .planar_base import PlanarBase, PlanarRoot

__all__ = ["ROOTS", "robot_from_urdf", "wheel_joints"]

ROOTS = ("fixed", "free_flyer", "planar")
"""The roots that are not a base name (see the module docstring)."""
_WHEEL = re.compile(r"wheel|caster", re.IGNORECASE)
_CASTER = re.compile(r"caster", re.IGNORECASE)
_CONTINUOUS = ("JointModelRUBX", "JointModelRUBY", "JointModelRUBZ",
               "JointModelRevoluteUnboundedUnaligned")


def wheel_joints(model: pin.Model) -> tuple[list[str], list[str]]:
    """``(wheels, drive_wheels)`` of a fixed-root URDF model: the joints on the root link named
    like wheels or casters, and among them the continuous ones that are not casters."""
    wheels = [model.names[j] for j in range(1, model.njoints)
              if model.parents[j] == 0 and _WHEEL.search(model.names[j])]
    drive = [name for name in wheels if not _CASTER.search(name)
             and model.joints[model.getJointId(name)].shortname() in _CONTINUOUS]
    return wheels, drive


def robot_from_urdf(
    path: str | os.PathLike[str],
    root: str | PlanarBase,
    *,
    root_name: str | None = None,
    ee_frame: str | None = None,
    name: str | None = None,
    locked_joints: Sequence[str] = (),
    home=None,
    v_max=None,
    a_max=None,
) -> PinocchioRobot:
    """A robot from a whole-robot URDF on the root ``root`` (see the module docstring).

    Args:
        path: the URDF file.
        root: ``"fixed"``, ``"free_flyer"``, ``"planar"`` or a
            :class:`~wbc.robots.planar_base.PlanarBase` (:func:`wbc.robots.from_urdf` turns a
            base name, :func:`wbc.robots.base_names`, into its model).
        root_name: how messages name the root (default: ``root`` or the base's name).
        ee_frame: the URDF frame aliased ``"ee"`` (default: none for ``"fixed"`` and
            ``"free_flyer"``; the root link for the planar roots, which always have one).
        name: robot name (default: the URDF's robot name).
        locked_joints: URDF joints to remove, held at their neutral value.
        home: the robot's home configuration, a whole ``q`` (``nq`` entries: the root's
            coordinates first; default: root at the origin, joints at their neutral value
            clipped into the limits).
        v_max, a_max: velocity / acceleration limits of the joints after the root (``n_arm``
            entries; default: the URDF's velocity limits, ``inf`` where missing, no
            acceleration limit).

    Raises:
        UnknownNameError: ``root`` is none of the above; a locked joint or ``ee_frame`` is not
            in the URDF.
        InvalidValueError: the wheels of the URDF do not match the base (the message names
            them); a bad argument.
        ModelLoadError: the file is missing or not a URDF.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidValueError(f"path of a URDF must be a str or a path, got {path!r}"[:120])
    path = os.fspath(path)
    base = _root_base(root)
    if root_name is None:
        root_name = root if isinstance(root, str) else root.name
    checked_name(name, "name")
    checked_name(ee_frame, "ee_frame")
    if not isinstance(locked_joints, (list, tuple)) or not all(isinstance(j, str)
                                                                for j in locked_joints):
        raise InvalidValueError(f"locked_joints must be a sequence of joint names, got "
                                f"{locked_joints!r}"[:160])
    free_flyer = root == "free_flyer"
    model = load_urdf_model(path, free_flyer=free_flyer)
    missing = [j for j in locked_joints if not model.existJointName(j)]
    if missing:
        raise UnknownNameError(f"cannot lock joints {missing}: not in {path}; joints: "
                               f"{list(model.names)[1:]}")
    wheels: list[str] = []
    if base is not None:
        wheels = _base_wheels(model, base, root_name, path)
    locked = [*locked_joints, *(w for w in wheels if w not in locked_joints)]
    if locked:
        model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked],
                                      pin.neutral(model))
    name = name or model.name or "robot"
    if base is None and free_flyer:
        robot: PinocchioRobot = _free_flyer(model, name, ee_frame, home, v_max, a_max)
    else:
        root_link = model.frames[1].name  # the root link's body frame, on the universe
        arm = arm_from_model(model, ee_frame or root_link, name=name, v_max=v_max,
                             a_max=a_max, source=f"URDF {path}")
        if base is None:  # "fixed"
            robot = FixedBaseRobot(arm.model, {"ee": arm.ee_frame} if ee_frame else None,
                                   name=name, limits=_arm_limits(arm),
                                   home=arm.home if home is None else _home(home, arm.n))
        else:
            robot = _on_base(arm, base, name, ee_frame, home)
    robot.urdf_path = path
    robot.locked_joints = tuple(locked)
    robot.wheel_joints = tuple(wheels)
    return robot


def _root_base(root) -> PlanarBase | None:
    """The planar base of ``root`` (a copy: its body is replaced by the URDF's root link),
    ``None`` for ``"fixed"`` and ``"free_flyer"``."""
    if isinstance(root, PlanarBase):
        return copy.copy(root)
    if not isinstance(root, str) or root not in ROOTS:
        raise UnknownNameError(f"unknown root {root!r}; use one of {list(ROOTS)}, a PlanarBase, "
                               f"or a base name through wbc.robots.from_urdf"[:300])
    return PlanarRoot() if root == "planar" else None


def _base_wheels(model: pin.Model, base: PlanarBase, root_name: str, path: str) -> list[str]:
    """The wheel joints to lock for ``base``; refuse a URDF whose drive wheels do not match."""
    wheels, drive = wheel_joints(model)
    needed = getattr(base, "n_wheels", 0)
    if needed and len(drive) != needed:
        raise InvalidValueError(
            f"root={root_name!r} drives {needed} wheels, but {path} has {len(drive)} drive wheels "
            f"on its root link ({drive}; continuous joints named like 'wheel', casters "
            f"excluded); use root='planar' (no wheel kinematics), 'fixed' or 'free_flyer'")
    return wheels


def _arm_limits(arm) -> Limits:
    return Limits(q_lower=arm.q_lower, q_upper=arm.q_upper, v_lower=-arm.v_max,
                  v_upper=arm.v_max, a_lower=-arm.a_max, a_upper=arm.a_max)


def _home(home, size: int) -> np.ndarray:
    value = as_float_array(home, "home")
    if value.shape != (size,):
        raise ShapeError(f"home must be a whole configuration of {size} entries, got shape "
                         f"{value.shape}")
    check_finite(value, "home")
    return value


def _joint_limit(value, default: np.ndarray, what: str) -> np.ndarray:
    if value is None:
        return default
    array = checked_vector(value, default.size, what, allow_inf=True)
    if (array <= 0).any():
        raise InvalidValueError(f"{what} must be > 0, got {array}")
    return array


def _free_flyer(model: pin.Model, name: str, ee_frame, home, v_max, a_max) -> FloatingBaseRobot:
    model, _ = _with_scalar_joints(model)  # continuous -> revolute; the free flyer is kept
    model = _unambiguous_frames(model)
    if ee_frame is not None and [f.name for f in model.frames].count(ee_frame) != 1:
        raise UnknownNameError(f"ee_frame {ee_frame!r} is not a frame of {name!r} (or is "
                               f"ambiguous: 'link:<name>' / 'joint:<name>')")
    limits = default_limits(model)
    n = model.nv - 6
    v = _joint_limit(v_max, limits.v_upper[6:], "v_max")
    a = _joint_limit(a_max, limits.a_upper[6:], "a_max")
    inf = np.full(6, np.inf)
    limits = Limits(q_lower=limits.q_lower, q_upper=limits.q_upper,
                    v_lower=-np.concatenate([inf, v]), v_upper=np.concatenate([inf, v]),
                    a_lower=-np.concatenate([inf, a]), a_upper=np.concatenate([inf, a]))
    return FloatingBaseRobot(model, name=name, limits=limits,
                             home=None if home is None else _home(home, 7 + n),
                             frames={"ee": ee_frame} if ee_frame else None)


def _on_base(arm, base: PlanarBase, name: str, ee_frame, home) -> MobileManipulator:
    # the base body is the URDF's root link: its inertia moves from the arm model's universe
    # (where the fixed-root parse put it) to the base, so it is counted once
    root_inertia = arm.model.inertias[0]
    base.mass = float(root_inertia.mass)
    base.com = np.array(root_inertia.lever, dtype=float)
    base.inertia = np.array(root_inertia.inertia, dtype=float)
    arm.model.inertias[0] = pin.Inertia.Zero()
    return MobileManipulator(base, arm, None, ee_frame=arm.ee_frame, name=name,
                             home=None if home is None else _home(home, 3 + arm.n))
