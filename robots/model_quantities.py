"""The model quantities a wbc robot offers the controller (its :class:`~wbc.QuantityRegistry`).

==============================  ==========  =====  ===============================================
name                            shape       v?     value (at the robot's last ``update``)
==============================  ==========  =====  ===============================================
``pose[<frame>]``               (4, 4)             world pose, translation [m]
``J[<frame>]``                  (6, nv)            Jacobian, rows [linear; angular], world axes
``Jdot_v[<frame>]``             (6, 1)      yes    drift ``J̇ v`` [m/s², rad/s²], world axes
``J_base[<frame>]``             (6, nv)            Jacobian in the base frame's (root body's) axes
``com``                         (3, 1)             centre of mass [m], world
``J_com``                       (3, nv)            centre-of-mass Jacobian, world axes
``manipulability[<frame>]``     (1, 1)             ``det(J Jᵀ)`` of the arm's columns
``manipulability_gradient[f]``  (n_arm, 1)         its gradient w.r.t. the arm joints
``M``                           (nv, nv)           joint-space mass matrix over ``v`` [kg, kg·m²]
==============================  ==========  =====  ===============================================

``pose``, ``J``, ``Jdot_v``, ``J_base``, ``com`` and ``J_com`` have symbolic forms (CasADi
functions of ``q``, or ``(q, v)`` for ``Jdot_v``, with one output each, built from
:meth:`~wbc.robots.pinocchio_robot.PinocchioRobot.symbolic_frame`, ``symbolic_drift``,
``symbolic_com`` and ``symbolic_com_jacobian``), so ``kinematics="compiled"`` inlines them;
the manipulability, its gradient and ``M`` are filled numerically. The compiled forms
are cached on the robot's shared function cache, so a clone's registry reuses them.

Fillers write element-wise into ``out`` (the shape above; possibly a column-major view into a
compiled stack's parameter vector): vector quantities are written through the ``out[:, 0]``
view, never by rebinding.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin

from wbc.quantities import QuantityRegistry

__all__ = ["register_quantities"]


def _mass_matrix_filler(robot):
    """The filler of ``"M"``: the joint-space mass matrix over the robot's velocity
    coordinates, ``M_v = Sᵀ M S`` (pinocchio's ``crba``, symmetrised; ``S(q)`` the velocity map
    of a planar base, none for a fixed base or a free flyer, whose ``v`` is pinocchio's own), so
    that ``1/2 vᵀ M_v v`` is the kinetic energy [J]. ``crba`` runs on a ``Data`` of its own, so
    the other fillers' kinematics are untouched whatever the order they run in."""
    data = None
    lower = np.tril_indices(robot.model.nv, -1)  # strictly lower triangle

    def fill(_, out) -> None:
        nonlocal data
        robot._ensure(None)  # the configuration of the last update (raises without one)
        if data is None:
            data = robot.model.createData()
        mass = pin.crba(robot.model, data, robot._q)  # a new array
        # crba computes the upper triangle; mirror it (np.triu would cost 10x the crba)
        mass[lower] = mass.T[lower]
        out[...] = mass if robot.base is None else robot._s.T @ mass @ robot._s

    return fill


def _one_output(robot, kind: str, frame, output: int) -> ca.Function:
    """Output ``output`` of ``robot.symbolic_frame(frame)`` as a one-output function of ``q``
    (cached on the robot, shared by clones)."""
    fid = robot.frame_id(frame)

    def build() -> ca.Function:
        kinematics = robot.symbolic_frame(fid)
        q = ca.SX.sym("q", robot.nq)
        value = kinematics(q)[output]
        rt = robot._symbolic_base_axes(q) if kind == "J_base" else None
        if rt is not None:
            # blockdiag(Rᵀ, Rᵀ) J_world with R the base frame's rotation (Rz(θ) for a planar
            # base, the root body's full rotation for a free flyer): the world twist in base axes
            value = ca.vertcat(rt @ value[:3, :], rt @ value[3:, :])
        name = kind.replace("_", "") + kinematics.name().removeprefix("kinematics")
        return ca.Function(name, [q], [value], ["q"], [kind])

    return robot._cached(kind, fid, build)


def register_quantities(robot) -> QuantityRegistry:
    """A registry of the quantities of ``robot`` (a
    :class:`~wbc.robots.pinocchio_robot.PinocchioRobot`), see the module docstring."""
    registry = QuantityRegistry()
    nv, n_arm = robot.nv, robot.n_arm

    def frames() -> list[str]:
        return robot.frame_names

    def fill_manipulability(frame: str | None, out) -> None:  # a frame name: argument="frame"
        out[0, 0] = robot.manipulability(None, frame)

    registry.register(
        "pose", argument="frame", arguments=frames, shape=lambda f: (4, 4),
        fill=lambda f, out: robot.frame_pose(None, f, out),
        symbolic=lambda f: _one_output(robot, "pose", f, 0),
        doc="world pose (4, 4) of the frame, translation [m]")
    registry.register(
        "J", argument="frame", arguments=frames, shape=lambda f: (6, nv),
        fill=lambda f, out: robot.frame_jacobian(None, f, "world", out),
        symbolic=lambda f: _one_output(robot, "J", f, 1),
        doc="frame Jacobian (6, nv): origin velocity [m/s] and angular velocity [rad/s], "
            "world axes, per unit v")
    registry.register(
        "Jdot_v", argument="frame", arguments=frames, shape=lambda f: (6, 1), needs_v=True,
        fill=lambda f, out: robot.frame_drift(None, None, f, "world", out[:, 0]),
        symbolic=lambda f: robot.symbolic_drift(f),
        doc="drift J̇v (6, 1) [m/s², rad/s²] at v̇ = 0, world axes")
    registry.register(
        "J_base", argument="frame", arguments=frames, shape=lambda f: (6, nv),
        fill=lambda f, out: robot.frame_jacobian(None, f, "base", out),
        symbolic=lambda f: _one_output(robot, "J_base", f, 1),
        doc="frame Jacobian (6, nv) in the base frame's axes (world axes for a fixed base, "
            "the root body's for a free flyer)")
    registry.register(
        "com", shape=lambda _: (3, 1), fill=lambda _, out: robot.com(None, out[:, 0]),
        symbolic=lambda _: robot.symbolic_com(), doc="centre of mass (3, 1) [m], world")
    registry.register(
        "J_com", shape=lambda _: (3, nv), fill=lambda _, out: robot.com_jacobian(None, out),
        symbolic=lambda _: robot.symbolic_com_jacobian(),
        doc="centre-of-mass Jacobian (3, nv) [m/s per unit v], world axes")
    registry.register(
        "manipulability", argument="frame", arguments=frames, shape=lambda f: (1, 1),
        fill=fill_manipulability,
        doc="Yoshikawa's det(J Jᵀ) (1, 1) of the arm's Jacobian columns")
    registry.register(
        "manipulability_gradient", argument="frame", arguments=frames,
        shape=lambda f: (n_arm, 1),
        fill=lambda f, out: robot.manipulability_gradient(None, f, out[:, 0]),
        doc="gradient (n_arm, 1) of manipulability[frame] w.r.t. the arm joints [per rad]")
    registry.register(
        "M", shape=lambda _: (nv, nv), fill=_mass_matrix_filler(robot),
        doc="joint-space mass matrix (nv, nv) over v, symmetric: 1/2 vᵀ M v is the kinetic "
            "energy [J]")
    return registry
