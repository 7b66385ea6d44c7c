"""A user's own robot and stack for ``wbc bench``, ``wbc fuzz`` and ``wbc audit``.

``--robot FILE.toml`` — a robot description (TOML, read with :mod:`tomllib`)::

    name = "lab_xarm7"                 # optional (default: the file's stem)
    urdf = "xarm7/xarm7.urdf"          # a path relative to this file ...
    # catalogue = "tiago_panda"        # ... or a catalogue robot (then only `name` besides)
    ee_frame = "link_eef"              # the URDF frame used as the end effector "ee"
    base = "mecanum"                   # a base name (wbc.robots.base_names()), or a table:
    # [base]
    # kind = "differential"            #   differential | mecanum | omni | steerable
    # separation = 0.40                #   ... and that base's constructor arguments
    # radius = 0.10
    # root = "fixed"                   # or "free_flyer", "planar" (instead of `base`)
    mount = { xyz = [0.0, 0.0, 0.3], rpy = [0.0, 0.0, 0.0] }   # arm root in the base frame
    v_max = [2.0, 2.0, 2.0, 2.0, 2.5, 2.5, 2.5]   # optional: arm velocity limits [rad/s]
    a_max = [10.0, 10.0, 10.0, 10.0, 15.0, 15.0, 15.0]   # optional: arm accelerations [rad/s²]
    home = [0.0, 0.3, 0.0, 1.2, 0.0, 0.5, 0.0]   # optional: the arm's home configuration
    locked_joints = ["gripper_joint"]  # optional: URDF joints removed

``--stack module:function`` — ``function(robot) -> wbc.Stack``, imported from the working
directory (``module`` may also be a path ``dir/file.py``). Its frame task named ``"ee"`` (a
parameter ``"ee.target"`` of shape 4 × 4) follows the scenarios' targets as the built-in
stacks' do; every other parameter must have a default. The decision vector's first ``robot.nv``
entries are the command: joint velocities, or accelerations when the stack's first variable
block is named one of :data:`ACCELERATION_BLOCKS` (the state is then integrated as
``v += a dt``).

Every error names the file (or the spec) and the key, as a :class:`~wbc.WbcError`.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomllib

import wbc
from wbc.errors import InvalidValueError, UnknownNameError, WbcError

#: Names of a first variable block that make a user stack's command an acceleration.
ACCELERATION_BLOCKS = ("a", "dv", "vdot", "qdd", "ddq", "acc")
ROOTS = ("fixed", "free_flyer", "planar")
_KEYS = {"name", "urdf", "catalogue", "ee_frame", "base", "root", "mount", "v_max", "a_max",
         "home", "locked_joints"}


# ----------------------------------------------------------------------------- robot files
def load_robot_file(path: str | os.PathLike[str]):
    """The robot described by the TOML file ``path`` (see the module docstring).

    Raises:
        WbcError: the file cannot be read or parsed, a key is unknown, missing or of the wrong
            type, or the robot library refuses a value — the message names the file and key.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as err:
        raise WbcError(f"robot file {str(path)!r}: cannot be read: {err.strerror or err}") \
            from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise WbcError(f"robot file {str(path)!r}: not valid TOML: {err}") from None
    where = f"robot file {str(path)!r}"
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise UnknownNameError(f"{where}: unknown key(s) {unknown}; keys: {sorted(_KEYS)}")
    name = _string(data, "name", where) if "name" in data else path.stem
    if "catalogue" in data:
        others = sorted(set(data) - {"catalogue", "name"})
        if others:
            raise InvalidValueError(f"{where}: key 'catalogue' names a whole robot; remove "
                                    f"{others} (or describe the robot with 'urdf')")
        import wbc.robots

        try:
            return wbc.robots.load(_string(data, "catalogue", where))
        except WbcError as err:
            raise type(err)(f"{where}, key 'catalogue': {err}") from None
    if "urdf" not in data:
        raise InvalidValueError(f"{where}: give 'urdf' (a path relative to the file) or "
                                "'catalogue' (a catalogue robot's name)")
    urdf = path.parent / _string(data, "urdf", where)
    if not urdf.is_file():
        raise WbcError(f"{where}, key 'urdf': no file {str(urdf)!r}")
    kwargs: dict[str, Any] = {"ee_frame": _string(data, "ee_frame", where), "name": name}
    if "mount" in data:
        kwargs["mount"] = _mount(data["mount"], where)
    for key in ("v_max", "a_max"):
        if key in data:
            kwargs[key] = _numbers(data[key], where, key, scalar_ok=False)
    if "home" in data:
        kwargs["home"] = _numbers(data["home"], where, "home", scalar_ok=False)
    if "locked_joints" in data:
        joints = data["locked_joints"]
        if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
            raise InvalidValueError(f"{where}, key 'locked_joints': a list of joint names, "
                                    f"got {joints!r}"[:200])
        kwargs["locked_joints"] = joints
    kwargs.update(_base_or_root(data, where))
    import wbc.robots

    try:
        return wbc.robots.from_urdf(urdf, **kwargs)
    except WbcError as err:
        raise type(err)(f"{where}: {err}") from None
    except (ValueError, TypeError, RuntimeError) as err:  # pinocchio's parser, a bad argument
        raise WbcError(f"{where}: {type(err).__name__}: {err}") from None


def _string(data: dict, key: str, where: str) -> str:
    """The non-empty string ``data[key]``; an error naming the file and key if it is missing
    or not one."""
    if key not in data:
        raise InvalidValueError(f"{where}: key {key!r} is missing")
    value = data[key]
    if not isinstance(value, str) or not value:
        raise InvalidValueError(f"{where}, key {key!r}: a non-empty string, got {value!r}"[:200])
    return value


def _numbers(value, where: str, key: str, scalar_ok: bool):
    """A float (when ``scalar_ok``) or a list of floats from a TOML value."""
    if scalar_ok and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, list) and value and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return np.asarray(value, float)
    kind = "a number or a list of numbers" if scalar_ok else "a list of numbers"
    raise InvalidValueError(f"{where}, key {key!r}: {kind}, got {value!r}"[:200])


def _mount(value, where: str) -> np.ndarray:
    """``{xyz = [...], rpy = [...]}`` as a 4 × 4 pose (roll-pitch-yaw in radians, about the
    fixed x, y, z axes: ``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""
    if not isinstance(value, dict) or set(value) - {"xyz", "rpy"}:
        raise InvalidValueError(f"{where}, key 'mount': a table {{xyz = [x, y, z], rpy = "
                                f"[roll, pitch, yaw]}}, got {value!r}"[:200])
    T = np.eye(4)
    for key in ("xyz", "rpy"):
        entry = np.asarray(_numbers(value.get(key, [0.0, 0.0, 0.0]), where, f"mount.{key}",
                                    scalar_ok=False))
        if entry.shape != (3,) or not np.all(np.isfinite(entry)):
            raise InvalidValueError(f"{where}, key 'mount.{key}': three finite numbers, got "
                                    f"{value.get(key)!r}"[:200])
        if key == "xyz":
            T[:3, 3] = entry
        else:
            import pinocchio as pin

            T[:3, :3] = pin.rpy.rpyToMatrix(*entry)  # URDF's convention
    return T


def _base_or_root(data: dict, where: str) -> dict:
    """``from_urdf``'s keyword for the robot's root: ``base=`` (a name or a base model) or
    ``root=`` (``"fixed"``, ``"free_flyer"``, ``"planar"``, when the installed ``from_urdf``
    has it)."""
    import wbc.robots

    if "base" in data and "root" in data:
        raise InvalidValueError(f"{where}: give 'base' or 'root', not both")
    if "root" in data:
        root = _string(data, "root", where)
        has_root = "root" in inspect.signature(wbc.robots.from_urdf).parameters
        if root not in ROOTS:
            if root in wbc.robots.base_names():
                return {"root": root} if has_root else {"base": root}
            raise InvalidValueError(f"{where}, key 'root': one of {list(ROOTS)} or a base name "
                                    f"({wbc.robots.base_names()}), got {root!r}")
        if not has_root:
            raise WbcError(f"{where}, key 'root': this installation's wbc.robots.from_urdf "
                           "takes no root= (only an arm on a base); use 'base'")
        return {"root": root}
    if "base" not in data:
        raise InvalidValueError(f"{where}: key 'base' (a base name or a table with 'kind') "
                                f"or 'root' ({list(ROOTS)}) is missing")
    base = data["base"]
    if isinstance(base, str):
        if base not in wbc.robots.base_names():
            raise UnknownNameError(f"{where}, key 'base': unknown base {base!r}; bases: "
                                   f"{wbc.robots.base_names()}")
        return {"base": base}
    if not isinstance(base, dict) or not isinstance(base.get("kind"), str):
        raise InvalidValueError(f"{where}, key 'base': a base name or a table with 'kind' "
                                f"({sorted(_base_classes())}) and that base's arguments, got "
                                f"{base!r}"[:240])
    classes = _base_classes()
    kind = base["kind"]
    if kind not in classes:
        raise UnknownNameError(f"{where}, key 'base.kind': unknown {kind!r}; kinds: "
                               f"{sorted(classes)}")
    arguments = {k: (np.asarray(v, float) if isinstance(v, list) else v)
                 for k, v in base.items() if k != "kind"}
    try:
        return {"base": classes[kind](**arguments)}
    except TypeError as err:  # a missing or unknown constructor argument
        signature = inspect.signature(classes[kind])
        raise InvalidValueError(f"{where}, key 'base': {kind} base{signature}: {err}") from None
    except WbcError as err:
        raise type(err)(f"{where}, key 'base': {err}") from None


def _base_classes() -> dict:
    import wbc.robots

    return {"differential": wbc.robots.DifferentialDriveBase, "mecanum": wbc.robots.MecanumBase,
            "omni": wbc.robots.OmniBase, "steerable": wbc.robots.SteerableBase}


# ----------------------------------------------------------------------------- stacks
@dataclass(frozen=True)
class UserStack:
    """A ``module:function`` stack builder, checked on a robot (:func:`load_stack`).

    Attributes:
        spec: the ``module:function`` text, as given (also the stack's name in reports).
        build: ``build(robot) -> wbc.Stack``.
    """

    spec: str
    build: Any

    def __call__(self, robot) -> wbc.Stack:
        """A new stack for ``robot``, checked (:func:`check_user_stack`)."""
        try:
            stack = self.build(robot)
        except WbcError as err:
            raise type(err)(f"--stack {self.spec!r}: {err}") from None
        return check_user_stack(stack, robot, self.spec)


def load_stack(spec: str) -> UserStack:
    """The builder named by ``spec`` = ``"module:function"`` (or ``"path/file.py:function"``),
    imported from the working directory.

    Raises:
        WbcError: a malformed spec, a module that cannot be imported (its error quoted), a
            missing or non-callable function.
    """
    module_name, sep, function = str(spec).rpartition(":")
    if not sep or not module_name or not function.isidentifier():
        raise InvalidValueError(f"--stack {spec!r}: expected 'module:function' (a module "
                                "importable from the working directory, or a .py file, and "
                                "the name of its function(robot) -> wbc.Stack)")
    try:
        module = (_module_from_file(Path(module_name)) if module_name.endswith(".py")
                  else import_from_working_directory(module_name))
    except WbcError:
        raise
    except Exception as err:  # the user's module: any exception it raises on import
        raise WbcError(f"--stack {spec!r}: cannot import {module_name!r}: "
                       f"{type(err).__name__}: {err}") from None
    build = getattr(module, function, None)
    if not callable(build):
        raise UnknownNameError(f"--stack {spec!r}: module {module_name!r} has no function "
                               f"{function!r}")
    return UserStack(str(spec), build)


def import_from_working_directory(module_name: str):
    """``importlib.import_module(module_name)`` with the working directory first on
    ``sys.path`` for the call (a user's module beside their data, as ``python -m`` finds it)."""
    cwd = os.getcwd()
    added = cwd not in sys.path
    if added:
        sys.path.insert(0, cwd)
    try:
        return importlib.import_module(module_name)
    finally:
        if added:
            sys.path.remove(cwd)


def _module_from_file(path: Path):
    if not path.is_file():
        raise WbcError(f"no file {str(path)!r}")
    name = f"wbc_user_stack_{path.stem}"
    module_spec = importlib.util.spec_from_file_location(name, path)
    assert module_spec is not None and module_spec.loader is not None  # a .py file
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    return module


def check_user_stack(stack, robot, spec: str) -> wbc.Stack:
    """``stack`` if it can run the scenarios on ``robot``: a :class:`wbc.Stack` with a 4 × 4
    reference ``"ee.target"`` (a frame task named ``"ee"``) and at least ``robot.nv``
    decision variables."""
    if not isinstance(stack, wbc.Stack):
        raise WbcError(f"--stack {spec!r}: the function returned {type(stack).__name__}, not "
                       "a wbc.Stack")
    target = stack.parameters.get("ee.target")
    if target is None or target.quantity or target.shape != (4, 4):
        raise WbcError(f"--stack {spec!r}: the stack has no frame task named 'ee' (a 4 × 4 "
                       f"reference 'ee.target'); its parameters: {sorted(stack.parameters)}")
    if stack.variables.n < int(robot.nv):
        raise WbcError(f"--stack {spec!r}: {stack.variables.n} decision variables, fewer "
                       f"than the robot's {robot.nv} velocities")
    return stack


def is_acceleration(stack: wbc.Stack) -> bool:
    """Whether the stack's command (its first ``nv`` variables) is an acceleration."""
    return stack.variables.names[0] in ACCELERATION_BLOCKS
