"""`FixedBaseRobot`: a fixed-base arm on pinocchio.

A fixed-base arm is the special case of :class:`~wbc.robots.pinocchio_robot.PinocchioRobot`
without a base: ``q`` are the joints, ``v = q̇`` (``S = I``, ``nq == nv``), the base axes are the
world axes (``reference="base"`` equals ``"world"``), and ``n_arm == nv``. Everything else — the
getters with ``out=``, the one update per tick, the symbolic forms, the quantity registry, the
clones — is shared with the mobile manipulators; see :mod:`wbc.robots.pinocchio_robot` and the
protocol :class:`wbc.robots.Robot`. :func:`load_panda` builds the Franka Panda.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from wbc.errors import ShapeError

from .arms import _with_scalar_joints
from .limits import Limits
from .pinocchio_robot import PinocchioRobot
from .resources import urdf_path

__all__ = ["FixedBaseRobot", "load_panda"]


class FixedBaseRobot(PinocchioRobot):
    """A fixed-base arm described by a pinocchio model.

    Args:
        model: the pinocchio model (1-DoF revolute or prismatic joints, so that ``nq == nv``;
            URDF ``continuous`` joints — pinocchio's unbounded revolute joints, ``(cos, sin)``
            configuration — are turned into plain revolute joints with infinite limits first).
        frames: aliases ``alias -> model frame name`` (e.g. ``{"ee": "panda_hand"}``); every
            model frame is also reachable by its own name.
        name: a label for reports (default: the model's name).
        acceleration_limit: ``(nv,)`` or scalar acceleration limits [rad/s²] (URDFs carry
            none; default ``inf``).
        limits: the robot's limits (default: the model's, and ``acceleration_limit``).
        home: the configuration :meth:`neutral` returns (default below).

    Raises:
        ShapeError: a joint has more than one degree of freedom (after the conversion above).
        WbcError: a joint type the kinematics do not support
            (:func:`wbc.robots.symbolic.check_joints`).

    :meth:`neutral` is pinocchio's neutral configuration (zeros) clipped into the position
    limits.
    """

    def __init__(
        self,
        model: pin.Model,
        frames: Mapping[str, str] | None = None,
        name: str = "",
        acceleration_limit=np.inf,
        *,
        limits: Limits | None = None,
        home=None,
    ) -> None:
        if model.nq != model.nv:
            try:  # continuous joints -> plain revolute joints
                model, _ = _with_scalar_joints(model)
            except ValueError:
                model = None
            if model is None or model.nq != model.nv or any(
                    model.joints[j].shortname() == "JointModelFreeFlyer"
                    for j in range(1, model.njoints)):
                raise ShapeError(
                    "FixedBaseRobot needs 1-DoF joints (nq == nv; continuous joints are "
                    "converted); for a free-floating root use FloatingBaseRobot or "
                    "wbc.robots.from_urdf(path, root='free_flyer')")
        if limits is None:
            acc = np.broadcast_to(np.asarray(acceleration_limit, dtype=float), (model.nv,))
            limits = Limits(
                q_lower=model.lowerPositionLimit.copy(),
                q_upper=model.upperPositionLimit.copy(),
                v_lower=-model.velocityLimit,
                v_upper=model.velocityLimit.copy(),
                a_lower=-acc,
                a_upper=acc.copy(),
            )
        if home is None:
            home = np.clip(pin.neutral(model), limits.q_lower, limits.q_upper)
        super().__init__(model, name=name or model.name, limits=limits, home=home,
                         aliases=frames)


def load_panda(
    fingers: bool = False,
    frames: Mapping[str, str] | None = None,
    q_locked: Sequence[float] | None = None,
) -> FixedBaseRobot:
    """Franka Emika Panda from example-robot-data's URDF (found offline, no Python loader).

    Args:
        fingers: keep the two finger joints (``nq = 9``); by default they are locked at
            ``q_locked`` (default: closed) and the arm has 7 joints.
        frames: extra aliases; ``"ee"`` is ``panda_hand`` and ``"tcp"`` ``panda_hand_tcp``.
        q_locked: configuration the locked finger joints are frozen at (2 values [m]).
    """
    path = str(urdf_path("panda_description/urdf/panda.urdf"))
    model = pin.buildModelFromUrdf(path)
    if not fingers:
        locked = [model.getJointId(f"panda_finger_joint{i}") for i in (1, 2)]
        q_ref = pin.neutral(model)
        if q_locked is not None:
            q_ref[-2:] = np.asarray(q_locked, dtype=float)
        model = pin.buildReducedModel(model, locked, q_ref)
    aliases = {"ee": "panda_hand"}
    if model.existFrame("panda_hand_tcp"):
        aliases["tcp"] = "panda_hand_tcp"
    aliases.update(frames or {})
    robot = FixedBaseRobot(model, aliases, name="panda")
    robot.urdf_path = path
    if not fingers:
        robot.locked_joints = ("panda_finger_joint1", "panda_finger_joint2")
    return robot
