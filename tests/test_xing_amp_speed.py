"""The fast :func:`wbc.papers.xing.closed_form.amp` (one SVD of the arm shared by SNS, the rank
test and P_A; P_A as ``I − J_F⁺J_F`` on the free joints where that provably agrees with eq. 10)
must compute what the former one computed (kept here as the referee: :func:`_amp_referee` and
its pieces, copied as they were): the command and β within 1e-9, α, the reason and the free
joints exactly, on random states of the study's robot (base enabled and disabled, SNS
saturating, bounds excluding zero), on rank-deficient Jacobians and on every tick of the study's
closed loops. The SNS core's new interval arithmetic must be bitwise the former one's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from helpers import random_matrix

import wbc.robots as robots
from wbc.experiments.studies import xing as study
from wbc.papers.xing import POSE, POSITION, ClosedFormPlanner
from wbc.papers.xing import closed_form as cf
from wbc.solvers.linalg import DERIVED_RTOL, _cutoff, _pinv_svd, _svd, pinv
from wbc.solvers.sns import _scale_intervals, sns_acceleration, sns_velocity

TOL = 1e-9
AMP = cf.amp  # the function under test (the planners' calls to it are wrapped below)


# ------------------------------------------------------------------ the referee (as it was)
def _scale_intervals_referee(a, b, lo, up):
    s_min = np.full(a.shape, -np.inf)
    s_max = np.full(a.shape, np.inf)
    pos, neg, zero = a > 0, a < 0, a == 0
    with np.errstate(invalid="ignore", over="ignore"):
        s_min[pos] = (lo[pos] - b[pos]) / a[pos]
        s_max[pos] = (up[pos] - b[pos]) / a[pos]
        s_min[neg] = (up[neg] - b[neg]) / a[neg]
        s_max[neg] = (lo[neg] - b[neg]) / a[neg]
    out = zero & ((b < lo) | (b > up))
    s_min[out], s_max[out] = np.inf, -np.inf
    return s_min, s_max


def _sns_referee(J, task, offset, lower, upper, tol, rtol, feas_tol):
    m, n = J.shape
    U, sv, Vt = _svd(J)
    smax = sv[0] if sv.size else 0.0
    cutoff = _cutoff(smax, J.shape, tol, DERIVED_RTOL if rtol is None else rtol)
    rank_J = int(np.count_nonzero(sv > cutoff))
    if feas_tol is None:
        finite = np.abs(np.concatenate([lower, upper]))
        finite = finite[np.isfinite(finite)]
        mag = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
        feas_tol = 1e-10 * mag
    lo_b, up_b = lower - feas_tol, upper + feas_tol
    free = np.ones(n, dtype=bool)
    q_sat = np.zeros(n)
    saturated: list[int] = []
    best = None
    it = 0
    while True:
        it += 1
        idx = np.flatnonzero(free)
        if it == 1:
            Uf, sf, Vtf = U, sv, Vt
        else:
            Uf, sf, Vtf = _svd(J[:, idx])
            if int(np.count_nonzero(sf > cutoff)) < rank_J:
                break
        P = _pinv_svd(Uf, sf, Vtf, cutoff)
        a = np.zeros(n)
        b = q_sat.copy()
        a[idx] = P @ task
        b[idx] = P @ (offset - J @ q_sat)
        s_min, s_max = _scale_intervals_referee(a[idx], b[idx], lo_b[idx], up_b[idx])
        violated = (s_min > 1.0) | (s_max < 1.0)
        if not violated.any():
            return a + b, 1.0, saturated, it
        s_hi = min(1.0, float(s_max.min()))
        s_lo = max(0.0, float(s_min.max()))
        if s_lo <= s_hi and (best is None or s_hi > best[0]):
            best = (s_hi, s_hi * a + b, tuple(saturated))
        with np.errstate(invalid="ignore"):
            gap = np.maximum(np.maximum(1.0 - s_max, s_min - 1.0), 0.0)
        j = int(idx[int(np.argmax(gap))])
        q1 = a[j] + b[j]
        q_sat[j] = upper[j] if (q1 - upper[j]) > (lower[j] - q1) else lower[j]
        free[j] = False
        saturated.append(j)
        if not free.any():
            break
    if best is None:
        return None, None, saturated, it
    s, q, sat = best
    return q, s, list(sat), it


def _scaling_factor_referee(demand, offset, lower, upper) -> float:
    s_min, s_max = _scale_intervals_referee(demand, offset, lower, upper)
    if np.any(s_min > 1e-12) or np.any(s_max < -1e-12):
        return 0.0
    return float(np.clip(s_max.min(initial=np.inf), 0.0, 1.0))


def _auxiliary_projector_referee(J, free):
    n = J.shape[1]
    P_N = np.eye(n) - pinv(J) @ J
    C = np.diag(~np.asarray(free, dtype=bool)).astype(float)
    return (np.eye(n) - pinv(C @ P_N)) @ P_N


def _amp_referee(J, xdd, drift, lower, upper, n_base, qdd_sa, transition, sigma_min,
                 sigma_thr):
    """``closed_form.amp`` as it was, on checked arguments."""
    r, n = J.shape
    base = slice(0, n_base)
    qdd = None
    if sigma_min >= sigma_thr:
        arm = slice(n_base, n)
        q_arm, alpha, saturated, _ = _sns_referee(J[:, arm], xdd,
                                                  -drift - J[:, base] @ transition,
                                                  lower[arm], upper[arm], None, None, None)
        spans = np.linalg.matrix_rank(J[:, arm]) == np.linalg.matrix_rank(J)
        if spans and q_arm is not None and alpha == 1.0:
            qdd = np.concatenate([transition, np.clip(q_arm, lower[arm], upper[arm])])
            free = np.ones(n, dtype=bool)
            free[base] = False
            free[[n_base + j for j in saturated]] = False
            reason = "arm"
        else:
            reason = "saturation"
    else:
        reason = "singularity"
    if qdd is None:
        qdd, alpha, saturated, _ = _sns_referee(J, xdd, -drift, lower, upper, None, None, None)
        if qdd is None:
            qdd, alpha, saturated = np.clip(np.zeros(n), lower, upper), 0.0, []
        qdd = np.clip(qdd, lower, upper)
        free = np.ones(n, dtype=bool)
        free[list(saturated)] = False
    tertiary = _auxiliary_projector_referee(J, free) @ qdd_sa
    tertiary[~free] = 0.0
    beta = _scaling_factor_referee(tertiary, qdd, lower, upper)
    return qdd + beta * tertiary, (float(alpha), beta, reason != "arm", reason, free)


# ------------------------------------------------------------------------------ checks
def _assert_same(J, xdd, drift, lower, upper, n_base, qdd_sa, transition, sigma_min,
                 sigma_thr) -> str:
    """``amp`` against the referee at one set of arguments; returns the reason."""
    got, info = AMP(J, xdd, drift, lower, upper, n_base, qdd_sa=qdd_sa, transition=transition,
                    sigma_min=sigma_min, sigma_thr=sigma_thr)
    want, (alpha, beta, enabled, reason, free) = _amp_referee(
        J, xdd, drift, lower, upper, n_base, qdd_sa, transition, sigma_min, sigma_thr)
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)
    assert abs(info.beta - beta) <= TOL
    assert (info.alpha, info.base_enabled, info.reason) == (alpha, enabled, reason)
    np.testing.assert_array_equal(info.free, free)
    return reason


@pytest.fixture(scope="module")
def robot():
    return robots.load(study.ROBOT)


@pytest.fixture
def checked_amp(monkeypatch):
    """Every ``amp`` call the planners make is checked against the referee; yields the list
    of the reasons seen."""
    reasons: list[str] = []

    def amp(J, xdd, drift, lower, upper, n_base, *, qdd_sa, transition, sigma_min, sigma_thr):
        reasons.append(_assert_same(J, xdd, drift, lower, upper, n_base, qdd_sa, transition,
                                    sigma_min, sigma_thr))
        return AMP(J, xdd, drift, lower, upper, n_base, qdd_sa=qdd_sa, transition=transition,
                   sigma_min=sigma_min, sigma_thr=sigma_thr)

    monkeypatch.setattr(cf, "amp", amp)
    return reasons


@pytest.mark.parametrize(("setup", "states", "jit"), [
    (POSITION, 1200, True), (POSE, 800, False), (replace(POSITION, bounds="viable"), 300, False)],
    ids=["position", "pose", "viable"])
def test_equals_the_former_amp_on_random_states(robot, checked_amp, setup, states, jit):
    rng = np.random.default_rng(11)
    planner = ClosedFormPlanner(robot, setup, "amp", jit)
    for _ in range(states):
        q, v, refs = study.random_state(rng, robot)
        planner.step(q, v, **refs)
    assert len(checked_amp) == states
    assert {"arm", "saturation", "singularity"} <= set(checked_amp)


def test_equals_the_former_amp_on_the_studys_closed_loops(robot, checked_amp):
    """The study's circle beyond the workspace, its pose case and the circle with the base
    enabled at σ_min < σ_thr (quick horizons), every tick."""
    start = study.staging(robot, None)
    pose0 = robot.frame_pose(start.q0, "ee")
    x0, rotation0 = pose0[:3, 3].copy(), pose0[:3, :3].copy()
    for references, seconds, setup, jit in (
            (study.circle(x0, 0.25, rotation0), 8.0, POSITION, True),
            (study.circle(x0, 0.10, rotation0), 4.0, POSITION, True),
            (study.swing(x0, rotation0), 4.0, POSE, False)):
        study.simulate(robot, ClosedFormPlanner(robot, setup, "amp", jit), references, seconds,
                       setup, start, study.DOCUMENTED, record=False)
    assert len(checked_amp) == 800
    assert {"arm", "singularity"} <= set(checked_amp)


@pytest.mark.parametrize("seed", range(6))
def test_equals_the_former_amp_on_saturating_and_rank_deficient_problems(seed):
    """Random Jacobians of every rank (arm and whole robot), tight bounds (SNS saturates),
    bounds that exclude zero (SNS finds no scale), both branches, tertiary objectives of
    every size; joints on their bounds with a tertiary of zero (β decided by round-off)."""
    rng = np.random.default_rng(seed)
    reasons = set()
    for _ in range(120):
        r, n_base = int(rng.choice([3, 6])), int(rng.choice([0, 2, 3]))
        n = n_base + 7
        J = random_matrix(rng, r, n, rank=int(rng.integers(1, r + 1)))
        kind = rng.integers(4)
        if kind == 1:  # the arm rank-deficient, the base columns not
            J[:, n_base:] = random_matrix(rng, r, 7, rank=int(rng.integers(1, r)))
        elif kind == 2:  # an exactly zero arm column and a repeated row
            J[:, n_base + int(rng.integers(7))] = 0.0
            J[-1] = J[0]
        width = rng.choice([0.05, 0.5, 5.0], n)
        lower = -width * rng.uniform(0.2, 1.0, n)
        upper = width * rng.uniform(0.2, 1.0, n)
        if kind == 3:  # bounds that exclude zero on some joints
            shift = rng.uniform(-1.0, 1.0, n) * width * (rng.random(n) < 0.3)
            lower, upper = lower + shift, upper + shift
        xdd, drift = rng.normal(0, rng.choice([0.1, 1, 10]), r), rng.normal(0, 0.5, r)
        qdd_sa = np.concatenate([np.zeros(n_base), rng.normal(0, rng.choice([0, 0.1, 10]), 7)])
        transition = rng.uniform(-0.5, 0.5, n_base) * (rng.random() < 0.5)
        sigma_min = float(rng.choice([0.0, np.inf]))
        reasons.add(_assert_same(J, xdd, drift, lower, upper, n_base, qdd_sa, transition,
                                 sigma_min, 0.15))
    assert {"arm", "saturation", "singularity"} <= reasons


def test_scale_intervals_are_bitwise_the_former_ones():
    """Every sign of ``a`` (zeros, ±0), offsets inside and outside the bounds, infinite
    bounds, bounds that exclude zero."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 12))
        a = rng.normal(0, 1, n) * rng.choice([0.0, -0.0, 1e-300, 1.0, 1e300], n)
        b = rng.normal(0, 2, n)
        lo, up = -rng.uniform(0, 2, n), rng.uniform(0, 2, n)
        lo[rng.random(n) < 0.2], up[rng.random(n) < 0.2] = -np.inf, np.inf
        b[rng.random(n) < 0.2] = lo[rng.random(n) < 1.0][0] if np.isfinite(lo[0]) else 0.0
        for got, want in zip(_scale_intervals(a, b, lo, up),
                             _scale_intervals_referee(a, b, lo, up), strict=True):
            np.testing.assert_array_equal(got, want)
        assert cf.scaling_factor(a, b, lo, up) == _scaling_factor_referee(a, b, lo, up)


@pytest.mark.parametrize("seed", range(4))
def test_sns_is_bitwise_the_former_one(seed):
    """:func:`sns_velocity` / :func:`sns_acceleration` (the SNS core, with the caller's
    tolerances or not) give exactly the former commands, scales and saturation orders."""
    rng = np.random.default_rng(seed)
    for _ in range(100):
        m, n = int(rng.integers(1, 7)), int(rng.integers(1, 10))
        J = random_matrix(rng, m, n, rank=int(rng.integers(0, min(m, n) + 1)))
        lower, upper = -rng.uniform(0.05, 2, n), rng.uniform(0.05, 2, n)
        task, drift = rng.normal(0, 3, m), rng.normal(0, 1, m)
        tol, feas = (None, None) if rng.random() < 0.5 else (1e-9, 1e-8)
        q, s, info = sns_velocity(J, task, lower, upper, tol=tol, feas_tol=feas,
                                  return_info=True)
        q0, s0, sat, _ = _sns_referee(J, task, np.zeros(m), lower, upper, tol, None, feas)
        np.testing.assert_array_equal(q, np.clip(q0, lower, upper))
        assert (s, info.saturated) == (s0, tuple(sat))
        shift = rng.uniform(-1, 1, n) * (rng.random(n) < 0.3)
        q, s, info = sns_acceleration(J, task, drift, lower + shift, upper + shift, tol=tol,
                                      feas_tol=feas, return_info=True)
        q0, s0, sat, _ = _sns_referee(J, task, -drift, lower + shift, upper + shift, tol, None,
                                      feas)
        if q0 is not None:
            np.testing.assert_array_equal(q, np.clip(q0, lower + shift, upper + shift))
            assert (s, info.saturated) == (s0, tuple(sat))
        else:
            assert s == 0.0
