"""The steerable base's controller (Sorour §IV): steer limits over random reference sequences
(ICR crossings at infinity and through a hip included), consistency of the feasible twist
with the steering, the inverse actuation model, the ICR QP on every backend."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.papers.sorour.steering import (
    SteerableController,
    drive_rates,
    icr_of_twist,
    scale_into,
    steering_of_icr,
)
from wbc.robots.steerable import mpo700
from wbc.solvers import available_backends

RATE, ACCEL = 1.0, 3.0


def reference_sequence(rng, hips, segments: int, ticks: int):
    """Piecewise-constant desired twists: pure translations (ICR at infinity, often reversed:
    complementary routes), pure rotations, rotations about a hip, generic twists, stops."""
    for _ in range(segments):
        kind = rng.integers(5)
        if kind == 0:
            twist = np.r_[rng.uniform(-0.9, 0.9, 2), 0.0]
        elif kind == 1:
            twist = np.r_[0.0, 0.0, rng.uniform(-1, 1)]
        elif kind == 2:
            hip, w = hips[rng.integers(len(hips))], rng.uniform(-1, 1)
            twist = np.array([w * hip[1], -w * hip[0], w])  # ICR on that hip
        elif kind == 3:
            twist = rng.uniform(-0.9, 0.9, 3)
        else:
            twist = np.zeros(3)
        yield from [twist] * ticks


def lateral_rows(hips, beta):
    c, s = np.cos(beta), np.sin(beta)
    return np.column_stack([-s, c, hips[:, 0] * c + hips[:, 1] * s])


@settings(max_examples=6)
@given(st.integers(0, 2**32 - 1))
def test_steer_limits_hold_and_the_twist_is_feasible(seed):
    """Rates never exceed β̇max; accelerations exceed β̈max exactly on the ticks the controller
    reports as relaxed (soft acceleration cones), and those are rare; the feasible twist
    satisfies the no-lateral-slip rows of the steering it comes with; routes through infinity
    and ICRs on a hip are exercised."""
    base = mpo700()
    controller = SteerableController(base, dt=0.025, steer_rate=RATE, steer_acceleration=ACCEL)
    rng = np.random.default_rng(seed)
    routes, relaxed, ticks = set(), 0, 0
    for twist in reference_sequence(rng, base.hips, 12, 30):
        step = controller.step(twist)
        ticks += 1
        routes.add(step.route)
        assert np.abs(step.steer_rates).max() <= RATE * (1 + 1e-4)
        over = np.abs(step.steer_accelerations).max() > ACCEL * (1 + 1e-4)
        assert over <= step.relaxed  # no violation unless reported
        relaxed += step.relaxed
        np.testing.assert_allclose(lateral_rows(base.hips, step.steering) @ step.twist, 0.0,
                                   atol=1e-9)
        assert np.all(np.abs(step.twist) <= base.v_max + 1e-12)
    assert relaxed == controller.acceleration_relaxed
    assert relaxed <= 0.1 * ticks
    assert "complementary" in routes or "direct" in routes


def test_constant_twist_is_reached_and_reversal_goes_through_infinity():
    base = mpo700()
    controller = SteerableController(base)
    target = np.array([0.3, 0.2, 0.2])
    for _ in range(400):
        step = controller.step(target)
    np.testing.assert_allclose(step.twist, target, atol=1e-6)
    icr = icr_of_twist(target)  # defined up to sign
    np.testing.assert_allclose(step.icr * np.sign(step.icr @ icr), icr, atol=1e-6)
    # a pure translation, then its reverse: same ICR (at infinity), no steering needed
    controller.reset()
    for _ in range(200):
        controller.step([0.5, 0.0, 0.0])
    step = controller.step([-0.5, 0.0, 0.0])
    np.testing.assert_allclose(step.steer_rates, 0.0, atol=1e-9)
    # ICR from (0, 50) m to (0, −50) m: through infinity, with little steering
    for _ in range(200):
        controller.step([0.5, 0.0, 0.01])
    step = controller.step([0.5, 0.0, -0.01])
    assert step.route == "complementary"
    for _ in range(100):
        step = controller.step([0.5, 0.0, -0.01])
        assert np.abs(step.steering).max() < 0.05
    np.testing.assert_allclose(step.twist, [0.5, 0.0, -0.01], atol=1e-6)
    step = controller.step(np.zeros(3))
    assert step.route == "none"


def test_icr_through_a_hip():
    """Rotating about a wheel's hip, then about the opposite wheel's: the ICR reaches the hip
    and crosses the deck; the rate limits hold throughout."""
    base = mpo700()
    controller = SteerableController(base, steer_rate=RATE, steer_acceleration=ACCEL)
    for hip in (base.hips[0], base.hips[2]):
        twist = 0.5 * np.array([hip[1], -hip[0], 1.0])  # ICR at the hip
        for _ in range(300):
            step = controller.step(twist)
            assert np.abs(step.steer_rates).max() <= RATE * (1 + 1e-4)
        distance = np.linalg.norm(step.icr[:2] - hip * step.icr[2]) / abs(step.icr[2])
        assert distance < 1e-6
        np.testing.assert_allclose(step.twist, twist, atol=1e-6)
    # measured: 7 of 600 ticks over β̈max (the soft cones), reported as relaxed
    assert controller.acceleration_relaxed <= 0.02 * 600


def test_steering_of_icr_is_the_papers_formula_modulo_pi():
    base = mpo700()
    X, Y = 1.3, -0.7
    icr = np.array([X, Y, 1.0]) / math.hypot(X, Y, 1.0)
    beta = steering_of_icr(base.hips, icr, np.zeros(4))
    paper = np.arctan2(Y - base.hips[:, 1], X - base.hips[:, 0]) - math.pi / 2
    np.testing.assert_allclose(np.sin(beta - paper), 0.0, atol=1e-12)  # equal modulo π
    assert np.all(np.abs(beta) <= math.pi / 2)


def test_inverse_actuation_model():
    """φ̇ r_w = e·(hip velocity) + d (ω + β̇): the drive rate of a wheel whose contact point is
    offset sideways by d."""
    base = mpo700()
    rng = np.random.default_rng(0)
    beta, beta_dot, twist = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4), rng.standard_normal(3)
    rates = drive_rates(base.hips, base.offset, base.radius, beta, beta_dot, twist)
    hip_v = twist[:2][None] + twist[2] * np.column_stack([-base.hips[:, 1], base.hips[:, 0]])
    e = np.column_stack([np.cos(beta), np.sin(beta)])
    expected = (np.sum(e * hip_v, axis=1) + base.offset * (twist[2] + beta_dot)) / base.radius
    np.testing.assert_allclose(rates, expected, atol=1e-12)
    np.testing.assert_allclose(scale_into([2.0, 0.5, 0.1], [1.0, 1.0, 1.0]), [1.0, 0.25, 0.05])


@pytest.mark.parametrize("backend", available_backends())
def test_icr_qp_agrees_across_backends(backend):
    base = mpo700()
    reference = SteerableController(base, backend="daqp", profile="tight")
    other = SteerableController(base, backend=backend, profile="tight")
    for twist in ([0.4, 0.1, 0.3], [0.0, 0.5, -0.4], [-0.3, 0.0, 0.0]):
        for _ in range(10):
            a, b = reference.step(twist), other.step(twist)
            np.testing.assert_allclose(b.icr, a.icr, atol=1e-5)
            np.testing.assert_allclose(b.twist, a.twist, atol=1e-5)


def test_bad_parameters_are_refused():
    with pytest.raises(wbc.InvalidValueError, match="steer_rate"):
        SteerableController(mpo700(), steer_rate=0.0)
    with pytest.raises(wbc.InvalidValueError, match="π/4"):
        SteerableController(mpo700(), dt=1.0, steer_rate=1.0)
    with pytest.raises(wbc.ShapeError, match="desired_twist"):
        SteerableController(mpo700()).step([1.0, 0.0])
