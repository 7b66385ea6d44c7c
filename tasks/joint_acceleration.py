"""Joint position, velocity and acceleration limits as bounds on the joint accelerations.

At the acceleration level a controller commands ``q̈`` for one period ``T`` and the state moves
as ``q̇⁺ = q̇ + T q̈``, ``q⁺ = q + T q̇ + T²/2 q̈`` (what :mod:`wbc.sim` integrates with
``command="acceleration"``). Position and velocity limits must then become bounds
``Q̈_min <= q̈ <= Q̈_max`` that depend on the state ``(q, q̇)``. Two methods:

``method="xing"`` — Xing et al., eqs. (6)–(8), exactly as printed (they cite Flacco et al.)::

    Q_low = Q_min − |q̇| q̇ / (2 A_max)          Q_up = Q_max + |q̇| q̇ / (2 A_min)
    Q̈_min = max(2 (Q_min − q − q̇ T)/T², (V_min − q̇)/T, A_min)   if q > Q_low, else A_max
    Q̈_max = min(2 (Q_max − q − q̇ T)/T², (V_max − q̇)/T, A_max)   if q < Q_up,  else A_min

``Q_low`` / ``Q_up`` are braking points: past ``Q_up`` (moving up) the joint must decelerate
at its maximum, so both bounds force ``A_min``. The position term asks the joint to stop *at*
the limit within one period, which the acceleration limit cannot always grant: the bounds can
cross (``Q̈_min > Q̈_max``) and a closed loop that stays inside them can still overshoot a
position limit. ``tests/test_xing_bounds.py`` counts how often on random states.

``method="viable"`` — bounds that keep the state in a viability kernel of the discrete-time
double integrator, after A. Del Prete, "Joint position and velocity bounds in discrete-time
acceleration/torque control of robot manipulators", IEEE RA-L 3(1), 2018 (TSID's
``TaskJointPosVelAccBounds.computeAccLimitsFromViability`` implements his bounds; this is our
own derivation of the same idea, written for the integration above). The kernel used
here is the set of states from which braking at the maximal deceleration stops the joint
inside its range, ``q + q̇²/(2|A_min|) <= Q_max`` for ``q̇ >= 0`` (and the mirror image for
the lower limit), with ``|q̇|`` within the velocity limits. The upper bound is the largest
``q̈`` whose next state ``(q⁺, q̇⁺)`` is still in that set: with ``u = q̇⁺`` and
``g = Q_max − q − q̇ T/2``,

* ``g >= 0``: ``u <= u* = −A T/2 + sqrt(A² T²/4 + 2 A g)`` (``A = |A_min|``; the root of
  ``q⁺ + u²/(2A) = Q_max`` with ``q⁺ = q + (q̇ + u) T/2``), i.e. ``q̈ <= (u* − q̇)/T``;
* ``g < 0`` (the joint must reverse within this period): ``q⁺ <= Q_max``, i.e.
  ``q̈ <= 2 (Q_max − q − q̇ T)/T²``;

both branches agree at ``g = 0``. Then ``Q̈_max = max(min(that, (V_max − q̇)/T, A_max), A_min)``
(braking at the maximal deceleration always stays allowed: on the kernel's boundary it is the
only choice, and the computed bound can miss it there by round-off) and ``Q̈_min`` is the mirror
image. From a state inside the kernel, braking at ``A_min`` keeps the
next state inside it (the continuous braking parabola is the envelope of the discrete one, so
the state at the samples never passes the stopping point), so the bounds stay ordered and a
closed loop choosing inside them never violates a position or velocity limit — provided the
range is wide enough to brake in (``Q_max − Q_min`` larger than a few ``|A| T²``, true of every
real joint). The kernel is that of continuous-time braking, checked at the samples: it may be
slightly more conservative than the exact discrete-time kernel, never less safe.

Infinite position limits (``±inf``) remove the position terms; the base's coordinates of a
mobile manipulator always have them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from wbc.checks import as_float_array, check_robot, checked_name, checked_number
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError, WbcError
from wbc.terms import Task, VariableBounds

from .frame import velocity_block
from .posture import arm_size

__all__ = ["METHODS", "JointAccelerationLimit", "joint_acceleration_bounds"]

METHODS = ("xing", "viable")


@dataclass(frozen=True)
class _Ops:
    """The element-wise operations the bound formulas need, for numpy or for CasADi."""

    fmax: Callable
    fmin: Callable
    where: Callable
    sqrt: Callable
    fabs: Callable


_NUMPY = _Ops(np.maximum, np.minimum, np.where, np.sqrt, np.abs)
_CASADI = _Ops(ca.fmax, ca.fmin, ca.if_else, ca.sqrt, ca.fabs)


def _stopping_speed(ops: _Ops, gap, brake, lag):
    """Largest speed ``u >= 0`` [unit/s] with ``lag · u + u² / (2 brake) <= gap``: a joint
    that still moves at ``u`` for ``lag`` [s] and then brakes at ``brake`` (> 0) [unit/s²] stops
    within ``gap`` [unit]. ``−brake · lag + sqrt(brake² lag² + 2 brake gap)``; where no
    ``u >= 0`` fits (``gap < 0``) the formula's value, clipped at the square root's zero.
    ``lag = 0`` is the continuous-time braking distance ``sqrt(2 brake gap)``; also used by
    :mod:`wbc.tasks.acceleration_limit` (``lag = T``)."""
    return -brake * lag + ops.sqrt(ops.fmax(brake * brake * lag * lag + 2 * brake * gap, 0))


def _braking_bound(ops: _Ops, q, qd, q_max, brake, T):
    """Largest acceleration [unit/s²] whose next state can still stop below ``q_max`` when
    braking at ``brake`` (> 0) (the ``"viable"`` upper bound, see the module docstring)."""
    gap = q_max - q - qd * T / 2
    u_star = _stopping_speed(ops, gap, brake, T / 2)
    return ops.where(gap >= 0, (u_star - qd) / T, 2 * (q_max - q - qd * T) / (T * T))


def _bounds(ops: _Ops, q, qd, q_min, q_max, v_min, v_max, a_min, a_max, T, method: str):
    """``(lower, upper)`` acceleration bounds of either method, element-wise, with ``ops``."""
    velocity_lower = (v_min - qd) / T
    velocity_upper = (v_max - qd) / T
    if method == "xing":
        q_low = q_min - ops.fabs(qd) * qd / (2 * a_max)
        q_up = q_max + ops.fabs(qd) * qd / (2 * a_min)
        position_lower = 2 * (q_min - q - qd * T) / (T * T)
        position_upper = 2 * (q_max - q - qd * T) / (T * T)
        lower = ops.where(q > q_low, ops.fmax(ops.fmax(position_lower, velocity_lower), a_min),
                          a_max)
        upper = ops.where(q < q_up, ops.fmin(ops.fmin(position_upper, velocity_upper), a_max),
                          a_min)
        return lower, upper
    position_upper = _braking_bound(ops, q, qd, q_max, -a_min, T)
    position_lower = -_braking_bound(ops, -q, -qd, -q_min, a_max, T)
    lower = ops.fmax(ops.fmax(position_lower, velocity_lower), a_min)
    upper = ops.fmin(ops.fmin(position_upper, velocity_upper), a_max)
    # braking at the maximal deceleration is always allowed: on the kernel's boundary it is
    # the only choice, and the bound computed there can miss it by round-off (1e-12)
    return ops.fmin(lower, a_max), ops.fmax(upper, a_min)


def _check_method(method: str, what: str) -> None:
    if not isinstance(method, str) or method not in METHODS:
        raise InvalidValueError(f"{what}: method must be one of {list(METHODS)}, got {method!r}")


def _check_limits(q_min, q_max, v_min, v_max, a_min, a_max, what: str) -> None:
    for name, value in (("v_min", v_min), ("v_max", v_max), ("a_min", a_min),
                        ("a_max", a_max)):
        if not np.all(np.isfinite(value)):
            raise NonFiniteError(f"{what}: {name} must be finite, got {value}")
    if np.any(np.isnan(q_min)) or np.any(np.isnan(q_max)):
        raise NonFiniteError(f"{what}: q_min / q_max hold NaN")
    for name, ok in (("q_min < q_max", q_min < q_max), ("v_min <= 0 <= v_max",
                     (v_min <= 0) & (v_max >= 0)), ("a_min < 0 < a_max",
                     (a_min < 0) & (a_max > 0))):
        if not np.all(ok):
            bad = np.flatnonzero(~np.broadcast_to(ok, np.shape(ok))).tolist()
            raise InvalidValueError(f"{what}: limits must satisfy {name} (fails at {bad})")


def joint_acceleration_bounds(q, qd, q_min, q_max, v_min, v_max, a_min, a_max, dt,
                              method: str = "xing") -> tuple[np.ndarray, np.ndarray]:
    """Acceleration bounds ``(lower, upper)`` [unit/s²] from position, velocity and
    acceleration limits at the state ``(q, qd)`` (see the module docstring).

    Args:
        q: joint positions [m or rad] (the current ``q_h``).
        qd: joint velocities [m/s or rad/s] (the current ``q̇_h``).
        q_min, q_max: position limits (``±inf`` for none), ``q_min < q_max``.
        v_min, v_max: velocity limits, finite, ``v_min <= 0 <= v_max``.
        a_min, a_max: acceleration limits, finite, ``a_min < 0 < a_max``.
        dt: the period ``T`` [s] over which the acceleration is held.
        method: ``"xing"`` (eqs. 7–8 as printed) or ``"viable"`` (Del Prete 2018).

    All arrays broadcast against each other (scalars allowed). ``lower > upper`` is possible
    for ``"xing"``, and for ``"viable"`` only outside its viability kernel.

    Raises:
        ShapeError: the arrays do not broadcast.
        NonFiniteError: NaN anywhere, or infinite velocity / acceleration limits.
        InvalidValueError: unknown method, ``dt <= 0``, or limits in the wrong order.
    """
    what = "joint_acceleration_bounds"
    _check_method(method, what)
    T = checked_number(dt, f"{what}: dt [s]", 0.0, strict=True)
    names = ("q", "qd", "q_min", "q_max", "v_min", "v_max", "a_min", "a_max")
    values = (q, qd, q_min, q_max, v_min, v_max, a_min, a_max)
    arrays = [as_float_array(value, f"{label} of {what}")
              for label, value in zip(names, values, strict=True)]
    try:
        broadcast = np.broadcast_arrays(*arrays)
    except ValueError as error:
        raise ShapeError(f"{what}: the arrays do not broadcast ({error})") from None
    q, qd, q_min, q_max, v_min, v_max, a_min, a_max = broadcast
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise NonFiniteError(f"{what}: q and qd must be finite")
    _check_limits(q_min, q_max, v_min, v_max, a_min, a_max, what)
    lower, upper = _bounds(_NUMPY, q, qd, q_min, q_max, v_min, v_max, a_min, a_max, T, method)
    return np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)


class JointAccelerationLimit(Task):
    """Hard bounds on the joint accelerations from the robot's position, velocity and
    acceleration limits (:func:`joint_acceleration_bounds`, computed inside the compiled
    stack from the model quantities ``"q"`` and ``"v"``: CasADi ``fmin``/``fmax``/``if_else``/
    ``sqrt``, no per-tick numpy). Add it with ``stack.constrain(...)``.

    Coordinates: the decision block holds ``v̇`` (``nv`` entries, base first). Position limits
    act on the arm joints (the last ``n_arm`` entries of ``q`` and of ``v``); the base's
    configuration limits must be infinite (they are for every catalogue robot), so its bounds
    come from the velocity and acceleration limits alone — which is why a base whose velocity
    coordinates differ from its configuration (a differential drive) is fine.

    Args:
        robot: the robot (``nq``, ``nv``, ``limits``).
        dt: the period ``T`` [s] the acceleration is held for (the control period).
        method: ``"xing"`` or ``"viable"`` (see :mod:`wbc.tasks.joint_acceleration`).
        name: task name.
        joints: number of trailing arm joints (default: as :class:`~wbc.tasks.PostureTask`).
        block: the acceleration block of the decision vector (``None``: all of it).

    Quantities it declares: ``"q"`` (nq,), ``"v"`` (nv,). The limits are constants of the
    compiled stack (taken from ``robot.limits`` when the task is built).
    """

    def __init__(self, robot, dt: float, method: str = "xing", name: str | None = None,
                 joints: int | None = None, block: str | None = None) -> None:
        what = f"JointAccelerationLimit {name!r}"
        _check_method(method, what)
        self.dt = checked_number(dt, f"{what}: dt [s]", 0.0, strict=True)
        self.method = method
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        self.n_arm = arm_size(robot, joints)
        limits = robot.limits
        base_q = np.concatenate([limits.q_lower[: self.nq - self.n_arm],
                                 limits.q_upper[: self.nq - self.n_arm]])
        if np.any(np.isfinite(base_q)):
            raise WbcError(f"{what}: the base coordinates must have infinite position limits")
        n_base = self.nv - self.n_arm
        self.q_min = np.concatenate([np.full(n_base, -np.inf), limits.q_lower[-self.n_arm:]])
        self.q_max = np.concatenate([np.full(n_base, np.inf), limits.q_upper[-self.n_arm:]])
        self.v_min, self.v_max = np.array(limits.v_lower), np.array(limits.v_upper)
        self.a_min, self.a_max = np.array(limits.a_lower), np.array(limits.a_upper)
        _check_limits(self.q_min, self.q_max, self.v_min, self.v_max, self.a_min, self.a_max,
                      what)
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        velocity_block(stack, self.block, self.nv, f"JointAccelerationLimit {self.name!r}")
        q = stack.quantity("q", self.nq)
        v = stack.quantity("v", self.nv)
        # the arm's positions in the velocity layout; the base entries meet infinite limits
        positions = ca.vertcat(ca.SX.zeros(self.nv - self.n_arm), q[self.nq - self.n_arm:])
        lower, upper = _bounds(_CASADI, positions, v, *(ca.DM(limit) for limit in (
            self.q_min, self.q_max, self.v_min, self.v_max, self.a_min, self.a_max)),
            self.dt, self.method)
        return [VariableBounds(lower, upper, self.block, self.name)]

    def __repr__(self) -> str:
        return (f"JointAccelerationLimit(dt={self.dt}, method={self.method!r}, "
                f"name={self.name!r})")
