"""Sorour, Cherubini & Fraisse's whole-body controller (eqs. 8, 9, 11, 14) with the MPO700's
steering controller in the loop: :class:`SorourController`, and the paper's parameters
(Table I, :data:`PARAMETERS`).

Three variants of the redundancy resolution, ``step(q, v, ee=target)`` each:

* ``pinv`` — the whole-body damped pseudo-inverse of eq. 8 (one level, ``ρ``, no mobility);
* ``proposed`` — eq. 9: the ψ-shared task (per-tick mobility on the task's level) and the
  dexterous posture in the null space (exact weighted QP form, docs/DESIGN.md, math note 3);
* ``compensated`` — eq. 9 plus eq. 14: the arm makes up for the base velocity the steering
  controller (:class:`~wbc.papers.sorour.steering.SteerableController`) will not deliver,
  predicted by its own copy of that controller (the paper's "next sample" prediction).

The fast path (``fused="auto"``, the default on daqp with a C compiler). The eq. 8/9 stack is
:class:`wbc.Controller`'s fused tick (:mod:`wbc.fused`) on both paths; everything after it — the
base reference scaled into the twist limits, the steering controller's tick with its ICR QP
(:mod:`~wbc.papers.sorour.steering_code`), ψ and eq. 14 — is one more generated C function
(:func:`tail_function`) on the fast path. Eq. 14's QP (a least-squares level, then the
minimum-norm level) is ``Δq̇_a = J_a⁺ J_b (q̇_b,ref − q̇_bf)``; with ``J_a`` (6 × 7) of full row
rank that is ``J_aᵀ (J_a J_aᵀ)⁻¹ J_b (q̇_b,ref − q̇_bf)``, solved there by a Cholesky
factorisation.

Eq. 14 is damped (``compensation_damping`` μ, default Table I's ρ: the paper uses "the damped
pseudo-inverse of the analytic Jacobian for redundancy resolution in the sequel"): ``Δq̇_a =
J_aᵀ (J_a J_aᵀ + μ² I)⁻¹ J_b (q̇_b,ref − q̇_bf)``, the minimiser of ``||J_a x − r||² + μ²||x||²``.
Undamped (μ = 0), near a singular ``J_a`` it commanded the arm up to 270 rad/s in the study's
compensated run. The QP (daqp) is not that exact where ``M = J_a J_aᵀ + μ² I`` is ill
conditioned (measured on 1500 random configurations of the LWR, a third of them near its elbow
or wrist singularity, random base twists, μ = 1e-3: at most 8.0e-9 from the closed form where
``1 / (tr(M) tr(M⁻¹)) >= 1e-4``, 6.4e-8 between 1e-6 and 1e-4, 9.0e-7 between 1e-8 and 1e-6;
μ = 1e-4: 5.4e-5 between 1e-6 and 1e-4), so the generated form answers only when ``1 / (tr(M)
tr(M⁻¹)) >=`` :data:`COMPENSATION_CONDITION` (a lower bound of ``λ_min/λ_max``).

Joint limits (the paper's formulation has none; the LWR-IV has them, :mod:`wbc.robots.kuka_lwr4`):
the stack holds the arm's position limits (:class:`~wbc.tasks.ConfigurationLimit`, gain
:data:`LIMIT_GAIN`) and velocity limits as hard bounds on every level; the base's velocity stays
unbounded there (its reference is scaled into the base's twist limits after the stack, as
before). Eq. 14 adds its correction after the stack, so the compensated command is saturated
per joint into the same bounds (:func:`arm_rate_bounds`): what a velocity-commanded joint drive
does with a rate beyond its limit.

A tick the generated code does not answer (that, or a steering tick it leaves to the ordinary
path) runs the ordinary path's steps after the stack; ``fused=False`` runs them every tick
(numpy, pinocchio and the Python daqp backend).
"""

from __future__ import annotations

import math
import time

import casadi as ca
import numpy as np

import wbc
from wbc.cbuild import compiled_c
from wbc.checks import checked_number
from wbc.tasks import Bounds, ConfigurationLimit, RpyPoseTask
from wbc.tasks.rpy_pose import pose_error, rpy_jacobian

from .closed_form import task_sharing_factor
from .steering import MPO700_STEER_LIMITS, SteerableController, scale_into
from .steering_code import fast_path_allowed, steering_function
from .task_sharing import ArmCompensation, DexterousPosture, share_task, sharing_factor

__all__ = ["LIMIT_GAIN", "N_BASE", "PARAMETERS", "Q_DEX", "SorourController", "VARIANTS",
           "arm_rate_bounds", "steering_controller"]

#: Table I (``ts`` the control period [s]; lengths [m]; gains [1/s]).
PARAMETERS = {"lambda_p": 1.7, "lambda_dex": 3.5, "rho": 0.001, "ts": 0.025, "Kp": 2.0,
              "r_w": 0.09, "d": 0.045, "h_x": 0.24, "h_y": 0.19, "r_fm": 0.25, "r_mm": 0.9,
              "steer_rate_max": MPO700_STEER_LIMITS[0],
              "steer_acceleration_max": MPO700_STEER_LIMITS[1], "icr_gain": 10.0}
#: the dexterous arm configuration (Table II) [rad]
Q_DEX = np.array([math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0])
#: the three redundancy resolutions of :class:`SorourController`
VARIANTS = ("pinv", "proposed", "compensated")
#: the base's velocity coordinates ``(v_x, v_y, ω)``
N_BASE = 3
#: The generated eq. 14 answers when ``1 / (tr(M) tr(M⁻¹))``, ``M = J_a J_aᵀ + μ² I``, is at
#: least this (see the module docstring).
COMPENSATION_CONDITION = 1e-6
#: Gain of the arm's position limits at the velocity level (:class:`~wbc.tasks.ConfigurationLimit`:
#: a joint may close half its distance to a limit per tick; pink's default, not from the paper).
LIMIT_GAIN = 0.5


def arm_rate_bounds(robot) -> ca.Function:
    """``q -> (lower, upper)`` [rad/s]: the arm joints' rates allowed this tick, the LWR's
    velocity limits within :data:`LIMIT_GAIN` ``· (q_limit − q) / t_s`` (the bounds the stack
    holds; eq. 14's compensated command is saturated into them)."""
    limits, n_arm = robot.limits, int(robot.nv) - N_BASE
    q = ca.SX.sym("q", int(robot.nq))
    q_arm, dt = q[-n_arm:], PARAMETERS["ts"]
    lower = ca.fmax(ca.DM(limits.v_lower[N_BASE:]),
                    LIMIT_GAIN * (ca.DM(limits.q_lower[-n_arm:]) - q_arm) / dt)
    upper = ca.fmin(ca.DM(limits.v_upper[N_BASE:]),
                    LIMIT_GAIN * (ca.DM(limits.q_upper[-n_arm:]) - q_arm) / dt)
    return ca.Function("sorour_arm_rate_bounds", [q], [lower, upper], ["q"], ["lower", "upper"])


class SorourController:
    """One of the three variants (see the module docstring) as a ``step(q, v, ee=target)``.

    Args:
        robot: ``load("mpo700_lwr4")``.
        variant: one of :data:`VARIANTS`.
        backend: QP backend of the stack, the ICR QP and eq. 14.
        fused: the fast path of the steps after the stack (module docstring): ``"auto"``
            (default) where it applies (daqp, a C compiler), ``True`` required (else an
            error), ``False`` off — passed on to the steering controller. The stack is on
            :class:`wbc.Controller`'s default path either way (fused on daqp).
        compensation_damping: μ of eq. 14 (``>= 0``; default Table I's ρ, see the module
            docstring).
        qp_options: backend options of the stack's and eq. 14's QPs (e.g. daqp's
            ``{"primal_tol": 1e-6}``); none by default.

    Attributes:
        psi: ψ of the last tick (eq. 11; ``nan`` for ``pinv``, which shares nothing).
        steering: the steering controller predicting the base's next-sample twist (one may
            assign another; the fast path reads its state and constants).
        tick_parts: wall times [s] of the last tick: ``"stack"``; ``"icr_qp"`` the steering
            controller's tick (its ICR QP; on the fast path the one generated call after the
            stack: steering, ψ and eq. 14); ``"compensation"`` the rest (ψ, eq. 14; on the fast
            path the copies after that call).
        fused: whether the fast path is on; fallback_ticks: its ticks whose steps after the
            stack took the ordinary path.
    """

    def __init__(self, robot, variant: str, backend: str = "daqp",
                 fused: bool | str = "auto", compensation_damping: float = PARAMETERS["rho"],
                 qp_options: dict | None = None) -> None:
        if variant not in VARIANTS:
            raise wbc.UnknownNameError(f"unknown variant {variant!r}; variants are {VARIANTS}")
        if fused not in (True, False, "auto"):
            raise wbc.InvalidValueError(f"fused must be True, False or 'auto', got {fused!r}")
        p = PARAMETERS
        self.robot, self.variant = robot, variant
        self.compensation_damping = checked_number(compensation_damping,
                                                   "compensation_damping of SorourController")
        options = dict(qp_options or {})
        stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping={0: p["rho"]}, min_norm=False)
        pose = RpyPoseTask(robot, "ee", p["lambda_p"], name="ee")
        stack.add(pose, priority=0)
        if variant != "pinv":
            share_task(stack, sharing_factor(pose.position_error_norm, p["r_fm"], p["r_mm"]),
                       N_BASE, priority=0)
            stack.add(DexterousPosture(robot, Q_DEX, p["lambda_dex"], name="dex"), priority=1)
        # the LWR's limits, which the paper's eqs. 7-13 lack (module docstring); the base's
        # velocity is left to the twist-limit scaling after the stack, as the paper's is
        unbounded = np.full(N_BASE, np.inf)
        stack.constrain(ConfigurationLimit(robot, LIMIT_GAIN, name="arm_position_limit"))
        stack.constrain(Bounds(np.r_[-unbounded, robot.limits.v_lower[N_BASE:]],
                               np.r_[unbounded, robot.limits.v_upper[N_BASE:]],
                               name="arm_velocity_limit"))
        self.controller = wbc.Controller(robot, stack, backend=backend, dt=p["ts"],
                                         missing_limits="ignore", **options)
        self._tail = None  # the fast path's generated call, bound by _fast_path
        self.steering = steering_controller(robot, backend, fused)
        self.compensation = (ArmCompensation(robot.nv - N_BASE, backend=backend,
                                             damping=self.compensation_damping, **options)
                             if variant == "compensated" else None)
        self._arm_bounds = arm_rate_bounds(robot)
        self.psi = math.nan
        self.tick_parts: dict[str, float] = {}
        self.fallback_ticks = 0
        self.fused = self._fast_path(fused, backend)

    def _fast_path(self, fused, backend: str) -> bool:
        """Build and bind the generated call after the stack if ``fused`` allows it."""
        if not fast_path_allowed(fused, backend, "the controller"):
            return False
        robot = self.robot
        self._q, self._target = np.zeros(int(robot.nq)), np.zeros(6)
        self._command, self._out = np.zeros(int(robot.nv)), np.zeros(int(robot.nv))
        self._next = np.zeros(2 * robot.base.n_wheels + 6)
        self._info = np.zeros(3)
        function = compiled_c(tail_function(robot, self.variant == "compensated",
                                            self.compensation_damping))
        self._buffer, self._tail = function.buffer()
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        for i, array in enumerate((self._q, self._target, self._command)):
            self._buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        for i, array in enumerate((self._out, self._next, self._info)):
            self._buffer.set_res(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        self._bind(self._steering)
        return True

    @property
    def steering(self) -> SteerableController:
        """The steering controller predicting the base's next-sample twist (assignable)."""
        return self._steering

    @steering.setter
    def steering(self, steering: SteerableController) -> None:
        self._steering = steering
        if self._tail is not None:
            self._bind(steering)

    def _bind(self, steering: SteerableController) -> None:
        """The generated call reads ``steering``'s state and constants in place."""
        if steering.base.n_wheels != self.robot.base.n_wheels:
            raise wbc.ShapeError(f"the steering controller has {steering.base.n_wheels} "
                                 f"wheels, the robot {self.robot.base.n_wheels}")
        for i, array in ((3, steering.state), (4, steering.constants)):
            self._buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]

    @property
    def last_solution(self) -> wbc.Solution | None:
        """The eq. 8/9 stack's solution of the last tick (read when asked: a fused tick's is
        copied then)."""
        return self.controller.last_solution

    def step(self, q, v=None, ee=None) -> np.ndarray:
        clock = time.perf_counter
        t0 = clock()
        if self._tail is None:
            return self._after_stack(q, ee, self.controller.step(q, ee=ee).copy(), t0)
        command = self.controller.step(q, out=self._command, ee=ee)  # (q and ee checked)
        self._q[...] = q
        self._target[...] = ee
        t1 = clock()
        self._tail()
        t2 = clock()
        if self._info[0] != 1.0:
            self.fallback_ticks += 1
            return self._after_stack(q, ee, command.copy(), t0)
        steering = self._steering
        steering.state[...] = self._next
        steering.acceleration_relaxed += bool(self._info[1])
        if self.variant != "pinv":
            self.psi = float(self._info[2])
        out = self._out.copy()
        self.tick_parts = {"stack": t1 - t0, "icr_qp": t2 - t1, "compensation": clock() - t2}
        return out

    def _after_stack(self, q, ee, command: np.ndarray, t0: float) -> np.ndarray:
        """The ordinary path's steps after the stack, on its ``command`` (a copy)."""
        clock = time.perf_counter
        # the base's reference within its twist limits (direction kept), see the summary
        command[:N_BASE] = scale_into(command[:N_BASE], self.robot.base.v_max)
        t1 = clock()
        # the base's next-sample twist on the ordinary path, as every step here: a tick the fast
        # path hands back computes what fused=False computes (eq. 14 at an ill-conditioned J_a
        # would amplify the generated steering's rounding)
        predicted = self.steering.ordinary_step(command[:N_BASE])
        t2 = clock()
        pose = self.robot.frame_pose(q, "ee")
        if self.variant != "pinv":
            self.psi = task_sharing_factor(float(np.linalg.norm(pose_error(pose, ee)[:3])),
                                           PARAMETERS["r_fm"], PARAMETERS["r_mm"])
        if self.compensation is not None:
            J = rpy_jacobian(self.robot.frame_jacobian(q, "ee"), pose[:3, :3], q[2])
            command[N_BASE:] += self.compensation(J[:, N_BASE:], J[:, :N_BASE],
                                                  command[:N_BASE], predicted.twist)
            lower, upper = (np.asarray(b).reshape(-1) for b in self._arm_bounds(q))
            command[N_BASE:] = np.minimum(np.maximum(command[N_BASE:], lower), upper)
        self.tick_parts = {"stack": t1 - t0, "icr_qp": predicted.qp_s,
                           "compensation": clock() - t2}
        return command


def _minimum_norm(J: ca.SX, rhs: ca.SX, damping: float) -> tuple[ca.SX, ca.SX]:
    """``(Jᵀ M⁻¹ rhs, 1 / (tr(M) tr(M⁻¹)))`` with ``M = J Jᵀ + damping² I`` (``J`` of full row
    rank if undamped; Cholesky factor ``L``; ``tr(M⁻¹) = ||L⁻¹||_F²``)."""
    m = J.shape[0]
    M = J @ J.T + damping ** 2 * ca.SX.eye(m)
    L = [[ca.SX(0)] * m for _ in range(m)]
    for j in range(m):
        L[j][j] = ca.sqrt(M[j, j] - sum((L[j][k] ** 2 for k in range(j)), ca.SX(0)))
        for i in range(j + 1, m):
            L[i][j] = (M[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), ca.SX(0))) / L[j][j]
    y: list = []
    for i in range(m):  # L y = rhs
        y.append((rhs[i] - sum((L[i][k] * y[k] for k in range(i)), ca.SX(0))) / L[i][i])
    z: list = [None] * m
    for i in reversed(range(m)):  # Lᵀ z = y
        z[i] = (y[i] - sum((L[k][i] * z[k] for k in range(i + 1, m)), ca.SX(0))) / L[i][i]
    inverse_norm = ca.SX(0)  # ||L⁻¹||_F², column by column of L⁻¹
    for j in range(m):
        column: list = [ca.SX(0)] * m
        for i in range(j, m):
            column[i] = ((1.0 if i == j else 0.0)
                         - sum((L[i][k] * column[k] for k in range(j, i)), ca.SX(0))) / L[i][i]
            inverse_norm += column[i] ** 2
    return J.T @ ca.vertcat(*z), 1.0 / (ca.trace(M) * inverse_norm)


def _arm_function(robot, damping: float) -> ca.Function:
    """``(q, target, reference, feasible) -> (Δq̇_a, well_conditioned, ψ)``: eq. 14's
    correction damped by ``damping`` in closed form and whether
    :data:`COMPENSATION_CONDITION` holds, and eq. 11's ψ, at ``q`` (see the module docstring)."""
    nq = int(robot.nq)
    q, target = ca.SX.sym("q", nq), ca.SX.sym("target", 6)
    reference, feasible = ca.SX.sym("reference", N_BASE), ca.SX.sym("feasible", N_BASE)
    pose, J_world = robot.symbolic_frame("ee")(q)
    psi = sharing_factor(ca.norm_2(pose_error(pose, target)[:3]), PARAMETERS["r_fm"],
                         PARAMETERS["r_mm"])
    heading = q[2]
    J = rpy_jacobian(J_world, pose[:3, :3], heading)  # type: ignore[arg-type]  # (CasADi too)
    correction, condition = _minimum_norm(J[:, N_BASE:], J[:, :N_BASE] @ (reference - feasible),
                                          damping)
    return ca.Function("sorour_arm", [q, target, reference, feasible],
                       [correction, condition >= COMPENSATION_CONDITION, psi],
                       ["q", "target", "reference", "feasible"],
                       ["correction", "well_conditioned", "psi"])


def _base_reference_function(v_max) -> ca.Function:
    """:func:`~wbc.papers.sorour.steering.scale_into` of the base's reference into ``v_max``."""
    base = ca.SX.sym("base", N_BASE)
    ratio = ca.mmax(ca.fabs(base) / ca.DM(np.asarray(v_max, dtype=float)))
    return ca.Function("sorour_base_reference", [base],
                       [ca.if_else(ratio > 1.0, base / ratio, base)])


def tail_function(robot, compensate: bool, damping: float = PARAMETERS["rho"]) -> ca.Function:
    """What :class:`SorourController`'s fast path computes after the stack, as one CasADi
    function (see the module docstring).

    Inputs: ``q`` (nq,); ``target`` (6,) the end tip's target ``(x, y, z [m], roll, pitch,
    yaw [rad])``; ``command`` (nv,) the stack's solution; ``state`` and ``constants`` of the
    steering controller (:func:`~wbc.papers.sorour.steering_code.steering_function`).

    Outputs: ``command_out`` (nv,) the tick's command (the base's reference scaled into
    ``robot.base.v_max``, the arm's with eq. 14's correction damped by ``damping`` and saturated
    into :func:`arm_rate_bounds` if ``compensate``); ``next`` the
    steering controller's state after its tick; ``info`` ``[ok, relaxed, ψ]``. With ``ok = 0``
    the ordinary path answers (the outputs mean nothing).
    """
    n_wheels = int(robot.base.n_wheels)
    steering = steering_function(n_wheels)
    q, target, command = (ca.MX.sym(name, size) for name, size in
                          (("q", int(robot.nq)), ("target", 6), ("command", int(robot.nv))))
    state, constants = (ca.MX.sym(name, steering.sparsity_in(name)) for name in ("state",
                                                                                "constants"))
    reference = _base_reference_function(robot.base.v_max)(command[:N_BASE])
    state_next, _, _, info = steering(reference, state, constants)
    correction, well_conditioned, psi = _arm_function(robot, damping)(
        q, target, reference, state_next[2 * n_wheels:2 * n_wheels + 3])
    lower, upper = arm_rate_bounds(robot)(q)
    arm = (ca.fmin(ca.fmax(command[N_BASE:] + correction, lower), upper) if compensate
           else command[N_BASE:])
    ok = ca.logic_and(info[0], well_conditioned) if compensate else info[0]
    return ca.Function("sorour_tail", [q, target, command, state, constants],
                       [ca.vertcat(reference, arm), state_next, ca.vertcat(ok, info[2], psi)],
                       ["q", "target", "command", "state", "constants"],
                       ["command_out", "next", "info"])


def steering_controller(robot, backend: str, fused: bool | str = "auto") -> SteerableController:
    """The MPO700's steering controller with Table I's parameters (period, steer limits, ICR
    and drive gains)."""
    p = PARAMETERS
    return SteerableController(robot.base, dt=p["ts"], steer_rate=p["steer_rate_max"],
                               steer_acceleration=p["steer_acceleration_max"],
                               icr_gain=p["icr_gain"], drive_gain=p["Kp"], backend=backend,
                               fused=fused)
