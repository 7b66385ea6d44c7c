"""Xing et al.'s adaptive motion planning (AMP) as a QP cascade: :func:`amp_stack`,
:func:`add_amp_levels`, :func:`amp_controller`, and the planner's parameters (:class:`Setup`).

The QP (:func:`amp_stack`), over ``q̈`` (nv):

* hard: :class:`~wbc.tasks.JointAccelerationLimit` (eqs. 6–8);
* level 0, task scaling: ``J q̈ + J̇q̇ = s·(ẍ_d + K_d ė + K_p e)`` — the LP maximises ``s``;
* level 1: ``q̈_base = q̈_trans`` (eq. 15 sampled,
  :func:`~wbc.papers.xing.closed_form.base_transition`), weight ``1 − base_free`` where
  ``base_free = [σ_min(J_m) < σ_thr]`` is computed in the compiled function
  (:func:`wbc.tasks.manipulability.smallest_singular_value`);
* level 2: :class:`~wbc.tasks.manipulability.ManipulabilityAccelerationTask` (eq. 13) over
  all joints.

How it differs from the paper's greedy loop, and where the two agree: the study's docstring
(:mod:`wbc.experiments.studies.xing`) and tests/test_xing_equivalence.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

import wbc
from wbc.errors import WbcError
from wbc.quantities import QuantityRegistry
from wbc.tasks import JointAccelerationLimit
from wbc.tasks.frame import so3_log
from wbc.tasks.manipulability import (
    ManipulabilityAccelerationTask,
    arm_jacobian,
    smallest_singular_value,
)
from wbc.terms import Cost

from .fast import AMPController

__all__ = ["DT", "POSE", "POSITION", "Setup", "add_amp_levels", "amp_controller", "amp_stack",
           "base_slice", "base_transition_expression", "cartesian_command", "symbolic_quantity"]

DT = 0.02
"""Control period [s] (the paper does not give it; its loop took 14.8 ms, so 50 Hz)."""


@dataclass(frozen=True)
class Setup:
    """The planner's parameters (the paper's, §4.2–4.4).

    Attributes:
        rows: task dimension ``r``: 3 (position) or 6 (position and orientation).
        kd, kp: the gains ``K_d``, ``K_p`` (r,) [1/s, 1/s²].
        sigma_thr: ``σ_min`` threshold of the base switch (0: never).
        gamma1, gamma2: the manipulability objective's gains [1/s] (0, 0: none).
        dt: the control period ``T`` [s]; bounds: ``"xing"`` or ``"viable"``.
    """

    rows: int = 3
    kd: tuple = (10.0, 10.0, 10.0)
    kp: tuple = (20.0, 20.0, 20.0)
    sigma_thr: float = 0.15
    gamma1: float = 5.0
    gamma2: float = 0.5
    dt: float = DT
    bounds: str = "xing"


POSITION = Setup()
POSE = Setup(rows=6, kd=(10.0, 10.0, 10.0, 3.0, 3.0, 3.0), kp=(20.0, 20.0, 20.0, 5.0, 5.0, 5.0),
             sigma_thr=0.19)

def cartesian_command(pose, J, drift, v, target, target_velocity, target_acceleration, kd,
                      kp, rows: int):
    """``(J_r, drift_r, ẍ_cmd)`` as SX: the task's rows of the frame Jacobian and drift (world
    axes) and the commanded acceleration ``ẍ_d + K_d (ẋ_d − J v) + K_p e`` (Appendix C), with
    ``e = [p_d − p; log3(R_d Rᵀ)]`` (orientation error in world axes, for ``rows = 6``);
    ``kd``, ``kp`` (rows,) the diagonal gains."""
    r = rows
    error = target[:3, 3] - pose[:3, 3]
    if r == 6:
        error = ca.vertcat(error, so3_log(target[:3, :3] @ pose[:3, :3].T))
    J_r, drift_r = J[:r, :], drift[:r]
    command = (target_acceleration[:r] + kd * (target_velocity[:r] - J_r @ v) + kp * error)
    return J_r, drift_r, command


def symbolic_quantity(registry: QuantityRegistry, name: str) -> ca.Function:
    """The CasADi function of the robot's model quantity ``name``."""
    build = registry.get(name).symbolic
    if build is None:
        raise WbcError(f"the robot has no symbolic form of {name!r}")
    return build()


def base_slice(robot) -> slice:
    return slice(0, int(robot.nv) - int(robot.n_arm))


def base_transition_expression(robot, v, dt: float):
    """Eq. (15) sampled (:func:`wbc.solvers.reference.base_transition`) as SX of ``v``."""
    base = base_slice(robot)
    lim = robot.limits
    return ca.fmin(ca.fmax(-v[base] / dt, ca.DM(lim.a_lower[base])), ca.DM(lim.a_upper[base]))


def add_amp_levels(stack: wbc.Stack, J, drift, xdd, n_base: int, transition, base_free,
                   tertiary: wbc.Task) -> wbc.Stack:
    """AMP's three priority levels (see the module docstring) over the stack's whole decision
    vector ``q̈``; the joint bounds are the caller's (``stack.constrain``)."""
    x = stack.variables.symbol
    stack.add(Cost(J @ x + drift, xdd, name="cartesian"), priority=0, scaling=True)
    stack.add(Cost(x[:n_base], transition, weight=1 - base_free, name="base_transition"),
              priority=1)
    stack.add(tertiary, priority=2)
    return stack


def amp_stack(robot, setup: Setup = POSITION) -> wbc.Stack:
    """The AMP cascade for ``robot`` (references ``"target"`` (4, 4) world pose,
    ``"target_velocity"`` (6,), ``"target_acceleration"`` (6,), rows ``[linear; angular]``;
    parameters ``"kd"``, ``"kp"`` (r,), ``"sigma_thr"``, ``"manipulability.gamma1"``,
    ``"manipulability.gamma2"`` default to ``setup``'s)."""
    nq, nv = int(robot.nq), int(robot.nv)
    stack = wbc.Stack(wbc.Variables(qdd=nv), min_norm=False)
    stack.constrain(JointAccelerationLimit(robot, setup.dt, setup.bounds, name="limits"))
    q, v = stack.quantity("q", nq), stack.quantity("v", nv)
    pose = stack.quantity("pose[ee]", (4, 4))
    J = stack.quantity("J[ee]", (6, nv))
    drift = stack.quantity("Jdot_v[ee]", (6, 1))
    target = stack.parameter("target", (4, 4), np.eye(4))
    target_velocity = stack.parameter("target_velocity", 6, np.zeros(6))
    target_acceleration = stack.parameter("target_acceleration", 6, np.zeros(6))
    # the setup's numbers are parameters (defaults), so every setup of one task size shares
    # one compiled (and JIT-built) stack
    kd = stack.parameter("kd", setup.rows, setup.kd)
    kp = stack.parameter("kp", setup.rows, setup.kp)
    sigma_thr = stack.parameter("sigma_thr", 1, setup.sigma_thr)
    J_r, drift_r, xdd = cartesian_command(pose, J, drift, v, target, target_velocity,
                                          target_acceleration, kd, kp, setup.rows)
    q_sym, J_m = arm_jacobian(robot)
    sigma = ca.substitute(smallest_singular_value(J_m), q_sym, q)
    base_free = ca.if_else(sigma < sigma_thr, 1.0, 0.0)
    tertiary = ManipulabilityAccelerationTask(robot, gamma1=setup.gamma1, gamma2=setup.gamma2,
                                  name="manipulability")
    n_base = base_slice(robot).stop
    return add_amp_levels(stack, J_r, drift_r, xdd, n_base,
                          base_transition_expression(robot, v, setup.dt), base_free, tertiary)


def amp_controller(robot, setup: Setup = POSITION, backend: str = "daqp",
                   profile: str = "default", jit: bool = True,
                   fused: bool | str = "auto") -> AMPController:
    """AMP as a QP in a :class:`wbc.Controller` (compiled kinematics, JIT by default; a
    failed solve decelerates within the bounds). ``fused``: AMP's fast path — the tick in
    generated C where the task is not saturated, the ordinary path elsewhere
    (:mod:`wbc.papers.xing.fast`): ``"auto"`` (default) where it applies (daqp, a position
    task, a C compiler), ``True`` (required) or ``False`` (the ordinary path)."""
    return AMPController(robot, amp_stack(robot, setup), base_slice(robot).stop, backend=backend,
                         profile=profile, dt=setup.dt, fallback="decelerate", jit=jit,
                         fused=fused)
