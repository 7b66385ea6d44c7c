"""`KineticEnergyRegularizationTask`: penalise the kinetic energy of the command.

With ``M(q)`` the joint-space mass matrix over the velocity coordinates (model quantity
``"M"``, ``(nv, nv)``, symmetric positive definite) and ``T(v) = 1/2 vᵀ M v`` the kinetic
energy [J] of the command ``v``, the cost over ``v`` is::

    cost = (w / dt²) · T(v) = 1/2 (w / dt²) vᵀ M(q) v

an inertia-weighted :class:`~wbc.tasks.damping.DampingTask`: heavy coordinates (a mobile base,
the shoulder) move less than light ones (the wrist) for the same cost. Light coordinates are
then nearly free, so pair it with a small uniform damping, as mink advises.

Peer. Mink's ``KineticEnergyRegularizationTask(cost=λ)`` with ``set_dt(dt)`` adds the Hessian
``λ M / dt²`` over ``Δq = v · dt``, i.e. ``λ · T(v)`` to mink's objective. Every wbc task is
its peer's objective divided by ``dt²`` (a frame task's weight is mink's ``cost²``), so the
same minimiser needs ``(λ / dt²) · T(v)`` here: ``w`` **is** mink's ``λ``, not squared (mink's
Hessian is linear in it) [cost² / J], and the ``1/dt²`` comes from the stack's ``"dt"``.

Rows. A cost of the stack is a sum of squared affine rows, so the task writes
``vᵀ M v = ‖Rᵀ v‖²`` with ``M = R Rᵀ`` the Cholesky factorisation of ``M``, computed inside the
compiled level function from the ``"M"`` parameter (``n³/6`` operations and ``n`` square roots
per tick, ``n = nv``). A pivot that is not positive (a semidefinite ``M``, e.g. a joint that
carries no inertia) gives a zero column instead of a NaN: that coordinate is then not
regularised, as its kinetic energy is 0.
"""

from __future__ import annotations

import casadi as ca

from wbc.checks import check_robot, checked_name, checked_weights
from wbc.terms import Cost, Task

from .frame import velocity_block

#: a Cholesky pivot at or below this [√(kg·m²)] gives a zero column (see the module docstring)
PIVOT_TOL = 1e-12


def cholesky_factor(M: ca.SX) -> ca.SX:
    """``R`` (lower triangular, SX) with ``R Rᵀ = M`` for a symmetric positive definite ``M``
    (only its lower triangle is read); non-positive pivots give zero columns (see the module
    docstring)."""
    n = M.shape[0]
    R = ca.SX(n, n)
    for j in range(n):
        d = M[j, j] - sum((R[j, k] ** 2 for k in range(j)), ca.SX(0))
        pivot = ca.sqrt(ca.fmax(d, 0))
        R[j, j] = pivot
        usable = pivot > PIVOT_TOL
        safe = ca.if_else(usable, pivot, 1.0)
        for i in range(j + 1, n):
            s = M[i, j] - sum((R[i, k] * R[j, k] for k in range(j)), ca.SX(0))
            R[i, j] = ca.if_else(usable, s / safe, 0.0)
    return R


class KineticEnergyRegularizationTask(Task):
    """``(w / dt²) · 1/2 vᵀ M(q) v`` (see the module docstring).

    Args:
        robot: the robot (``nv``; it must offer the model quantity ``"M"``, as
            :class:`~wbc.robots.pinocchio_robot.PinocchioRobot` does); see
            :class:`wbc.Controller`.
        weight: ``w >= 0`` (a number, or a 1 × 1 CasADi SX expression of the stack's
            parameters) [cost² / J]; equals mink's ``cost`` ``λ`` (not squared).
        name: task name (default: the stack names it).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Parameters it declares: ``"M"`` (nv, nv) [kg, kg·m, kg·m²], ``"dt"`` (1,). Its residual is
    the kinetic energy ``T(v)`` [J].
    """

    def __init__(self, robot, weight=1.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"KineticEnergyRegularizationTask {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.weight = checked_weights(weight, 1, f"weight of {what}")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv,
                           f"KineticEnergyRegularizationTask {self.name!r}")
        M = stack.quantity("M", (self.nv, self.nv))
        dt = stack.quantity("dt", 1)
        energy = 0.5 * (v.T @ M @ v)  # reported residual [J]
        return [Cost(cholesky_factor(M).T @ v, 0.0, self.weight / dt ** 2, self.name,
                     energy)]

    def __repr__(self) -> str:
        return f"KineticEnergyRegularizationTask(weight={self.weight}, name={self.name!r})"
