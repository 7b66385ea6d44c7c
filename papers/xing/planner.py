"""Xing et al.'s planners in closed form, in closed loop: :class:`ClosedFormPlanner` (AMP, the
paper's algorithm, and §4.3's traditional pseudo-inverse planner)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.errors import InvalidValueError
from wbc.jit import compiled_c
from wbc.quantities import registry_of
from wbc.tasks.joint_acceleration import _CASADI, _bounds
from wbc.tasks.manipulability import arm_jacobian_derivatives, smallest_singular_value

from . import closed_form as ref
from .stacks import (
    POSITION,
    Setup,
    base_transition_expression,
    cartesian_command,
    symbolic_quantity,
)

__all__ = ["ClosedFormPlanner"]


def _manipulability_acceleration(J, dJ, dJ_dot, qd, gamma1, gamma2):
    """Eq. (13)'s ``q̈_sa`` (m,) as SX, with the appendix's closed forms of ``∇H`` and ``∇²H q̇_m``
    (:func:`~wbc.papers.xing.closed_form.manipulability_gradient`,
    :func:`~wbc.papers.xing.closed_form.manipulability_hessian_product`) written out per
    joint: ``J`` (r, m), ``dJ`` / ``dJ_dot`` (r·m, m) as :func:`arm_jacobian_derivatives`
    gives them, ``qd`` the arm's ``q̇_m`` (m,) [rad/s], ``gamma1``, ``gamma2`` [1/s]."""
    r, m = J.shape
    d = [ca.reshape(dJ[:, k], r, m) for k in range(m)]  # ∂_k J
    d_dot = [ca.reshape(dJ_dot[:, k], r, m) for k in range(m)]  # ∂_k J̇
    psi = J @ J.T
    psi_inv, det = ca.inv(psi), ca.det(psi)
    M = [psi_inv @ (dk @ J.T + J @ dk.T) for dk in d]  # Ψ⁻¹ ∂_k Ψ
    traces = ca.vertcat(*[ca.trace(Mk) for Mk in M])
    J_dot = sum(d[k] * qd[k] for k in range(m))
    second = ca.vertcat(*[ca.trace(psi_inv @ (d_dot[p] @ J.T + J_dot @ d[p].T + d[p] @ J_dot.T
                                               + J @ d_dot[p].T)) for p in range(m)])
    cross = ca.vertcat(*[sum(ca.trace(M[k] @ M[p]) * qd[k] for k in range(m))
                         for p in range(m)])  # Σ_q tr(Ψ⁻¹∂_qΨ Ψ⁻¹∂_pΨ) q̇_q
    gradient = det * traces
    hessian_qd = det * (traces * ca.dot(traces, qd) - cross + second)
    return gamma1 * hessian_qd + gamma2 * (gamma1 * gradient - qd)


class ClosedFormPlanner:
    """The paper's planners in closed form, in closed loop (``step(q, v, **references)``).

    ``method="amp"``: :func:`wbc.solvers.reference.amp` with the appendix's manipulability
    derivatives; ``method="traditional"``: :func:`wbc.solvers.reference.traditional`.
    Everything these closed forms take as input is one CasADi function of ``(q, v,
    references)``, compiled to C once (:func:`wbc.jit.compiled_c`) when ``jit``: the task
    rows, drift and command, eq. (13)'s ``q̈_sa`` (the appendix's ``∇H`` and ``∇²H q̇_m``),
    ``σ_min(J_m)`` (:func:`~wbc.tasks.manipulability.smallest_singular_value`), the joint
    acceleration bounds (eqs. 6–8 or the viable ones) and the base transition (eq. 15). A
    tick is that one call and the closed form.

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
        gamma1, gamma2 = ca.SX.sym("gamma1"), ca.SX.sym("gamma2")
        pose = symbolic_quantity(registry, "pose[ee]")(q)
        J = symbolic_quantity(registry, "J[ee]")(q)
        drift = symbolic_quantity(registry, "Jdot_v[ee]")(q, v)
        J_r, drift_r, xdd = cartesian_command(pose, J, drift, v, target, target_velocity,
                                              target_acceleration, kd, kp, setup.rows)
        v_arm = v[self.n_base:]
        J_m, dJ, dJ_dot = arm_jacobian_derivatives(robot)(q, v_arm)
        qdd_sa = ca.vertcat(ca.SX.zeros(self.n_base), _manipulability_acceleration(
            J_m, dJ, dJ_dot, v_arm, gamma1, gamma2))
        lim = robot.limits
        self.q_min = np.concatenate([np.full(self.n_base, -np.inf), lim.q_lower[-self.n_arm:]])
        self.q_max = np.concatenate([np.full(self.n_base, np.inf), lim.q_upper[-self.n_arm:]])
        # the arm's positions in the velocity layout; the base entries meet infinite limits
        positions = ca.vertcat(ca.SX.zeros(self.n_base), q[self.nq - self.n_arm:])
        lower, upper = _bounds(_CASADI, positions, v, ca.DM(self.q_min), ca.DM(self.q_max),
                               ca.DM(lim.v_lower), ca.DM(lim.v_upper), ca.DM(lim.a_lower),
                               ca.DM(lim.a_upper), setup.dt, setup.bounds)
        outputs = [ca.densify(o) for o in (
            J_r, drift_r, xdd, qdd_sa, smallest_singular_value(J_m), lower, upper,
            base_transition_expression(robot, v, setup.dt))]
        # the gains are inputs, so that every setup of one task size shares one C library
        function = ca.Function("xing_planner", [q, v, target, target_velocity,
                                                target_acceleration, kd, kp, gamma1, gamma2],
                               outputs)
        if jit:
            try:
                function = compiled_c(function)
            except RuntimeError:  # no C compiler: CasADi's virtual machine, same values
                pass
        # evaluated through a buffer into preallocated arrays (no DM conversions per tick)
        self._inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        kd_in, kp_in, gamma1_in, gamma2_in = self._inputs[5:]  # the setup's: written once
        kd_in[:], kp_in[:] = setup.kd, setup.kp
        gamma1_in[:], gamma2_in[:] = setup.gamma1, setup.gamma2
        self._outputs = [np.zeros(function.size_out(i), order="F")
                         for i in range(function.n_out())]
        self._buffer, self._evaluate = function.buffer()
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        for i, array in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        for i, out in enumerate(self._outputs):
            self._buffer.set_res(i, memoryview(out.reshape(-1, order="F")))  # type: ignore[call-arg, arg-type]
        self.last_info: ref.AMPInfo | None = None

    def _evaluate_at(self, q, v, target, target_velocity, target_acceleration) -> None:
        """Evaluate the compiled function at a state into ``self._outputs``."""
        q_in, v_in, target_in, tv_in, ta_in = self._inputs[:5]
        q_in[:] = q
        v_in[:] = v
        target_in[:] = np.ravel(np.asarray(target).T)  # column-major: the transpose's rows
        tv_in[:] = target_velocity
        ta_in[:] = target_acceleration
        self._evaluate()

    def terms(self, q, v, target, target_velocity, target_acceleration):
        """``(J_r, drift_r, ẍ_cmd, q̈_sa, σ_min)`` at a state, numerically."""
        self._evaluate_at(q, v, target, target_velocity, target_acceleration)
        J, drift, xdd, qdd_sa, sigma = self._outputs[:5]
        return J.copy(), drift[:, 0].copy(), xdd[:, 0].copy(), qdd_sa[:, 0].copy(), \
            float(sigma[0, 0])

    def bounds(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """The joint acceleration bounds (eqs. 6–8, or the viable ones) at a state."""
        q_in, v_in = self._inputs[:2]
        q_in[:] = q
        v_in[:] = v
        self._evaluate()
        lower, upper = self._outputs[5:7]
        return lower[:, 0].copy(), upper[:, 0].copy()

    def step(self, q, v, target, target_velocity, target_acceleration) -> np.ndarray:
        self._evaluate_at(q, v, target, target_velocity, target_acceleration)
        J, drift, xdd, qdd_sa, sigma, lower, upper, transition = self._outputs
        if self.method == "traditional":
            return ref.traditional(J, xdd[:, 0], drift[:, 0], qdd_sa[:, 0])
        # bounds of eqs. 7-8 can cross (see wbc.tasks.joint_acceleration): the joint then
        # gets its lower bound, as SNS saturating it there would
        qdd, self.last_info = ref.amp(J, xdd[:, 0], drift[:, 0], lower[:, 0],
                                      np.maximum(lower[:, 0], upper[:, 0]), self.n_base,
                                      qdd_sa=qdd_sa[:, 0], transition=transition[:, 0],
                                      sigma_min=float(sigma[0, 0]),
                                      sigma_thr=self.setup.sigma_thr)
        return qdd
