"""The equivalence suite on the fused path (:mod:`wbc.fused`).

The tests of ``test_equivalence.py`` whose stacks have no task-scaling LP run again with every
daqp workspace replaced by a :class:`~wbc.fused.FusedWorkspace`, to the same tolerances and KKT
checks (of the QPs the generated daqp solved, frozen rows in their band): damped and weighted
damped pseudo-inverses (rank-deficient and conflicting instances, pinned variables), strict
hierarchies against recursive null-space projection (dependent and conflicting levels, the
min-norm level), additive null-space terms, rate limit then saturation. An example whose
generated daqp fails (an undamped level: a singular Hessian) takes the ordinary path; each
test asserts that the fused path answered some of its examples. The task-scaling tests are not
fused (see :mod:`wbc.fused`) and not repeated here.

The fused function is evaluated on CasADi's virtual machine here: hypothesis draws dozens of
shapes and each would be a C compilation (≈ 0.5–1 s). ``test_fused.py`` checks on fixed
instances that the compiled C gives the same numbers as this very function.
"""

from __future__ import annotations

import pytest
import test_equivalence as eq

import wbc
from wbc.fused import FusedWorkspace, why_not_fused

FUSED_ANSWERED = []  # one entry per fused solve of the running test


@pytest.fixture(autouse=True)
def fused_workspaces(monkeypatch):
    ordinary = wbc.Stack.workspace

    def workspace(stack, backend="daqp", profile="default", jit=False, **options):
        compiled = stack.compile()
        if why_not_fused(compiled, options) is not None:
            return ordinary(stack, backend, profile, jit, **options)
        ws = FusedWorkspace(compiled, profile, compile=False, **options)
        fused_solve = ws.solve

        def solve():
            solution = fused_solve()
            FUSED_ANSWERED.append(ws.fallback_solves == 0)
            return solution

        ws.solve = solve
        return ws

    monkeypatch.setattr(wbc.Stack, "workspace", workspace)
    FUSED_ANSWERED.clear()
    yield
    assert any(FUSED_ANSWERED), "no example of this test took the fused path"


test_damped_pinv_equals_one_level_qp = eq.test_damped_pinv_equals_one_level_qp
test_weighted_damped_pinv_equals_one_level_qp = eq.test_weighted_damped_pinv_equals_one_level_qp
test_strict_hierarchy_equals_recursive_nullspace_projection = (
    eq.test_strict_hierarchy_equals_recursive_nullspace_projection)
test_additive_nullspace_term_is_plain_cascade_when_unweighted = (
    eq.test_additive_nullspace_term_is_plain_cascade_when_unweighted)
test_additive_nullspace_term_needs_exact_form_when_weighted = (
    eq.test_additive_nullspace_term_needs_exact_form_when_weighted)
test_rate_limit_then_saturation_is_bounded_qp = eq.test_rate_limit_then_saturation_is_bounded_qp
