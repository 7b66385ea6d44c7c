"""Petrič & Žlajpah's decoupled controller (:class:`DecoupledController`: eq. 22 on the arm,
the velocity field on the base) and, beyond the paper, :class:`WholeBodyController` (the
field's base twist as a soft reference in one whole-body QP); both ``step(q, v, ee=T)``.

The fast path (``fused="auto"``, the default): the base's field — the reduced Panda's TEE
point from ``q`` and :meth:`VelocityField.step` — as one generated C function
(:meth:`VelocityField.symbolic_step`), and the QPs as generated C too: the decoupled arm's as
:class:`wbc.Controller`'s fused tick (:mod:`wbc.fused`), the whole-body cascade as the tick of
:mod:`wbc.papers.petric.fast` (where the field's twist is reachable; the ordinary path answers
the other ticks), all called on preallocated buffers. It computes what the ordinary path
(``fused=False``: the QPs through the Python backend, the TEE point from pinocchio and the
field in Python floats) computes, to rounding (``tests/test_petric_fast.py``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

import wbc
from wbc.cbuild import compiled_c, compiler_available
from wbc.checks import all_finite, as_float_array
from wbc.errors import NonFiniteError, ShapeError
from wbc.robots import ReducedPanda

from .fast import WholeBodyQPController
from .stacks import DT, arm_stack, whole_body_stack
from .velocity_field import VelocityField

__all__ = ["DecoupledController", "FieldDriver", "WholeBodyController"]


class FieldDriver:
    """The field's input: ``p`` of the reduced Panda relative to the arm root (base axes).

    Args:
        robot: ``load("tiago_panda")``.
        field: the base's :class:`VelocityField` (its :attr:`~VelocityField.state` is the
            driver's state on both paths).
        fused: ``"auto"`` (default) — :meth:`base_command` as one compiled C function of
            ``q`` when a C compiler is present (:attr:`fused` says whether); ``True`` — the
            same, a ``RuntimeError`` without a compiler; ``False`` — pinocchio and the field's
            Python :meth:`~VelocityField.step`.
    """

    def __init__(self, robot, field: VelocityField, fused: bool | str = "auto") -> None:
        if fused not in (True, False, "auto"):
            raise wbc.InvalidValueError(f"fused must be True, False or 'auto', got {fused!r}")
        self.reduced = ReducedPanda(robot)
        self.root = robot.mount.translation.copy()
        self.field = field
        self.fused = fused is True or (fused == "auto" and compiler_available())
        if self.fused:
            function = compiled_c(self._symbolic_tick(robot))
            # one C call per tick on these buffers: q in, the field's new state out
            self._q, self._next = np.zeros(int(robot.nq)), np.zeros(4)
            self._command = self._next[:2]  # (v, ω) of the new state
            self._buffer, self._call = function.buffer()
            # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
            self._buffer.set_arg(0, memoryview(self._q))  # type: ignore[call-arg, arg-type]
            self._buffer.set_arg(1, memoryview(field.state))  # type: ignore[call-arg, arg-type]
            self._buffer.set_res(0, memoryview(self._next))  # type: ignore[call-arg, arg-type]

    def _symbolic_tick(self, robot) -> ca.Function:
        """``(q, state) -> state``: :meth:`tee` (as :meth:`ReducedPanda.point`, from the
        joint origins' symbolic poses) then :meth:`VelocityField.symbolic_step`."""
        q, state = ca.SX.sym("q", int(robot.nq)), ca.SX.sym("state", 4)
        elbow, wrist, base = (robot.symbolic_frame(frame)(q)[0]
                              for frame in ("panda_joint4", "panda_joint6", "base"))
        forearm = wrist[:3, 3] - elbow[:3, 3]
        point = elbow[:3, 3] + self.reduced.lengths[2] * forearm / ca.norm_2(forearm)
        tee = base[:3, :3].T @ (point - base[:3, 3]) - ca.DM(self.root)
        return ca.Function("petric_field_tick", [q, state], [self.field.symbolic_step(tee, state)],
                           ["q", "state"], ["next"])

    def reset(self) -> None:
        """Field at rest, no latched heading (before a new run)."""
        self.field.reset()

    def tee(self, q) -> np.ndarray:
        """The TEE point ``p`` [m] (arm-root origin, base axes)."""
        return self.reduced.point(q, "base") - self.root

    def base_command(self, q) -> np.ndarray:
        """One tick of the field at configuration ``q`` (nq,): the applied ``(v [m/s],
        ω [rad/s])`` (a new array), kept in the field's state for the next tick."""
        if self.fused:  # (the ordinary path's pinocchio and field.step check q and p)
            q = as_float_array(q, "q")
            if q.shape != self._q.shape:
                raise ShapeError(f"q must have shape {self._q.shape}, got {q.shape}")
            if not all_finite(q):
                raise NonFiniteError("q contains NaN or inf")
        return self._advance(q).copy()

    def _advance(self, q) -> np.ndarray:
        """:meth:`base_command` on a ``q`` already checked (by the caller's
        :class:`wbc.Controller`); on the fused path the ``(v, ω)`` returned is a buffer the next
        tick overwrites."""
        if not self.fused:
            return np.array(self.field.step(self.tee(q)))
        self._q[...] = q
        self._call()
        self.field.state[...] = self._next
        return self._command


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
        fused: the fast path (module docstring): ``"auto"`` (default) where it applies,
            ``True`` required (else an error), ``False`` off — passed to the arm's
            :class:`wbc.Controller` and to the :class:`FieldDriver`.

    Attributes:
        move_base: ``False`` holds the base still (Fig. 6's fixed base); the field is then not
            evaluated.

    ``step(q, v, ee=T)`` takes the TCP target pose ``T`` (4, 4) (its translation is used) and
    returns the velocity command ``(v, ω, q̇_arm)``.
    """

    def __init__(self, robot, field: VelocityField, backend: str = "daqp",
                 dt: float = DT, projector: str = "exact", fused: bool | str = "auto") -> None:
        # the paper's eq. 22 holds no joint limits: reproduced as printed, on purpose
        self.arm = wbc.Controller(robot, arm_stack(robot, dt=dt, projector=projector),
                                  backend=backend, dt=dt, missing_limits="ignore", fused=fused)
        self.driver = FieldDriver(robot, field, fused)
        self.nb = int(robot.nv_base)
        self.move_base = True

    @property
    def last_solution(self) -> wbc.Solution | None:
        """The arm's last :class:`wbc.Solution` (read when asked: a fused tick's is copied
        then)."""
        return self.arm.last_solution

    def step(self, q, v=None, **references) -> np.ndarray:
        # a copy: the array step returns is also the arm controller's last_command (q is
        # checked there)
        command = np.array(self.arm.step(q, v, **references))
        command[: self.nb] = self.driver._advance(q) if self.move_base else 0.0
        return command


class WholeBodyController:
    """Beyond the paper: the field's ``(v, ω)`` as a soft reference one level below the TCP
    task of a whole-body QP (:func:`whole_body_stack`). Same ``step`` and ``fused`` as
    :class:`DecoupledController` (the QP's fast path: :class:`WholeBodyQPController`)."""

    def __init__(self, robot, field: VelocityField, backend: str = "daqp",
                 dt: float = DT, fused: bool | str = "auto") -> None:
        self.qp = WholeBodyQPController(robot, whole_body_stack(robot, dt=dt), backend=backend,
                                        dt=dt, missing_limits="ignore",  # as eq. 22
                                        fused=fused)
        self.driver = FieldDriver(robot, field, fused)

    @property
    def last_solution(self) -> wbc.Solution | None:
        """The QP's last :class:`wbc.Solution` (read when asked)."""
        return self.qp.last_solution

    def step(self, q, v=None, **references) -> np.ndarray:
        base = self.driver.base_command(q)
        return self.qp.step(q, v, **{"base.b": base}, **references)
