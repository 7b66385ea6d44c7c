"""Wheel-torque distribution of the omni platform: closed forms (wbc.solvers.reference) and their
QP stacks (wbc.papers.omni.distribution_tasks) on every backend with the tight profile.

Instances: the paper's wheel Jacobian or a random full-rank (4, 3) one, unequal (or equal)
normal forces, per-wheel or common friction coefficients, random platform wrenches.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import random_matrix
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linprog, minimize_scalar

import wbc
import wbc.robots as robots
from wbc.papers.omni import DISTRIBUTIONS, TorqueDistribution, distribution_stack
from wbc.papers.omni import closed_form as ref
from wbc.solvers import available_backends

BACKENDS = available_backends()
TOL = 1e-7
J_PAPER = robots.omni4_octagon().jacobian
METHODS = ref.DISTRIBUTION_METHODS


@st.composite
def instances(draw):
    """``(J, f_d, normal_forces, mu)``."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    J = J_PAPER if draw(st.booleans()) else random_matrix(rng, 4, 3)
    kind = draw(st.sampled_from(["unequal", "unequal", "equal"]))
    forces = rng.uniform(5.0, 300.0, 4) if kind == "unequal" else np.full(4, 110.0)
    mu = rng.uniform(0.2, 1.2, 4) if draw(st.booleans()) else np.full(4, 0.7)
    f_d = rng.standard_normal(3) * np.array([50.0, 50.0, 10.0])
    return J, f_d, forces, mu


def utilisation(tau, forces, mu) -> float:
    return float(np.max(np.abs(tau) / (mu * forces)))


# ------------------------------------------------------------------ closed forms
@given(instances())
def test_every_method_produces_the_wrench(inst):
    J, f_d, forces, mu = inst
    for method in METHODS:
        tau = ref.torque_distribution(J, f_d, forces, mu, method=method)
        np.testing.assert_allclose(J.T @ tau, f_d, atol=1e-9 * (1 + np.abs(f_d).max()))


@given(instances())
def test_min_norm_is_eq7_with_a_zero(inst):
    J, f_d, forces, mu = inst
    tau = ref.torque_distribution(J, f_d, forces, mu, method="min_norm")
    np.testing.assert_allclose(tau, np.linalg.lstsq(J.T, f_d, rcond=None)[0], atol=1e-10)
    assert abs(ref.torque_null_space(J)[:, 0] @ tau) < 1e-10  # no redundant component


@given(instances())
def test_proportional_maximises_the_reconstructed_H(inst):
    """α_opt is the maximiser of H(α) = −Σ (τ_i(α)/(μ_i f_i))², found here numerically; H is a
    quadratic in α (constant second difference) with zero derivative at α_opt."""
    J, f_d, forces, mu = inst
    tau0 = ref.torque_distribution(J, f_d, forces, mu, method="min_norm")
    n = ref.torque_null_space(J)[:, 0]
    tau = ref.torque_distribution(J, f_d, forces, mu, method="proportional")
    alpha_opt = n @ (tau - tau0)
    np.testing.assert_allclose(tau, tau0 + alpha_opt * n, atol=1e-10)

    def H(alpha):
        return -np.sum(((tau0 + alpha * n) / (mu * forces)) ** 2)

    numeric = minimize_scalar(lambda a: -H(a), bracket=(-10.0, 10.0), tol=1e-12).x
    assert alpha_opt == pytest.approx(numeric, abs=1e-5 * (1 + abs(numeric)))
    h = 1e-3 * (1 + abs(alpha_opt))
    assert abs(H(alpha_opt + h) - H(alpha_opt - h)) / (2 * h) < 1e-9 * (1 + abs(H(alpha_opt)))
    step = 1.0 + abs(alpha_opt)  # exact for a quadratic: a large step avoids cancellation
    second = [H(a + step) - 2 * H(a) + H(a - step) for a in (alpha_opt - 3.0, alpha_opt, 7.0)]
    np.testing.assert_allclose(second, second[1], rtol=1e-6)
    assert second[1] < 0  # concave: a maximum


def test_proportional_is_min_norm_when_capacities_are_equal():
    f_d = np.array([30.0, -12.0, 4.0])
    forces = np.full(4, 45.0 * 9.81 / 4)
    np.testing.assert_allclose(
        ref.torque_distribution(J_PAPER, f_d, forces, 0.6, method="proportional"),
        ref.torque_distribution(J_PAPER, f_d, forces, 0.6, method="min_norm"), atol=1e-12)


def test_proportional_shifts_torque_to_loaded_wheels():
    """A pure push along a wheel diagonal: with wheel 0 carrying more, it takes more torque."""
    f_d = np.array([0.0, 40.0, 0.0])
    forces = np.array([200.0, 110.0, 20.0, 110.0])
    tau = ref.torque_distribution(J_PAPER, f_d, forces, method="proportional")
    tau_min = ref.torque_distribution(J_PAPER, f_d, forces, method="min_norm")
    assert abs(tau[0]) > abs(tau_min[0]) and abs(tau[2]) < abs(tau_min[2])
    assert utilisation(tau, forces, 1.0) < utilisation(tau_min, forces, 1.0)


def test_proportional_can_exceed_min_norms_peak_but_minmax_cannot():
    """H is a sum of squares: it may raise the largest utilisation (here wheel 2, the least
    loaded, by 23 %) while lowering the others; minmax never does."""
    f_d, forces = np.array([-40.0, -20.0, -5.0]), np.array([150.0, 110.0, 60.0, 120.0])
    u = {m: utilisation(ref.torque_distribution(J_PAPER, f_d, forces, method=m), forces, 1.0)
         for m in METHODS}
    assert u["proportional"] > 1.2 * u["min_norm"]
    assert u["minmax"] < u["min_norm"] < u["proportional"]


@given(instances())
def test_minmax_is_the_lp_optimum_and_beats_the_others(inst):
    J, f_d, forces, mu = inst
    c = mu * forces
    tau = ref.torque_distribution(J, f_d, forces, mu, method="minmax")
    lp = linprog(np.r_[np.zeros(4), 1.0],
                 A_ub=np.block([[np.diag(1 / c), -np.ones((4, 1))],
                                [-np.diag(1 / c), -np.ones((4, 1))]]),
                 b_ub=np.zeros(8), A_eq=np.c_[J.T, np.zeros(3)], b_eq=f_d,
                 bounds=[(None, None)] * 5, method="highs")
    assert lp.status == 0
    assert utilisation(tau, forces, mu) == pytest.approx(lp.fun, rel=1e-7, abs=1e-12)
    for other in ("min_norm", "proportional"):
        tau_other = ref.torque_distribution(J, f_d, forces, mu, method=other)
        assert utilisation(tau, forces, mu) <= utilisation(tau_other, forces, mu) * (1 + 1e-12)


def test_friction_utilisation_units():
    u = ref.friction_utilisation([1.0, -2.0, 0.0, 0.5], [100.0, 100.0, 50.0, 10.0], 0.1, 0.5)
    np.testing.assert_allclose(u, [0.2, 0.4, 0.0, 1.0])


def test_three_wheels_have_no_redundancy():
    J = robots.OmniBase([0.0, 2.1, 4.2], 0.2, 0.05, mass=5.0, com=[0, 0, 0],
                        inertia=np.eye(3), v_max=[1, 1, 1], a_max=[1, 1, 1]).jacobian
    f_d, forces = np.array([3.0, 1.0, 0.2]), np.array([10.0, 20.0, 30.0])
    taus = [ref.torque_distribution(J, f_d, forces, method=m) for m in METHODS]
    np.testing.assert_allclose(taus[1], taus[0], atol=1e-12)
    np.testing.assert_allclose(taus[2], taus[0], atol=1e-12)


@pytest.mark.parametrize("bad, error", [
    (dict(normal_forces=[100.0, 0.0, 100.0, 100.0]), wbc.InvalidValueError),
    (dict(normal_forces=[100.0, -5.0, 100.0, 100.0]), wbc.InvalidValueError),
    (dict(normal_forces=[100.0, 100.0, 100.0]), wbc.ShapeError),
    (dict(normal_forces=[100.0, np.nan, 100.0, 100.0]), wbc.NonFiniteError),
    (dict(mu=0.0), wbc.InvalidValueError),
    (dict(mu=[0.5, 0.5]), wbc.ShapeError),
    (dict(f_d=[1.0, 2.0]), wbc.ShapeError),
    (dict(J=np.ones((4, 2))), wbc.ShapeError),
    (dict(J=np.c_[J_PAPER[:, :2], J_PAPER[:, 0]]), wbc.InvalidValueError),
    (dict(method="least_squares"), wbc.InvalidValueError),
])
def test_reference_refuses_bad_input(bad, error):
    args = dict(J=J_PAPER, f_d=[10.0, 0.0, 0.0], normal_forces=np.full(4, 100.0), mu=1.0,
                method="proportional") | bad
    with pytest.raises(error, match=next(iter(bad)) if "method" not in bad else "method"):
        ref.torque_distribution(**args)


def test_minmax_needs_one_redundant_torque():
    J = robots.OmniBase(np.linspace(0, 5, 5), 0.2, 0.05, mass=5.0, com=[0, 0, 0],
                        inertia=np.eye(3), v_max=[1, 1, 1], a_max=[1, 1, 1]).jacobian
    with pytest.raises(wbc.InvalidValueError, match="minmax"):
        ref.torque_distribution(J, [1.0, 0.0, 0.0], np.full(5, 10.0), method="minmax")


# ------------------------------------------------------------------ the stacks
_DISTRIBUTIONS: dict[tuple[str, str], TorqueDistribution] = {}


def distribution(backend: str, method: str) -> TorqueDistribution:
    """One compiled distribution per backend and method, reused across examples."""
    key = (backend, method)
    if key not in _DISTRIBUTIONS:
        _DISTRIBUTIONS[key] = TorqueDistribution(J_PAPER, method, backend=backend,
                                                 profile="tight")
    return _DISTRIBUTIONS[key]


def solve(backend: str, method: str, J, f_d, forces, mu) -> np.ndarray:
    dist = distribution(backend, method)
    dist.workspace.set(**{"wrench.J": J})
    if method != "min_norm":
        dist.workspace.set(**{"friction.mu": mu})
    tau = dist(f_d, forces)
    assert dist.last_solution.ok, dist.last_solution.message
    np.testing.assert_allclose(J.T @ tau, f_d, atol=TOL * (1 + np.abs(f_d).max()))
    return tau


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("method", ["min_norm", "proportional"])
@given(inst=instances())
def test_qp_equals_closed_form(backend, method, inst):
    J, f_d, forces, mu = inst
    tau = solve(backend, method, J, f_d, forces, mu)
    expected = ref.torque_distribution(J, f_d, forces, mu, method=method)
    assert np.abs(tau - expected).max() <= TOL * max(1.0, np.abs(expected).max())


@pytest.mark.parametrize("backend", BACKENDS)
@given(inst=instances())
def test_qp_minmax_is_optimal_and_beats_the_others(backend, inst):
    J, f_d, forces, mu = inst
    tau = solve(backend, "minmax", J, f_d, forces, mu)
    value = utilisation(tau, forces, mu)
    expected = ref.torque_distribution(J, f_d, forces, mu, method="minmax")
    assert value == pytest.approx(utilisation(expected, forces, mu), rel=1e-6, abs=1e-12)
    assert np.abs(tau - expected).max() <= 1e-6 * max(1.0, np.abs(expected).max())
    for other in ("min_norm", "proportional"):
        tau_other = solve(backend, other, J, f_d, forces, mu)
        assert value <= utilisation(tau_other, forces, mu) * (1 + 1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_minmax_ties_take_the_least_norm_member(backend):
    """Rows 0–2 dependent: the null vector n = (1, 1, −1, 0)/√3 leaves wheel 3 alone with a yaw
    moment, so every small α is optimal; both forms return the least-norm member (α = 0)."""
    J = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    f_d, forces, mu = np.array([0.0, 0.0, 2.0]), np.full(4, 10.0), np.full(4, 1.0)
    expected = ref.torque_distribution(J, f_d, forces, mu, method="minmax")
    np.testing.assert_allclose(expected, [0.0, 0.0, 0.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(solve(backend, "minmax", J, f_d, forces, mu), expected,
                               atol=1e-6)


def test_stack_shapes_and_parameters():
    stack = distribution_stack(J_PAPER, "minmax", mu=[0.5, 0.6, 0.7, 0.8])
    assert stack.variables.names == ["tau", "t"]
    assert {"wrench.J", "wrench.f_d", "friction.normal_forces", "friction.mu"} <= set(
        stack.parameters)
    assert set(DISTRIBUTIONS) == set(METHODS)
    assert distribution_stack(J_PAPER, "min_norm").variables.names == ["tau"]


@pytest.mark.parametrize("method", DISTRIBUTIONS)
@pytest.mark.parametrize("forces, error, match", [
    ([100.0, 0.0, 100.0, 100.0], wbc.InvalidValueError, "normal_forces"),
    ([100.0, 100.0, -1.0, 100.0], wbc.InvalidValueError, "normal_forces"),
    ([100.0, 100.0, 100.0], wbc.ShapeError, "normal_forces"),
    ([100.0, np.inf, 100.0, 100.0], wbc.NonFiniteError, "normal_forces"),
])
def test_stack_refuses_bad_normal_forces(method, forces, error, match):
    dist = distribution("daqp", method)
    with pytest.raises(error, match=match):
        dist([10.0, 0.0, 0.0], forces)


def test_stack_refuses_bad_construction_and_wrench():
    with pytest.raises(wbc.ShapeError, match="J"):
        TorqueDistribution(np.ones((4, 2)))
    with pytest.raises(wbc.InvalidValueError, match="mu"):
        TorqueDistribution(J_PAPER, mu=[1.0, 1.0, -0.1, 1.0])
    with pytest.raises(wbc.ShapeError, match="mu"):
        TorqueDistribution(J_PAPER, mu=[1.0, 1.0])
    with pytest.raises(wbc.InvalidValueError, match="method"):
        TorqueDistribution(J_PAPER, method="fair")
    with pytest.raises(wbc.ShapeError, match="f_d"):
        distribution("daqp", "proportional")([1.0, 2.0], np.full(4, 100.0))
