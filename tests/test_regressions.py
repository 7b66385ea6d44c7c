"""One test per defect the fuzz campaign and the audits found (issue 12), so none comes back.

1. quadprog looped forever on degenerate constraints (duplicated rows of ``C' x >= b``): the
   adapter drops parallel rows before the call, and bounds every call in time.
2. ``FusedWorkspace.variable_bounds()`` returned a previous tick's bounds after a fused tick.
3. OSQP, updated with a lower side above its upper one (a joint outside its limits), kept the
   previous tick's data and reported that old problem's solution as solved; an upper bound of
   -inf it took for -1e30 and "solved" (x = -inf after clipping).
4. qpOASES failed every tick ("Division by zero") on a cascade level whose Hessian covers only
   some variables below frozen rows (wbc study petric's whole-body stack): a failed solve is
   tried once more from a cold start with every bound initially inactive.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from helpers import PETRIC_LEVEL

import wbc
from wbc.fused import compiler_available
from wbc.solvers import available_backends, make_backend

# The generator of the degenerate problems the hang hunt found (quadprog 0.1.14): a
# rank-deficient H plus 1e-5 I, random rows of C whose trailing ones repeat leading ones
# (same sides), and, with combo, a last row that is the sum of the first two.
PROBLEM = textwrap.dedent("""
    import numpy as np

    def degenerate(seed, combo=False):
        r = np.random.default_rng(seed)
        n = int(r.integers(1, 8)); k = int(r.integers(1, 10))
        M = r.standard_normal((n, n)); M[:, :int(r.integers(0, n + 1))] = 0
        H = M @ M.T + 1e-5 * np.eye(n)
        C = r.standard_normal((n, k)); b = r.standard_normal(k)
        d = int(r.integers(0, k)); C[:, d:] = C[:, :k - d]
        if combo and k > 2:
            C[:, -1] = C[:, 0] + C[:, 1]; b[-1] = b[0] + b[1]
        b[d:] = b[:k - d]
        return H, r.standard_normal(n), C, b
""")
HANGS = 7  # seed whose problem quadprog.solve_qp never returns from
HANGS_AFTER_DEDUP = 3740  # with combo: still cycles once the duplicated rows are gone
namespace: dict = {}
exec(PROBLEM, namespace)
degenerate = namespace["degenerate"]


def as_backend_qp(H, a, C, b):
    """quadprog's ``min 1/2 x'Hx - a'x, C'x >= b`` in the form of :mod:`wbc.qp`."""
    n, k = C.shape
    return (H, -a, np.ascontiguousarray(C.T), b, np.full(k, np.inf), np.full(n, -np.inf),
            np.full(n, np.inf))


def run_python(code: str, timeout: float) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter (a thread left spinning in quadprog ends with it)."""
    return subprocess.run([sys.executable, "-c", PROBLEM + textwrap.dedent(code)],
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.skipif("quadprog" not in available_backends(), reason="quadprog not installed")
def test_quadprog_itself_hangs_on_the_degenerate_problem():
    """The premise: quadprog's C loop does not return on this problem."""
    with pytest.raises(subprocess.TimeoutExpired):
        run_python(f"""
            import quadprog
            H, a, C, b = degenerate({HANGS})
            quadprog.solve_qp(H, a, C, b, 0)
        """, timeout=3.0)


@pytest.mark.skipif("quadprog" not in available_backends(), reason="quadprog not installed")
def test_quadprog_backend_solves_the_degenerate_problem_like_daqp():
    """The duplicated rows are dropped before the call: solved, in well under a second, with
    daqp's answer and multipliers that satisfy the KKT conditions of the full problem."""
    qp = as_backend_qp(*degenerate(HANGS))
    backend = make_backend("quadprog", "tight")
    backend.setup(*qp)
    start = time.perf_counter()
    result = backend.solve()
    assert time.perf_counter() - start < 0.5
    assert result.status is wbc.Status.SOLVED
    oracle = make_backend("daqp", "tight")
    oracle.setup(*qp)
    np.testing.assert_allclose(result.x, oracle.solve().x, atol=1e-7)
    H, g, A = qp[:3]
    np.testing.assert_allclose(H @ result.x + g + A.T @ result.y + result.z, 0, atol=1e-8)


@pytest.mark.skipif("quadprog" not in available_backends(), reason="quadprog not installed")
def test_quadprog_backend_call_is_bounded_when_degeneracy_remains():
    """A row that is the sum of two others still makes quadprog cycle: the backend stops
    waiting after ``time_limit`` and reports NUMERICAL (the workspace then falls back)."""
    out = run_python(f"""
        import time
        import numpy as np
        from wbc.solvers import make_backend
        H, a, C, b = degenerate({HANGS_AFTER_DEDUP}, combo=True)
        n, k = C.shape
        backend = make_backend("quadprog", "tight", time_limit=0.2)
        backend.setup(H, -a, np.ascontiguousarray(C.T), b, np.full(k, np.inf),
                      np.full(n, -np.inf), np.full(n, np.inf))
        start = time.perf_counter()
        result = backend.solve()
        print(result.status.name, time.perf_counter() - start, np.isfinite(result.x).all())
    """, timeout=30.0)
    status, elapsed, finite = out.stdout.split()
    assert status == "NUMERICAL" and float(elapsed) < 1.0 and finite == "True", out.stderr


def test_quadprog_parallel_rows_keeps_what_matters():
    """Parallel inequalities keep the tightest; implied ones beside an equality go; rows that
    contradict an equality stay (quadprog must see the conflict)."""
    from wbc.solvers.quadprog_backend import parallel_rows

    e = np.array([[1.0], [0.0]])
    # columns: x0 >= 1 (equality x0 = 1), 2 x0 >= 1 (implied), x0 >= 3 (contradicts), -x0 >= -5
    C = np.hstack([e, 2 * e, e, -e])
    keep = parallel_rows(C, np.array([1.0, 1.0, 3.0, -5.0]), n_eq=1)
    assert keep.tolist() == [True, False, True, False]
    # two inequalities the same way: the tighter stays
    keep = parallel_rows(np.hstack([e, 3 * e]), np.array([1.0, 6.0]), n_eq=0)
    assert keep.tolist() == [False, True]
    assert parallel_rows(np.eye(2), np.zeros(2), n_eq=0) is None


@pytest.mark.skipif(not compiler_available(), reason="no C compiler for the fused tick")
def test_fused_variable_bounds_are_this_ticks():
    """After a fused tick, ``variable_bounds()`` is that tick's (it was a previous tick's: the
    fuzz saw 'bound excursions' of 86 on a commanded x that was inside its bounds)."""
    from wbc.fused import FusedWorkspace
    from wbc.tasks import Bounds, LinearTask

    stack = wbc.Stack(wbc.Variables(x=3), damping=1e-3)
    stack.add(LinearTask(np.eye(3), np.zeros(3), name="t"))
    stack.constrain(Bounds(-np.ones(3), np.ones(3), name="box"))
    ws = FusedWorkspace(stack.compile(), "tight")
    for k in range(3):
        lower = np.full(3, -1.0 - k)
        ws.set(**{"box.lower": lower, "box.upper": lower + 0.5, "t.b": np.zeros(3)})
        assert ws.solve().status is wbc.Status.SOLVED and ws.fallback_solves == 0
        lb, ub = ws.variable_bounds()
        np.testing.assert_array_equal(lb, lower)
        np.testing.assert_array_equal(ub, lower + 0.5)


@pytest.mark.parametrize("backend", [b for b in ("qpoases", "casadi:osqp")
                                     if b in available_backends()])
@pytest.mark.parametrize("rows", [0, 1])
def test_constant_objective_level_is_solved(backend, rows):
    """An empty or all-zero task on an undamped level (H = 0, g = 0) was 'unbounded' for
    qpOASES: every x is optimal there, so the level below decides."""
    from wbc.tasks import LinearTask

    stack = wbc.Stack(wbc.Variables(x=3))
    stack.add(LinearTask(np.zeros((rows, 3)), np.zeros(rows), name="empty"))
    stack.add(LinearTask(np.eye(3), np.ones(3), name="t"), priority=1)
    solution = stack.solve(backend)
    assert solution.status is wbc.Status.SOLVED
    np.testing.assert_allclose(solution.x, np.ones(3), atol=1e-5)


@pytest.mark.skipif("proxqp" not in available_backends(), reason="proxqp not installed")
def test_proxqp_tick_is_bounded_on_a_badly_scaled_level():
    """wbc fuzz's stack structure 0 of seed 1: a level with H up to 1e13 made ProxQP iterate
    for 48 s (10⁴ × 1500 iterations); the default profile now stops it well under 1 s."""
    from wbc.experiments.campaigns import fuzz

    for case, _, defect, message in fuzz.stack_cases("proxqp", seed=1, structures=1, draws=1):
        assert defect is None, (case["tick"], message)


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("bad", ["crossed", "upper_minus_inf"])
def test_an_empty_box_after_a_solved_tick_is_not_solved(backend, bad):
    """Every backend reports an empty feasible set as a failure, never the previous answer."""
    n = 3
    H, g, A = np.eye(n), -np.ones(n), np.ones((1, n))
    lA, uA = np.array([-10.0]), np.array([10.0])
    lb, ub = -np.ones(n), np.ones(n)
    qp = make_backend(backend)
    qp.setup(H, g, A, lA, uA, lb, ub)
    assert qp.solve().status is wbc.Status.SOLVED
    lb, ub = lb.copy(), ub.copy()
    if bad == "crossed":
        lb[1], ub[1] = 2.0, -2.0
    else:
        lb[1], ub[1] = -np.inf, -np.inf
    qp.update(H, g, A, lA, uA, lb, ub)
    result = qp.solve()
    assert result.status is not wbc.Status.SOLVED, result.x


@pytest.mark.skipif("qpoases" not in available_backends(), reason="qpoases not installed")
@pytest.mark.parametrize("retry", [True, False])
def test_qpoases_level_with_a_partial_hessian_below_frozen_rows(retry, monkeypatch):
    """Level 1 of wbc study petric's whole-body stack at the start pose: min |x_base|² under
    the three frozen TCP rows (equalities), velocity bounds. Its optimum has x_base = 0."""
    from wbc.solvers import casadi_backend

    if not retry:
        monkeypatch.setattr(casadi_backend, "RETRY_OPTIONS", {})
    H, g, A, lA, uA, lb, ub = PETRIC_LEVEL  # exact: the failure depends on roundoff entries
    qp = make_backend("qpoases")
    qp.setup(H, g, A, lA, uA, lb, ub)
    result = qp.solve()
    if retry:
        assert result.status is wbc.Status.SOLVED
        np.testing.assert_allclose(A @ result.x, 0.0, atol=1e-9)
        np.testing.assert_allclose(result.x[:2], 0.0, atol=1e-9)
    else:  # the premise: qpOASES' own first attempt fails here
        assert result.status is not wbc.Status.SOLVED


def test_daqp_retries_a_solve_its_tight_proximal_tolerance_fails():
    """A level of a random ``wbc fuzz`` stack (data scaled up to 1e6, singular Hessian): with
    the profiles' eta_prox = 1e-10 DAQP reports it unbounded, with its own 1e-6 it solves it.
    The backend retries at 1e-6 and says so; the answer is DAQP's default's."""
    from pathlib import Path

    qp = np.load(Path(__file__).parent / "data" / "daqp_unbounded_at_tight_eta_prox.npz")
    data = [qp[k] for k in ("H", "g", "A", "lA", "uA", "lb", "ub")]
    loose = make_backend("daqp", "default", eta_prox=1e-6)
    loose.setup(*data)
    expected = loose.solve()
    assert expected.status is wbc.Status.SOLVED and expected.message == ""
    for profile in ("default", "tight"):
        backend = make_backend("daqp", profile)
        backend.setup(*data)
        result = backend.solve()
        assert result.status is wbc.Status.SOLVED, result.message
        assert result.message == "solved with eta_prox 1e-6 after unbounded"
        np.testing.assert_allclose(result.x, expected.x, atol=1e-9 * np.abs(expected.x).max())
    infeasible = make_backend("daqp")  # not retried: an infeasible verdict stands
    H = np.eye(2)
    infeasible.setup(H, np.zeros(2), np.ones((1, 2)), np.array([5.0]), np.array([6.0]),
                     -np.ones(2), np.ones(2))
    result = infeasible.solve()
    assert result.status is wbc.Status.INFEASIBLE and "eta_prox" not in result.message
