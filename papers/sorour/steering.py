"""The steerable base's own controller (Sorour et al., §IV): ICR steering under steer-joint
rate and acceleration limits, then the drive controller.

Kinematic model (the paper's, §IV): wheel ``i`` steers about its hip ``h_i``; its rolling
direction ``e_i = (cos β_i, sin β_i)`` is the direction of the hip's velocity, so the wheels
agree on a twist ``ξ = (v_x, v_y, ω)`` (base frame) exactly when every hip velocity
``v + ω ẑ × h_i`` is parallel to ``e_i`` — the *lateral* rows ``[−sin β_i, cos β_i,
h_x cos β_i + h_y sin β_i] ξ = 0``. The wheel's contact point is offset sideways by ``d``, which
enters the drive rates only (the inverse actuation model)::

    φ̇_i = f(β_i) ξ / r_w + d β̇_i / r_w,     f(β) = [cos β, sin β, d − h_y cos β + h_x sin β].

(``wbc.robots.SteerableBase`` models the offset as a trailing caster instead, whose steering
rates follow from the twist; the paper's controller chooses the steering itself, so this module
uses the paper's model.)

ICR representation. The instantaneous centre of rotation of a twist is the point
``(−v_y/ω, v_x/ω)``; we use its homogeneous unit vector ``X ∝ (−v_y, v_x, ω)``, finite for pure
translations (``X₃ = 0``, the "border" of the paper's Cartesian ICR space) and defined up to
sign. Wheel ``i``'s steering angle is the direction of ``w_i(X) = (X₁ − h_x X₃, X₂ − h_y X₃)``
(the hip-to-ICR direction) minus π/2 — the paper's ``β_i = atan2(Y − h_y, X − h_x) − π/2`` —
taken modulo π (a wheel reverses its drive rather than turning half a turn).

The tick (:meth:`SteerableController.step`), for a desired twist ``ξ*``:

1. ``X*`` of ``ξ*``. *Route*: of ``±X*`` (the same ICR) the one nearer the current ``X`` is
   taken. When the way there crosses ``X₃ = 0`` the ICR passes through infinity — the paper's
   *complementary route* through the borders of the Cartesian ICR space; otherwise it is the
   *direct* route. Both are the same straight move on the sphere of homogeneous ICRs.
2. ICR velocity controller: ``X_ref = X + λ_ICR t_s (X* − X)``.
3. Next-sample ICR as a QP (a :class:`wbc.Stack`, any backend): ``X_next = X + T u`` with
   ``T`` an orthonormal basis of the tangent plane at ``X`` and ``u ∈ R²`` the decision,
   minimising ``||X + T u − X_ref||²`` under two linear constraints per steer joint: ``w_i``
   stays in the cone between the directions ``β_i + π/2 + δ_lo,i`` and ``β_i + π/2 + δ_hi,i``
   (the paper's "two straight lines per joint"; cones are invariant to scaling ``X``, so the
   constraints are exact, not linearised). The rate cones (``δ = ±β̇max t_s``) are hard. The
   acceleration cones (``[δ_lo, δ_hi] = t_s · [β̇_i − β̈max t_s, β̇_i + β̈max t_s]``) are soft,
   at a priority above the tracking: the four wheels share one ICR (two degrees of freedom for
   eight cones), and when they cannot all be kept the least violation is taken (the tick is
   reported: ``SteerStep.relaxed``, ``acceleration_relaxed``). Each wheel's cone is the half
   facing the reference ICR, so the ICR may cross a hip; if that is infeasible, the half of
   the current ICR (``u = 0`` is then feasible).
4. Steering angles of ``X_next`` (nearest representative modulo π; a wheel whose hip is the
   ICR brakes its steering within the acceleration limit), ``β̇_ref`` by numerical
   differentiation.
5. Drive controller: ``ξ_init = ξ̂ + t_s K_p (ξ* − ξ̂)`` (one Euler step of
   ``ξ̈ = K_p (ξ* − ξ̂)``), projected onto the null space of the next sample's lateral rows —
   the span of the twist direction ``(X₂, −X₁, X₃)`` of ``X_next``: the *feasible* twist
   ``q̇_bf``, scaled uniformly into the base's twist limits (``base.v_max``: the performance
   limits the paper's controller respects; scaling keeps the ICR). ``ξ̂`` is then ``q̇_bf``
   (the wheels are assumed to track their rates).
6. Wheel rates by the inverse actuation model.

The fast path (``SteerableController(fused="auto")``, the default with a C compiler): the whole
tick as one generated C function (:func:`~wbc.papers.sorour.steering_code.steering_function`),
its ICR QP in closed form where that is the ordinary path's answer; the other ticks (relaxed
accelerations, near-ties the ordinary path's daqp may break either way) take the ordinary path,
whose QP is a :class:`wbc.Stack` on ``backend`` (``fused=False`` always). See
:mod:`wbc.papers.sorour.steering_code`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

import wbc
from wbc.cbuild import compiled_c
from wbc.checks import checked_number, checked_vector
from wbc.errors import InvalidValueError
from wbc.qp import Status
from wbc.robots.steerable import SteerableBase
from wbc.sim.actuation import Actuation

from .steering_code import fast_path_allowed, steering_function

__all__ = ["MPO700_STEER_LIMITS", "SteerStep", "SteerableController", "SteerableDrive",
           "drive_rates", "icr_of_twist", "scale_into", "steering_of_icr"]

#: ``(β̇max [rad/s], β̈max [rad/s²])`` assumed for the MPO700's steer joints. Neither the paper
#: nor the data sheet we could consult offline gives them; 1 rad/s and 3 rad/s² are a
#: documented estimate (a steer motor turning a quarter-turn in about 1.6 s from rest).
MPO700_STEER_LIMITS = (1.0, 3.0)


def icr_of_twist(twist) -> np.ndarray | None:
    """Homogeneous unit ICR ``X ∝ (−v_y, v_x, ω)`` of a body twist, or ``None`` for a zero
    twist (which has no ICR)."""
    vx, vy, omega = twist
    h = np.array([-vy, vx, omega], dtype=float)
    norm = float(np.linalg.norm(h))
    return None if norm < 1e-12 else h / norm


def steering_of_icr(hips: np.ndarray, icr: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Steering angles [rad] whose hip velocities are perpendicular to the hip-to-ICR lines,
    each the representative modulo π nearest to ``current`` (a wheel at the ICR keeps its
    angle).

    Args:
        hips: ``(N, 2)`` hip positions [m]; icr: homogeneous ICR ``(3,)``; current: ``(N,)``.
    """
    w = icr[:2][None, :] - hips * icr[2]
    beta = np.arctan2(w[:, 1], w[:, 0]) - math.pi / 2
    beta = current + _wrap_half(beta - current)
    at_icr = np.linalg.norm(w, axis=1) < 1e-9
    beta[at_icr] = current[at_icr]
    return beta


def drive_rates(hips: np.ndarray, offset: float, radius: float, steering, steer_rates,
                twist) -> np.ndarray:
    """Inverse actuation model (Sorour §IV): ``φ̇_i = f(β_i) ξ / r_w + d β̇_i / r_w`` [rad/s]."""
    c, s = np.cos(steering), np.sin(steering)
    f = np.column_stack([c, s, offset - hips[:, 1] * c + hips[:, 0] * s])
    return (f @ np.asarray(twist, dtype=float) + offset * np.asarray(steer_rates)) / radius


def scale_into(twist, limits) -> np.ndarray:
    """``twist`` scaled uniformly (its direction, hence its ICR, kept) so that
    ``|twist_i| <= limits_i``."""
    twist = np.asarray(twist, dtype=float)
    ratio = np.max(np.abs(twist) / np.asarray(limits, dtype=float))
    return twist / ratio if ratio > 1.0 else twist.copy()


#: the route of :class:`SteerStep` by the generated tick's route code
_ROUTES = ("none", "direct", "complementary")


def _wrap_half(angle):
    """Wrap to [−π/2, π/2)."""
    return np.remainder(np.asarray(angle) + math.pi / 2, math.pi) - math.pi / 2


def _tangent_basis(x: np.ndarray) -> np.ndarray:
    """``(3, 2)`` orthonormal basis of the plane orthogonal to the unit vector ``x``."""
    a = np.eye(3)[int(np.argmin(np.abs(x)))]
    t1 = np.cross(x, a)
    t1 /= np.linalg.norm(t1)
    return np.column_stack([t1, np.cross(x, t1)])


@dataclass
class SteerStep:
    """One tick of :class:`SteerableController`.

    Attributes:
        twist: feasible body twist ``q̇_bf`` ``(v_x, v_y, ω)`` [m/s, m/s, rad/s].
        steering: steering angles after the tick [rad], ``(N,)``.
        steer_rates: ``β̇_ref`` [rad/s], ``(N,)``; steer_accelerations: ``β̈`` [rad/s²].
        drive_rates: ``φ̇_ref`` [rad/s], ``(N,)``.
        icr: homogeneous ICR after the tick ``(3,)``.
        route: ``"direct"``, ``"complementary"`` or ``"none"`` (zero desired twist: the ICR is
            held, the steering decelerates).
        qp_status: status of the ICR QP (``"solved"``, or the failure).
        relaxed: whether a steer acceleration exceeds ``β̈max`` this tick (the soft acceleration
            cones could not all be kept).
        qp_s: wall time of the ICR QP [s].
    """

    twist: np.ndarray
    steering: np.ndarray
    steer_rates: np.ndarray
    steer_accelerations: np.ndarray
    drive_rates: np.ndarray
    icr: np.ndarray
    route: str
    qp_status: str
    relaxed: bool
    qp_s: float


class SteerableController:
    """Sorour et al.'s motion-discontinuity-robust controller of a steerable base (§IV).

    Args:
        base: the :class:`~wbc.robots.SteerableBase` (hips, offset ``d``, radius ``r_w``).
        dt: sample period ``t_s`` [s] (Table I: 0.025).
        steer_rate: ``β̇max`` [rad/s]; steer_acceleration: ``β̈max`` [rad/s²]
            (default :data:`MPO700_STEER_LIMITS`).
        icr_gain: ``λ`` of the ICR velocity controller [1/s]; not given in the paper, 10 chosen
            (the ICR reference closes a quarter of the gap per 25 ms tick).
        drive_gain: ``K_p`` of the drive controller [1/s] (Table I: 2).
        backend: QP backend of the ICR QP; profile: its tolerance profile.
        steering: initial steering angles [rad] (default: zeros, i.e. the ICR of a pure
            forward translation).
        fused: the fast path (module docstring): ``"auto"`` (default) on daqp with a C
            compiler, ``True`` the same or an error, ``False`` the ordinary path only.

    Attributes:
        state: ``[β (N) [rad], β̇ (N) [rad/s], ξ̂ (3), X (3)]``, the controller's state (each
            tick writes it in place, the generated tick reads it); :attr:`steering`,
            :attr:`steer_rates`, :attr:`twist` and :attr:`icr` are copies of its parts, which
            a later tick never rewrites.
        constants: ``[t_s, β̇max, β̈max, λ_ICR, K_p, d, r_w, v_max (3), hips (N × 2)]``, the
            generated tick's constants.
        fused: whether the fast path is on; fallback_steps: its ticks the ordinary path took.
    """

    def __init__(self, base: SteerableBase, dt: float = 0.025,
                 steer_rate: float = MPO700_STEER_LIMITS[0],
                 steer_acceleration: float = MPO700_STEER_LIMITS[1], icr_gain: float = 10.0,
                 drive_gain: float = 2.0, backend: str = "daqp", profile: str = "default",
                 steering=None, fused: bool | str = "auto") -> None:
        if fused not in (True, False, "auto"):
            raise InvalidValueError(f"fused must be True, False or 'auto', got {fused!r}")
        dt = checked_number(dt, "dt", strict=True)
        steer_rate = checked_number(steer_rate, "steer_rate", strict=True)
        steer_acceleration = checked_number(steer_acceleration, "steer_acceleration", strict=True)
        icr_gain = checked_number(icr_gain, "icr_gain", strict=True)
        drive_gain = checked_number(drive_gain, "drive_gain", strict=True)
        if steer_rate * dt >= math.pi / 4:
            raise InvalidValueError(f"steer_rate * dt must be < π/4 (one tick's cone), got "
                                    f"{steer_rate * dt}")
        self.base = base
        self.hips = base.hips
        self.dt = float(dt)
        self.steer_rate = float(steer_rate)
        self.steer_acceleration = float(steer_acceleration)
        self.icr_gain = float(icr_gain)
        self.drive_gain = float(drive_gain)
        n = base.n_wheels
        # priority 0: acceleration cones, soft (least violation); priority 1: track X_ref;
        # hard at both: rate cones.
        stack = wbc.Stack(wbc.Variables(icr=2), min_norm=False)  # level 1 is strictly convex
        u = stack.variables.symbol
        cones = {}
        for name in ("steer_acceleration", "steer_rate"):
            C = stack.parameter(f"{name}.C", (2 * n, 2), np.zeros((2 * n, 2)))
            upper = stack.parameter(f"{name}.upper", 2 * n, np.zeros(2 * n))
            cones[name] = wbc.Inequality(C @ u, -np.inf, upper, name)
        stack.add(cones["steer_acceleration"], priority=0)
        T = stack.parameter("icr_ref.A", (3, 2), np.zeros((3, 2)))
        stack.add(wbc.Cost(T @ u, stack.parameter("icr_ref.b", 3, np.zeros(3)), 1.0, "icr_ref"),
                  priority=1)
        stack.constrain(cones["steer_rate"])
        self.stack = stack
        self.workspace = stack.workspace(backend, profile)
        view = self.workspace.view
        self._A, self._b = view("icr_ref.A"), view("icr_ref.b")
        self._rows = {name: (view(f"{name}.C"), view(f"{name}.upper"))
                      for name in ("steer_acceleration", "steer_rate")}
        self.state = np.zeros(2 * n + 6)
        self.constants = np.concatenate([
            [self.dt, self.steer_rate, self.steer_acceleration, self.icr_gain, self.drive_gain,
             base.offset, base.radius], base.v_max, self.hips.ravel()]).astype(float)
        self.reset(steering)
        self.fallback_steps = 0
        self.fused = self._fast_path(fused, backend)

    def _fast_path(self, fused, backend: str) -> bool:
        """Bind the generated tick to this controller's buffers if ``fused`` allows it."""
        if not fast_path_allowed(fused, backend, "the steering controller"):
            return False
        n = self.base.n_wheels
        self._desired, self._next = np.zeros(3), np.zeros(2 * n + 6)
        self._accelerations, self._wheels, self._info = np.zeros(n), np.zeros(n), np.zeros(3)
        self._buffer, self._call = compiled_c(steering_function(n)).buffer()
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        for i, array in enumerate((self._desired, self.state, self.constants)):
            self._buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        for i, array in enumerate((self._next, self._accelerations, self._wheels, self._info)):
            self._buffer.set_res(i, memoryview(array))  # type: ignore[call-arg, arg-type]
        return True

    @property
    def steering(self) -> np.ndarray:
        """Steering angles β [rad] (N,), a copy of :attr:`state`'s part."""
        return self.state[:self.base.n_wheels].copy()

    @property
    def steer_rates(self) -> np.ndarray:
        """β̇ of the last tick [rad/s] (N,), a copy of :attr:`state`'s part."""
        n = self.base.n_wheels
        return self.state[n:2 * n].copy()

    @property
    def twist(self) -> np.ndarray:
        """The last feasible twist ``ξ̂`` [m/s, m/s, rad/s], a copy of :attr:`state`'s part."""
        n = self.base.n_wheels
        return self.state[2 * n:2 * n + 3].copy()

    @property
    def icr(self) -> np.ndarray:
        """The homogeneous ICR ``X`` (3,), a copy of :attr:`state`'s part."""
        return self.state[2 * self.base.n_wheels + 3:].copy()

    def reset(self, steering=None) -> None:
        """Back to rest with the given steering angles [rad] (default zeros)."""
        n = self.base.n_wheels
        angles = (np.zeros(n) if steering is None
                  else checked_vector(steering, n, "steering", broadcast=False))
        self.state[:n] = angles
        self.state[n:2 * n + 3] = 0.0  # at rest
        # the ICR of the steering: forward translation for zeros
        self.state[2 * n + 3:] = _icr_of_steering(self.hips, angles)
        self.acceleration_relaxed = 0

    # ------------------------------------------------------------------ the tick
    def step(self, desired_twist) -> SteerStep:
        """One sample period for the desired body twist ``ξ*`` [m/s, m/s, rad/s]."""
        if self.fused:
            self._desired[...] = checked_vector(desired_twist, 3, "desired_twist",
                                                broadcast=False)
            t0 = time.perf_counter()
            self._call()
            qp_s = time.perf_counter() - t0
            if self._info[0] == 1.0:
                relaxed = bool(self._info[2])
                self.state[...] = self._next
                self.acceleration_relaxed += relaxed
                return SteerStep(self.twist, self.steering, self.steer_rates,
                                 self._accelerations.copy(), self._wheels.copy(), self.icr,
                                 _ROUTES[int(self._info[1])], "solved", relaxed, qp_s)
            self.fallback_steps += 1
        return self.ordinary_step(desired_twist)

    def ordinary_step(self, desired_twist) -> SteerStep:
        """:meth:`step` on the ordinary path whatever :attr:`fused` is: numpy around the ICR
        QP on the backend (what the fast path hands a tick to)."""
        desired_twist = checked_vector(desired_twist, 3, "desired_twist", broadcast=False)
        target = icr_of_twist(desired_twist)
        x = self.icr
        route, x_ref = "none", x  # no desired ICR: hold it (the steering decelerates)
        if target is not None:
            if float(target @ x) < 0.0:  # ±X* is the same ICR: take the nearer one
                target = -target
            # crossing X₃ = 0 is passing through infinity: the paper's complementary route
            route = "complementary" if target[2] * x[2] < 0.0 else "direct"
            x_ref = x + self.icr_gain * self.dt * (target - x)
        t0 = time.perf_counter()
        x_next, status = self._next_icr(x, x_ref)
        qp_s = time.perf_counter() - t0
        beta = steering_of_icr(self.hips, x_next, self.steering)
        # A wheel whose hip is the ICR may take any angle (its hip does not move): it brakes
        # its steering as fast as the acceleration limit allows.
        at_icr = np.linalg.norm(x_next[:2][None, :] - self.hips * x_next[2], axis=1) < 1e-9
        if at_icr.any():
            braked = np.clip(0.0, self.steer_rates - self.steer_acceleration * self.dt,
                             self.steer_rates + self.steer_acceleration * self.dt)
            beta[at_icr] = (self.steering + self.dt * braked)[at_icr]
        rates = (beta - self.steering) / self.dt
        accelerations = (rates - self.steer_rates) / self.dt
        # 1e-4 relative: the QP meets its cones to its tolerance
        relaxed = bool(np.any(np.abs(accelerations) > self.steer_acceleration * (1 + 1e-4)))
        # drive controller: one Euler step of K_p (ξ* − ξ̂), projected on the next ICR's twist
        initial = self.twist + self.dt * self.drive_gain * (desired_twist - self.twist)
        direction = np.array([x_next[1], -x_next[0], x_next[2]])
        feasible = scale_into(direction * float(direction @ initial), self.base.v_max)
        wheels = drive_rates(self.hips, self.base.offset, self.base.radius, beta, rates,
                             feasible)
        self.state[...] = np.concatenate([beta, rates, feasible, x_next])
        self.acceleration_relaxed += relaxed
        return SteerStep(feasible.copy(), beta.copy(), rates.copy(), accelerations, wheels,
                         x_next.copy(), route, status, relaxed, qp_s)

    def _next_icr(self, x: np.ndarray, x_ref: np.ndarray) -> tuple[np.ndarray, str]:
        """Solve the ICR QP; returns ``(X_next, status)`` (``X`` itself if it failed).

        Tries the half-cones facing the reference (so the ICR may cross a hip), then those of the
        current ICR (feasible: ``u = 0``).
        """
        T = _tangent_basis(x)
        self._A[...] = T
        self._b[:, 0] = x_ref - x
        dt = self.dt
        rate = self.steer_rate * dt
        lo = np.maximum(-rate, (self.steer_rates - self.steer_acceleration * dt) * dt)
        hi = np.minimum(rate, (self.steer_rates + self.steer_acceleration * dt) * dt)
        full = np.full_like(lo, rate)
        for facing in (x_ref, x):  # the second is feasible: u = 0
            self._cones("steer_acceleration", x, facing, T, lo, hi)
            self._cones("steer_rate", x, facing, T, -full, full)
            solution = self.workspace.solve()
            if solution.status is Status.SOLVED:
                x_next = x + T @ solution.x
                return x_next / np.linalg.norm(x_next), "solved"
        return x, solution.status.value

    def _cones(self, name, x, facing, T, lo, hi) -> None:
        """Rows ``C u <= upper`` of constraint ``name``: ``w_i(X + T u)`` between the directions
        ``a_lo, a_hi`` of the half-cone on the side of the ICR ``facing``; each row is divided
        by ``|w_i(X)|`` so that a soft row's slack is about an angle [rad]."""
        C, upper = self._rows[name]
        hips = self.hips
        heading = self.steering + math.pi / 2  # direction of w_i for the current steering
        w_ref = facing[:2][None, :] - hips * facing[2]
        e = np.column_stack([np.cos(heading), np.sin(heading)])
        side = np.where(np.sum(e * w_ref, axis=1) < 0.0, math.pi, 0.0)  # which half-cone
        scale = 1.0 / np.maximum(np.linalg.norm(x[:2][None, :] - hips * x[2], axis=1), 1e-3)
        for k, (angles, sign) in enumerate(((heading + side + lo, -1.0),
                                            (heading + side + hi, 1.0))):
            u = np.column_stack([np.cos(angles), np.sin(angles)])
            # cross(u, w) = r · X with r = (−u_y, u_x) P_i, P_i = [[1, 0, −h_x], [0, 1, −h_y]]
            r = np.column_stack([-u[:, 1], u[:, 0],
                                 u[:, 1] * hips[:, 0] - u[:, 0] * hips[:, 1]])
            # a_lo: cross(u_lo, w) >= 0  ->  −r T u <= r X ; a_hi: cross(u_hi, w) <= 0
            rows = slice(k * len(hips), (k + 1) * len(hips))
            r *= scale[:, None]
            C[rows] = sign * (r @ T)
            upper[rows, 0] = -sign * (r @ x)


def _icr_of_steering(hips: np.ndarray, steering: np.ndarray) -> np.ndarray:
    """Homogeneous ICR common to the wheels' hip normals (least squares), ``X₃ >= 0``."""
    e = np.column_stack([np.cos(steering), np.sin(steering)])
    rows = np.column_stack([e, -np.sum(e * hips, axis=1)])
    x = np.linalg.svd(rows)[2][-1]
    return -x if (x[2] < 0.0 or (x[2] == 0.0 and x[0] < 0.0)) else x


class SteerableDrive(Actuation):
    """Actuation model for :mod:`wbc.sim`: the base moves at the feasible twist of a
    :class:`SteerableController` fed with the commanded base twist (the arm as commanded).

    Args:
        controller: the steering controller (its state is this model's state; ``reset`` with
            the simulation).
        steering: initial steering angles [rad] at every reset.

    Per tick it writes the signals ``"steer_rate_max"`` (max ``|β̇|`` [rad/s]),
    ``"steer_acceleration_max"`` (max ``|β̈|`` [rad/s²]) and ``"icr_qp_s"`` (QP time [s]).
    """

    def __init__(self, controller: SteerableController, steering=None) -> None:
        self.controller = controller
        self._steering = steering

    def reset(self, robot, dt: float) -> None:
        self.controller.reset(self._steering)

    def apply(self, state) -> None:
        step = self.controller.step(state.v_command[:3])
        state.v_true = np.concatenate([step.twist, state.v_command[3:]])
        state.v_measured = state.v_true.copy()
        state.signals["steer_rate_max"] = float(np.abs(step.steer_rates).max())
        state.signals["steer_acceleration_max"] = float(np.abs(step.steer_accelerations).max())
        state.signals["icr_qp_s"] = step.qp_s
