r"""§II-A.2's retreat-region invariance in closed loop, over many placements at once.

The paper argues that the retreat law (``v < 0`` when ``d_r < Δ_r``) makes the safe region
``d_r ≥ Δ_r`` forward invariant "under the assumed kinematic base model". This module runs that
setting: the TEE held fixed in the world (an ideal arm; with the arm's joints frozen instead
``p`` would be constant in the base frame and the property vacuous), the base starting at rest,
driven by the field's tick (:meth:`VelocityField.symbolic_step`, the expression the controllers'
fast path compiles) through the base's velocity loop of :mod:`wbc.sim.actuation` — a
first-order :class:`~wbc.sim.actuation.Lag` then a :class:`~wbc.sim.actuation.Saturation` of
velocity and acceleration, in that order — and the unicycle of eqs. 1–3 integrated exactly
(arcs), one control period ``dt`` per tick. The placements are integrated side by side as
arrays (one mapped CasADi call per tick), which makes a grid of hundreds cost a fraction of a
second; ``tests/test_petric_fidelity.py`` holds it equal to :class:`wbc.sim.Simulation` on the
Tiago + Panda with the same chain.

Where invariance can fail (:mod:`~wbc.papers.petric.velocity_field`'s docstring): a base at
rest outside the zone moves only forward, so it enters the zone only where the forward zone
``d_f < Δ_f`` reaches it — below :func:`touch_height` — or by coasting on the lag.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from wbc.cbuild import compiled_c, compiler_available
from wbc.checks import as_float_array
from wbc.errors import InvalidValueError, ShapeError

from .velocity_field import VelocityField

__all__ = ["held_point_depths", "placements", "touch_height"]

HEIGHTS = (-0.30, -0.20, -0.10, -0.06, -0.05, 0.0, 0.15, 0.30, 0.60)
"""TEE heights [m] of :func:`placements`, from the arm root (−0.29 m is the floor)."""
BEARINGS_DEG = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 150.0, 180.0)
"""TEE bearings φ [deg] of :func:`placements` (the field is symmetric in y)."""
CLEARANCES = (0.001, 0.01, 0.03, 0.06, 0.10, 0.20, 0.30, 0.45)
"""Start distances ``d_r − Δ_r`` [m] outside the retreat zone of :func:`placements` (the first
just outside its boundary: on it, rounding may put the point inside by 1e-15 m)."""


def touch_height(field: VelocityField) -> float:
    """The height [m] below which the forward zone (``d_f < Δ_f``, outside the sphere of radius
    ``r_f − Δ_f`` about the shoulder) reaches the retreat zone's boundary (the cylinder of
    radius ``b_d + Δ_r``): ``l0 − √((r_f − Δ_f)² − (b_d + Δ_r)²)``; ``+inf`` when the cylinder
    is wider than the sphere (they touch at every height)."""
    sphere, cylinder = field.r_f - field.delta_f, field.b_d + field.delta_r
    if cylinder >= sphere:
        return math.inf
    return field.l0 - math.sqrt(sphere * sphere - cylinder * cylinder)


def placements(field: VelocityField) -> np.ndarray:
    """TEE points [m] (N, 3) in the field's frame at the start, on the grid
    :data:`HEIGHTS` × :data:`BEARINGS_DEG` × :data:`CLEARANCES`: each at ``d_r = Δ_r +
    clearance``, outside the retreat zone."""
    out = []
    for z in HEIGHTS:
        for bearing in BEARINGS_DEG:
            for clearance in CLEARANCES:
                reach = field.b_d + field.delta_r + clearance  # eq. 6's distance at the start
                above = max(z - field.l0, 0.0)                # above l0: to the shoulder
                planar = math.sqrt(max(reach * reach - above * above, 0.0))
                phi = math.radians(bearing)
                out.append((planar * math.cos(phi), planar * math.sin(phi), z))
    return np.array(out)


def held_point_depths(field: VelocityField, points, root, *, dt: float, seconds: float,
                      lag, velocity_limit=math.inf, acceleration_limit=math.inf) -> np.ndarray:
    """Per placement, the deepest penetration ``max_t (Δ_r − d_r)`` [m] into the retreat zone
    (negative: never entered) while the field drives the base and the TEE stays where it was
    in the world.

    Args:
        field: the :class:`VelocityField` (its parameters; its state is not used or changed).
        points: (N, 3) TEE points [m] in the field's frame at the start (base at the world
            origin, facing +x, at rest, no heading latched).
        root: (3,) the field frame's origin in the base frame [m] (the arm root).
        dt: control period [s]; seconds: duration [s].
        lag: time constant(s) of the base's first-order velocity lag [s], scalar or
            ``(τ_v, τ_ω)``.
        velocity_limit, acceleration_limit: the base's saturation, scalar or per
            coordinate ``(v, ω)`` [m/s, rad/s] and [m/s², rad/s²] (``inf``: none).
    """
    points = as_float_array(points, "points")
    if points.ndim != 2 or points.shape[1] != 3:
        raise ShapeError(f"points must have shape (N, 3), got {points.shape}")
    n = points.shape[0]
    root = np.asarray(root, dtype=float)
    column = (2, 1)
    tau = np.broadcast_to(np.asarray(lag, float), 2).reshape(column)
    if not (np.all(np.isfinite(tau)) and np.all(tau > 0.0)):
        raise InvalidValueError(f"lag must be finite and > 0 [s], got {lag!r}")
    gain = 1.0 - np.exp(-dt / tau)
    v_max = np.broadcast_to(np.asarray(velocity_limit, float), 2).reshape(column)
    dv_max = np.broadcast_to(np.asarray(acceleration_limit, float), 2).reshape(column) * dt
    tick = _mapped_tick(field, n)
    # the call's buffers, flat and column-major: column k is placement k
    tee_flat, state_flat, next_flat, d_r = (np.zeros(k * n) for k in (3, 4, 4, 1))
    buffer, call = tick.buffer()
    for i, array in enumerate((tee_flat, state_flat)):
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res)
        buffer.set_arg(i, memoryview(array))  # type: ignore[call-arg, arg-type]
    for i, array in enumerate((next_flat, d_r)):
        buffer.set_res(i, memoryview(array))  # type: ignore[call-arg, arg-type]
    tee, state, after = (a.reshape(n, -1).T for a in (tee_flat, state_flat, next_flat))
    world = points.T + root[:, None]               # the held points, world frame (3, N)
    pose = np.zeros((3, n))                        # base (x, y, θ) [m, m, rad]
    velocity = np.zeros((2, n))                    # the base's true (v, ω)
    depth = np.full(n, -math.inf)
    for _ in range(int(round(seconds / dt))):
        c, s = np.cos(pose[2]), np.sin(pose[2])
        dx, dy = world[0] - pose[0], world[1] - pose[1]
        tee[0], tee[1], tee[2] = c * dx + s * dy - root[0], -s * dx + c * dy - root[1], \
            world[2] - root[2]
        call()
        state[...] = after
        np.maximum(depth, field.delta_r - d_r, out=depth)
        # actuation.Lag, then actuation.Saturation (rate, then value), from the true velocity
        lagged = velocity + gain * (state[:2] - velocity)
        velocity = np.clip(np.clip(lagged, velocity - dv_max, velocity + dv_max), -v_max, v_max)
        # eqs. 1-3 over the tick at constant (v, ω): an arc
        angle = velocity[1] * dt
        small = np.abs(angle) < 1e-9
        safe = np.where(small, 1.0, angle)
        along = np.where(small, 1.0 - angle * angle / 6.0, np.sin(angle) / safe)
        across = np.where(small, angle / 2.0, (1.0 - np.cos(angle)) / safe)
        step = velocity[0] * dt
        pose = pose + np.vstack([step * (c * along - s * across), step * (s * along + c * across),
                                 angle])
    return depth


def _mapped_tick(field: VelocityField, n: int) -> ca.Function:
    """``(p, state) -> (next state, d_r)`` of the field for ``n`` points side by side (columns),
    compiled C when a compiler is present (as the controllers' fast path), else CasADi's
    virtual machine."""
    p, state = ca.SX.sym("p", 3), ca.SX.sym("state", 4)
    tick = ca.Function("petric_held_point_tick", [p, state],
                       [field.symbolic_step(p, state), field.symbolic_distances(p)[1]]).map(n)
    return compiled_c(tick) if compiler_available() else tick
