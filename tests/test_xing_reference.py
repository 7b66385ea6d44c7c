"""Xing et al.'s closed forms (wbc.solvers.reference.amp and its pieces) and the manipulability
objective (wbc.tasks.manipulability): finite differences, projector algebra, AMP's decisions."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from helpers import random_matrix
from hypothesis import given
from hypothesis import strategies as st

import wbc.robots as robots
from wbc.errors import InvalidValueError, ShapeError
from wbc.solvers import reference as ref
from wbc.tasks.manipulability import (
    ManipulabilityAccelerationTask,
    arm_jacobian_derivatives,
    smallest_singular_value,
)


@pytest.fixture(scope="module")
def robot():
    return robots.load("mecanum_gen3")


@pytest.fixture(scope="module")
def derivatives(robot):
    return arm_jacobian_derivatives(robot)


def _arm_terms(derivatives, q):
    """``(J_m, ∂J_m/∂q_k (m, 3, m), ∂²J_m/∂q_p∂q_q (m, m, 3, m))``, the last from the
    contracted derivative with unit directions."""
    m = 7

    def unvec(a):  # rows i + 3j -> [k, i, j]
        return np.array(a).reshape(m, 3, m).transpose(2, 1, 0)

    J, dJ, _ = derivatives(q, np.zeros(m))
    ddJ = np.stack([unvec(derivatives(q, np.eye(m)[k])[2]) for k in range(m)], axis=1)
    return np.array(J), unvec(dJ), ddJ


def _H(robot, q):
    J = robot.frame_jacobian(q, "ee")[:3, 3:]
    return np.linalg.det(J @ J.T)


def _states(robot, n, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q = robot.neutral()
        q[3:] += rng.uniform(-0.8, 0.8, 7)
        yield q, rng


def test_symbolic_arm_jacobian_is_the_robots(robot, derivatives):
    for q, _ in _states(robot, 5):
        J, _, _ = _arm_terms(derivatives, q)
        np.testing.assert_allclose(J, robot.frame_jacobian(q, "ee")[:3, 3:], atol=1e-13)


def test_appendix_gradient_and_hessian_match_finite_differences(robot, derivatives):
    """Appendix A (eq. 17) and B (eqs. 18–20) against central differences of
    H = det(J_m J_mᵀ) computed from the robot's numeric Jacobian."""
    h = 1e-5
    for q, _ in _states(robot, 4):
        J, dJ, ddJ = _arm_terms(derivatives, q)
        gradient = ref.manipulability_gradient(J, dJ)
        hessian = ref.manipulability_hessian(J, dJ, ddJ)
        fd_gradient = np.zeros(7)
        fd_hessian = np.zeros((7, 7))
        for k in range(7):
            dq = np.zeros(10)
            dq[3 + k] = h
            fd_gradient[k] = (_H(robot, q + dq) - _H(robot, q - dq)) / (2 * h)
            plus = ref.manipulability_gradient(*_arm_terms(derivatives, q + dq)[:2])
            minus = ref.manipulability_gradient(*_arm_terms(derivatives, q - dq)[:2])
            fd_hessian[:, k] = (plus - minus) / (2 * h)
        scale = np.abs(fd_gradient).max()
        np.testing.assert_allclose(gradient, fd_gradient, atol=1e-7 * scale)
        np.testing.assert_allclose(hessian, fd_hessian, atol=1e-6 * np.abs(fd_hessian).max())
        np.testing.assert_allclose(hessian, hessian.T, atol=1e-12 * np.abs(hessian).max())


def test_compiled_manipulability_acceleration_is_eq_13_of_the_appendix(robot, derivatives):
    """ManipulabilityAccelerationTask's q̈_sa (CasADi reverse + forward mode) equals eq. 13
    evaluated with the appendix's closed forms."""
    task = ManipulabilityAccelerationTask(robot, name="m")
    q_sym, v_sym = ca.SX.sym("q", 10), ca.SX.sym("v", 10)
    target = ca.Function("target", [q_sym, v_sym], [task.target(q_sym, v_sym, 5.0, 0.5)])
    for q, rng in _states(robot, 5, seed=1):
        v = rng.uniform(-1, 1, 10)
        J, dJ, ddJ = _arm_terms(derivatives, q)
        hessian_qd = ref.manipulability_hessian(J, dJ, ddJ) @ v[3:]
        dJ_dot = np.array(derivatives(q, v[3:])[2]).reshape(7, 3, 7).transpose(2, 1, 0)
        np.testing.assert_allclose(ref.manipulability_hessian_product(J, dJ, dJ_dot, v[3:]),
                                   hessian_qd, atol=1e-12 * (1 + np.abs(hessian_qd).max()))
        expected = ref.manipulability_acceleration(ref.manipulability_gradient(J, dJ),
                                                   hessian_qd, v[3:], 5.0, 0.5)
        got = np.array(target(q, v)).ravel()
        assert np.all(got[:3] == 0)
        np.testing.assert_allclose(got[3:], expected, atol=1e-12 * (1 + np.abs(expected).max()))


@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 2, 1]))
def test_symbolic_sigma_min_is_the_svds(seed, rank):
    rng = np.random.default_rng(seed)
    J_sym = ca.SX.sym("J", 3, 7)
    sigma = ca.Function("sigma", [J_sym], [smallest_singular_value(J_sym)])
    J = random_matrix(rng, 3, 7, rank)
    expected = np.linalg.svd(J, compute_uv=False)[-1]
    assert float(sigma(J)) == pytest.approx(expected, abs=1e-7 * np.linalg.norm(J, 2))


@given(st.integers(0, 2**32 - 1), st.integers(1, 4))
def test_auxiliary_projector_is_the_null_space_of_task_and_still_joints(seed, stills):
    rng = np.random.default_rng(seed)
    J = random_matrix(rng, 3, 10)
    free = np.ones(10, dtype=bool)
    free[rng.choice(10, stills, replace=False)] = False
    P = ref.auxiliary_projector(J, free)
    np.testing.assert_allclose(J @ P, 0, atol=1e-10)
    np.testing.assert_allclose(P[~free], 0, atol=1e-10)
    np.testing.assert_allclose(P, P.T, atol=1e-10)
    np.testing.assert_allclose(P @ P, P, atol=1e-10)
    stacked = np.vstack([J, np.eye(10)[~free]])  # its rank: what P must leave
    assert np.linalg.matrix_rank(P, tol=1e-6) == 10 - np.linalg.matrix_rank(stacked)


def test_scaling_factor_of_fig_4():
    lower, upper = -np.ones(3), np.ones(3)
    assert ref.scaling_factor([0.5, 0.0, -0.2], [0.0, 0.9, 0.0], lower, upper) == 1.0
    assert ref.scaling_factor([4.0, 0.0, -1.0], [0.0, 0.0, 0.0], lower, upper) == 0.25
    assert ref.scaling_factor([1.0, 0.0, 0.0], [2.0, 0.0, 0.0], lower, upper) == 0.0


@given(st.floats(-0.25, 0.25), st.floats(0.005, 0.05))
def test_transition_stops_the_base_at_its_maximal_deceleration(v0, dt):
    """Eq. (15) sampled: |a| = A until the last step, which lands on v = 0 (to round-off), at
    the first sample after eq. 15's t_f = |v0| / A."""
    A = 0.025
    v, steps = v0, 0
    while abs(v) > 1e-15:
        a = ref.base_transition([v], [-A], [A], dt)[0]
        assert abs(a) <= A and (abs(a) == A or a == -v / dt)
        v += a * dt
        steps += 1
        assert steps <= 10_000
    assert abs(steps - abs(v0) / (A * dt)) < 1 + 1e-6


def _problem(rng, scale):
    J = random_matrix(rng, 3, 10)
    return dict(J=J, xdd=scale * rng.standard_normal(3), drift=0.1 * rng.standard_normal(3),
                lower=-rng.uniform(0.5, 2.0, 10), upper=rng.uniform(0.5, 2.0, 10), n_base=3)


@given(st.integers(0, 2**32 - 1), st.sampled_from([0.05, 1.0, 20.0]))
def test_amp_decisions(seed, scale):
    """AMP keeps the base at its transition value when the arm alone succeeds (and then the
    task holds exactly), enables it otherwise, and always respects the bounds."""
    rng = np.random.default_rng(seed)
    p = _problem(rng, scale)
    transition = rng.uniform(p["lower"][:3], p["upper"][:3])
    qdd_sa = np.concatenate([np.zeros(3), rng.standard_normal(7)])
    qdd, info = ref.amp(**p, qdd_sa=qdd_sa, transition=transition)
    assert np.all(qdd >= p["lower"] - 1e-9) and np.all(qdd <= p["upper"] + 1e-9)
    assert 0 <= info.alpha <= 1 and 0 <= info.beta <= 1
    residual = p["J"] @ qdd + p["drift"] - info.alpha * p["xdd"]
    if info.reason == "arm":
        np.testing.assert_array_equal(qdd[:3], transition)
        assert info.alpha == 1.0
    assert np.abs(residual).max() <= 1e-8 * (1 + np.abs(p["xdd"]).max())
    # the tertiary motion never disturbs the task nor a still joint
    without, _ = ref.amp(**p, transition=transition)
    np.testing.assert_allclose(p["J"] @ (qdd - without), 0, atol=1e-9)
    np.testing.assert_allclose((qdd - without)[~info.free], 0, atol=1e-9)


def test_amp_enables_the_base_near_a_singularity():
    rng = np.random.default_rng(4)
    p = _problem(rng, 0.05)
    _, info = ref.amp(**p, sigma_min=0.1, sigma_thr=0.15)
    assert info.base_enabled and info.reason == "singularity"
    _, info = ref.amp(**p, sigma_min=0.2, sigma_thr=0.15)
    assert info.reason == "arm"


def test_traditional_is_the_pseudo_inverse_plus_null_space_term():
    rng = np.random.default_rng(5)
    J = random_matrix(rng, 3, 10)
    xdd, drift, z = rng.standard_normal(3), rng.standard_normal(3), rng.standard_normal(10)
    qdd = ref.traditional(J, xdd, drift, z)
    np.testing.assert_allclose(J @ qdd + drift, xdd, atol=1e-12)
    np.testing.assert_allclose(qdd, ref.pinv(J) @ (xdd - drift) + ref.nullspace_projector(J)
                               @ z, atol=1e-12)


def test_bad_input_is_refused():
    rng = np.random.default_rng(6)
    p = _problem(rng, 1.0)
    with pytest.raises(ShapeError, match="n_base"):
        ref.amp(**{**p, "n_base": 10})
    with pytest.raises(ShapeError, match="transition"):
        ref.amp(**p, transition=np.zeros(2))
    with pytest.raises(ShapeError, match="dJ"):
        ref.manipulability_gradient(np.ones((3, 7)), np.ones((7, 7, 3)))
    with pytest.raises(InvalidValueError, match="dt"):
        ref.base_transition([0.1], [-1], [1], 0.0)
    with pytest.raises(InvalidValueError, match="gamma1"):
        ManipulabilityAccelerationTask(robots.load("mecanum_gen3"), gamma1=-1.0)
