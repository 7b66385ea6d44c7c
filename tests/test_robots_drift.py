"""``symbolic_drift``: the CasADi ``J̇ v`` of a frame equals the numeric ``frame_drift`` (world
axes) of the mobile manipulators and of the fixed-base Panda, and the time derivative of
``J(q(t)) v`` along the motion that ``v`` produces."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wbc.robots
from wbc.robots.fixed_base import FixedBaseRobot, load_panda

SEED = 20240917
H = 1e-5  # central-difference step [s]


def _load(name: str):
    if name == "panda":
        return load_panda()
    if name == "panda_fingers":  # prismatic finger joints too
        return load_panda(fingers=True)
    return wbc.robots.load(name)


@pytest.fixture(scope="module", params=[*wbc.robots.names(), "panda", "panda_fingers"])
def robot(request):
    return _load(request.param)


def states(robot, rng: np.random.Generator, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random ``(q, v)``: for mobile bases headings far beyond ±π [rad] and base velocities up to
    6 m/s and 5 rad/s (beyond the robots' limits: the kinematics do not care); arm rates up to
    3 rad/s; the arm uniform within its position limits (``[−π, π]`` where unbounded)."""
    lower = np.where(np.isfinite(robot.limits.q_lower), robot.limits.q_lower, -math.pi)
    upper = np.where(np.isfinite(robot.limits.q_upper), robot.limits.q_upper, math.pi)
    out = []
    for _ in range(count):
        q = rng.uniform(lower, upper)
        v = rng.uniform(-3.0, 3.0, robot.nv)
        if not isinstance(robot, FixedBaseRobot):
            q[:2] = rng.uniform(-5.0, 5.0, 2)
            q[2] = rng.uniform(-math.pi, math.pi) + 2.0 * math.pi * rng.integers(-4, 5)
            nb = robot.nv_base
            v[: nb - 1] = rng.uniform(-6.0, 6.0, nb - 1)  # v_x (v_y) [m/s]
            v[nb - 1] = rng.uniform(-5.0, 5.0)  # ω [rad/s]
        out.append((q, v))
    if not isinstance(robot, FixedBaseRobot):
        assert any(abs(q[2]) > math.pi for q, _ in out)
    return out


def drift(function, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    result = np.array(function(q, v))
    assert result.shape == (6, 1)
    return result.ravel()


def scaled_error(value: np.ndarray, reference: np.ndarray) -> float:
    """``max |value − reference|`` relative to ``max(1, max |reference|)``: the drift grows as
    ``|v|²`` (centripetal terms of large base velocities)."""
    return float(np.abs(value - reference).max()) / max(1.0, float(np.abs(reference).max()))


def test_symbolic_drift_equals_frame_drift(robot):
    f = robot.symbolic_drift("ee")
    assert f.size_in(0) == (robot.nq, 1) and f.size_in(1) == (robot.nv, 1)
    worst = 0.0
    for q, v in states(robot, np.random.default_rng(SEED), 12):
        numeric = robot.frame_drift(q, v, "ee").copy()
        symbolic = drift(f, q, v)
        error = scaled_error(symbolic, numeric)
        worst = max(worst, error)
        assert error < 1e-9, (q, v, symbolic, numeric)
    print(f"{robot.name}: max scaled |symbolic - numeric| = {worst:.2e}")


def test_symbolic_drift_is_the_derivative_of_the_twist_along_the_motion(robot):
    """``(J(q(t+h)) v − J(q(t−h)) v) / 2h`` with ``q(t)`` the motion at constant ``v``
    (``integrate``: exact arcs for mobile bases) is ``J̇ v`` up to O(h²)."""
    f = robot.symbolic_drift("ee")
    worst = 0.0
    for q, v in states(robot, np.random.default_rng(SEED + 1), 6):
        ahead = robot.frame_jacobian(robot.integrate(q, v, H), "ee", "world") @ v
        behind = robot.frame_jacobian(robot.integrate(q, v, -H), "ee", "world") @ v
        difference = (ahead - behind) / (2.0 * H)
        symbolic = drift(f, q, v)
        error = scaled_error(difference, symbolic)
        worst = max(worst, error)
        # truncation ~ h² |d³(Jv)/dt³| / 6 and round-off ~ eps |J v| / h: both below 1e-7
        assert error < 1e-6, (q, v, difference, symbolic)
    print(f"{robot.name}: max scaled |finite difference - symbolic| = {worst:.2e}")


def test_symbolic_drift_of_every_frame(robot):
    q, v = states(robot, np.random.default_rng(SEED + 2), 1)[0]
    for frame in robot.frame_names:
        numeric = robot.frame_drift(q, v, frame).copy()
        scale = max(1.0, float(np.abs(numeric).max()))
        np.testing.assert_allclose(
            drift(robot.symbolic_drift(frame), q, v), numeric, rtol=0, atol=1e-9 * scale,
            err_msg=frame,
        )


def test_symbolic_drift_is_cached(robot):
    f = robot.symbolic_drift("ee")
    assert robot.symbolic_drift("ee") is f
    assert robot.symbolic_drift() is f  # "ee" by default
    if not isinstance(robot, FixedBaseRobot):
        assert robot.symbolic_drift(robot.frame_id("ee")) is f  # by index too
        assert robot.clone().symbolic_drift("ee") is f  # clones share the model's functions


def test_unknown_frame_raises_as_frame_pose(robot):
    with pytest.raises(Exception) as numeric:
        robot.frame_pose(robot.neutral(), "no_such_frame")
    with pytest.raises(type(numeric.value)):
        robot.symbolic_drift("no_such_frame")
