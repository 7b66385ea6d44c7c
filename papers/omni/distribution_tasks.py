"""Wheel-torque distribution of an omni platform (torque-redundancy paper, eqs. 5–13) as stacks.

The decision vector is the wheel torques ``tau`` [N m] (N entries), plus a scalar ``t`` for
``"minmax"``. Every method holds the platform wrench hard — :class:`WheelWrench`,
``Jᵀ τ = f_d`` (eq. 5) — and picks one member of the remaining (N − 3)-dimensional set:

* ``"min_norm"`` — one level ``min ||τ||²``: ``τ = (Jᵀ)⁺ f_d`` (eq. 7 with a = 0).
* ``"proportional"`` — one level :class:`FrictionUtilisation`, ``min Σ (c̄ τ_i / (μ_i f_i))²``:
  the maximiser of the reconstructed ``H(α) = −Σ (τ_i / (μ_i f_i))²`` of eq. 12 (see
  :mod:`wbc.papers.omni.closed_form`). The weights are normalised by the mean capacity
  ``c̄ = mean(μ_i f_i)`` (the minimiser does not change) so that the QP's Hessian is of order 1
  whatever the robot's weight.
* ``"minmax"`` — hard :class:`UtilisationBound` rows ``|τ_i| c̄ / (μ_i f_i) <= t`` and one
  level ``min t²`` (``t >= 0`` on the feasible set, so this minimises the largest friction
  utilisation, the LP of the issue, as a QP). The level is damped (``ρ = 1e-3``, i.e.
  ``+ ρ²/2 (||τ||² + t²)``): at the generic optimum — a kink of ``max_i |τ_i| w_i`` along the
  null space — a damping whose pull ``ρ² |α|`` is smaller than the jump of the slopes there
  does not move the minimiser at all (measured: 300 random instances per backend agree with the
  closed form to 3e-9), and where the minimisers form a segment it picks the least-norm one, as
  the closed form does. ``ρ = 1e-4`` was too weak a tie-break for casadi:osqp's ADMM. (A second,
  undamped level minimising another criterion with ``t`` frozen was tried first: its feasible
  set is then a single point or a thin segment, which daqp, osqp and casadi:osqp reported
  infeasible or ran out of iterations on in about 1 % of random instances.)

The normal forces ``f_i`` [N], the friction coefficients ``μ_i`` and ``f_d`` are per-tick
parameters (``"<name>.normal_forces"``, ``"<name>.mu"``, ``"<name>.f_d"``); ``J`` is one too
(``"<name>.J"``). :func:`distribution_stack` builds the stack of a method, compiled once;
:class:`TorqueDistribution` wraps its workspace with checked per-tick input.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import casadi as ca
import numpy as np

import wbc
from wbc.cbuild import compiler_available
from wbc.checks import checked_array, checked_integer, checked_name, checked_vector
from wbc.errors import InvalidValueError, ShapeError, WbcError
from wbc.fused import FusedWorkspace, build_fused, why_not_fused
from wbc.tasks.linear import LinearTask
from wbc.terms import Cost, Equality, Inequality, Task

from .closed_form import checked_wheel_jacobian

__all__ = ["DISTRIBUTIONS", "FUSED_METHODS", "FrictionUtilisation", "TorqueDistribution",
           "UtilisationBound", "WheelWrench", "distribution_stack"]

#: the methods of :func:`distribution_stack` (as in ``wbc.solvers.reference``).
DISTRIBUTIONS = ("min_norm", "proportional", "minmax")
#: damping ``ρ`` of the minmax level (tie-break only; see the module docstring).
MINMAX_DAMPING = 1e-3
#: the methods :class:`TorqueDistribution` fuses. Not ``"minmax"``: its optimum is a vertex
#: where several utilisation rows meet under a Hessian of ``ρ²`` = 1e-6 along ``τ``, and the
#: daqp bundled with casadi answers some of them off (measured on 3000 random wrenches of
#: 1–3000 N and loads of 5–400 N: 5 answers more than 1e-6 from the closed form, up to 8e-4;
#: the ``"tight"`` profile 3, up to 6e-6), where the Python backend agrees to 5e-13.
FUSED_METHODS = ("min_norm", "proportional")


def _torques(stack, block: str, what: str) -> ca.SX:
    if block not in stack.variables.names:
        raise WbcError(f"{what}: the stack has no variable block {block!r} (wheel torques)")
    return stack.variables.symbol[stack.variables.slice(block)]


class WheelWrench(Task):
    """``Jᵀ τ = f_d``: the wheel torques produce the platform wrench ``f_d`` (eq. 5). Hard:
    add it with ``stack.constrain``.

    Args:
        J: wheel Jacobian (N, 3) (eq. 1), the default of parameter ``"<name>.J"``.
        name: task name; ``f_d`` [N, N, N m] (platform frame) is parameter ``"<name>.f_d"``
            (default zero).
        block: the wheel-torque block.
    """

    def __init__(self, J, name: str = "wrench", block: str = "tau") -> None:
        self.J = checked_wheel_jacobian(J)
        self.name = checked_name(name, "name of WheelWrench")
        self.block = checked_name(block, f"block of WheelWrench {name!r}", optional=False)

    def terms(self, stack):
        tau = _torques(stack, self.block, f"WheelWrench {self.name!r}")
        if tau.shape[0] != self.J.shape[0]:
            raise ShapeError(f"WheelWrench {self.name!r}: J has {self.J.shape[0]} wheels but "
                             f"block {self.block!r} has {tau.shape[0]} entries")
        J = stack.parameter(f"{self.name}.J", self.J.shape, self.J)
        f_d = stack.parameter(f"{self.name}.f_d", 3, np.zeros(3))
        return [Equality(J.T @ tau, f_d, self.name)]


def _friction_coefficients(mu, n: int) -> np.ndarray:
    """``μ`` as (N,) finite positive coefficients (a scalar is broadcast)."""
    mu = checked_vector(mu, n, "mu")
    if np.any(mu <= 0):
        raise InvalidValueError(f"mu must be > 0, got {mu}")
    return mu


def _normalised_weights(stack, name: str, n: int, mu: np.ndarray) -> ca.SX:
    """``c̄ / (μ_i f_i)`` from the parameters ``"<name>.normal_forces"`` and ``"<name>.mu"``
    (shared by the tasks of one distribution when they have the same ``name``)."""
    forces = stack.parameter(f"{name}.normal_forces", n, np.ones(n))
    mu = stack.parameter(f"{name}.mu", n, mu)
    capacity = mu * forces
    return (ca.sum1(capacity) / n) / capacity


class FrictionUtilisation(Task):
    """Cost ``Σ (c̄ τ_i / (μ_i f_i))²``: maximises the reconstructed ``H(α)`` of eq. 12.

    Args:
        n_wheels: N.
        mu: default friction coefficients (scalar or (N,), > 0).
        name: task name.
        parameters: prefix of the per-tick parameters ``"<parameters>.normal_forces"`` [N]
            (> 0; default 1) and ``"<parameters>.mu"`` (tasks with the same prefix share them).
        block: the wheel-torque block.
    """

    def __init__(self, n_wheels: int, mu=1.0, name: str = "friction",
                 parameters: str = "friction", block: str = "tau") -> None:
        what = f"FrictionUtilisation {name!r}"
        self.n = checked_integer(n_wheels, f"n_wheels of {what}", 1)
        self.name = checked_name(name, f"name of {what}")
        self.parameters = checked_name(parameters, f"parameters of {what}", optional=False)
        self.block = checked_name(block, f"block of {what}", optional=False)
        self.mu = _friction_coefficients(mu, self.n)

    def terms(self, stack):
        tau = _torques(stack, self.block, f"FrictionUtilisation {self.name!r}")
        w = _normalised_weights(stack, self.parameters, self.n, self.mu)
        return [Cost(w * tau, 0.0, 1.0, self.name)]


class UtilisationBound(Task):
    """``−t <= c̄ τ_i / (μ_i f_i) <= t`` for every wheel: ``t`` bounds the (normalised) friction
    utilisations. Hard: add it with ``stack.constrain``.

    Args:
        n_wheels, mu, parameters: as :class:`FrictionUtilisation`.
        name: task name.
        block: the wheel-torque block; ``bound``: the block of ``t`` (one entry).
    """

    def __init__(self, n_wheels: int, mu=1.0, name: str = "utilisation_bound",
                 parameters: str = "friction", block: str = "tau", bound: str = "t") -> None:
        what = f"UtilisationBound {name!r}"
        self.n = checked_integer(n_wheels, f"n_wheels of {what}", 1)
        self.name = checked_name(name, f"name of {what}")
        self.parameters = checked_name(parameters, f"parameters of {what}", optional=False)
        self.block = checked_name(block, f"block of {what}", optional=False)
        self.bound = checked_name(bound, f"bound of {what}", optional=False)
        self.mu = _friction_coefficients(mu, self.n)

    def terms(self, stack):
        tau = _torques(stack, self.block, f"UtilisationBound {self.name!r}")
        t = _torques(stack, self.bound, f"UtilisationBound {self.name!r}")
        scaled = _normalised_weights(stack, self.parameters, self.n, self.mu) * tau
        return [Inequality(scaled - t, -np.inf, 0.0, f"{self.name}.upper"),
                Inequality(scaled + t, 0.0, np.inf, f"{self.name}.lower")]


def distribution_stack(J, method: str = "proportional", mu=1.0) -> wbc.Stack:
    """The stack of one distribution method over ``Variables(tau=N)`` (``+ t`` for minmax).

    Parameters to set per tick: ``"wrench.f_d"`` (3,), ``"friction.normal_forces"`` (N,) and
    ``"friction.mu"`` (N,) (not used by ``"min_norm"``); ``"wrench.J"`` defaults to ``J``.
    """
    if not isinstance(method, str) or method not in DISTRIBUTIONS:
        raise InvalidValueError(f"method must be one of {DISTRIBUTIONS}, got {method!r}")
    J = checked_wheel_jacobian(J)
    n = J.shape[0]
    mu = _friction_coefficients(mu, n)
    blocks = {"tau": n, "t": 1} if method == "minmax" else {"tau": n}
    damping = MINMAX_DAMPING if method == "minmax" else 0.0
    stack = wbc.Stack(wbc.Variables(**blocks), damping=damping, min_norm=False)
    stack.constrain(WheelWrench(J))
    if method == "min_norm":
        stack.add(LinearTask(np.eye(n), np.zeros(n), name="torque_norm", block="tau"))
    elif method == "proportional":
        stack.add(FrictionUtilisation(n, mu))
    else:
        stack.constrain(UtilisationBound(n, mu))
        stack.add(LinearTask(np.eye(1), np.zeros(1), name="max_utilisation", block="t"))
    return stack


class TorqueDistribution:
    """A compiled distribution on one backend: ``tau = dist(f_d, normal_forces)``.

    Args:
        J: wheel Jacobian (N, 3).
        method: ``"min_norm"``, ``"proportional"`` or ``"minmax"``.
        mu: friction coefficients (scalar or (N,), > 0).
        backend, profile: QP backend and its profile.
        fused: the QP as one generated C call (:class:`wbc.fused.FusedWorkspace`, as
            ``wbc.Controller``'s ``fused=``). ``"auto"`` (default): on ``"daqp"`` for the
            methods of :data:`FUSED_METHODS` when a C compiler is present; ``True``: the same,
            but a distribution that cannot be fused is a :class:`~wbc.WbcError`; ``False``:
            the Python daqp backend. A tick the generated daqp does not solve takes the
            ordinary path (same status and answer). Measured (3000 random wrenches of
            1–3000 N, loads of 5–400 N): the QP call ≈ 1.3 µs against ≈ 12 µs, torques within
            4e-11 of the ordinary path's.

    Attributes:
        stack, workspace: the stack and its workspace; ``last_solution``: the last
        :class:`wbc.Solution` (its status says whether the QP was solved; on the fused path
        the workspace's reused solution, copied when first read, so that what a caller holds is
        never rewritten by a later solve — as :attr:`wbc.Controller.last_solution`);
        ``fused``: whether the QP is fused, ``fused_reason``: why not (``None`` when it is).
    """

    def __init__(self, J, method: str = "proportional", mu=1.0, backend: str = "daqp",
                 profile: str = "default", fused: bool | str = "auto") -> None:
        if fused not in (True, False, "auto"):
            raise WbcError(f"fused must be True, False or 'auto', got {fused!r}")
        self.stack = distribution_stack(J, method, mu)
        self.n = self.stack.variables.size("tau")
        fused_workspace = self._fused_workspace(fused, method, backend, profile)
        self.fused = fused_workspace is not None
        self.workspace: wbc.Workspace = (self.stack.workspace(backend, profile)
                                         if fused_workspace is None else fused_workspace)
        #: one solve on the parameters in the workspace, bound once: the fused workspace's
        #: closure (:meth:`wbc.fused.FusedWorkspace.solver`) or :meth:`wbc.Workspace.solve`
        self.solve: Callable[[], wbc.Solution] = (
            self.workspace.solve if fused_workspace is None
            else partial(fused_workspace.solver(), None))
        self._f_d = self.workspace.view("wrench.f_d")
        self._forces = None if method == "min_norm" else self.workspace.view(
            "friction.normal_forces")
        self._tau = self.stack.variables.slice("tau")
        self._live = None if fused_workspace is None else fused_workspace.fused_solution
        self._last_solution: wbc.Solution | None = None

    @property
    def last_solution(self) -> wbc.Solution | None:
        """The last solve's :class:`wbc.Solution` (class docstring)."""
        solution = self._last_solution
        if solution is not None and solution is self._live:
            # the fused workspace's buffers, rewritten by every answered tick: copied once
            solution = self._last_solution = solution.snapshot()
        return solution

    @last_solution.setter
    def last_solution(self, solution: wbc.Solution | None) -> None:
        self._last_solution = solution

    def _fused_workspace(self, fused, method: str, backend: str,
                         profile: str) -> FusedWorkspace | None:
        """A :class:`~wbc.fused.FusedWorkspace` when ``fused`` allows it (class docstring),
        else ``None`` with ``self.fused_reason`` saying why."""
        def why_not() -> str | None:
            if method not in FUSED_METHODS:
                return f"method {method!r} is not fused (see FUSED_METHODS)"
            if backend != "daqp":
                return f"the backend is {backend!r}; the fused QP solves with daqp"
            if not compiler_available():
                return "no C compiler found ($CC, default cc)"
            return why_not_fused(self.stack.compile(), {})

        workspace, self.fused_reason = build_fused(
            fused, why_not, lambda: FusedWorkspace(self.stack.compile(), profile),
            "the distribution cannot be fused")
        return workspace

    def __call__(self, f_d, normal_forces) -> np.ndarray:
        """Wheel torques [N m] for the platform wrench ``f_d`` (3,) and the wheels' normal
        forces [N] (N,), > 0 (ignored by ``"min_norm"`` but checked)."""
        f_d = self.workspace.checked_value("wrench.f_d", f_d, "f_d")
        forces = checked_array(normal_forces, (self.n, 1), "normal_forces")
        if np.any(forces <= 0):
            raise InvalidValueError(f"normal_forces must be > 0 [N] (a wheel without load "
                                    f"transmits no traction), got {forces.ravel()}")
        self._f_d[...] = f_d
        if self._forces is not None:
            self._forces[...] = forces
        self.last_solution = self.solve()
        return self.last_solution.x[self._tau].copy()
