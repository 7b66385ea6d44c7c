"""The robot protocol: what the controller, the tasks and the simulator use of a robot.

:class:`Robot` is a runtime-checkable :class:`typing.Protocol`; any object with these members
is a robot (``isinstance(obj, Robot)`` checks that the members exist, not their signatures;
the conformance suite ``tests/test_robot_protocol.py`` checks the behaviour of the library's
robots). The robots of :mod:`wbc.robots` (the catalogue's mobile manipulators,
:class:`~wbc.robots.FixedBaseRobot`, the free-flyer
:class:`~wbc.robots.floating_base.FloatingBaseRobot` and the whole-robot URDFs of
:mod:`wbc.robots.whole_body`) implement it through
:class:`~wbc.robots.pinocchio_robot.PinocchioRobot`.
:class:`SymbolicRobot` adds the optional CasADi forms that ``kinematics="compiled"`` uses.

Conventions (units, axes, the ``q=None`` "last update" shortcut, ``out=`` arrays written
element-wise, possibly column-major views) are those of :mod:`wbc.robots.pinocchio_robot`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import casadi as ca
import numpy as np

from wbc.quantities import QuantityRegistry

from .limits import Limits

__all__ = ["Robot", "SymbolicRobot"]


@runtime_checkable
class Robot(Protocol):
    """A robot model as wbc uses it.

    Attributes:
        name: a label for messages and reports.
        nq: size of the configuration ``q``.
        nv: size of the velocity coordinates ``v`` (``nq − 1`` for a differential drive base
            and for a free-flyer root, whose 7 configuration entries — position and unit
            quaternion — have 6 velocity entries, the root's twist in its own axes).
        limits: position limits over ``q``, velocity / acceleration limits over ``v``.
        quantities: the model quantities the robot offers the controller (``pose[<frame>]``,
            ``J[<frame>]``, ``Jdot_v[<frame>]``, ``com``, …).
    """

    name: str
    nq: int
    nv: int
    limits: Limits
    quantities: QuantityRegistry

    @property
    def frame_names(self) -> list[str]:
        """Names the frame getters accept."""

    def has_frame(self, frame: str) -> bool:
        """Whether ``frame`` is one of :attr:`frame_names`."""

    def neutral(self) -> np.ndarray:
        """A home configuration ``(nq,)`` within the position limits."""

    def random_configuration(self, rng: np.random.Generator | None = None) -> np.ndarray:
        """A configuration ``(nq,)`` uniform within the finite position limits (a documented
        range where a coordinate is unbounded)."""

    def integrate(self, q: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        """The configuration after ``dt`` [s] at constant velocity ``v``, on the configuration
        manifold (for a free flyer pinocchio's Lie-group ``integrate``: the quaternion stays a
        unit quaternion)."""

    def update(self, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """One kinematics update at ``q`` (and ``v``, for drifts) that the getters then read."""

    def frame_pose(self, q=None, frame: str = "ee", out: np.ndarray | None = None) -> np.ndarray:
        """World pose ``(4, 4)`` of ``frame`` [m]."""

    def frame_jacobian(self, q=None, frame: str = "ee", reference: str = "world",
                       out: np.ndarray | None = None) -> np.ndarray:
        """Jacobian ``(6, nv)``, rows ``[linear; angular]``, of ``frame``'s twist."""

    def frame_drift(self, q=None, v=None, frame: str = "ee", reference: str = "world",
                    out: np.ndarray | None = None) -> np.ndarray:
        """Drift ``J̇ v`` ``(6,)`` [m/s², rad/s²] of ``frame``."""

    def clone(self) -> Robot:
        """A copy sharing the immutable model, with its own per-tick state."""


@runtime_checkable
class SymbolicRobot(Robot, Protocol):
    """A :class:`Robot` with CasADi forms of its frame kinematics."""

    def symbolic_frame(self, frame: str = "ee") -> ca.Function:
        """``q -> (pose (4, 4), J (6, nv))``: :meth:`Robot.frame_pose` and the ``"world"``
        :meth:`Robot.frame_jacobian`."""

    def symbolic_drift(self, frame: str = "ee") -> ca.Function:
        """``(q, v) -> J̇ v (6, 1)``: the ``"world"`` :meth:`Robot.frame_drift`."""
