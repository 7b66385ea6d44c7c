"""Manipulability objectives: Xing et al.'s at the acceleration level, pink's at the velocity level.

Two tasks, one per control level:

* :class:`ManipulabilityAccelerationTask` — acceleration level, Xing et al. eq. (13) (below);
* :class:`ManipulabilityTask` — velocity level, pink's ``ManipulabilityTask``
  (pink 4.4, ``pink/tasks/manipulability_task.py``): one cost row asking Yoshikawa's
  ``m = sqrt(det(J Jᵀ))`` to grow at a given rate (see its docstring).

Xing et al.'s singularity-avoidance objective: ``H = det(J_m J_mᵀ)`` and its acceleration.

``J_m`` is the arm's part of a frame's Jacobian: the arm columns (the last ``n_arm``) of the
position rows of ``J[<frame>]`` (world axes) — the rows that see the singularity Xing et al.
fight, the fully stretched arm at the border of its workspace. (Their appendix leaves the rows
open; with the 6 rows of the Gen3's pose Jacobian, mixing metres and radians, ``σ_min`` is
0.16 already at their start configuration, below their thresholds 0.15 / 0.19, whereas their
base starts later in both experiments; with the position rows it is 0.245.) ``H`` does not
depend on the base pose: rotating the rows leaves ``det(J_m J_mᵀ)`` unchanged.

Eq. (12) asks for the joint velocity ``q̇_sa = γ1 ∇H`` and eq. (13) turns it into the
acceleration ``q̈_sa = γ1 ∇²H q̇_m + γ2 (γ1 ∇H − q̇_m)`` (its derivative along the motion, plus
a pull of ``q̇_m`` towards it), zero on the base. Everything here is CasADi, derived from the
robot's symbolic Jacobian (``robot.quantities``' ``"J[<frame>]"``):
:class:`ManipulabilityAccelerationTask` puts ``q̈_sa`` in a compiled stack (gradient by reverse
mode, ``∇²H q̇`` by one forward sweep, from the quantities ``"q"`` and ``"v"``), and
:func:`arm_jacobian_derivatives` gives ``J_m``, ``∂J_m/∂q`` and ``∂J̇_m/∂q`` for the appendix's
closed forms
(:func:`wbc.solvers.reference.manipulability_gradient` / ``manipulability_hessian_product``).
"""

from __future__ import annotations

import casadi as ca

from wbc.checks import (
    check_frame,
    check_robot,
    checked_name,
    checked_number,
    checked_weights,
)
from wbc.errors import WbcError
from wbc.quantities import registry_of
from wbc.terms import Cost, Task

from .frame import lm_damping_terms, velocity_block
from .posture import arm_size

__all__ = ["ManipulabilityAccelerationTask", "ManipulabilityTask", "arm_jacobian",
           "arm_jacobian_derivatives", "manipulability_expressions", "smallest_singular_value"]


def arm_jacobian(robot, frame: str = "ee", joints: int | None = None):
    """``(q, J_m)``: a configuration symbol (nq,) and ``J_m(q)`` (3 × n_arm) as SX, from the
    robot's symbolic ``"J[<frame>]"``."""
    quantity = registry_of(robot).get(f"J[{frame}]")
    if quantity.symbolic is None:
        raise WbcError(f"the robot has no symbolic form of 'J[{frame}]'")
    n_arm = arm_size(robot, joints)
    q = ca.SX.sym("q", int(robot.nq))
    return q, quantity.symbolic()(q)[:3, int(robot.nv) - n_arm:]


def manipulability_expressions(J_m, q_arm, qd_arm):
    """``(H, ∇H, ∇²H q̇_m)`` as SX for ``J_m`` an expression of ``q_arm``."""
    H = ca.det(J_m @ J_m.T)
    gradient = ca.gradient(H, q_arm)
    return H, gradient, ca.jtimes(gradient, q_arm, qd_arm)


def smallest_singular_value(J_m):
    """``σ_min`` of a 3-row matrix as SX: the square root of the smallest eigenvalue of the
    symmetric ``Ψ = J_m J_mᵀ`` (3 × 3) by the trigonometric closed form (O. K. Smith,
    "Eigenvalues of a symmetric 3 × 3 matrix", CACM 1961), so that Xing's σ switch can sit
    inside a compiled stack (CasADi has no symbolic SVD)."""
    psi = J_m @ J_m.T
    mean = ca.trace(psi) / 3
    off = psi[0, 1] ** 2 + psi[0, 2] ** 2 + psi[1, 2] ** 2
    spread = ca.sqrt(((psi[0, 0] - mean) ** 2 + (psi[1, 1] - mean) ** 2
                      + (psi[2, 2] - mean) ** 2 + 2 * off) / 6)
    safe = ca.if_else(spread > 1e-12 * (1 + mean), spread, 1.0)  # Ψ = mean·I: no spread
    half_det = ca.det((psi - mean * ca.SX.eye(3)) / safe) / 2
    angle = ca.acos(ca.fmin(ca.fmax(half_det, -1.0), 1.0)) / 3
    smallest = mean + 2 * spread * ca.cos(angle + 2 * ca.pi / 3)
    return ca.sqrt(ca.fmax(smallest, 0.0))


def arm_jacobian_derivatives(robot, frame: str = "ee", joints: int | None = None) -> ca.Function:
    """``(q, qd_arm) -> (J_m, dJ, dJ_dot)``: ``J_m`` (3, m); ``dJ`` (3·m, m) with
    ``dJ[i + 3j, k] = ∂J_m[i, j]/∂q_k`` (CasADi's column-major ``vec``); ``dJ_dot`` the same
    for ``J̇_m = Σ_k ∂J_m/∂q_k q̇_k``, i.e. the second derivatives of ``J_m`` contracted with
    ``qd_arm`` (``q_k`` the arm joints). With ``qd_arm = e_k`` it is ``∂²J_m/∂q ∂q_k``."""
    n_arm = arm_size(robot, joints)
    q, J_m = arm_jacobian(robot, frame, joints)
    q_arm = q[int(robot.nq) - n_arm:]
    qd_arm = ca.SX.sym("qd_arm", n_arm)
    dJ = ca.jacobian(ca.vec(J_m), q_arm)
    dJ_dot = ca.jacobian(ca.vec(ca.jtimes(J_m, q_arm, qd_arm)), q_arm)
    return ca.Function("arm_jacobian_derivatives", [q, qd_arm], [J_m, dJ, dJ_dot],
                       ["q", "qd_arm"], ["J_m", "dJ", "dJ_dot"])


class ManipulabilityAccelerationTask(Task):
    """Cost ``1/2 ||v̇ − q̈_sa||²`` over the whole acceleration vector, ``q̈_sa = [0_base;
    γ1 ∇²H q̇_m + γ2 (γ1 ∇H − q̇_m)]`` (Xing et al. eq. 13, see the module docstring),
    computed inside the compiled stack from the quantities ``"q"`` and ``"v"``.

    As the lowest level of a cascade, this cost over all joints makes the solution unique and
    equals Xing's tertiary term ``P_A q̈_sa`` when no bound is active (the levels above leave
    ``x₁* + range(P_A)`` free, and ``x₁*`` is orthogonal to it: docs/DESIGN.md, math note 3).

    Args:
        robot: the robot (``nq``, ``nv``, a symbolic ``"J[<frame>]"``).
        frame: the end-effector frame.
        gamma1: ``γ1`` [1/s] (paper: 5); gamma2: ``γ2`` [1/s] (paper: 0.5); they are the
            defaults of the parameters ``"<name>.gamma1"``, ``"<name>.gamma2"`` (settable per
            tick without recompiling).
        name: task name. joints: number of trailing arm joints.
        block: the acceleration block of the decision vector (``None``: all of it).
        weight: ``w`` of the cost ``w/2 ||v̇ − q̈_sa||²`` (Xing's is 1): a number, one per
            joint (``nv``), or a CasADi SX expression of the stack's parameters, set every
            tick (see :func:`wbc.checks.checked_weights`).
    """

    def __init__(self, robot, frame: str = "ee", gamma1: float = 5.0, gamma2: float = 0.5,
                 name: str | None = None, joints: int | None = None,
                 block: str | None = None, weight=1.0) -> None:
        what = f"ManipulabilityAccelerationTask {name!r}"
        self.gamma1 = checked_number(gamma1, f"gamma1 [1/s] of {what}")
        self.gamma2 = checked_number(gamma2, f"gamma2 [1/s] of {what}")
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        checked_name(frame, f"frame of {what}", optional=False)
        check_frame(robot, frame, what)
        self.robot, self.frame = robot, frame
        self.n_arm = arm_size(robot, joints)
        self.joints = joints
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.weight = checked_weights(weight, self.nv, f"weight of {what}")

    def target(self, q, v, gamma1, gamma2):
        """``q̈_sa`` (nv,) as SX of the symbols ``q`` (nq,), ``v`` (nv,) and the gains."""
        q_sym, J_m = arm_jacobian(self.robot, self.frame, self.joints)
        q_arm, qd_arm = q_sym[self.nq - self.n_arm:], v[self.nv - self.n_arm:]
        _, gradient, hessian_qd = manipulability_expressions(J_m, q_arm, qd_arm)
        arm = gamma1 * hessian_qd + gamma2 * (gamma1 * gradient - qd_arm)
        arm = ca.substitute(arm, q_sym, q)
        return ca.vertcat(ca.SX.zeros(self.nv - self.n_arm), arm)

    def terms(self, stack):
        x = velocity_block(stack, self.block, self.nv,
                           f"ManipulabilityAccelerationTask {self.name!r}")
        q = stack.quantity("q", self.nq)
        v = stack.quantity("v", self.nv)
        gamma1 = stack.parameter(f"{self.name}.gamma1", 1, self.gamma1)
        gamma2 = stack.parameter(f"{self.name}.gamma2", 1, self.gamma2)
        return [Cost(x, self.target(q, v, gamma1, gamma2), self.weight, self.name)]


#: ``det(J Jᵀ)`` below this [-] counts as singular: the row ``∇m`` is then 0
SINGULAR = 1e-300


class ManipulabilityTask(Task):
    """Velocity-level manipulability: one cost row ``1/2 w (∇m · v − ṁ*)²`` asking Yoshikawa's
    ``m = sqrt(det(J Jᵀ))`` to grow at the rate ``ṁ*`` [1/s] (pink's ``ManipulabilityTask``).

    ``J`` is the arm's columns of the frame's 6-row Jacobian, as the robot's quantities
    ``"manipulability[<frame>]"`` (``H = det(J Jᵀ) = m²``) and
    ``"manipulability_gradient[<frame>]"`` (``∇H``, over the arm joints) define them, so that
    ``∇m = ∇H / (2 sqrt(H))`` on the arm joints and 0 on a base (0 where ``H <= 1e-300``). The
    row's minimum-norm solution is ``v ∝ ∇m``: gradient ascent of the manipulability, at the
    rate asked, leaving the directions orthogonal to ``∇m`` to the other tasks.

    Relation to pink: pink minimises ``1/2 ‖c (∇m · Δq − α ρ)‖² + μ/2 ‖Δq‖²`` over
    ``Δq = v · dt`` (its error is ``−ρ``, ``ρ`` its ``manipulability_rate``, ``α`` its gain,
    ``μ = lm_damping (c α ρ)²``): it asks ``ṁ = α ρ / dt``, so its "rate" is per control period,
    not per second. Divided by ``dt²`` that is this cost with ``w = c²``, ``ṁ* = α ρ / dt`` and
    ``lm_damping`` unchanged (``μ = lm_damping · w · (ṁ* dt)²``). Pink's ``∇m`` is over every
    joint of its model and its default Jacobian is the LOCAL one; ``det(J Jᵀ)`` of a 6-row
    Jacobian does not depend on the axes its rows are expressed in, so on a fixed-base arm the
    two rows are equal (tested to 1e-12); on a mobile manipulator pink's would include the
    base columns, wbc's is the arm's (the quantities'). Pink's masks (position rows only, ...)
    are not offered.

    Args:
        robot: the robot (quantities ``"manipulability[<frame>]"`` and
            ``"manipulability_gradient[<frame>]"``; ``n_arm``).
        frame: the frame whose Jacobian is measured (e.g. ``"ee"``).
        rate: ``ṁ*`` [1/s], the default of the reference ``"<name>.target"`` (1,), settable per
            tick (negative: towards a singularity).
        weight: ``w >= 0`` (pink's ``cost²``).
        lm_damping: pink's Levenberg–Marquardt damping [-].
        name: task name. joints: number of trailing arm joints (the quantities' ``n_arm``).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Quantities it declares: ``"manipulability[<frame>]"`` (1, 1),
    ``"manipulability_gradient[<frame>]"`` (n_arm, 1), ``"dt"`` (numeric quantities: filled by
    the robot each tick, not compiled).
    """

    def __init__(self, robot, frame: str = "ee", rate: float = 0.1, weight=1.0,
                 lm_damping: float = 0.0, name: str | None = None, joints: int | None = None,
                 block: str | None = None) -> None:
        what = f"ManipulabilityTask {name!r}"
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        self.frame = checked_name(frame, f"frame of {what}", optional=False)
        check_frame(robot, frame, what)
        self.rate = checked_number(rate, f"rate [1/s] of {what}", low=None)
        self.weight = checked_weights(weight, 1, f"weight of {what}")
        self.lm_damping = checked_number(lm_damping, f"lm_damping of {what}")
        self.n_arm = arm_size(robot, joints)
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")
        self.row: ca.SX | None = None  # ∇m over v, set by terms()

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv,
                           f"ManipulabilityTask {self.name!r}")
        H = stack.quantity(f"manipulability[{self.frame}]", (1, 1))
        gradient = stack.quantity(f"manipulability_gradient[{self.frame}]", (self.n_arm, 1))
        dt = stack.quantity("dt", 1)
        rate = stack.parameter(f"{self.name}.target", 1, self.rate)
        arm = ca.if_else(H > SINGULAR, gradient / (2 * ca.sqrt(ca.fmax(H, SINGULAR))),
                         ca.SX.zeros(self.n_arm))
        row = ca.vertcat(ca.SX.zeros(self.nv - self.n_arm), arm).T
        self.row = row
        # pink's damping of this task: its error is the rate asked per tick, rate · dt
        return [Cost(row @ v, rate, self.weight, self.name),
                *lm_damping_terms(self.name, v, self.weight, 1.0, self.lm_damping, rate * dt)]

    def __repr__(self) -> str:
        return (f"ManipulabilityTask(frame={self.frame!r}, rate={self.rate}, "
                f"name={self.name!r})")
