"""Petrič & Žlajpah's decoupled controller (:class:`DecoupledController`: eq. 22 on the arm,
the velocity field on the base) and, beyond the paper, :class:`WholeBodyController` (the
field's base twist as a soft reference in one whole-body QP); both ``step(q, v, ee=T)``.
"""

from __future__ import annotations

import numpy as np

import wbc
from wbc.robots import ReducedPanda

from .stacks import DT, arm_stack, whole_body_stack
from .velocity_field import VelocityField

__all__ = ["DecoupledController", "FieldDriver", "WholeBodyController"]


class FieldDriver:
    """The field's input: ``p`` of the reduced Panda relative to the arm root (base axes)."""

    def __init__(self, robot, field: VelocityField) -> None:
        self.reduced = ReducedPanda(robot)
        self.root = robot.mount.translation.copy()
        self.field = field

    def reset(self) -> None:
        """Field at rest, no latched heading (before a new run)."""
        self.field.reset()

    def tee(self, q) -> np.ndarray:
        """The TEE point ``p`` [m] (arm-root origin, base axes)."""
        return self.reduced.point(q, "base") - self.root

    def base_command(self, q) -> np.ndarray:
        return np.array(self.field.step(self.tee(q)))


class DecoupledController:
    """Petrič & Žlajpah's controller: eq. 22 on the arm (:func:`arm_stack`) and the velocity
    field on the base, independent of each other.

    Args:
        robot: ``load("tiago_panda")``.
        field: the base's :class:`wbc.tasks.VelocityField`.
        backend: QP backend of the arm stack.
        dt: control period [s].
        projector: the arm's null-space projector, ``"exact"`` or ``"damped"`` (eq. 26 as
            printed), see :func:`arm_stack`.

    Attributes:
        move_base: ``False`` holds the base still (Fig. 6's fixed base); the field is then not
            evaluated.

    ``step(q, v, ee=T)`` takes the TCP target pose ``T`` (4, 4) (its translation is used) and
    returns the velocity command ``(v, ω, q̇_arm)``.
    """

    def __init__(self, robot, field: VelocityField, backend: str = "daqp",
                 dt: float = DT, projector: str = "exact") -> None:
        # the paper's eq. 22 holds no joint limits: reproduced as printed, on purpose
        self.arm = wbc.Controller(robot, arm_stack(robot, dt=dt, projector=projector),
                                  backend=backend, dt=dt, missing_limits="ignore")
        self.driver = FieldDriver(robot, field)
        self.nb = int(robot.nv_base)
        self.move_base = True
        self.last_solution: wbc.Solution | None = None

    def step(self, q, v=None, **references) -> np.ndarray:
        command = np.array(self.arm.step(q, v, **references))
        self.last_solution = self.arm.last_solution
        command[: self.nb] = self.driver.base_command(q) if self.move_base else 0.0
        return command


class WholeBodyController:
    """Beyond the paper: the field's ``(v, ω)`` as a soft reference one level below the TCP
    task of a whole-body QP (:func:`whole_body_stack`). Same ``step`` as
    :class:`DecoupledController`."""

    def __init__(self, robot, field: VelocityField, backend: str = "daqp",
                 dt: float = DT) -> None:
        self.qp = wbc.Controller(robot, whole_body_stack(robot, dt=dt), backend=backend, dt=dt,
                                 missing_limits="ignore")  # no position limits, as eq. 22
        self.driver = FieldDriver(robot, field)
        self.last_solution: wbc.Solution | None = None

    def step(self, q, v=None, **references) -> np.ndarray:
        base = self.driver.base_command(q)
        command = np.array(self.qp.step(q, v, **{"base.b": base}, **references))
        self.last_solution = self.qp.last_solution
        return command
