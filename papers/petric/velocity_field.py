r"""Petrič & Žlajpah's spatially modulated velocity field (paper 001, eqs. 4–19).

A nonholonomic base (inputs ``u = (v [m/s], ω [rad/s])``, kinematics eqs. 1–3) is driven only by
the translational end-effector point ``p = (x, y, z)`` [m] of a reduced arm model, expressed in the
base frame with the arm root at its origin (``c = (0, 0, l0)`` is the shoulder).

Pipeline of one tick (:meth:`VelocityField.step`):

1. geometry (:meth:`~VelocityField.distances`): ``d_f = r_f − |p − c|`` (eq. 4, ``r_f = l1 + l2``),
   ``d_r`` the signed distance to the base's capsule (eq. 6), ``φ = atan2(y, x)``;
2. heading latch (:meth:`~VelocityField.update_heading`): on entering the retreat zone
   (``d_r < Δ_r``) the target heading ``φ_t = −sign(φ)·|φ_t|`` is computed once (eq. 11) and
   held until the point leaves the zone;
3. raw laws (:meth:`~VelocityField.raw`): ``v`` of eq. 7, ``ω`` of eqs. 8–13;
4. exponential smoothing against the previous applied command (eqs. 14–15,
   :meth:`~VelocityField.smooth`);
5. rate limit then saturation (eqs. 16–18): the two-stage clip, written out here (tasks import
   no solver; its closed form, the tests' oracle, is
   :func:`wbc.papers.petric.closed_form.rate_limited_twist`); the same stage as a QP level a
   stack can carry: :meth:`~VelocityField.rate_limit_level`.

The same tick as a CasADi expression (:meth:`~VelocityField.symbolic_step`, branches as
``if_else``, the latched heading in :attr:`~VelocityField.state`) is what the controllers'
fast path compiles (:class:`wbc.papers.petric.FieldDriver`).

**Readings of the printed equations** (decided here, each tested):

* *Eq. 6 sign.* The paper prints ``d_r = b_d − |·|``, which is large next to the base and negative
  far from it, so ``d_r < Δ_r`` would make the base retreat from a *distant* end-effector. The
  text (retreat when the point "encroaches too close to the base"; eq. 20's argument that backward
  motion *increases* ``d_r``) needs the distance *outside* the capsule:
  ``d_r = |p_⊥| − b_d`` for ``z ≤ l0`` and ``|p − c| − b_d`` for ``z > l0`` (continuous at
  ``z = l0``).
* *Eq. 11.* It prints ``φ_t = −sign(φ)·φ_max``; the experiments use ``|φ_t| = 30°`` (``φ_max`` is
  45°), so ``|φ_t|`` is its own parameter ``phi_t``. ``sign(0)`` is taken as ``+1`` here (an
  entry straight ahead turns to ``φ_t = −|φ_t|``), so the latched heading is never 0.
* *Eq. 12.* It prints ``s = (d_r − (Δ_r − ε))/ε``, which runs the smoothstep backwards
  (``η`` would jump 0 → 1 at ``d_r = Δ_r`` and 1 → 0 at ``Δ_r − ε``). The text asks for ``η = 0``
  at the boundary and ``η = 1`` at depth ``ε``: ``s = (Δ_r − d_r)/ε``.
* *Eq. 10* is used as printed: ``ω_r = −sign(φ_t − φ)·ω_max·η`` with the difference *not* wrapped
  to (−π, π] (a bang-bang turn towards ``φ_t``; ``sign(0) = 0`` there).
* *Eqs. 14–17.* ``v_{k−1}`` is the command applied at the previous tick (after limiting), as the
  text says; the rate limits are changes per tick (``Δv_max`` [m/s per tick]), independent of the
  tick length, as printed.

**Where the field is not continuous** (reported, tested as counterexamples): across the mode
boundary ``d_r = Δ_r`` (by design: ``v`` jumps from ``K_f(Δ_f − d_f)`` to 0 where the forward
zone reaches the retreat zone, and ``ω_n`` is cut off); within the nominal mode across the ray
behind the base (``φ = ±π``: ``ω_n`` flips from ``+K_ω`` to ``−K_ω``) and at the vertical axis
above the capsule (``φ`` undefined); within the retreat zone across ``φ = φ_t`` (the bang-bang
sign of eq. 10), ``φ = ±π`` and the vertical axis, and — without a latched heading — across
``φ = 0``, wherever ``η > 0``. Everywhere else ``v`` and ``ω`` are Lipschitz in ``p``.

**Retreat-region invariance** (§II-A.2), with the TEE held fixed in the world (with the arm's
joints frozen instead, ``p`` is constant in the base frame and the property is vacuous): the
rate of ``d_r`` is ``−v·x/ρ`` (ω does not change it), so the retreat law's ``v < 0`` pushes
the point out only while it is in front of the axle (``x > 0``); behind it the retreat drives
the base onto the point. Starting outside (``d_r ≥ Δ_r``) from rest, the base moves only
forward, so the zone can only be entered by forward motion: where the forward zone
``d_f < Δ_f`` reaches it (below ``z ≈ −0.055`` m with the defaults) or lies within the few cm
the smoothing lag coasts (``≈ 3·v·dt``). Below, the forward law drives the base into the zone
(``v = K_f(Δ_f − d_f) > 0`` on its boundary) and the smoothing lag carries it further:
1.2–1.7 cm deep in 10 ms loops with an ideal base over random placements, after which it
settles on the boundary from inside; in the study's own loop (50 Hz, the base behind a 0.1 s
lag and the PMB2's saturation) up to 11.6 cm, the deepest from the floor's height at start
clearances of 0.3–0.45 m (:mod:`~wbc.papers.petric.invariance`, claim ``retreat_invariance``
of ``wbc study petric``). For ``z ≥ 0`` (the zones ≥ 4.5 cm apart) no sampled run entered the
zone. The tests give the counterexamples.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from wbc.checks import all_finite, as_float_array, checked_name, checked_number
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError
from wbc.terms import Cost, VariableBounds

__all__ = ["VelocityField", "smoothstep"]

_DEG30, _DEG45 = math.radians(30.0), math.radians(45.0)


def smoothstep(s):
    """``3s² − 2s³`` of ``s`` clipped to ``[0, 1]`` (eqs. 9 and 12 with their outer branches);
    a float for a float (the control tick's path), an array for an array, a CasADi expression
    for one (the compiled tick, :meth:`VelocityField.symbolic_step`)."""
    if isinstance(s, (int, float)):
        s = min(max(s, 0.0), 1.0)
    elif isinstance(s, ca.SX):
        s = ca.fmin(ca.fmax(s, 0.0), 1.0)
    else:
        s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _sign(x: float) -> float:
    """``sign(x)`` with ``sign(0) = 0``, as eqs. 8 and 10 print it."""
    return float((x > 0.0) - (x < 0.0))


class VelocityField:
    """The base policy of Petrič & Žlajpah: ``p`` (TEE point [m], base frame) → ``(v, ω)``.

    Keyword parameters (defaults: §IV of the paper unless marked *ours*; lengths [m], angles
    [rad], gains [1/s], velocities [m/s] and [rad/s]):

    Args:
        l0, l1, l2: reduced arm: shoulder height over the arm root, upper arm, forearm
            (0.333, 0.328, 0.394 as printed in §IV). ``r_f = l1 + l2``.
        b_d: radius of the base's capsule, from the base centre to its front (*ours*: 0.27 m,
            the radius of Tiago's round PMB2 base, 0.54 m across; the paper gives no value).
        k_f, k_r, k_omega: forward, retreat and heading gains ``K_f = K_r = 2``, ``K_ω = 1``.
        delta_f, delta_r: activation thresholds ``Δ_f = Δ_r = 0.15`` m on ``d_f``, ``d_r``.
        phi_min, phi_max: heading dead band and full-activation angle (30°, 45°).
        phi_t: magnitude of the retreat heading ``|φ_t|`` (30°; eq. 11 prints ``φ_max``).
        epsilon: depth [m] over which the retreat rotation ramps in (*ours*: 0.05 m, "a few cm";
            the paper gives no value).
        v_max: speed limit (*ours*: 1.0 m/s, Tiago's top speed — the URDF's wheel limit
            10.15 rad/s × 0.0985 m; the paper gives no value).
        omega_max: yaw-rate limit and retreat turn rate ``ω_max = 1`` rad/s.
        alpha: smoothing coefficient ``α = 0.25`` of eqs. 14–15, in ``(0, 1]`` (1: no smoothing).
        dv_max, domega_max: largest change of ``v``, ``ω`` per tick (1.0 and 1.0).

    State (of :meth:`step`): the previous applied command :attr:`command` and the latched
    retreat heading :attr:`heading` (``None`` outside the retreat zone), both kept in
    :attr:`state` ``(v, ω, heading, latched)``; :meth:`reset` clears it.

    Example:
        >>> field = VelocityField()
        >>> [round(u, 3) for u in field.raw([0.8, 0.0, 0.3])]  # far ahead: drive forward
        [0.457, 0.0]
    """

    def __init__(self, *, l0=0.333, l1=0.328, l2=0.394, b_d=0.27, k_f=2.0, k_r=2.0, k_omega=1.0,
                 delta_f=0.15, delta_r=0.15, phi_min=_DEG30, phi_max=_DEG45, phi_t=_DEG30,
                 epsilon=0.05, v_max=1.0, omega_max=1.0, alpha=0.25, dv_max=1.0,
                 domega_max=1.0) -> None:
        self.l0 = checked_number(l0, "l0", 0.0, strict=False)
        self.l1 = checked_number(l1, "l1", 0.0, strict=True)
        self.l2 = checked_number(l2, "l2", 0.0, strict=True)
        self.b_d = checked_number(b_d, "b_d", 0.0, strict=False)
        self.k_f = checked_number(k_f, "k_f", 0.0, strict=False)
        self.k_r = checked_number(k_r, "k_r", 0.0, strict=False)
        self.k_omega = checked_number(k_omega, "k_omega", 0.0, strict=False)
        self.delta_f = checked_number(delta_f, "delta_f", low=None)
        self.delta_r = checked_number(delta_r, "delta_r", low=None)
        self.phi_min = checked_number(phi_min, "phi_min", 0.0, strict=False)
        self.phi_max = checked_number(phi_max, "phi_max", self.phi_min, strict=True)
        if self.phi_max > math.pi:
            raise InvalidValueError(f"phi_max must be <= pi, got {self.phi_max}")
        self.phi_t = checked_number(phi_t, "phi_t", 0.0, strict=True)
        if self.phi_t > math.pi:
            raise InvalidValueError(f"phi_t must be <= pi, got {self.phi_t}")
        self.epsilon = checked_number(epsilon, "epsilon", 0.0, strict=True)
        self.v_max = checked_number(v_max, "v_max", 0.0, strict=True)
        self.omega_max = checked_number(omega_max, "omega_max", 0.0, strict=True)
        self.alpha = checked_number(alpha, "alpha", 0.0, strict=True)
        if self.alpha > 1.0:
            raise InvalidValueError(f"alpha must be <= 1, got {self.alpha}")
        self.dv_max = checked_number(dv_max, "dv_max", 0.0, strict=True)
        self.domega_max = checked_number(domega_max, "domega_max", 0.0, strict=True)
        self.r_f = self.l1 + self.l2
        self.limit = np.array([self.v_max, self.omega_max])
        self.rate_limit = np.array([self.dv_max, self.domega_max])
        # (v, ω) applied at the previous tick, the latched heading [rad] and whether one is
        # latched (1.0) or not (0.0): one array, which the compiled tick reads in place
        self.state = np.zeros(4)
        self.reset()

    # ------------------------------------------------------------------ geometry and raw laws
    # The laws are written once, for one point in plain floats (a control tick costs a few µs
    # instead of the ~50 µs of numpy on 0-d arrays); arrays of points map them element-wise.
    @staticmethod
    def _points(p) -> np.ndarray:
        arr = as_float_array(p, "p")
        if arr.ndim == 0 or arr.shape[-1] != 3:
            raise ShapeError(f"p must have shape (3,) or (..., 3), got {arr.shape}")
        if not all_finite(arr.reshape(-1)):
            raise NonFiniteError("p holds NaN or inf")
        return arr

    def _geometry(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        planar = math.hypot(x, y)
        to_shoulder = math.hypot(planar, z - self.l0)
        d_r = (planar if z <= self.l0 else to_shoulder) - self.b_d         # eq. 6 (sign: above)
        return self.r_f - to_shoulder, d_r, math.atan2(y, x)               # eq. 4

    def _laws(self, d_f: float, d_r: float, phi: float, heading: float | None):
        """Eqs. 7-13 from the geometry; ``heading`` ``None``: eq. 11 from ``phi`` itself."""
        if d_r < self.delta_r:                                              # eq. 13: retreat
            if heading is None:
                heading = self.retreat_heading(phi)
            eta = smoothstep((self.delta_r - d_r) / self.epsilon)          # eq. 12 (s: above)
            return (-self.k_r * (self.delta_r - d_r),                      # eq. 7
                    -_sign(heading - phi) * self.omega_max * eta)          # eq. 10
        v = self.k_f * (self.delta_f - d_f) if d_f < self.delta_f else 0.0  # eq. 7
        gamma = smoothstep((abs(phi) - self.phi_min) / (self.phi_max - self.phi_min))
        return v, self.k_omega * _sign(phi) * gamma                         # eqs. 8-9

    def distances(self, p):
        """``(d_f, d_r, φ)`` at ``p`` [m] ((3,) or (..., 3)): signed distances [m] to the reach
        sphere (positive inside) and to the base's capsule (positive outside), heading [rad];
        floats for one point, arrays of shape ``p.shape[:-1]`` otherwise."""
        p = self._points(p)
        if p.shape == (3,):
            return self._geometry(*p.tolist())
        return np.vectorize(self._geometry, otypes=[float] * 3)(p[..., 0], p[..., 1], p[..., 2])

    def retreat_heading(self, phi: float) -> float:
        """Eq. 11 with ``|φ_t|``: ``−sign(φ)·|φ_t|`` [rad], ``sign(0) = +1``."""
        return -self.phi_t if phi >= 0.0 else self.phi_t

    def raw(self, p, phi_t=None):
        """Eqs. 4–13: the raw command at ``p`` [m] ((3,) or (..., 3), base frame).

        Args:
            phi_t: the latched retreat heading [rad] in ``[−π, π]``; ``None``: computed from
                ``p`` by eq. 11 (``−sign(φ)·|φ_t|``). Used only inside the retreat zone.

        Returns:
            ``(v [m/s], ω [rad/s])``, floats for one point, arrays of shape ``p.shape[:-1]``
            otherwise. Not saturated: eq. 7 is proportional.
        """
        p = self._points(p)
        if phi_t is not None:
            phi_t = checked_number(phi_t, "phi_t", low=None)
            if abs(phi_t) > math.pi:
                raise InvalidValueError(f"phi_t must lie in [-pi, pi], got {phi_t}")

        def at(x, y, z):
            return self._laws(*self._geometry(x, y, z), phi_t)

        if p.shape == (3,):
            return at(*p.tolist())
        return np.vectorize(at, otypes=[float, float])(p[..., 0], p[..., 1], p[..., 2])

    # ------------------------------------------------------------------ the stateful tick
    def reset(self, command=(0.0, 0.0)) -> None:
        """Forget the latched heading and set the previous command ``(v, ω)`` (default rest)."""
        command = as_float_array(command, "command")
        if command.shape != (2,):
            raise ShapeError(f"command must have shape (2,), got {command.shape}")
        if not np.all(np.isfinite(command)):
            raise NonFiniteError("command holds NaN or inf")
        # written in place: a compiled tick reads this array (wbc.papers.petric.FieldDriver)
        self.state[:] = (command[0], command[1], 0.0, 0.0)

    @property
    def command(self) -> np.ndarray:
        """The previous applied command ``(v [m/s], ω [rad/s])`` (a copy of :attr:`state`'s)."""
        return self.state[:2].copy()

    @property
    def heading(self) -> float | None:
        """The latched retreat heading [rad], ``None`` outside the retreat zone."""
        return float(self.state[2]) if self.state[3] else None

    def _point(self, p) -> list[float]:
        p = self._points(p)
        if p.shape != (3,):
            raise ShapeError(f"p must have shape (3,), got {p.shape}")
        return p.tolist()

    def _latch(self, d_r, phi) -> float | None:
        state = self.state  # (item by item: cheaper than slices on a 2-vector)
        if d_r >= self.delta_r:
            state[2] = state[3] = 0.0
            return None
        if not state[3]:
            state[2], state[3] = self.retreat_heading(phi), 1.0
        return float(state[2])

    def update_heading(self, p) -> float | None:
        """Latch stage of :meth:`step`: on entering the retreat zone latch eq. 11's heading from
        the entry point's ``φ``; release it on leaving. Returns the heading [rad] or ``None``."""
        _, d_r, phi = self._geometry(*self._point(p))
        return self._latch(d_r, phi)

    def smooth(self, raw, previous) -> np.ndarray:
        """Eqs. 14–15: ``(1 − α)·previous + α·raw`` for ``(v, ω)`` pairs."""
        previous, raw = np.asarray(previous, float), np.asarray(raw, float)
        return (1.0 - self.alpha) * previous + self.alpha * raw

    def step(self, p) -> tuple[float, float]:
        """One control tick at the TEE point ``p`` [m] (3,): latch, raw laws, smoothing, rate
        limit and saturation (eqs. 4–19). Returns the applied ``(v [m/s], ω [rad/s])`` and keeps
        it as :attr:`command` for the next tick."""
        d_f, d_r, phi = self._geometry(*self._point(p))
        raw = self._laws(d_f, d_r, phi, self._latch(d_r, phi))
        previous = self.state[:2]
        smoothed = self.smooth(raw, previous)
        # eqs. 16-17, the two-stage clip; its closed form with checked arguments, the oracle
        # of the tests and of rate_limit_level, is wbc.papers.petric.closed_form's
        self.state[:2] = np.clip(previous + np.clip(smoothed - previous, -self.rate_limit,
                                                    self.rate_limit), -self.limit, self.limit)
        return float(self.state[0]), float(self.state[1])

    def symbolic_distances(self, p: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """:meth:`distances` as CasADi expressions of the TEE point ``p`` (3,) [m]: ``(d_f,
        d_r, φ)`` [m, m, rad], the same operations as :meth:`_geometry`."""
        x, y, z = p[0], p[1], p[2]
        planar = ca.hypot(x, y)
        to_shoulder = ca.hypot(planar, z - self.l0)
        d_r = ca.if_else(z <= self.l0, planar, to_shoulder) - self.b_d     # eq. 6
        return self.r_f - to_shoulder, d_r, ca.atan2(y, x)                 # eq. 4

    def symbolic_step(self, p: ca.SX, state: ca.SX) -> ca.SX:
        """:meth:`step` as a CasADi expression, for a tick compiled to C: the new :attr:`state`
        (4,) from the TEE point ``p`` (3,) [m] and the previous ``state`` (4,), the branches as
        ``if_else`` and the latch as the state's last two entries. The same operations as
        :meth:`_geometry`, :meth:`_latch`, :meth:`_laws` and :meth:`step` in the same order
        (``tests/test_petric_fast.py`` holds the two equal)."""
        d_f, d_r, phi = self.symbolic_distances(p)
        inside = d_r < self.delta_r                                         # eq. 13: retreat
        entry = ca.if_else(phi >= 0.0, -self.phi_t, self.phi_t)           # eq. 11
        heading = ca.if_else(inside, ca.if_else(state[3], state[2], entry), 0.0)
        eta = smoothstep((self.delta_r - d_r) / self.epsilon)              # eq. 12
        gamma = smoothstep((ca.fabs(phi) - self.phi_min) / (self.phi_max - self.phi_min))
        v = ca.if_else(inside, -self.k_r * (self.delta_r - d_r),           # eq. 7
                       ca.if_else(d_f < self.delta_f, self.k_f * (self.delta_f - d_f), 0.0))
        omega = ca.if_else(inside, -ca.sign(heading - phi) * self.omega_max * eta,  # eq. 10
                           self.k_omega * ca.sign(phi) * gamma)            # eqs. 8-9
        previous = state[:2]
        smoothed = (1.0 - self.alpha) * previous + self.alpha * ca.vertcat(v, omega)
        step = ca.fmin(ca.fmax(smoothed - previous, -self.rate_limit), self.rate_limit)
        command = ca.fmin(ca.fmax(previous + step, -self.limit), self.limit)
        return ca.vertcat(command, heading, ca.if_else(inside, 1.0, 0.0))

    # ------------------------------------------------------------------ eqs. 16-17 as a QP level
    def rate_limit_level(self, stack, priority: int = 0, block: str | None = None,
                         name: str = "base_rate_limit"):
        """Carry eqs. 16–17 in ``stack`` (docs/DESIGN.md, math note 5): at ``priority`` the cost
        ``½||u − û||²`` on the two entries ``u = (v, ω)`` of variable ``block``, and, hard at
        every level, the bounds ``clip(u_prev ∓ Δu_max, ±u_max)``
        (:func:`wbc.papers.petric.closed_form.rate_limit_interval`). Its minimiser is the
        two-stage clip :func:`~wbc.papers.petric.closed_form.rate_limited_twist`.

        Parameters set every tick: ``"<name>.target"`` — the smoothed command ``û``
        (:meth:`smooth` of :meth:`raw`), ``"<name>.previous"`` — the previous applied command.
        Both default to rest. The bounds are named ``"<name>.bounds"``.

        Returns:
            ``stack``.
        """
        name = checked_name(name, "name of rate_limit_level", optional=False)
        block = checked_name(block, "block of rate_limit_level")
        size = stack.variables.size(block) if block else stack.variables.n
        if size != 2:
            where = f"block {block!r}" if block else "the decision vector"
            raise ShapeError(f"rate_limit_level needs (v, omega): {where} has {size} entries")
        target = stack.parameter(f"{name}.target", 2, np.zeros(2))
        previous = stack.parameter(f"{name}.previous", 2, np.zeros(2))
        limit, rate = ca.DM(self.limit), ca.DM(self.rate_limit)
        lower = ca.fmin(ca.fmax(previous - rate, -limit), limit)
        upper = ca.fmin(ca.fmax(previous + rate, -limit), limit)
        u = stack.variables.symbol[stack.variables.slice(block)]
        stack.add(Cost(u, target, 1.0, name), priority=priority)
        stack.constrain(VariableBounds(lower, upper, block, f"{name}.bounds"))
        return stack
