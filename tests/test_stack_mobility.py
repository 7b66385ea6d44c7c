"""Per-tick mobility, level-local hard constraints and ``Stack.x_above`` (the core pieces of
Sorour et al.'s eq. 9: ψ changes every tick, its pins hold while the task level is solved only).

Every equivalence runs on every installed backend with the ``"tight"`` profile.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from helpers import assert_kkt, random_matrix
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.solvers import available_backends
from wbc.solvers import reference as ref
from wbc.tasks import Bounds, LinearTask

BACKENDS = available_backends()
TOL = 1e-7
# Backends whose persistent state does not survive a bound switching between 0 and ±inf from
# one tick to the next (a pin appearing or vanishing): ProxQP keeps its first data's
# preconditioner (answers then drift by ~1e-5), OSQP's and qpOASES' warm starts (multipliers on
# absent bounds; qpOASES's homotopy fails). For them the equivalence is checked on a fresh
# workspace per tick; the study's controllers use daqp by default.
FRESH_PER_TICK = {"proxqp", "osqp", "casadi:osqp", "qpoases"}


def shared_stack(n: int, rho: float, nullspace: bool) -> wbc.Stack:
    """``qd_base: 3`` + ``qd_arm: n − 3``; mobility ``diag((1 − ψ) I, ψ I)`` at level 0 only,
    ψ a parameter; optionally the exact null-space level ``min ||x − x_above − z||²``."""
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=n - 3), damping={0: rho})
    psi = stack.parameter("psi", 1)
    stack.set_mobility(ca.vertcat(ca.repmat(1 - psi, 3, 1), ca.repmat(psi, n - 3, 1)),
                       levels=[0])
    stack.add(LinearTask(np.zeros((6, n)), np.zeros(6), name="task"), priority=0)
    if nullspace:
        z = stack.parameter("z", n)
        stack.add(wbc.Cost(stack.variables.symbol, stack.x_above() + z, name="dex"), priority=1)
    return stack


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.sampled_from([4, 6, 10]), st.sampled_from([6, 5, 2]),
       st.sampled_from([0.05, 0.1, 0.5]))
def test_per_tick_mobility_recovers_weighted_pinv_and_nullspace_term(backend, seed, n, rank,
                                                                     rho):
    """One workspace, ψ changed every tick (0, 0.3, 0.5, 1, random): level 0 is
    ``M Jᵀ(J M Jᵀ + ρ²I)⁻¹ v`` with the pins of ψ ∈ {0, 1}; level 1 adds ``(I − J⁺J) z``
    exactly, moving the joints level 0 pinned. (ρ > 0: with ρ = 0 and a rank-deficient J the
    level-0 optimum is a set, and the weighted pseudo-inverse picks one point of it.)"""
    rng = np.random.default_rng(seed)
    stack = shared_stack(n, rho, nullspace=True)
    compiled = stack.compile()
    ws = stack.workspace(backend, "tight")
    for psi in (0.0, 0.3, 0.5, 1.0, rng.uniform()):
        J = random_matrix(rng, 6, n, min(rank, n))
        v, z = rng.standard_normal(6), rng.standard_normal(n)
        if backend in FRESH_PER_TICK:
            ws = stack.workspace(backend, "tight")
        ws.set(psi=[psi], z=z, **{"task.A": J, "task.b": v})
        sol = ws.solve()
        assert sol.ok, sol.message
        mobility = np.r_[np.full(3, 1 - psi), np.full(n - 3, psi)]
        x1 = ref.weighted_damped_pinv(J, rho, mobility) @ v
        np.testing.assert_allclose(sol.levels[0].x, x1, atol=TOL)
        np.testing.assert_allclose(sol.x, x1 + ref.nullspace_projector(J) @ z, atol=TOL)
        assert_kkt(ws)
        if psi in (0.0, 1.0):
            pinned = slice(3, n) if psi == 0.0 else slice(0, 3)
            assert np.abs(sol.levels[0].x[pinned]).max() < 1e-9
            moved = (np.eye(n) - np.linalg.pinv(J) @ J) @ z
            if np.abs(moved[pinned]).max() > 1e-3:  # the null-space level moves them
                assert np.abs(sol.x[pinned]).max() > 1e-4
    assert stack.compile() is compiled  # nothing recompiled


def test_mobility_everywhere_pins_every_level():
    """``levels=None``: the pins hold at the null-space level too (the joints stay at 0)."""
    n = 6
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=3), damping={0: 0.1})
    psi = stack.parameter("psi", 1, [1.0])
    stack.set_mobility(ca.vertcat(ca.repmat(1 - psi, 3, 1), ca.repmat(psi, 3, 1)))
    rng = np.random.default_rng(3)
    stack.add(LinearTask(random_matrix(rng, 3, n), rng.standard_normal(3), name="t"))
    stack.add(LinearTask(np.eye(n), rng.standard_normal(n), name="ns"), priority=1)
    sol = stack.solve("daqp")
    assert sol.ok
    np.testing.assert_array_equal(sol["qd_base"], 0.0)
    lb, ub = stack.workspace().variable_bounds()
    assert np.all(np.isinf(lb)) and np.all(np.isinf(ub))  # not solved yet: nothing evaluated


@pytest.mark.parametrize("backend", BACKENDS)
def test_level_local_constraint_holds_at_its_level_only(backend):
    """Level 0: ``x₀ + x₁ = 2`` with ``x₁ <= 0`` local to it; level 1: ``x₁ = 1``. Level 1
    keeps level 0's task row, not its constraint: ``x = (1, 1)``. A constraint of every level
    gives ``(2, 0)``."""
    for levels, expected in (([0], [1.0, 1.0]), (None, [2.0, 0.0])):
        stack = wbc.Stack(2)
        stack.add(LinearTask([[1.0, 1.0]], [2.0], name="sum"), priority=0)
        stack.add(LinearTask([[0.0, 1.0]], [1.0], name="second"), priority=1)
        stack.constrain(Bounds([-np.inf, -np.inf], [np.inf, 0.0], name="cap"), levels=levels)
        ws = stack.workspace(backend, "tight")
        sol = ws.solve()
        assert sol.ok, sol.message
        assert sol.levels[0].x[1] <= 1e-7
        np.testing.assert_allclose(sol.levels[0].x.sum(), 2.0, atol=TOL)
        np.testing.assert_allclose(sol.x, expected, atol=1e-6)


def test_level_local_row_constraint_and_min_norm_level():
    """A level-local inequality row is absent from the min-norm level's QP."""
    stack = wbc.Stack(2)
    stack.add(LinearTask([[1.0, 0.0]], [1.0], name="first"), priority=0)
    x = stack.variables.symbol
    stack.constrain(wbc.Inequality(x[0] + x[1], 2.0, 3.0, name="band"), levels=[0])
    compiled = stack.compile()
    assert [b.m_hard for b in compiled.blocks] == [1, 0]
    sol = stack.solve("daqp")
    assert sol.ok
    assert 2.0 - 1e-9 <= sol.levels[0].x.sum() <= 3.0 + 1e-9
    np.testing.assert_allclose(sol.x, [1.0, 0.0], atol=1e-9)  # min-norm: band not kept


def test_x_above_is_zero_at_the_first_level_and_the_previous_optimum_below():
    stack = wbc.Stack(2)
    above = stack.x_above()
    stack.add(wbc.Cost(stack.variables.symbol, above + np.array([1.0, 2.0]), name="a"))
    stack.add(wbc.Cost(stack.variables.symbol, 2 * above, name="b"), priority=1)
    sol = stack.solve("daqp")
    np.testing.assert_allclose(sol.levels[0].x, [1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(sol.x, [1.0, 2.0], atol=1e-12)  # frozen: level 0 fixes x
    sol = stack.solve("daqp")  # reset every tick: same answer again
    np.testing.assert_allclose(sol.levels[0].x, [1.0, 2.0], atol=1e-12)


def test_constant_mobility_with_levels_matches_per_tick_form():
    rng = np.random.default_rng(7)
    J, v, z = random_matrix(rng, 3, 6, 2), rng.standard_normal(3), rng.standard_normal(6)
    mobility = np.r_[np.zeros(3), np.ones(3)]
    stack = wbc.Stack(6, damping={0: 0.2}).set_mobility(mobility, levels=0)
    stack.add(LinearTask(J, v, name="t"), priority=0)
    stack.add(wbc.Cost(stack.variables.symbol, stack.x_above() + z, name="ns"), priority=1)
    sol = stack.solve("daqp", "tight")
    x1 = ref.weighted_damped_pinv(J, 0.2, mobility) @ v
    np.testing.assert_allclose(sol.x, x1 + ref.nullspace_projector(J) @ z, atol=TOL)


def test_bad_mobility_and_levels_are_refused():
    stack = wbc.Stack(3)
    with pytest.raises(wbc.ShapeError, match="3 entries"):
        stack.set_mobility(ca.SX.sym("m", 2))
    with pytest.raises(wbc.WbcError, match="decision vector"):
        stack.set_mobility(stack.variables.symbol)
    with pytest.raises(wbc.WbcError, match="levels is empty"):
        stack.set_mobility(np.ones(3), levels=[])
    with pytest.raises(wbc.WbcError, match="integer priorities"):
        stack.constrain(Bounds(-1.0, 1.0, name="b"), levels=["first"])
    with pytest.raises(wbc.InvalidValueError, match="positive semi-definite"):
        stack.set_mobility(np.array([1.0, -1.0, 1.0]))
