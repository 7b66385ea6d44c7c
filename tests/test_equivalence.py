"""The QP cascade recovers the closed forms of the literature (docs/DESIGN.md, math notes 1–6).

Every test runs on every installed backend with its ``"tight"`` profile, over random instances
drawn by hypothesis (task rows m 1–6, variables n from m to m+6), including rank-deficient and
conflicting cases and active bounds; it asserts the solution difference and the KKT residuals
of every QP of the cascade.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import assert_kkt, random_matrix
from hypothesis import given
from hypothesis import strategies as st

import wbc
from wbc.solvers import available_backends
from wbc.solvers import reference as ref
from wbc.tasks import Bounds, LinearTask

BACKENDS = available_backends()
TOL = 1e-7

# Task-scaling levels end on a vertex of the bounds (the LP optimum), where the next QPs'
# optimum has zero multipliers on active bounds: active-set backends (daqp, quadprog, qpoases)
# stay exact, interior-point ones converge to about the square root of their tolerance there.
# Measured worst case on these tests: clarabel 9e-6.
SCALING_TOL = {"clarabel": 5e-5}
# Backends that fail on some of these degenerate LPs: a failure status, or (proxqp, casadi:osqp)
# an answer outside the tolerance reported as solved. Measured on 300 random instances per test
# (velocity / acceleration): osqp 11 / 11, casadi:osqp 12 / 13, proxqp 7 / 9 failures. At such
# rates a run of the derandomised examples may meet none (an XPASS): the marks are not stale.
SCALING_UNRELIABLE = {
    "osqp": "ADMM stalls on degenerate vertex LPs (max_iter / solved inaccurate)",
    "casadi:osqp": "ADMM stalls on degenerate vertex LPs (max_iter / solved inaccurate)",
    "proxqp": "ProxQP 0.8 reports primal infeasibility on some feasible vertex LPs",
}
# quadprog needs H > 0: the adapter's proximal iterations on the singular level after a scaling
# LP can stall at a degenerate vertex. Rare (measured: 1 in 1000 random velocity instances, 3 in
# 1000 acceleration ones; none among the derandomised examples here, where an xfail marker only
# XPASSed), so instead of an expected failure the tests accept exactly that status from it.
SCALING_STALLS = {"quadprog": wbc.Status.MAX_ITER}


def scaling_backends():
    return [pytest.param(b, marks=pytest.mark.xfail(reason=SCALING_UNRELIABLE[b], strict=False))
            if b in SCALING_UNRELIABLE else b for b in BACKENDS]


@st.composite
def instances(draw, min_n: int = 1):
    """``(m, n, rank, rng)``: the random instances of docs/DESIGN.md, math note 6."""
    m = draw(st.integers(1, 6))
    n = draw(st.integers(max(m, min_n), m + 6))
    rank = draw(st.sampled_from([min(m, n), max(1, min(m, n) - 1), 1]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    return m, n, rank, rng


def solve(stack: wbc.Stack, backend: str,
          stall: wbc.Status | None = None) -> tuple[wbc.Solution, wbc.Workspace]:
    """Solve on ``backend`` with the tight profile; the solution must be solved, or have the
    documented ``stall`` status (then ``sol.ok`` is false and the caller stops)."""
    ws = stack.workspace(backend, "tight")
    sol = ws.solve()
    assert sol.ok or sol.status is stall, sol.message
    assert np.isfinite(sol.x).all()
    return sol, ws


# ----------------------------------------------------------------------------- 5a
@pytest.mark.parametrize("backend", BACKENDS)
@given(instances(), st.sampled_from([0.0, 0.05, 0.3, 1.0]))
def test_damped_pinv_equals_one_level_qp(backend, inst, rho):
    m, n, rank, rng = inst
    J = random_matrix(rng, m, n, rank)
    v = rng.standard_normal(m)  # outside range(J) when rank < m: the task conflicts with itself
    stack = wbc.Stack(n, damping=rho).add(LinearTask(J, v, name="task"))
    sol, ws = solve(stack, backend)
    np.testing.assert_allclose(sol.x, ref.damped_pinv(J, rho) @ v, atol=TOL)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
@given(instances(min_n=4), st.sampled_from([0.0, 0.3, 0.5, 1.0]),
       st.sampled_from([0.0, 0.05, 0.5]))
def test_weighted_damped_pinv_equals_one_level_qp(backend, inst, psi, rho):
    """Mobility diag((1−ψ) I_base, ψ I_arm); ψ = 0 and ψ = 1 are singular (one part pinned)."""
    m, n, rank, rng = inst
    J = random_matrix(rng, m, n, rank)
    v = rng.standard_normal(m)
    mobility = np.r_[np.full(3, 1 - psi), np.full(n - 3, psi)]
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=n - 3), damping=rho, mobility=mobility)
    stack.add(LinearTask(J, v, name="task"))
    sol, ws = solve(stack, backend)
    expected = ref.weighted_damped_pinv(J, rho, np.diag(mobility)) @ v
    np.testing.assert_allclose(sol.x, expected, atol=TOL)
    assert_kkt(ws)
    if psi in (0.0, 1.0):  # ψ = 0: the base alone moves; ψ = 1: the arm alone
        pinned = sol["qd_arm"] if psi == 0.0 else sol["qd_base"]
        assert np.abs(pinned).max() < 1e-9


# ----------------------------------------------------------------------------- 5b
@st.composite
def hierarchies(draw):
    """2 or 3 levels over n variables; a later level may repeat an earlier row (rank-deficient
    projected task) or contradict it (conflicting targets)."""
    n = draw(st.integers(2, 10))
    depth = draw(st.sampled_from([2, 3]))
    mode = draw(st.sampled_from(["generic", "dependent", "conflicting"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    levels = []
    for k in range(depth):
        m = draw(st.integers(1, min(4, n)))
        J = random_matrix(rng, m, n)
        if k and mode != "generic":
            earlier = levels[0][0]
            J[0] = earlier[0] if mode == "conflicting" else earlier[0] + 0.5 * J[-1] * (m > 1)
        levels.append((J, rng.standard_normal(m)))
    return levels


@pytest.mark.parametrize("backend", BACKENDS)
@given(hierarchies(), st.sampled_from([0.0, 0.1, 0.5]))
def test_strict_hierarchy_equals_recursive_nullspace_projection(backend, levels, rho):
    n = levels[0][0].shape[1]
    stack = wbc.Stack(n, damping=rho)
    for k, (J, v) in enumerate(levels):
        stack.add(LinearTask(J, v, name=f"level{k}"), priority=k)
    sol, ws = solve(stack, backend)
    np.testing.assert_allclose(sol.x, ref.hierarchy(levels, rho=rho), atol=TOL)
    assert_kkt(ws)
    assert stack.min_norm == (rho == 0.0)


# ----------------------------------------------------------------------------- 5c
@pytest.mark.parametrize("backend", BACKENDS)
@given(instances(), st.sampled_from([0.0, 0.1, 0.5]), st.floats(0.5, 3.5))
def test_additive_nullspace_term_is_plain_cascade_when_unweighted(backend, inst, rho, lam):
    """x = J^# v + λ(I − J⁺J) z equals 'level 1: J^# v; level 2: min ||x − λz||²' because the
    (damped) unweighted J^# v lies in the row space of J (docs/DESIGN.md, math note 3)."""
    m, n, rank, rng = inst
    J, v, z = random_matrix(rng, m, n, rank), rng.standard_normal(m), rng.standard_normal(n)
    stack = wbc.Stack(n, damping={0: rho})
    stack.add(LinearTask(J, v, name="task"), priority=0)
    stack.add(LinearTask(np.eye(n), lam * z, name="nullspace"), priority=1)
    sol, ws = solve(stack, backend)
    expected = ref.damped_pinv(J, rho) @ v + lam * ref.nullspace_projector(J) @ z
    np.testing.assert_allclose(sol.x, expected, atol=TOL)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
@given(instances(min_n=4), st.sampled_from([0.05, 0.5]), st.floats(0.5, 3.5))
def test_additive_nullspace_term_needs_exact_form_when_weighted(backend, inst, rho, lam):
    """With a weighted J^# the plain cascade differs; level 2 minimising ||x − x₁* − λz||²
    under the same equality is exact (docs/DESIGN.md, math note 3)."""
    m, n, rank, rng = inst
    J, v, z = random_matrix(rng, m, n, rank), rng.standard_normal(m), rng.standard_normal(n)
    mobility = np.r_[np.full(3, 0.7), np.full(n - 3, 0.3)]  # ψ = 0.3
    x1 = ref.weighted_damped_pinv(J, rho, np.diag(mobility)) @ v
    expected = x1 + lam * ref.nullspace_projector(J) @ z
    stack = wbc.Stack(n, damping={0: rho}, mobility=mobility)
    stack.add(LinearTask(J, v, name="task"), priority=0)
    stack.add(LinearTask(np.eye(n), lam * z, name="nullspace"), priority=1)
    ws = stack.workspace(backend, "tight")
    plain = ws.solve()
    np.testing.assert_allclose(plain.levels[0].x, x1, atol=TOL)
    # The plain cascade pulls the row-space-external part of x₁* to zero: x = x₁* + N(λz − x₁*).
    N = ref.nullspace_projector(J)
    np.testing.assert_allclose(plain.x, x1 + N @ (lam * z - x1), atol=TOL)
    if np.linalg.norm(N @ x1) > 1e-5:
        assert np.abs(plain.x - expected).max() > 1e-6
    ws.set(**{"nullspace.b": plain.levels[0].x + lam * z})
    exact = ws.solve()
    assert exact.ok, exact.message
    np.testing.assert_allclose(exact.x, expected, atol=TOL)
    assert_kkt(ws)


# ----------------------------------------------------------------------------- 5d
def _sns_problem(rng, m, n, rank):
    J = random_matrix(rng, m, n, rank)
    # in range(J), so that a rank-deficient task is still consistent (else only s = 0 is exact)
    target = J @ rng.standard_normal(n)
    target *= rng.uniform(0.5, 6.0) / max(np.linalg.norm(target), 1e-12)
    lower = -rng.uniform(0.2, 1.0, n)
    upper = rng.uniform(0.2, 1.0, n)
    return J, target, lower, upper


def _assert_sns_agreement(sns_x, sns_s, sol, J, lower, upper, tol=TOL):
    """docs/DESIGN.md, math note 4: the LP scale is never below SNS's; x is compared only when
    scales agree.

    With equal scales the QP's x is the minimum-norm point of ``{J x = s·target, bounds}`` and
    SNS's x is a point of that set, so ``||x_QP|| <= ||x_SNS||``; they are equal when SNS
    saturates nothing (both are then the pseudo-inverse solution). SNS's x is *not* the
    minimum-norm point in general when it saturates joints, so no equality is asserted there.
    """
    assert sol.scale >= sns_s - tol
    if abs(sol.scale - sns_s) < 1e-9:
        assert np.linalg.norm(sol.x) <= np.linalg.norm(sns_x) + tol
        if np.all((sns_x > lower + 1e-9) & (sns_x < upper - 1e-9)):
            np.testing.assert_allclose(sol.x, sns_x, atol=tol)


@pytest.mark.parametrize("backend", scaling_backends())
@given(instances())
def test_sns_velocity_vs_scaling_lp(backend, inst):
    tol = SCALING_TOL.get(backend, TOL)
    m, n, rank, rng = inst
    J, xd, lower, upper = _sns_problem(rng, m, n + 1, rank)
    sns_x, sns_s = ref.sns_velocity(J, xd, lower, upper)
    stack = wbc.Stack(n + 1).add(LinearTask(J, xd, name="task"), scaling=True)
    stack.constrain(Bounds(lower, upper, name="limits"))
    sol, ws = solve(stack, backend, SCALING_STALLS.get(backend))
    if not sol.ok:
        return
    assert 0.0 <= sol.scale <= 1.0
    assert np.all(sol.x >= lower - 1e-8) and np.all(sol.x <= upper + 1e-8)
    np.testing.assert_allclose(J @ sol.x, sol.scale * xd, atol=tol * max(1, abs(xd).max()))
    _assert_sns_agreement(sns_x, sns_s, sol, J, lower, upper, tol)
    assert_kkt(ws, max(tol, 1e-6))


@pytest.mark.parametrize("backend", scaling_backends())
@given(instances())
def test_sns_acceleration_vs_scaling_lp(backend, inst):
    """J q̈ + J̇q̇ = s ẍ_d: the drift is compensated in full, only ẍ_d is scaled."""
    tol = SCALING_TOL.get(backend, TOL)
    m, n, _, rng = inst
    J, xdd, lower, upper = _sns_problem(rng, m, n + 1, min(m, n + 1))
    drift = 0.05 * rng.standard_normal(m)
    sns_x, sns_s = ref.sns_acceleration(J, xdd, drift, lower, upper)
    x = wbc.Variables(qdd=n + 1)
    stack = wbc.Stack(x)
    Jp = stack.parameter("J", J.shape, J)
    dp = stack.parameter("drift", m, drift)
    tp = stack.parameter("xdd", m, xdd)
    stack.add(wbc.Cost(Jp @ x["qdd"] + dp, target=tp, name="accel"), scaling=True)
    stack.constrain(Bounds(lower, upper, name="limits"))
    sol, ws = solve(stack, backend, SCALING_STALLS.get(backend))
    if not sol.ok:
        return
    np.testing.assert_allclose(J @ sol.x + drift, sol.scale * xdd,
                               atol=tol * max(1, abs(xdd).max()))
    _assert_sns_agreement(sns_x, sns_s, sol, J, lower, upper, tol)
    assert_kkt(ws, max(tol, 1e-6))


def test_sns_suboptimality_rate():
    """How often basic SNS misses the LP-optimal scale (docs/DESIGN.md, math note 4: roughly 2–4 %).

    Run on daqp over 300 seeded 6×7 problems; the rate is printed (``pytest -s``) and only
    guarded loosely, the one-sided inequality is asserted on every problem.
    """
    rng = np.random.default_rng(2024)
    stack = wbc.Stack(7).add(LinearTask(np.ones((6, 7)), np.ones(6), name="task"), scaling=True)
    stack.constrain(Bounds(-np.ones(7), np.ones(7), name="limits"))
    ws = stack.workspace("daqp", "tight")
    worse = 0
    for _ in range(300):
        J, xd, lower, upper = _sns_problem(rng, 6, 7, 6)
        ws.set(**{"task.A": J, "task.b": xd, "limits.lower": lower, "limits.upper": upper})
        sol = ws.solve()
        assert sol.ok, sol.message
        _, sns_s = ref.sns_velocity(J, xd, lower, upper)
        assert sol.scale >= sns_s - 1e-7
        worse += sol.scale > sns_s + 1e-7
    print(f"SNS sub-optimal in {worse}/300 = {worse / 3:.1f} % of problems")
    assert worse / 300 < 0.15


# ----------------------------------------------------------------------------- 5e
@pytest.mark.parametrize("backend", BACKENDS)
@given(st.integers(1, 6), st.integers(0, 2**32 - 1))
def test_rate_limit_then_saturation_is_bounded_qp(backend, k, seed):
    """clip(clip(û, u_prev ± Δ), ±u_max) = argmin (u − û)² over both intervals (docs/DESIGN.md,
    math note 5)."""
    rng = np.random.default_rng(seed)
    u_max = rng.uniform(0.5, 2.0, k)
    delta = rng.uniform(0.05, 1.0, k)
    u_prev = rng.uniform(-1, 1, k) * (u_max + delta)  # the two intervals always intersect
    u_hat = 3 * rng.standard_normal(k)
    expected = np.clip(np.clip(u_hat, u_prev - delta, u_prev + delta), -u_max, u_max)
    stack = wbc.Stack(k).add(LinearTask(np.eye(k), u_hat, name="command"))
    stack.constrain(Bounds(u_prev - delta, u_prev + delta, name="rate_limit"))
    stack.constrain(Bounds(-u_max, u_max, name="saturation"))
    sol, ws = solve(stack, backend)
    np.testing.assert_allclose(sol.x, expected, atol=TOL)
    assert_kkt(ws)
