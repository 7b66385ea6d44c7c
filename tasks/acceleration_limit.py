"""`AccelerationLimit`: acceleration limits as velocity bounds, with the braking distance.

At the velocity level the command ``v`` replaces the previous velocity ``v_prev`` for one
period ``T`` (``dt``), so the joint accelerates by ``(v − v_prev)/T`` and moves to
``q⁺ = q + v T``. Two kinds of bound keep that motion acceleration-feasible, per joint ``i``
(``a⁺ = a_max > 0`` its largest acceleration, ``a⁻ = |a_min| > 0`` its largest deceleration)::

    acceleration:   v_prev − a⁻ T  <=  v  <=  v_prev + a⁺ T
    braking:        −s(q − q_min, a⁺)  <=  v  <=  s(q_max − q, a⁻)

where ``s(gap, b)`` is the largest speed from which the joint can still stop within ``gap``
when decelerating at ``b`` (:func:`wbc.tasks.joint_acceleration._stopping_speed`). Two readings
of ``s`` (``method``):

``method="pink"`` — pink's ``AccelerationLimit`` (pink 4.4, ``pink/limits/acceleration_limit.py``;
Flacco et al. 2015, Del Prete 2018): the continuous-time braking distance
``s = sqrt(2 b gap)``. Pink writes it over ``Δq = v T`` as ``G Δq <= h`` with
``h = min(a T² + Δq_prev, T sqrt(2 a (q_max ⊖ q)))`` (and the mirror image), a symmetric
``a_max`` and ``Δq_prev = v_prev T`` from ``set_last_integration(v_prev, T)``; dividing by
``T`` gives the bounds above with ``a⁺ = a⁻ = a_max``. It ignores the period the command is
held for: a joint at ``v = s(gap)`` first moves ``v T`` and only then brakes. Riding that bound,
the next tick's braking bound drops below ``v_prev − a⁻ T`` (``sqrt(v² − 2 a v T) < v − a T``),
where pink's QP is infeasible; braking at ``a⁻`` from there (see below) takes
``v² / 2a + v T / 2``, so a closed loop passes the position limit by up to about
``v T / 2 + a T² / 2`` (``v`` the speed when braking starts; measured 7.8 mm at 1.54 rad/s,
``a = 8`` rad/s², ``T = 10`` ms, ``tests/test_common_limits.py``).

``method="viable"`` (default) — the discrete-time braking distance: the joint moves ``v T``
this tick, then brakes, so ``v T + v² / (2 b) <= gap``, i.e.
``s = −b T + sqrt(b² T² + 2 b gap)``. From a state that satisfies it (``v_prev`` within it),
the next tick's braking bound is never below ``v − a⁻ T`` (it is ``≥ −b T + sqrt(b² T² + v²)``),
so the bounds stay ordered and a closed loop that chooses inside them never passes a position
limit and never exceeds an acceleration limit. ``s`` is smaller than pink's by at most ``b T``.

Both methods: maximal deceleration is always allowed (``upper >= v_prev − a⁻ T``,
``lower <= v_prev + a⁺ T``) — on ``"pink"`` this changes the bounds only where pink's QP has no
solution; past a position limit (``gap < 0``) ``s`` is clipped at 0 for ``"pink"`` (pink's
square root would be NaN) and asks the joint back for ``"viable"``. Joints whose acceleration
limits are infinite are unbounded; joints without finite position limits (and a mobile base's
coordinates) get the acceleration bounds only.

Units: positions [rad or m], velocities [rad/s or m/s], accelerations [rad/s² or m/s²],
``T`` [s]. The bounds are :class:`~wbc.VariableBounds` (hard): add the task with
``stack.constrain(...)``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import as_float_array, check_robot, checked_name, checked_number, checked_vector
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError
from wbc.terms import Task, VariableBounds

from .frame import velocity_block
from .joint_acceleration import _CASADI, _NUMPY, _Ops, _stopping_speed
from .posture import arm_size

__all__ = ["ACCELERATION_LIMIT_METHODS", "AccelerationLimit", "acceleration_limit_bounds"]

ACCELERATION_LIMIT_METHODS = ("viable", "pink")


def _check_method(method, what: str) -> str:
    if not isinstance(method, str) or method not in ACCELERATION_LIMIT_METHODS:
        raise InvalidValueError(f"{what}: method must be one of "
                                f"{list(ACCELERATION_LIMIT_METHODS)}, got {method!r}")
    return method


def _bounds(ops: _Ops, q, v_prev, q_min, q_max, a_min, a_max, T, method: str):
    """``(lower, upper)`` velocity bounds [unit/s] (module docstring), element-wise; ``a_min``
    < 0 < ``a_max`` finite."""
    lag = T if method == "viable" else 0.0
    acceleration_lower = v_prev + a_min * T
    acceleration_upper = v_prev + a_max * T
    braking_upper = _stopping_speed(ops, q_max - q, -a_min, lag)
    braking_lower = -_stopping_speed(ops, q - q_min, a_max, lag)
    upper = ops.fmax(ops.fmin(acceleration_upper, braking_upper), acceleration_lower)
    lower = ops.fmin(ops.fmax(acceleration_lower, braking_lower), acceleration_upper)
    return lower, upper


def _checked_accelerations(a_min, a_max, size: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``(a_min, a_max)`` of ``size`` entries, ``a_min < 0 < a_max`` (``±inf``: no limit)."""
    lo = checked_vector(a_min, size, f"{what}: a_min", allow_inf=True)
    up = checked_vector(a_max, size, f"{what}: a_max", allow_inf=True)
    if not np.all((lo < 0) & (up > 0)):
        bad = np.flatnonzero(~((lo < 0) & (up > 0))).tolist()
        raise InvalidValueError(f"{what}: acceleration limits must satisfy a_min < 0 < a_max "
                                f"(fails at {bad})")
    return lo, up


def acceleration_limit_bounds(q, v_prev, q_min, q_max, a_min, a_max, dt,
                              method: str = "viable") -> tuple[np.ndarray, np.ndarray]:
    """Velocity bounds ``(lower, upper)`` [unit/s] from acceleration and position limits (see
    the module docstring), in numpy: the closed form :class:`AccelerationLimit` compiles.

    Args:
        q: joint positions [rad or m].
        v_prev: the velocities of the previous period [unit/s].
        q_min, q_max: position limits (``±inf`` for none), ``q_min < q_max``.
        a_min, a_max: acceleration limits [unit/s²], ``a_min < 0 < a_max``, finite.
        dt: the period ``T`` [s].
        method: ``"viable"`` or ``"pink"``.

    All arrays broadcast against each other (scalars allowed).

    Raises:
        ShapeError, NonFiniteError, InvalidValueError: as their names say, naming the argument.
    """
    what = "acceleration_limit_bounds"
    _check_method(method, what)
    T = checked_number(dt, f"{what}: dt [s]", 0.0, strict=True)
    names = ("q", "v_prev", "q_min", "q_max", "a_min", "a_max")
    arrays = [as_float_array(value, f"{label} of {what}")
              for label, value in zip(names, (q, v_prev, q_min, q_max, a_min, a_max),
                                      strict=True)]
    try:
        q, v_prev, q_min, q_max, a_min, a_max = np.broadcast_arrays(*arrays)
    except ValueError as error:
        raise ShapeError(f"{what}: the arrays do not broadcast ({error})") from None
    for label, value in (("q", q), ("v_prev", v_prev), ("a_min", a_min), ("a_max", a_max)):
        if not np.all(np.isfinite(value)):
            raise NonFiniteError(f"{what}: {label} must be finite")
    if np.any(np.isnan(q_min)) or np.any(np.isnan(q_max)) or not np.all(q_min < q_max):
        raise InvalidValueError(f"{what}: position limits must satisfy q_min < q_max")
    if not np.all((a_min < 0) & (a_max > 0)):
        raise InvalidValueError(f"{what}: acceleration limits must satisfy a_min < 0 < a_max")
    lower, upper = _bounds(_NUMPY, q, v_prev, q_min, q_max, a_min, a_max, T, method)
    return np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)


class AccelerationLimit(Task):
    """Hard velocity bounds from acceleration limits and the braking distance to the position
    limits (see :mod:`wbc.tasks.acceleration_limit`), computed inside the compiled stack.

    The previous velocity ``v_prev`` is the model quantity ``"v"``: pass the velocity the
    joints move at — measured, or the previous command — as ``controller.step(q, v, ...)``
    (:class:`wbc.sim.Simulation` does). A controller stepped without ``v`` sees ``v = 0`` every
    tick and then allows at most ``a⁺ T`` per joint.

    Relation to pink: ``AccelerationLimit(model, a)`` + ``set_last_integration(v_prev, T)`` is
    ``AccelerationLimit(robot, a_max=a, method="pink")`` stepped with ``v = v_prev``: the same
    constraint set over ``v = Δq / T`` (wherever pink's is not empty).

    Args:
        robot: the robot (``nq``, ``nv``, ``limits``).
        a_max: largest acceleration [unit/s²], ``> 0``, scalar or one per velocity coordinate
            (``inf``: no limit on that joint); the limit is symmetric, ``a_min = −a_max``.
            ``None`` (default): ``robot.limits.a_lower`` / ``a_upper``.
        method: ``"viable"`` (default, discrete-time braking distance: never passes a position
            limit) or ``"pink"`` (pink's continuous-time one).
        name: task name.
        joints: number of trailing arm joints whose position limits are used (default: as
            :class:`~wbc.tasks.PostureTask`).
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Quantities it declares: ``"q"`` (nq,), ``"v"`` (nv,), ``"dt"`` (1,). The limits are
    constants of the compiled stack (position limits from ``robot.limits``).
    """

    def __init__(self, robot, a_max=None, method: str = "viable", name: str | None = None,
                 joints: int | None = None, block: str | None = None) -> None:
        what = f"AccelerationLimit {name!r}"
        self.method = _check_method(method, what)
        self.nq, self.nv = check_robot(robot, f"robot of {what}")
        self.n_arm = arm_size(robot, joints)
        limits = robot.limits
        if a_max is None:
            self.a_min, self.a_max = _checked_accelerations(limits.a_lower, limits.a_upper,
                                                            self.nv, what)
        else:
            upper = checked_vector(a_max, self.nv, f"{what}: a_max", allow_inf=True)
            self.a_min, self.a_max = _checked_accelerations(-upper, upper, self.nv, what)
        self.limited = np.isfinite(self.a_min) & np.isfinite(self.a_max)
        if not self.limited.any():
            raise InvalidValueError(f"{what}: every acceleration limit is infinite (the "
                                    "robot's limits have none?): pass a_max=")
        n_base = self.nv - self.n_arm
        q_lower = np.asarray(limits.q_lower, dtype=float).reshape(-1)
        q_upper = np.asarray(limits.q_upper, dtype=float).reshape(-1)
        if q_lower.shape != (self.nq,) or q_upper.shape != (self.nq,):
            raise ShapeError(f"{what}: robot.limits.q_lower/q_upper must have shape "
                             f"({self.nq},)")
        self.q_min = np.concatenate([np.full(n_base, -np.inf), q_lower[self.nq - self.n_arm:]])
        self.q_max = np.concatenate([np.full(n_base, np.inf), q_upper[self.nq - self.n_arm:]])
        if np.any(np.isnan(self.q_min)) or np.any(np.isnan(self.q_max)) or not np.all(
                self.q_min < self.q_max):
            raise InvalidValueError(f"{what}: the robot's position limits must satisfy "
                                    "q_lower < q_upper")
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        velocity_block(stack, self.block, self.nv, f"AccelerationLimit {self.name!r}")
        q = stack.quantity("q", self.nq)
        v_prev = stack.quantity("v", self.nv)
        dt = stack.quantity("dt", 1)
        # the arm's positions in the velocity layout; the base entries meet infinite limits
        positions = ca.vertcat(ca.SX.zeros(self.nv - self.n_arm), q[self.nq - self.n_arm:])
        # unlimited joints: any finite stand-in (1) keeps inf·0 out, then ±inf replaces them
        a_min = ca.DM(np.where(self.limited, self.a_min, -1.0))
        a_max = ca.DM(np.where(self.limited, self.a_max, 1.0))
        lower, upper = _bounds(_CASADI, positions, v_prev, ca.DM(self.q_min),
                               ca.DM(self.q_max), a_min, a_max, dt, self.method)
        inf = float("inf")
        lower = ca.vertcat(*[lower[i] if self.limited[i] else -inf for i in range(self.nv)])
        upper = ca.vertcat(*[upper[i] if self.limited[i] else inf for i in range(self.nv)])
        return [VariableBounds(lower, upper, self.block, self.name)]

    def __repr__(self) -> str:
        return f"AccelerationLimit(method={self.method!r}, name={self.name!r})"
