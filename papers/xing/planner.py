"""Xing et al.'s planners in closed form, in closed loop: :class:`ClosedFormPlanner` (AMP, the
paper's algorithm, and §4.3's traditional pseudo-inverse planner)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.errors import InvalidValueError
from wbc.jit import compiled_c
from wbc.quantities import registry_of
from wbc.tasks import joint_acceleration_bounds
from wbc.tasks.manipulability import arm_jacobian_derivatives

from . import closed_form as ref
from .stacks import POSITION, Setup, cartesian_command, symbolic_quantity

__all__ = ["ClosedFormPlanner"]


class ClosedFormPlanner:
    """The paper's planners in closed form, in closed loop (``step(q, v, **references)``).

    ``method="amp"``: :func:`wbc.solvers.reference.amp` with the appendix's manipulability
    derivatives; ``method="traditional"``: :func:`wbc.solvers.reference.traditional`. The
    model (task rows, drift, command, ``J_m`` and its derivatives) is one CasADi function of
    ``(q, v, references)``, compiled to C once (:func:`wbc.jit.compiled_c`) when ``jit``.

    Attributes:
        last_solution: always ``None`` (no QP); ``last_info``: the last :class:`AMPInfo`.
    """

    last_solution = None

    def __init__(self, robot, setup: Setup = POSITION, method: str = "amp",
                 jit: bool = True) -> None:
        if method not in ("amp", "traditional"):
            raise InvalidValueError(f"method must be 'amp' or 'traditional', got {method!r}")
        self.robot, self.setup, self.method = robot, setup, method
        self.nq, self.nv, self.n_arm = int(robot.nq), int(robot.nv), int(robot.n_arm)
        self.n_base = self.nv - self.n_arm
        registry = registry_of(robot)
        q, v = ca.SX.sym("q", self.nq), ca.SX.sym("v", self.nv)
        target = ca.SX.sym("target", 4, 4)
        target_velocity, target_acceleration = ca.SX.sym("tv", 6), ca.SX.sym("ta", 6)
        kd, kp = ca.SX.sym("kd", setup.rows), ca.SX.sym("kp", setup.rows)
        pose = symbolic_quantity(registry, "pose[ee]")(q)
        J = symbolic_quantity(registry, "J[ee]")(q)
        drift = symbolic_quantity(registry, "Jdot_v[ee]")(q, v)
        J_r, drift_r, xdd = cartesian_command(pose, J, drift, v, target, target_velocity,
                                              target_acceleration, kd, kp, setup.rows)
        outputs = [ca.densify(o) for o in (J_r, drift_r, xdd, *arm_jacobian_derivatives(robot)(
            q, v[self.n_base:]))]
        # the gains are inputs, so that every setup of one task size shares one C library
        function = ca.Function("xing_model", [q, v, target, target_velocity,
                                              target_acceleration, kd, kp], outputs)
        if jit:
            try:
                function = compiled_c(function)
            except RuntimeError:  # no C compiler: CasADi's virtual machine, same values
                pass
        # evaluated through a buffer into preallocated arrays (no DM conversions per tick)
        self._inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        self._outputs = [np.zeros(function.size_out(i), order="F")
                         for i in range(function.n_out())]
        self._buffer, self._evaluate = function.buffer()
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        for i, out in enumerate(self._outputs):
            self._buffer.set_res(i, memoryview(out.reshape(-1, order="F")))  # type: ignore[call-arg, arg-type]
        lim = robot.limits
        self.q_min = np.concatenate([np.full(self.n_base, -np.inf), lim.q_lower[-self.n_arm:]])
        self.q_max = np.concatenate([np.full(self.n_base, np.inf), lim.q_upper[-self.n_arm:]])
        self.last_info: ref.AMPInfo | None = None

    def terms(self, q, v, target, target_velocity, target_acceleration):
        """``(J_r, drift_r, ẍ_cmd, q̈_sa, σ_min)`` at a state, numerically."""
        m = self.n_arm
        for array, value in zip(self._inputs, (q, v, np.asarray(target).T, target_velocity,
                                               target_acceleration, self.setup.kd,
                                               self.setup.kp), strict=True):
            array[:] = np.ravel(value)  # column-major: the transpose's rows
        self._evaluate()
        J, drift, xdd, J_m, dJ, dJ_dot = self._outputs
        dJ = dJ.reshape(m, 3, m).transpose(2, 1, 0)  # rows i + 3j -> [k, i, j]
        dJ_dot = dJ_dot.reshape(m, 3, m).transpose(2, 1, 0)
        v_arm = v[self.n_base:]
        qdd_sa = np.zeros(self.nv)
        qdd_sa[self.n_base:] = ref.manipulability_acceleration(
            ref.manipulability_gradient(J_m, dJ),
            ref.manipulability_hessian_product(J_m, dJ, dJ_dot, v_arm), v_arm,
            self.setup.gamma1, self.setup.gamma2)
        sigma = float(np.linalg.svd(J_m, compute_uv=False)[-1])
        return J.copy(), drift[:, 0].copy(), xdd[:, 0].copy(), qdd_sa, sigma

    def bounds(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """The joint acceleration bounds (eqs. 6–8, or the viable ones) at a state."""
        positions = np.concatenate([np.zeros(self.n_base), q[-self.n_arm:]])
        lim = self.robot.limits
        return joint_acceleration_bounds(positions, v, self.q_min, self.q_max, lim.v_lower,
                                         lim.v_upper, lim.a_lower, lim.a_upper, self.setup.dt,
                                         self.setup.bounds)

    def step(self, q, v, target, target_velocity, target_acceleration) -> np.ndarray:
        q, v = np.asarray(q, float), np.asarray(v, float)
        J, drift, xdd, qdd_sa, sigma = self.terms(q, v, target, target_velocity,
                                                  target_acceleration)
        if self.method == "traditional":
            return ref.traditional(J, xdd, drift, qdd_sa)
        lower, upper = self.bounds(q, v)
        lim = self.robot.limits
        base = slice(0, self.n_base)
        transition = ref.base_transition(v[base], lim.a_lower[base], lim.a_upper[base],
                                         self.setup.dt)
        # bounds of eqs. 7-8 can cross (see wbc.tasks.joint_acceleration): the joint then
        # gets its lower bound, as SNS saturating it there would
        qdd, self.last_info = ref.amp(J, xdd, drift, lower, np.maximum(lower, upper),
                                      self.n_base, qdd_sa=qdd_sa, transition=transition,
                                      sigma_min=sigma, sigma_thr=self.setup.sigma_thr)
        return qdd
