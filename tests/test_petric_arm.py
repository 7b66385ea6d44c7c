"""Petrič & Žlajpah's arm controller (eqs. 22–26): closed forms, their QP forms on every
backend (profile "tight"), the leak of the paper's damped projector, and the study's arm stack
on the Tiago + Panda.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import assert_kkt, random_matrix
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.papers import petric
from wbc.papers.petric import PETRIC_LAMBDA, damped_projector, dls_arm_velocity, projector_leak
from wbc.solvers import available_backends
from wbc.solvers.reference import nullspace_projector
from wbc.tasks import LinearTask

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

BACKENDS = available_backends()
TOL = 1e-7


# ----------------------------------------------------------------------------- closed forms
def test_dls_is_eq_25_with_lambda_inside_j_jt():
    rng = np.random.default_rng(0)
    J, u = rng.standard_normal((3, 7)), rng.standard_normal(3)
    expected = J.T @ np.linalg.solve(J @ J.T + 0.05 * np.eye(3), u)
    np.testing.assert_allclose(dls_arm_velocity(J, u), expected, atol=1e-13)
    assert PETRIC_LAMBDA == 0.05


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 6]), st.sampled_from([None, 2, 1]))
def test_exact_projector_keeps_the_task_and_damped_one_leaks(seed, m, rank):
    rng = np.random.default_rng(seed)
    J = random_matrix(rng, m, 7, rank, smin=0.05, smax=2.0)
    u, z = rng.standard_normal(m), rng.standard_normal(7)
    exact = dls_arm_velocity(J, u, z, projector="exact")
    damped = dls_arm_velocity(J, u, z, projector="damped")
    plain = dls_arm_velocity(J, u)
    np.testing.assert_allclose(J @ exact, J @ plain, atol=1e-12)
    leak = projector_leak(J, z)
    np.testing.assert_allclose(J @ damped - J @ plain, leak, atol=1e-12)
    assert np.linalg.norm(leak) <= math.sqrt(PETRIC_LAMBDA) / 2 * np.linalg.norm(z) + 1e-12
    assert np.linalg.norm(leak) > 1e-6  # a random z has a component along J's row space


def test_leak_gain_peaks_at_sqrt_lambda_over_two():
    """Per singular value σ the leak gain is λσ/(σ² + λ): √λ/2 at σ = √λ, and → 0 at both
    ends (well-conditioned J, or a direction J does not see)."""
    lam = PETRIC_LAMBDA
    for sigma, gain in ((math.sqrt(lam), math.sqrt(lam) / 2), (10.0, lam * 10 / (100 + lam)),
                        (0.0, 0.0)):
        J = np.zeros((1, 2))
        J[0, 0] = sigma
        assert np.linalg.norm(projector_leak(J, [1.0, 0.0], lam)) == pytest.approx(gain)


def test_damped_projector_is_not_a_projector_and_lambda_zero_is_exact():
    rng = np.random.default_rng(3)
    J = random_matrix(rng, 3, 7, smin=0.1, smax=1.0)
    N = damped_projector(J)
    assert np.abs(N @ N - N).max() > 1e-3
    np.testing.assert_allclose(damped_projector(J, 0.0), nullspace_projector(J), atol=1e-12)
    z = rng.standard_normal(7)
    np.testing.assert_array_equal(projector_leak(J, z, 0.0), 0.0)


def test_bad_input_names_the_parameter():
    J = np.ones((3, 7))
    with pytest.raises(wbc.InvalidValueError, match="projector"):
        dls_arm_velocity(J, np.zeros(3), np.zeros(7), projector="pseudo")
    with pytest.raises(wbc.InvalidValueError, match="lam"):
        dls_arm_velocity(J, np.zeros(3), lam=-1.0)
    with pytest.raises(wbc.ShapeError, match="task_velocity"):
        dls_arm_velocity(J, np.zeros(2))
    with pytest.raises(wbc.ShapeError, match="qd_null"):
        projector_leak(J, np.zeros(6))
    with pytest.raises(wbc.NonFiniteError, match="J"):
        damped_projector(np.full((3, 7), np.nan))


# ----------------------------------------------------------------------------- QP = closed form
def _exact_stack(J, u, z, lam):
    """Level 0: ½||Jx − u||² + ½λ||x||²; level 1: ½||x − z||² under J x = J x₀*."""
    n = J.shape[1]
    stack = wbc.Stack(wbc.Variables(qd=n), damping={0: math.sqrt(lam)}, min_norm=False)
    stack.add(LinearTask(J, u, name="ee"), priority=0)
    stack.add(LinearTask(np.eye(n), z, name="posture"), priority=1)
    return stack


def _damped_stack(J, u, z, lam):
    """One level: ½||Jx − u||² + ½λ||x − z||² — eq. 22 with eq. 26 as printed."""
    n = J.shape[1]
    stack = wbc.Stack(wbc.Variables(qd=n), min_norm=False)
    stack.add(LinearTask(J, u, name="ee"), priority=0)
    stack.add(LinearTask(np.eye(n), z, name="posture"), priority=0, weight=lam)
    return stack


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("projector", ["exact", "damped"])
@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 6]), st.sampled_from([None, 2, 1]),
       st.sampled_from([PETRIC_LAMBDA, 0.5]))
def test_qp_equals_closed_form(backend, projector, seed, m, rank, lam):
    rng = np.random.default_rng(seed)
    J = random_matrix(rng, m, 7, rank)
    u, z = rng.standard_normal(m), rng.standard_normal(7)
    build = _exact_stack if projector == "exact" else _damped_stack
    ws = build(J, u, z, lam).workspace(backend, "tight")
    sol = ws.solve()
    assert sol.ok, sol.message
    expected = dls_arm_velocity(J, u, z, lam, projector)
    np.testing.assert_allclose(sol.x, expected, atol=TOL)
    assert_kkt(ws)


# ----------------------------------------------------------------------------- the robot's stack
@pytest.fixture(scope="module")
def tiago():
    from wbc.robots import load

    return load("tiago_panda")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("projector", ["exact", "damped"])
def test_study_arm_stack_is_eq_22_on_the_tiago_panda(tiago, backend, projector):
    """``arm_stack`` (base pinned; exact: TCP position task damped by λ, posture one level
    below; damped: one level with the posture weighted by λ) on the robot =
    ``dls_arm_velocity`` of the arm's position Jacobian with ``u = K_p e`` and
    ``q̇_n = K_n (q_mid − q)``, at random configurations and targets."""
    from wbc.experiments.studies import petric as study

    robot = tiago
    controller = wbc.Controller(robot, petric.arm_stack(robot, projector=projector),
                                backend=backend, profile="tight", dt=petric.DT)
    rng = np.random.default_rng(7)
    na, nb = robot.n_arm, robot.nv_base
    q_mid = petric.posture_target(robot)[-na:]
    for _ in range(5):
        q = study._start(robot)
        q[:3] = rng.uniform(-1, 1, 3)
        q[-na:] += rng.uniform(-0.3, 0.3, na)
        target = np.eye(4)
        x = robot.frame_pose(q, "ee")[:3, 3]
        target[:3, 3] = x + rng.uniform(-0.1, 0.1, 3)
        command = controller.step(q, ee=target)
        assert controller.last_solution.ok, controller.last_solution.message
        J = robot.frame_jacobian(q, "ee")[:3, nb:]
        expected = dls_arm_velocity(J, petric.KP * (target[:3, 3] - x),
                                    petric.K_POSTURE * (q_mid - q[-na:]),
                                    projector=projector)
        np.testing.assert_array_equal(command[:nb], 0.0)
        np.testing.assert_allclose(command[nb:], expected, atol=TOL)


def test_study_arm_stack_refuses_an_unknown_projector(tiago):
    with pytest.raises(wbc.InvalidValueError, match="projector"):
        petric.arm_stack(tiago, projector="pseudo")
