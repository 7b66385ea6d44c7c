"""Sorour et al.'s task sharing (eqs. 9–11, 13) and arm compensation (eq. 14) as stack pieces.

* :func:`sharing_factor` — eq. 11 as a CasADi expression of the position-error norm.
* :func:`share_task` — the per-tick mobility ``M = diag((1 − ψ) I_base, ψ I_arm)`` (eq. 10 with
  the erratum: ψ = 1 moves the arm only; see :mod:`wbc.papers.sorour.closed_form`) on the task's
  level only (:meth:`wbc.Stack.set_mobility` with ``levels``): its pins hold while the task is
  solved, and the null-space level below may still move the pinned joints, as eq. 9's
  ``(I − J⁺J) z`` does.
* :class:`DexterousPosture` — eq. 9's null-space term with eq. 13's ``z_dex`` in the exact QP
  form of docs/DESIGN.md, math note 3 (weighted case): the level below the task minimises
  ``||q̇ − q̇₁* − λ_dex z||²`` while the task's rows keep their optimal values
  (``J q̇ = J q̇₁*``), whose minimiser is ``q̇₁* + λ_dex (I − J⁺J) z`` exactly. ``q̇₁*`` is
  :meth:`wbc.Stack.x_above`. (The plain form ``||q̇ − λ z||²`` would also pull ``q̇₁*``'s part
  outside the row space of ``J`` to zero, which a weighted ``J^#`` has.)
* :class:`ArmCompensation` — eq. 14's ``Δq̇_a = J_a^# J_b (q̇_b,ref − q̇_bf)`` as a QP: one
  least-squares level damped by μ (``J_a^# = J_aᵀ (J_a J_aᵀ + μ² I)⁻¹``), or undamped with the
  minimum-norm level below (``J_a⁺``, the pseudo-inverse for any rank).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

import wbc
from wbc.checks import (
    as_float_array,
    check_finite,
    check_robot,
    checked_integer,
    checked_name,
    checked_number,
)
from wbc.errors import InvalidValueError, ShapeError
from wbc.tasks.frame import velocity_block
from wbc.terms import Cost, Task

__all__ = ["ArmCompensation", "DexterousPosture", "share_task", "sharing_factor"]


def sharing_factor(error_norm, r_fm: float = 0.25, r_mm: float = 0.9):
    """Eq. 11: ψ = 1 if ``error_norm <= r_fm``, 0.5 if ``<= r_mm``, else 0 (CasADi); radii
    [m]."""
    if not isinstance(error_norm, (ca.SX, ca.DM)):
        error_norm = checked_number(error_norm, "error_norm [m] of sharing_factor")
    r_fm = checked_number(r_fm, "r_fm [m] of sharing_factor")
    r_mm = checked_number(r_mm, "r_mm [m] of sharing_factor")
    if not r_fm < r_mm:
        raise InvalidValueError(f"need 0 <= r_fm < r_mm, got r_fm = {r_fm}, r_mm = {r_mm}")
    return ca.if_else(error_norm <= r_fm, 1.0, ca.if_else(error_norm <= r_mm, 0.5, 0.0))


def share_task(stack, psi, n_base: int, priority: int = 0) -> ca.SX:
    """Set the stack's mobility to ``diag((1 − ψ) I_{n_base}, ψ I_rest)`` at ``priority`` only.

    Args:
        stack: the :class:`wbc.Stack` (its decision vector: base velocities first).
        psi: ψ as a CasADi expression (e.g. :func:`sharing_factor` of a pose task's
            ``position_error_norm``) or a parameter name (declared ``(1,)``).
        n_base: number of base velocity coordinates.
        priority: the task's level.

    Returns:
        The ψ expression (to report it, e.g. as a solution quantity).
    """
    n = stack.variables.n
    n_base = checked_integer(n_base, "n_base of share_task")
    priority = checked_integer(priority, "priority of share_task", low=None)
    if not n_base <= n:
        raise ShapeError(f"n_base must lie in [0, {n}], got {n_base}")
    if isinstance(psi, str):
        psi = stack.parameter(psi, 1)
    elif not isinstance(psi, (ca.SX, ca.DM)):
        psi = checked_number(psi, "psi of share_task", 0.0, high=1.0)
    psi = ca.SX(psi)
    if psi.shape != (1, 1):
        raise ShapeError(f"psi of share_task must be a scalar, got shape {psi.shape}")
    stack.set_mobility(ca.vertcat(ca.repmat(1 - psi, n_base, 1), ca.repmat(psi, n - n_base, 1)),
                       levels=[priority])
    return psi


class DexterousPosture(Task):
    """Eq. 9's null-space term with eq. 13's ``z = [0; −(q_a − q_dex)]``, exact QP form: add it
    one priority below the task (see the module docstring). ``q_a − q_dex`` is not wrapped: for
    joints whose limits span less than a turn (the LWR's ±170°, ±120°) with ``q_a`` and
    ``q_dex`` inside them, the plain difference is the only path the joint can take (the
    wrapped one would drive a joint through its limit, e.g. from −139° towards q_dex = 90°).

    Args:
        robot: the mobile manipulator (``nq``, ``nv``; the arm's coordinates are the last
            ``len(q_dex)`` of ``q`` and of the velocity).
        q_dex: dexterous arm configuration [rad] (Table II: ``(π/2, π/2, π/2, −π/2, 0, 0, 0)``).
        gain: ``λ_dex`` [1/s] (Table I: 3.5).
        name: task name.
    """

    def __init__(self, robot, q_dex, gain: float = 3.5, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"DexterousPosture {name!r}"
        nv = check_robot(robot, f"robot of {what}")[1]
        self.q_dex = as_float_array(q_dex, f"q_dex of {what}")
        if self.q_dex.ndim != 1 or not 0 < self.q_dex.size <= nv:
            raise ShapeError(f"q_dex of {what} must be a vector of 1 to nv = {nv} entries, "
                             f"got shape {self.q_dex.shape}")
        check_finite(self.q_dex, f"q_dex of {what}")
        self.gain = checked_number(gain, f"gain [1/s] of {what}")
        self.robot = robot
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        nv, na = int(self.robot.nv), self.q_dex.size
        qd = velocity_block(stack, self.block, nv, f"DexterousPosture {self.name!r}")
        q = stack.quantity("q", int(self.robot.nq))
        q_dex = stack.parameter(f"{self.name}.q_dex", na, self.q_dex)
        z = ca.vertcat(ca.SX.zeros(nv - na), -(q[-na:] - q_dex))
        above = stack.x_above()[stack.variables.slice(self.block)]
        return [Cost(qd, above + self.gain * z, 1.0, self.name)]


class ArmCompensation:
    """Eq. 14's correction ``Δq̇_a = J_a^# J_b (q̇_b,ref − q̇_bf)`` solved as a QP on ``backend``
    (``J_a^# = J_aᵀ (J_a J_aᵀ + μ² I)⁻¹``, the pseudo-inverse ``J_a⁺`` for μ = 0).

    Args:
        n_arm: arm joints (>= 1); rows: task rows (>= 1, 6 for a pose).
        backend: QP backend; profile: its tolerance profile; options: the backend's options.
        damping: μ (>= 0) [-]; 0: the least-squares level and a minimum-norm level below it.

    Call it with ``(J_arm, J_base, qd_base_ref, qd_base_feasible)`` (numpy) to get ``Δq̇_a``.
    """

    def __init__(self, n_arm: int, rows: int = 6, backend: str = "daqp",
                 profile: str = "default", damping: float = 0.0, **options) -> None:
        n_arm = checked_integer(n_arm, "n_arm of ArmCompensation", 1)
        rows = checked_integer(rows, "rows of ArmCompensation", 1)
        self.damping = checked_number(damping, "damping of ArmCompensation")
        # damped, the level is strictly convex: its minimiser is unique without a min-norm level
        stack = wbc.Stack(wbc.Variables(dqd_arm=n_arm), damping=self.damping,
                          min_norm=self.damping == 0.0)
        x = stack.variables.symbol
        J = stack.parameter("J_arm", (rows, n_arm), np.zeros((rows, n_arm)))
        missed = stack.parameter("missed", rows, np.zeros(rows))
        stack.add(Cost(J @ x, missed, 1.0, "compensation"))
        self.stack = stack
        self.workspace = stack.workspace(backend, profile, **options)
        self._J, self._missed = self.workspace.view("J_arm"), self.workspace.view("missed")
        self.last_solution = None

    def __call__(self, J_arm, J_base, qd_base_ref, qd_base_feasible) -> np.ndarray:
        self._J[...] = J_arm
        self._missed[:, 0] = np.asarray(J_base) @ (np.asarray(qd_base_ref)
                                                   - np.asarray(qd_base_feasible))
        self.last_solution = solution = self.workspace.solve()
        if not solution.ok:
            raise wbc.InfeasibleError(f"arm compensation: {solution.message}")
        return solution.x
