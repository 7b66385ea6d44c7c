"""The steering controller's tick (:meth:`SteerableController.step
<wbc.papers.sorour.steering.SteerableController.step>`) as one CasADi function, for generated C
code: the fast path of :class:`~wbc.papers.sorour.steering.SteerableController` and of
:class:`~wbc.papers.sorour.SorourController`.

:func:`steering_function` mirrors the ordinary tick step by step (the same formulas, the same
order of operations; branches as ``if_else``); only its ICR QP is solved differently, in closed
form, and answers only where that closed form is the ordinary path's answer.

The ICR QP in closed form
-------------------------
The ordinary path solves a two-level cascade over ``u ∈ R²``: level 0 the least violation of the
eight acceleration-cone rows (soft) under the eight rate-cone rows (hard), level 1 ``min ||T u −
b||²`` (``T`` orthonormal: the projection of ``c = Tᵀ b`` onto a polygon) with the level-0 rows
at their optimal violation. When the sixteen rows have a common point, the optimal violation is
0 and level 1 is the projection of ``c`` onto that polygon. Its optimum has at most two active
rows, so it is ``c`` itself, the projection of ``c`` onto one row's line, or the intersection of
two lines: of these candidates, the nearest to ``c`` that meets every row (to
:data:`FEASIBLE_TOL`, relative) is the exact optimum. The acceleration rows alone make and check
the candidates: each wheel's acceleration cone lies inside its rate cone (``[lo, hi] ⊂
[−β̇max t_s, β̇max t_s]`` by construction), so the rate rows hold wherever the acceleration rows
do, and a rate row is active only where it is the acceleration row.

The ordinary path's daqp is not exact: it stops when no row is violated by more than its
``primal_tol`` (1e-6, the default profile), so it may end on another candidate — one that
violates a row by less than that and whose multipliers have the right signs — up to 1.7e-6 from
the exact optimum (measured on the study's 65 s runs: 3 ticks of 7800), and which one depends on
its warm start. The closed form therefore answers only when no such candidate exists farther
than :data:`AMBIGUITY` from the optimum (violations up to :data:`DAQP_TOL` counted, twice daqp's
tolerance, in daqp's unit-row measure), and when no wheel's acceleration row lies within
:data:`NEAR_ANGLE` of its rate row without being it (daqp may then take either). Such a tick's
answer depends on the ordinary path's warm start: on one of the quick study's timing states two
ordinary paths, one started after the tick before, the other cold, end 1.06e-6 apart in ``u``,
2.3e-5 rad/s in a β̇ (``tests/test_sorour_fast.py``). Measured on the study's 65 s runs
(:class:`~wbc.papers.sorour.SorourController`'s fast path against its ordinary path, 7800 ticks,
each replayed with both paths' QPs started cold): commands and steering states within 4.6e-9,
144 ticks handed to the ordinary path — 58 by this function (21 ambiguous, 23 near angles or
inverted cones, 14 whose try's rows have no common point), 86 by eq. 14 at ill-conditioned arm
configurations; on 5000 random states of ``tests/test_sorour_fast.py`` steering states within
1.2e-9.

The cascade's other branches: when the sixteen rows facing the reference have no common point,
the ordinary path either relaxes the acceleration cones (the rate rows have a common point: level
0's least violation, left to the ordinary path) or finds level 0 infeasible and tries the
half-cones of the current ICR. The function takes that second try only when the rate rows facing
the reference are *clearly* infeasible — no common point even with every row moved outwards by
:data:`EMPTY_MARGIN`, far beyond daqp's tolerance — and answers it as the first. Everything else
(relaxed accelerations, a wheel whose rate exceeds β̇max so that its acceleration cone is
inverted, both tries failing) is ``ok = 0``: the ordinary path answers the tick.

Cost: the candidates of ``N`` wheels are ``1 + 2N + N(2N − 1)`` (37 for the MPO700), each checked
against the ``2N`` acceleration rows; the second try (its rows, the clear-infeasibility test, its
projection) is a branch the generated code evaluates only when the first try has no point
(about 4 % of the study's ticks).
"""

from __future__ import annotations

import math
from functools import cache
from itertools import combinations

import casadi as ca

from wbc.cbuild import compiler_available
from wbc.errors import WbcError

__all__ = ["fast_path_allowed", "steering_function"]


def fast_path_allowed(fused, backend: str, subject: str) -> bool:
    """Whether ``subject`` (a controller, named in the error) may take its fast path: not with
    ``fused=False``, another backend than daqp (the generated code replaces daqp's QPs) or no C
    compiler; ``fused=True`` where it cannot raises :class:`~wbc.errors.WbcError` saying why."""
    reason = ("turned off (fused=False)" if fused is False else
              f"the backend is {backend!r}; the fast path replaces daqp's QPs"
              if backend != "daqp" else
              None if compiler_available() else "no C compiler found ($CC, default cc)")
    if reason is not None and fused is True:
        raise WbcError(f"fused=True, but {subject} cannot take the fast path: {reason}")
    return reason is None

#: Relative violation up to which a candidate meets a row (the exact optimum meets its rows to
#: rounding).
FEASIBLE_TOL = 1e-12
#: Violation [unit rows] up to which the ordinary path's daqp may accept a candidate: twice its
#: ``primal_tol`` (1e-6).
DAQP_TOL = 2e-6
#: Distance in ``u`` beyond which two acceptable candidates are different answers.
AMBIGUITY = 1e-9
#: Angle [rad] within which a wheel's acceleration row and rate row count as nearly the same
#: line (their difference below 1e-12 rad: the same line).
NEAR_ANGLE = 1e-5
#: Outward shift [unit rows] the rate rows must not have a common point under, for a clearly
#: infeasible first try.
EMPTY_MARGIN = 1e-5
#: A multiplier down to this value counts as non-negative.
DUAL_TOL = 1e-9
#: constants before the hips: dt, β̇max, β̈max, icr_gain, drive_gain, offset, radius, v_max (3)
N_CONSTANTS = 10


def _dot(a, b):
    """``a·b`` of two 2-vectors."""
    return a[0] * b[0] + a[1] * b[1]


def _norm2(a):
    """``|a|`` of a 2-vector."""
    return ca.sqrt(a[0] * a[0] + a[1] * a[1])


def _any(flags) -> ca.SX:
    """The logical or of ``flags``."""
    out = ca.SX(0)
    for flag in flags:
        out = ca.logic_or(out, flag)
    return out


def _cone_rows(hips, steering, x, facing, T, lo, hi) -> ca.SX:
    """The rows of ``SteerableController._cones`` (per wheel the lower-side row, then the
    upper-side rows) as unit rows: a ``(3, 2N)`` matrix whose column ``(â, b̂)`` stands for
    ``â·u <= b̂``, ``|â| = 1``."""
    rows: dict[float, list] = {-1.0: [], 1.0: []}
    for i, (hx, hy) in enumerate(hips):
        heading = steering[i] + math.pi / 2
        w_ref = (facing[0] - hx * facing[2], facing[1] - hy * facing[2])
        e = (ca.cos(heading), ca.sin(heading))
        side = ca.if_else(_dot(e, w_ref) < 0.0, math.pi, 0.0)
        w = (x[0] - hx * x[2], x[1] - hy * x[2])
        scale = 1.0 / ca.fmax(_norm2(w), 1e-3)
        for angle, sign in ((heading + side + lo[i], -1.0), (heading + side + hi[i], 1.0)):
            uy, ux = ca.sin(angle), ca.cos(angle)
            r = [-uy * scale, ux * scale, (uy * hx - ux * hy) * scale]
            a = [sign * (r[0] * T[0, k] + r[1] * T[1, k] + r[2] * T[2, k]) for k in range(2)]
            norm = _norm2(a)
            b = -sign * (r[0] * x[0] + r[1] * x[1] + r[2] * x[2])
            rows[sign].append(ca.vertcat(a[0] / norm, a[1] / norm, b / norm))
    return ca.horzcat(*rows[-1.0], *rows[1.0])


def _vertices(rows: ca.SX, c):
    """``(u, valid, dual)`` per intersection of two of the unit ``rows``' lines (``valid`` 0
    for parallel ones); ``dual``: ``c`` projects onto it with non-negative multipliers."""
    out = []
    for i, j in combinations(range(rows.shape[1]), 2):
        ai, aj, bi, bj = rows[:2, i], rows[:2, j], rows[2, i], rows[2, j]
        det = ai[0] * aj[1] - ai[1] * aj[0]
        valid = ca.fabs(det) > 1e-12
        d = ca.if_else(valid, det, 1.0)
        u = ca.vertcat((bi * aj[1] - bj * ai[1]) / d, (ai[0] * bj - aj[0] * bi) / d)
        r = c - u  # stationarity: u − c + λ_i a_i + λ_j a_j = 0
        lam_i, lam_j = (r[0] * aj[1] - r[1] * aj[0]) / d, (ai[0] * r[1] - ai[1] * r[0]) / d
        out.append((u, valid, ca.logic_and(lam_i >= -DUAL_TOL, lam_j >= -DUAL_TOL)))
    return out


def _violation(rows: ca.SX, u) -> list:
    """``â·u − b̂`` per unit row."""
    return [rows[0, k] * u[0] + rows[1, k] * u[1] - rows[2, k] for k in range(rows.shape[1])]


@cache
def _projection_function(m: int) -> ca.Function:
    """``(rows (3, m) unit rows, c (2,)) -> (u, [found, ambiguous])``: the projection of ``c``
    onto the polygon of ``rows``, whether the polygon has a point, and whether the ordinary
    path's daqp could end on another candidate (module docstring)."""
    rows, c = ca.SX.sym("rows", 3, m), ca.SX.sym("c", 2)
    candidates = [(c, ca.SX(1), ca.SX(1))]
    for k in range(m):
        lam = rows[0, k] * c[0] + rows[1, k] * c[1] - rows[2, k]
        candidates.append((c - lam * rows[:2, k], ca.SX(1), lam >= -DUAL_TOL))
    candidates += _vertices(rows, c)
    tolerance = [FEASIBLE_TOL * (1.0 + ca.fabs(rows[2, k])) for k in range(m)]
    best, best_d, found, acceptable = c, ca.SX(ca.inf), ca.SX(0), []
    for u, valid, dual in candidates:
        violation = _violation(rows, u)
        worst, excess = violation[0], violation[0] - tolerance[0]
        for v, t in zip(violation[1:], tolerance[1:], strict=True):
            worst, excess = ca.fmax(worst, v), ca.fmax(excess, v - t)
        feasible = ca.logic_and(valid, excess <= 0.0)
        d = _dot(u - c, u - c)
        take = ca.logic_and(feasible, d < best_d)
        best, best_d = ca.if_else(take, u, best), ca.if_else(take, d, best_d)
        found = ca.logic_or(found, feasible)
        acceptable.append(ca.logic_and(ca.logic_and(valid, dual), worst <= DAQP_TOL))
    ambiguous = _any(ca.logic_and(ok, ca.fmax(ca.fabs(u[0] - best[0]), ca.fabs(u[1] - best[1]))
                                  > AMBIGUITY)
                     for (u, _, _), ok in zip(candidates, acceptable, strict=True))
    return ca.Function("sorour_icr_projection", [rows, c], [best, ca.vertcat(found, ambiguous)])


def _clearly_empty(rows: ca.SX) -> ca.SX:
    """1 if the unit rows have no common point even moved outwards by :data:`EMPTY_MARGIN`: no
    intersection of two moved lines meets them all. (Their polygon, if not empty, is pointed —
    the rows of one wheel are not parallel — so it has such a vertex.)"""
    moved = ca.vertcat(rows[:2, :], rows[2, :] + EMPTY_MARGIN)
    feasible = []
    for u, valid, _ in _vertices(moved, ca.SX.zeros(2)):
        excess = [v - FEASIBLE_TOL * (1.0 + ca.fabs(moved[2, k]))
                  for k, v in enumerate(_violation(moved, u))]
        worst = excess[0]
        for v in excess[1:]:
            worst = ca.fmax(worst, v)
        feasible.append(ca.logic_and(valid, worst <= 0.0))
    return 1 - _any(feasible)


class _Symbols:
    """The tick's inputs (SX) and the named parts of them every stage reads."""

    def __init__(self, n: int) -> None:
        self.desired = ca.SX.sym("desired", 3)
        self.state = ca.SX.sym("state", 2 * n + 6)
        self.constants = ca.SX.sym("constants", N_CONSTANTS + 2 * n)
        self.inputs = [self.desired, self.state, self.constants]
        self.steering, self.rates = self.state[:n], self.state[n:2 * n]
        self.twist, self.x = self.state[2 * n:2 * n + 3], self.state[2 * n + 3:]
        k = self.constants
        (self.dt, self.rate_max, self.acceleration_max, self.icr_gain, self.drive_gain,
         self.offset, self.radius) = (k[i] for i in range(7))
        self.v_max = k[7:10]
        self.hips = [(k[N_CONSTANTS + 2 * i], k[N_CONSTANTS + 2 * i + 1]) for i in range(n)]
        # _tangent_basis: the first axis of smallest |X_i|
        x = self.x
        first = ca.logic_and(ca.fabs(x[0]) <= ca.fabs(x[1]), ca.fabs(x[0]) <= ca.fabs(x[2]))
        second = ca.logic_and(1 - first, ca.fabs(x[1]) <= ca.fabs(x[2]))
        t1 = ca.cross(x, ca.vertcat(first, second, 1 - first - second))
        t1 = t1 / ca.norm_2(t1)
        self.T = ca.horzcat(t1, ca.cross(x, t1))
        # the acceleration cones [lo, hi] and the rate cones ±β̇max t_s [rad]
        self.step_max = self.rate_max * self.dt
        change = self.acceleration_max * self.dt
        self.lo = ca.fmax(-self.step_max, (self.rates - change) * self.dt)
        self.hi = ca.fmin(self.step_max, (self.rates + change) * self.dt)

    def function(self, name: str, outputs: list, output_names: list,
                 u: ca.SX | None = None) -> ca.Function:
        """A function of the tick's inputs (and of the ICR QP's answer ``u``, if given)."""
        extra = [] if u is None else [u]
        return ca.Function(name, [*self.inputs, *extra], outputs,
                           ["desired", "state", "constants", *(["u"] if extra else [])],
                           output_names)


def _setup_functions(n: int) -> tuple[ca.Function, ca.Function]:
    """``setup``: ``(c, the first try's unit rows, [near, route])`` — the route and ``X_ref``
    of ``SteerableController.step``, ``c = Tᵀ (X_ref − X)``, the cones facing ``X_ref``, and
    whether a wheel's acceleration row nearly coincides with its rate row or is inverted;
    ``retry``: ``(the second try's unit rows, rates_empty)`` — the cones facing ``X``, and
    whether the first try's rate cones are clearly infeasible (the ordinary path's level 0 then
    fails)."""
    s = _Symbols(n)
    x = s.x
    h = ca.vertcat(-s.desired[1], s.desired[0], s.desired[2])
    norm = ca.norm_2(h)
    has_target = norm >= 1e-12
    target = h / ca.if_else(has_target, norm, 1.0)
    target = ca.if_else(ca.dot(target, x) < 0.0, -target, target)
    route = ca.if_else(has_target, ca.if_else(target[2] * x[2] < 0.0, 2, 1), 0)
    x_ref = ca.if_else(has_target, x + s.icr_gain * s.dt * (target - x), x)
    c = ca.vertcat(*[ca.dot(s.T[:, k], x_ref - x) for k in range(2)])
    gaps = ca.vertcat(s.lo + s.step_max, s.step_max - s.hi)
    near = ca.logic_or(ca.mmax(ca.logic_and(gaps > 1e-12, gaps < NEAR_ANGLE)),
                       ca.mmax(s.lo > s.hi))
    first = _cone_rows(s.hips, s.steering, x, x_ref, s.T, s.lo, s.hi)
    setup = s.function("sorour_steering_setup", [c, first, ca.vertcat(near, route)],
                       ["c", "rows", "flags"])
    full = ca.SX.ones(n) * s.step_max
    rates_facing_ref = _cone_rows(s.hips, s.steering, x, x_ref, s.T, -full, full)
    retry = s.function("sorour_steering_retry",
                       [_cone_rows(s.hips, s.steering, x, x, s.T, s.lo, s.hi),
                        _clearly_empty(rates_facing_ref)], ["rows", "rates_empty"])
    return setup, retry


def _finish_function(n: int) -> ca.Function:
    """After the ICR QP's answer ``u``: ``X_next``, ``steering_of_icr`` (``np.remainder``'s
    sign convention, exactly) and the braking of a wheel at the ICR, the rates and
    accelerations, the drive controller projected on the next ICR's twist and scaled into the
    limits, the inverse actuation model."""
    s = _Symbols(n)
    u = ca.SX.sym("u", 2)
    x_next = s.x + s.T @ u
    x_next = x_next / ca.norm_2(x_next)
    dt, steering = s.dt, s.steering
    brake = ca.fmin(ca.fmax(0.0, s.rates - s.acceleration_max * dt),
                    s.rates + s.acceleration_max * dt)
    angles = []
    for i, (hx, hy) in enumerate(s.hips):
        w = (x_next[0] - hx * x_next[2], x_next[1] - hy * x_next[2])
        shifted = ca.fmod(ca.atan2(w[1], w[0]) - math.pi / 2 - steering[i] + math.pi / 2,
                          math.pi)
        shifted = ca.if_else(shifted < 0.0, shifted + math.pi, shifted)
        angles.append(ca.if_else(_norm2(w) < 1e-9, steering[i] + dt * brake[i],
                                 steering[i] + (shifted - math.pi / 2)))
    beta = ca.vertcat(*angles)
    rates = (beta - steering) / dt
    accelerations = (rates - s.rates) / dt
    relaxed = ca.mmax(ca.fabs(accelerations)) > s.acceleration_max * (1 + 1e-4)
    initial = s.twist + dt * s.drive_gain * (s.desired - s.twist)
    direction = ca.vertcat(x_next[1], -x_next[0], x_next[2])
    feasible = direction * ca.dot(direction, initial)
    ratio = ca.mmax(ca.fabs(feasible) / s.v_max)
    feasible = ca.if_else(ratio > 1.0, feasible / ratio, feasible)
    wheels = []
    for i, (hx, hy) in enumerate(s.hips):
        cb, sb = ca.cos(beta[i]), ca.sin(beta[i])
        wheels.append((cb * feasible[0] + sb * feasible[1]
                       + (s.offset - hy * cb + hx * sb) * feasible[2]
                       + s.offset * rates[i]) / s.radius)
    return s.function("sorour_steering_finish",
                      [ca.vertcat(beta, rates, feasible, x_next), accelerations,
                       ca.vertcat(*wheels), relaxed],
                      ["next", "steer_accelerations", "drive_rates", "relaxed"], u)


@cache
def steering_function(n_wheels: int) -> ca.Function:
    """The steering controller's tick for ``n_wheels`` wheels as a CasADi function (see the
    module docstring).

    Inputs: ``desired`` (3,) the desired body twist ``ξ*`` [m/s, m/s, rad/s]; ``state``
    (2N + 6,) ``[β (N) [rad], β̇ (N) [rad/s], ξ̂ (3), X (3)]``; ``constants`` (10 + 2N,)
    ``[t_s [s], β̇max [rad/s], β̈max [rad/s²], λ_ICR [1/s], K_p [1/s], d [m], r_w [m],
    v_max (3), hips (N × 2, row by row) [m]]``.

    Outputs: ``next`` (2N + 6,) the state after the tick (``β``, ``β̇_ref``, the feasible twist
    ``q̇_bf``, ``X_next``); ``steer_accelerations`` (N,) [rad/s²]; ``drive_rates`` (N,)
    [rad/s]; ``info`` (3,) ``[ok, route (0 none, 1 direct, 2 complementary), relaxed]``. With
    ``ok = 0`` the outputs mean nothing: the ordinary path answers the tick.
    """
    setup, retry = _setup_functions(n_wheels)
    finish = _finish_function(n_wheels)
    project = _projection_function(2 * n_wheels)
    inputs = [ca.MX.sym(setup.name_in(i), setup.sparsity_in(i)) for i in range(3)]
    c, rows, flags = setup(*inputs)
    u_first, first = project(rows, c)
    # the second try is a branch the generated code evaluates only when taken
    second_rows, rates_empty = retry(*inputs)
    u_second, second = project(second_rows, c)
    answer = ca.if_else(first[0], ca.vertcat(u_first, 1 - first[1]),
                        ca.vertcat(u_second, ca.logic_and(ca.logic_and(rates_empty, second[0]),
                                                          1 - second[1])), True)
    state_next, accelerations, drive_rates, relaxed = finish(*inputs, answer[:2])
    ok = ca.logic_and(1 - flags[0], answer[2])
    return ca.Function("sorour_steering", inputs,
                       [state_next, accelerations, drive_rates, ca.vertcat(ok, flags[1], relaxed)],
                       ["desired", "state", "constants"],
                       ["next", "steer_accelerations", "drive_rates", "info"])
