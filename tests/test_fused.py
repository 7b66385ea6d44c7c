"""The fused tick (:mod:`wbc.fused`): compiled C equals the virtual machine and the ordinary
daqp path (active bounds, hard and soft rows), failures keep their statuses and fallbacks, the
controller picks the path as documented, and a tick allocates nothing in steady state.
No speed is asserted."""

from __future__ import annotations

import time
import tracemalloc

import casadi as ca
import numpy as np
import pytest
from helpers import assert_kkt, kkt_residuals

import wbc
from wbc.fused import (
    FROZEN_BAND,
    MAX_SKIPPED_TICKS,
    FusedWorkspace,
    fused_function,
    why_not_fused,
)
from wbc.tasks import (
    Bounds,
    ConfigurationLimit,
    FrameTask,
    LinearConstraint,
    LinearTask,
    PostureTask,
    VelocityLimit,
)

N = 6
DT = 0.01
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])


def one_qp_stack() -> wbc.Stack:
    """One level: a 3-row task, a soft inequality row, a hard row and bounds (every number a
    parameter, so that one compiled function serves every instance)."""
    stack = wbc.Stack(N, damping=0.05)
    stack.add(LinearTask(np.ones((3, N)), np.ones(3), name="task"))
    stack.add(LinearConstraint(np.ones((1, N)), [-1.0], [1.0], name="soft"), weight=2.0)
    stack.constrain(LinearConstraint(np.ones((1, N)), [-1.0], [1.0], name="row"))
    stack.constrain(Bounds(-np.ones(N), np.ones(N), name="box"))
    stack.constrain(Bounds(-np.inf, np.inf, name="floor"))  # with "box", sides can cross
    return stack


def instance(rng, active: bool) -> dict:
    """Random data; ``active``: tight bounds and rows, so that several are active."""
    width = 0.1 if active else 10.0
    return {"task.A": rng.standard_normal((3, N)), "task.b": 3 * rng.standard_normal(3),
            "soft.C": rng.standard_normal((1, N)), "soft.lower": [-width], "soft.upper": [width],
            "row.C": rng.standard_normal((1, N)), "row.lower": [-width], "row.upper": [width],
            "box.lower": -width * np.ones(N), "box.upper": width * np.ones(N)}


@pytest.fixture(scope="module")
def workspaces():
    """(compiled C, virtual machine, ordinary daqp) on the same stack, tight profile."""
    compiled = one_qp_stack().compile()
    return (FusedWorkspace(compiled, "tight"), FusedWorkspace(compiled, "tight", compile=False),
            wbc.Workspace(compiled, "daqp", "tight"))


@pytest.mark.parametrize("active", [False, True])
def test_compiled_c_equals_the_virtual_machine_and_the_ordinary_path(workspaces, active):
    rng = np.random.default_rng(int(active))
    for _ in range(20):
        data = instance(rng, active)
        solutions = []
        for ws in workspaces:
            ws.set(**data)
            solution = ws.solve()
            assert solution.ok, solution.message
            solutions.append(solution.x.copy())
            assert_kkt(ws, tol=1e-8)
        c, vm, ordinary = solutions
        np.testing.assert_allclose(c, vm, atol=1e-12)
        np.testing.assert_allclose(c, ordinary, atol=1e-8)
        lower, upper = data["box.lower"], data["box.upper"]
        assert np.all(c >= lower) and np.all(c <= upper)  # clipped exactly into the bounds
    assert workspaces[0].fallback_solves == workspaces[1].fallback_solves == 0


def test_the_kkt_check_of_a_fused_tick_can_fail(workspaces):
    fused = workspaces[0]
    fused.set(**instance(np.random.default_rng(5), active=True))
    assert fused.solve().ok
    (_, qp, result), = fused.last_qps()
    assert np.abs(result.y).max() + np.abs(result.z).max() > 1e-6  # something is active
    assert max(kkt_residuals(qp, result).values()) < 1e-8
    flipped = wbc.QPResult(result.x, result.status, -result.y, -result.z)
    assert max(kkt_residuals(qp, flipped).values()) > 1e-6


@pytest.mark.parametrize("crossing", ["bounds", "rows"])
def test_an_infeasible_tick_keeps_its_status_and_message(workspaces, crossing):
    fused, _, ordinary = workspaces
    data = instance(np.random.default_rng(7), active=False)
    if crossing == "bounds":  # lower > upper: the bundled daqp does not check it, the fused
        data["floor.lower"] = np.full(N, -np.inf)  # function does
        data["floor.lower"][2] = 11.0
    else:  # consistent sides, contradictory rows and bounds: daqp finds it infeasible
        data["box.lower"], data["box.upper"] = -np.ones(N), np.ones(N)
        data["row.C"] = np.ones((1, N))
        data["row.lower"], data["row.upper"] = [N + 1.0], [N + 2.0]
    failures = fused.fallback_solves
    expected = ordinary.set(**data).solve() if crossing == "rows" else None
    solution = fused.set(**data).solve()
    assert fused.fallback_solves == failures + 1
    assert solution.status is wbc.Status.INFEASIBLE and not solution.partial
    assert np.array_equal(solution.x, np.zeros(N))  # never a silent garbage command
    if expected is not None:
        assert solution.message == expected.message and solution.conflict == expected.conflict
    fused.set(**instance(np.random.default_rng(8), active=False),
              **{"floor.lower": np.full(N, -np.inf)})
    assert fused.solve().ok  # and the next tick is fused again
    assert fused.fallback_solves == failures + 1


def test_the_solver_callable_is_solve_with_the_model_time(workspaces):
    """:meth:`FusedWorkspace.solver` hands out the fused solve itself: an answered tick returns
    :attr:`~FusedWorkspace.fused_solution` (as ``solve()`` does), with ``timings.model`` the
    time from ``started`` to the call; a failed call returns the ordinary path's own solution,
    timed the same way."""
    fused = workspaces[0]
    solve = fused.solver()
    assert solve is fused.solver()  # built once
    fused.set(**instance(np.random.default_rng(11), active=True))
    assert fused.solve() is fused.fused_solution
    started = time.perf_counter() - 1.0  # a caller's tick that began one second ago
    solution = solve(started)
    assert solution is fused.fused_solution and solution.ok
    assert 1.0 <= solution.timings.model < 2.0 and 0.0 < solution.timings.solve < 1.0
    data = instance(np.random.default_rng(12), active=False)
    data["floor.lower"] = np.full(N, -np.inf)
    data["floor.lower"][2] = 11.0  # crossed sides: the fused call fails
    failures = fused.fallback_solves
    failed = fused.set(**data).solver()(started)
    assert failed is not fused.fused_solution and failed.status is wbc.Status.INFEASIBLE
    assert fused.fallback_solves == failures + 1 and 1.0 <= failed.timings.model < 2.0
    data["floor.lower"] = np.full(N, -np.inf)
    assert fused.set(**data).solve() is fused.fused_solution  # fused again


def test_the_controller_reads_no_private_attribute_of_its_workspace():
    """The tick is the workspace's public operation: ``wbc/controller.py`` reads no ``_name``
    of a workspace (``self.workspace``, ``workspace``, ``ws``)."""
    import ast
    from pathlib import Path

    import wbc.controller

    source = Path(wbc.controller.__file__).read_text()

    def is_workspace(node: ast.expr) -> bool:
        return ((isinstance(node, ast.Name) and node.id in ("workspace", "ws"))
                or (isinstance(node, ast.Attribute) and node.attr == "workspace"))

    private = sorted({f"{ast.unparse(node.value)}.{node.attr}"
                      for node in ast.walk(ast.parse(source))
                      if isinstance(node, ast.Attribute) and node.attr.startswith("_")
                      and not node.attr.startswith("__") and is_workspace(node.value)})
    assert private == []


def scaling_stack() -> wbc.Stack:
    stack = wbc.Stack(3, damping=0.1)
    stack.add(LinearTask(np.eye(3)[:1], [1.0], name="a"), priority=0, scaling=True)
    stack.constrain(Bounds(-np.ones(3), np.ones(3), name="box"))
    return stack


def test_what_is_not_fused_says_why():
    scaling = scaling_stack().compile()
    assert "task-scaling LPs (scaling LP of level 0" in why_not_fused(scaling, {})
    single = one_qp_stack().compile()
    assert why_not_fused(single, {"primal_tol": 1e-9}) is None
    assert "sing_tol" in why_not_fused(single, {"sing_tol": 1e-9})
    undamped = wbc.Stack(3).add(LinearTask(np.eye(3), np.ones(3), name="a"))
    assert why_not_fused(undamped.compile(), {}) is None  # ρ = 0: with its min-norm level
    with pytest.raises(wbc.WbcError, match="cannot fuse"):
        fused_function(scaling, {})


# ----------------------------------------------------------------------------- cascades
def cascade_stack() -> wbc.Stack:
    """Three damped levels and the min-norm level: a task and a soft row at
    level 0, a second task at level 1 (which may repeat a row of level 0: dependent frozen
    rows), at level 2 a full-rank pull towards ``x_above + target`` (Stack.x_above()), after
    which the frozen rows leave the min-norm level a single point; a hard row and bounds."""
    stack = wbc.Stack(N, damping={0: 0.05, 1: 0.1, 2: 0.02}, min_norm=True)
    x = stack.variables.symbol
    target = stack.parameter("pull.target", N, np.zeros(N))
    stack.add(LinearTask(np.ones((3, N)), np.ones(3), name="task"), priority=0)
    stack.add(LinearConstraint(np.ones((1, N)), [-1.0], [1.0], name="soft"), weight=2.0)
    stack.add(LinearTask(np.ones((2, N)), np.ones(2), name="second"), priority=1)
    stack.add(wbc.Cost(x - stack.x_above(), target=target, name="pull"), priority=2)
    stack.constrain(LinearConstraint(np.ones((1, N)), [-1.0], [1.0], name="row"))
    stack.constrain(Bounds(-np.ones(N), np.ones(N), name="box"))
    return stack


def cascade_instance(rng, active: bool, dependent: bool) -> dict:
    data = instance(rng, active)
    data.pop("floor.lower", None)
    second = rng.standard_normal((2, N))
    if dependent:  # level 1 repeats a row of level 0 (and conflicts with it)
        second[0] = data["task.A"][0]
    data.update({"second.A": second, "second.b": 3 * rng.standard_normal(2),
                 "pull.target": rng.standard_normal(N)})
    return data


@pytest.fixture(scope="module")
def cascade_workspaces():
    """(compiled C, virtual machine, ordinary daqp) on the cascade, tight profile."""
    compiled = cascade_stack().compile()
    assert [b.kind for b in compiled.blocks] == ["level"] * 3 + ["min_norm"]
    return (FusedWorkspace(compiled, "tight"), FusedWorkspace(compiled, "tight", compile=False),
            wbc.Workspace(compiled, "daqp", "tight"))


@pytest.mark.parametrize("active", [False, True])
@pytest.mark.parametrize("dependent", [False, True])
def test_a_fused_cascade_equals_the_ordinary_one(cascade_workspaces, active, dependent):
    """Every level's x agrees with the ordinary cascade (levels above eliminated, exact)
    to 1e-8, C with the virtual machine to 1e-12; every fused QP meets its KKT conditions;
    the frozen task rows hold from level to level to the band (and daqp's primal_tol)."""
    rng = np.random.default_rng(10 + 2 * active + dependent)
    fused = cascade_workspaces[0]
    fallbacks = fused.fallback_solves
    for _ in range(10):
        data = cascade_instance(rng, active, dependent)
        solutions = []
        for ws in cascade_workspaces:
            solution = ws.set(**data).solve()
            assert solution.ok, solution.message
            solutions.append([level.x.copy() for level in solution.levels])
            assert_kkt(ws, tol=1e-8)
        c, vm, ordinary = solutions
        assert len(c) == len(ordinary) == 4
        np.testing.assert_allclose(c, vm, atol=1e-12)
        np.testing.assert_allclose(c, ordinary, atol=1e-8)
        assert np.all(np.abs(c[-1]) <= data["box.upper"])  # clipped exactly into the bounds
        J0 = data["task.A"] / np.linalg.norm(data["task.A"], axis=1, keepdims=True)
        for above, x in zip(c[:-1], c[1:], strict=True):  # kept where the level above left them
            c0 = J0 @ above
            assert np.all(np.abs(J0 @ x - c0) <= FROZEN_BAND * (1 + np.abs(c0)) + 1e-10)
    # ticks whose levels touch a bound, a hard row or a frozen soft row (the soft row of level
    # 0 is violated on most instances) are answered by the ordinary path
    assert fused.fallback_solves >= fallbacks
    before = fused.fallback_solves + fused.skipped_solves
    solution = fused.solve()
    labels = [label for label, _, _ in fused.last_qps()]
    if fused.fallback_solves + fused.skipped_solves == before:  # the fused call answered
        assert labels == [level.label for level in solution.levels]
        assert solution.levels[1].frozen_band == FROZEN_BAND
    else:  # the ordinary path: exact, a level the levels above determine is not solved
        assert set(labels) <= {level.label for level in solution.levels}
        assert solution.levels[1].frozen_band == 0.0


def saturated_cascade(saturated: bool) -> wbc.CompiledStack:
    """Two strict levels on a box; ``saturated``: level 0 pushed into the box's bounds."""
    rng = np.random.default_rng(7)
    n = 5
    stack = wbc.Stack(wbc.Variables(x=n), damping=1e-3)
    stack.add(LinearTask(rng.standard_normal((2, n)), 30 * np.ones(2) if saturated
                         else 0.1 * np.ones(2), name="first"), priority=0)
    stack.add(LinearTask(np.eye(n), rng.standard_normal(n), name="posture"), priority=1)
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    return stack.compile()


@pytest.mark.parametrize("saturated", [False, True])
def test_a_certified_cascade_touching_bounds_stays_on_the_fused_path(saturated):
    """Two strict levels: with the box far away, and with level 0 pushed into the box's
    bounds (a non-degenerate vertex), the fused call answers (its certificate holds), and its
    answer is the exact one."""
    compiled = saturated_cascade(saturated)
    fused = FusedWorkspace(compiled, "default")
    referee = wbc.Workspace(compiled, "quadprog", "tight")
    solution = fused.solve()
    assert solution.ok, solution.message
    assert fused.fallback_solves == 0
    np.testing.assert_allclose(solution.x, referee.solve().x, atol=1e-7)
    if saturated:  # bounds are active at the second level
        assert np.abs(fused.last_qps()[1][2].z).max() > 1e-6


def test_the_certificate_rejects_an_inexact_answer():
    """The certificate (:func:`wbc.passes._certified`) on the fused cascade's own answer holds;
    moved off an active bound by 1e-7, or with a bound multiplier of the wrong sign, it does
    not."""
    from wbc.passes import _cascade, _certified, fused_settings

    compiled = saturated_cascade(True)
    fused = FusedWorkspace(compiled, "default", compile=False)
    fused.solve()
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    symbols = [[ca.MX.sym(f"{k}_{i}", size) for k, size in
                (("z", b.n_z), ("y", b.m_top + b.n_frozen_soft + b.n_frozen_cost),
                 ("zb", b.n_z))] for i, b in enumerate(compiled.blocks)]
    _, levels = _cascade(compiled, p, lambda i, qp: (symbols[i][0], 0, symbols[i][1],
                                                     symbols[i][2]))
    certificate = ca.Function("c", [p, *[s for level in symbols for s in level]],
                              [_certified(compiled, levels)])
    answer = [np.array(r) for result in fused._results for r in (result.x, result.y, result.z)]

    def holds(values):
        return bool(certificate(fused.p, *values))

    assert fused_settings(compiled, {})["primal_tol"] <= 1e-10
    assert holds(answer)
    z1, bound_multipliers = answer[3], answer[5]
    j = int(np.argmax(np.abs(bound_multipliers[:compiled.n])))
    assert abs(bound_multipliers[j]) > 1e-6  # a bound active at level 1
    moved = [a.copy() for a in answer]
    moved[3][j] -= 1e-7 * np.sign(bound_multipliers[j])  # off its side, multiplier kept
    assert not holds(moved)
    flipped = [a.copy() for a in answer]
    flipped[5][j] = -bound_multipliers[j]
    assert not holds(flipped)
    assert np.isfinite(z1).all()


def test_x_above_at_the_start_of_the_parameter_vector():
    """A stack whose only parameter is Stack.x_above() (offset 0 in ``p``): level 1 pulls
    ``x − x_above`` towards ``t`` under level 0's frozen rows ``[e0; (0, 1, 2)]``, so that
    ``x = x₀* + d (d·t) / (1 + ρ²)`` with ``d`` their null direction (``x₀*`` lies in their
    row space)."""
    stack = wbc.Stack(3, damping=0.1)
    x = stack.variables.symbol
    rows = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 2.0]])
    t = np.array([0.3, 1.0, -0.5])
    stack.add(wbc.Cost(rows @ x, target=np.array([0.5, 1.0]), name="first"), priority=0)
    stack.add(wbc.Cost(x - stack.x_above(), target=t, name="pull"), priority=1)
    compiled = stack.compile()
    assert compiled.x_above_offset == 0
    expected = wbc.Workspace(compiled, "daqp", "tight").solve()
    solution = FusedWorkspace(compiled, "tight", compile=False).solve()
    assert solution.ok and expected.ok
    np.testing.assert_allclose(solution.x, expected.x, atol=1e-9)
    d = np.array([0.0, 2.0, -1.0]) / np.sqrt(5.0)
    np.testing.assert_allclose(solution.x, solution.levels[0].x + d * (d @ t) / 1.01,
                               atol=1e-9)


def test_a_lower_level_that_fails_falls_back_to_the_ordinary_partial_solution():
    """A level-local constraint at level 1 contradicts level 0's optimum: the generated daqp
    fails there, and the tick is the ordinary path's: infeasible, partial (level 0's x), with
    its message and conflict."""
    stack = wbc.Stack(N, damping=0.1)
    stack.add(LinearTask(np.eye(N)[:1], [0.5], name="first"), priority=0)
    stack.add(LinearTask(np.eye(N), np.ones(N), name="posture"), priority=1)
    stack.constrain(LinearConstraint(np.eye(N)[:1], [-np.inf], [0.0], name="local"), levels=1)
    compiled = stack.compile()
    expected = wbc.Workspace(compiled, "daqp", "tight").solve()
    assert expected.status is wbc.Status.INFEASIBLE and expected.partial
    for ws in (FusedWorkspace(compiled, "tight"), FusedWorkspace(compiled, "tight",
                                                                 compile=False)):
        solution = ws.solve()
        assert ws.fallback_solves == 1
        assert solution.status is expected.status and solution.partial
        assert solution.message == expected.message and solution.conflict == expected.conflict
        np.testing.assert_array_equal(solution.x, expected.x)
        np.testing.assert_allclose(solution.x[0], 0.5 / 1.01)


def test_repeated_failures_are_retried_ever_more_rarely():
    """An undamped level with a rank-deficient task has a singular Hessian, which the generated
    daqp refuses: after k consecutive failed calls the next 2^(k−1) − 1 ticks take the ordinary
    path directly (at most MAX_SKIPPED_TICKS); every answer is the ordinary path's; once the
    Hessian is regular again the next try succeeds and the ticks are fused again."""
    stack = wbc.Stack(N)
    stack.add(LinearTask(np.diag([1.0, 1.0] + [0.0] * (N - 2)), np.ones(N), name="first"))
    compiled = stack.compile()
    fused, ordinary = (FusedWorkspace(compiled, "tight", compile=False),
                       wbc.Workspace(compiled, "daqp", "tight"))
    for _ in range(20):
        solution = fused.solve()
        assert solution.ok
        np.testing.assert_allclose(solution.x, ordinary.solve().x, atol=1e-9)
    assert (fused.fallback_solves, fused.skipped_solves) == (5, 15)  # tried at 0, 1, 3, 7, 15
    for ws in (fused, ordinary):  # a regular Hessian from now on
        ws.set(**{"first.A": np.eye(N)})
    for _ in range(20):  # skipped up to tick 30, then tried and fused
        np.testing.assert_allclose(fused.solve().x, ordinary.solve().x, atol=1e-9)
    assert (fused.fallback_solves, fused.skipped_solves) == (5, 26)  # 15 + ticks 20-30
    assert fused.solve() is fused.solve()  # the fused solution object: fused ticks
    stuck = FusedWorkspace(compiled, "tight", compile=False)
    for _ in range(300):
        stuck.solve()
    assert stuck.fallback_solves == 10  # 0, 1, 3, 7, 15, 31, 63, then every 64th: 127, 191, 255
    assert stuck.fallback_solves + stuck.skipped_solves == 300
    assert MAX_SKIPPED_TICKS == 63


def test_pinned_variables_are_fused():
    """A per-tick mobility with zeros pins variables (bounds 0 <= x_i <= 0) and zeroes their
    metric: the fused QP puts 1 on their diagonal of H (constant on the feasible set), so the
    generated daqp solves it, and the answer is the ordinary path's."""
    stack = wbc.Stack(N, damping=0.1)
    psi = stack.parameter("psi", 1, 0.0)
    stack.set_mobility(ca.vertcat(ca.repmat(1 - psi, 3, 1), ca.repmat(psi, N - 3, 1)))
    stack.add(LinearTask(np.ones((3, N)), np.ones(3), name="task"))
    stack.add(LinearTask(np.eye(N), np.zeros(N), name="posture"), priority=1)
    compiled = stack.compile()
    assert why_not_fused(compiled, {}) is None
    fused, ordinary = FusedWorkspace(compiled, "tight"), wbc.Workspace(compiled, "daqp", "tight")
    rng = np.random.default_rng(3)
    for psi in (0.0, 0.4, 1.0):
        data = {"psi": psi, "task.A": rng.standard_normal((3, N)),
                "task.b": rng.standard_normal(3)}
        x = fused.set(**data).solve().x.copy()
        np.testing.assert_allclose(x, ordinary.set(**data).solve().x, atol=1e-8)
        pinned = slice(3, N) if psi == 0.0 else slice(0, 3) if psi == 1.0 else slice(0, 0)
        assert np.all(x[pinned] == 0.0)
        assert_kkt(fused, tol=1e-8)
    assert fused.fallback_solves == 0


# ----------------------------------------------------------------------------- controller
@pytest.fixture(scope="module")
def robot():
    from wbc.robots.fixed_base import load_panda

    return load_panda()


def panda_stack(robot, levels: int = 1) -> wbc.Stack:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-4)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-4, name="posture"), priority=levels - 1)
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="qlim"))
    stack.constrain(VelocityLimit(robot, name="vlim"))
    return stack


@pytest.fixture(scope="module")
def controllers(robot):
    """(fused, ordinary) controllers of the same one-QP Panda stack."""
    fused = wbc.Controller(robot, panda_stack(robot), dt=DT)
    ordinary = wbc.Controller(robot, panda_stack(robot), dt=DT, fused=False)
    for ctrl in (fused, ordinary):
        ctrl.set_references(posture=Q0, ee=robot.frame_pose(Q0, "ee"))
    return fused, ordinary


def test_daqp_controllers_are_fused_by_default_and_agree_with_the_ordinary_path(robot,
                                                                              controllers):
    fused, ordinary = controllers
    assert fused.fused and fused.fused_reason is None
    assert not ordinary.fused and "fused=False" in ordinary.fused_reason
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += [0.1, -0.15, 0.1]
    q = Q0.copy()
    for k in range(200):  # velocity limits active at first, then converging
        refs = {"ee": target} if k == 0 else {}
        v = fused.step(q, **refs).copy()
        np.testing.assert_allclose(v, ordinary.step(q, **refs), atol=1e-9)
        assert fused.last_solution.ok and fused.last_solution.fallback is None
        q = q + DT * v
    assert fused.workspace.fallback_solves == 0
    assert np.linalg.norm(robot.frame_pose(q, "ee")[:3, 3] - target[:3, 3]) < 0.05


def test_scaling_levels_and_other_backends_keep_todays_path(robot):
    stack = panda_stack(robot, levels=2)
    stack.add(LinearTask(np.eye(robot.nv)[:1], [0.1], name="joint"), priority=2, scaling=True)
    scaling = wbc.Controller(robot, stack, dt=DT, jit=False)
    assert not scaling.fused and "task-scaling LPs" in scaling.fused_reason
    with pytest.raises(wbc.WbcError, match="cannot be fused"):
        wbc.Controller(robot, stack, dt=DT, fused=True, jit=False)
    quadprog = wbc.Controller(robot, panda_stack(robot), backend="quadprog", dt=DT, jit=False)
    assert not quadprog.fused and "quadprog" in quadprog.fused_reason
    with pytest.raises(wbc.WbcError, match="fused must be"):
        wbc.Controller(robot, panda_stack(robot), dt=DT, fused="yes")


def test_without_a_compiler_one_warning_and_todays_path(robot, monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.warns(RuntimeWarning, match="no C compiler"):
        ctrl = wbc.Controller(robot, panda_stack(robot), dt=DT)
    assert not ctrl.fused and "compiler" in ctrl.fused_reason
    ctrl.set_references(posture=Q0, ee=robot.frame_pose(Q0, "ee"))
    assert ctrl.step(Q0 + 0.01).shape == (robot.nv,) and ctrl.last_solution.ok


@pytest.mark.parametrize("policy", ["hold", "last", "decelerate"])
def test_fallbacks_after_a_failed_fused_tick(robot, controllers, policy):
    fused = controllers[0]
    fused.fallback = policy
    try:
        fused.set_references(ee=robot.frame_pose(Q0, "ee"))
        previous = fused.step(Q0 + 0.05).copy()
        q = Q0.copy()
        q[0] = robot.limits.q_upper[0] + 0.1  # position bound v < −10, velocity bound ≥ −2.2
        command = fused.step(q)
        solution = fused.last_solution
        assert solution.status is wbc.Status.INFEASIBLE and solution.fallback == policy
        expected = {"hold": np.zeros(robot.nv), "last": previous,
                    "decelerate": None}[policy]
        if expected is not None:
            np.testing.assert_array_equal(command, expected)
        else:  # the previous command halved, within this tick's (crossed: not applied) bounds
            np.testing.assert_allclose(command, 0.5 * previous)
        assert fused.step(Q0).shape == (robot.nv,) and fused.last_solution.ok
    finally:
        fused.fallback = "hold"


def test_a_solved_tick_after_a_failed_one_resets_the_back_off_and_the_qps(robot, controllers):
    """The controller makes the fused call itself: after a tick the ordinary path took, the next
    solved call reports the fused QPs and ends the back-off (an isolated failure costs
    nothing later)."""
    fused = controllers[0]
    fused.set_references(ee=robot.frame_pose(Q0, "ee"))
    crossed = Q0.copy()
    crossed[0] = robot.limits.q_upper[0] + 0.1  # crossed bounds: the fused call fails
    ws = fused.workspace
    for _ in range(3):
        failed, skipped = ws.fallback_solves, ws.skipped_solves
        fused.step(crossed)
        assert ws.fallback_solves == failed + 1 and ws.skipped_solves == skipped
        assert fused.last_solution.status is wbc.Status.INFEASIBLE
        fused.step(Q0)  # solved by the fused call, not skipped
        assert ws.skipped_solves == skipped and fused.last_solution.ok
        assert fused.last_solution.levels[0].iterations == -1  # (the fused call's mark)
        # the QPs reported are this tick's fused ones, not the failed tick's (crossed bounds)
        (_, (*_, lb, ub), _), = ws.last_qps()
        assert np.all(lb <= ub)


class _CountingController(wbc.Controller):
    """A subclass with its own step (the tick closure must not shadow it)."""

    def step(self, q, v=None, **references):
        self.calls = getattr(self, "calls", 0) + 1
        return super().step(q, v, **references)


def test_a_subclass_step_stays_in_charge(robot):
    ctrl = _CountingController(robot, panda_stack(robot), dt=DT)
    ctrl.set_references(posture=Q0, ee=robot.frame_pose(Q0, "ee"))
    ctrl.step(Q0)
    ctrl.step(Q0 + 0.01)
    assert ctrl.calls == 2 and ctrl.fused and ctrl.last_solution.ok


def test_step_is_a_method_of_the_class(controllers):
    """``Controller.step`` is the class's method on every path (no closure stored on the
    instance in its place): what readers, ``help`` and tools see is what runs."""
    import inspect

    for ctrl in controllers:
        assert ctrl.step.__func__ is wbc.Controller.step  # (a bound method, not a closure)
        assert list(inspect.signature(ctrl.step).parameters) == ["q", "v", "out",
                                                                 "references"]


def test_bad_input_is_refused_before_any_write(controllers):
    fused = controllers[0]
    fused.step(Q0)
    p = fused.workspace.p.copy()
    bad = Q0.copy()
    bad[3] = np.nan
    with pytest.raises(wbc.NonFiniteError, match="q contains NaN"):
        fused.step(bad)
    with pytest.raises(wbc.ShapeError, match=r"q must have shape \(7,\)"):
        fused.step(Q0[:6])
    with pytest.raises(wbc.ShapeError, match="ee"):
        fused.step(Q0 + 0.1, ee=np.eye(3))
    np.testing.assert_array_equal(fused.workspace.p, p)


@pytest.fixture(scope="module")
def cascade_controllers(robot):
    """(fused, ordinary) controllers of the two-level Panda stack (pose, then posture)."""
    fused = wbc.Controller(robot, panda_stack(robot, levels=2), dt=DT)
    ordinary = wbc.Controller(robot, panda_stack(robot, levels=2), dt=DT, fused=False)
    for ctrl in (fused, ordinary):
        ctrl.set_references(posture=Q0, ee=robot.frame_pose(Q0, "ee"))
    return fused, ordinary


def test_a_fused_cascade_controller_agrees_with_the_ordinary_path(robot, cascade_controllers):
    fused, ordinary = cascade_controllers
    assert fused.fused and len(fused.compiled.blocks) == 2
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += [0.1, -0.15, 0.1]
    q = Q0.copy()
    for k in range(100):  # velocity limits active at first
        refs = {"ee": target} if k == 0 else {}
        v = fused.step(q, **refs).copy()
        np.testing.assert_allclose(v, ordinary.step(q, **refs), atol=1e-8)
        assert fused.last_solution.ok and len(fused.last_solution.levels) == 2
        q = q + DT * v
    # the first ticks meet the velocity limits (non-degenerate vertices): certified, fused
    assert fused.workspace.fallback_solves == 0


@pytest.mark.parametrize("levels", [1, 2])
def test_a_fused_tick_allocates_nothing_in_steady_state(robot, controllers, cascade_controllers,
                                                        levels):
    """With ``out=`` the command is written into the caller's buffer and the solution stays in
    the tick's buffers (copied only when ``last_solution`` is read): over 1000 ticks no memory
    block stays allocated, and the peak stays at the level of the loop's own bookkeeping. The
    ordinary path, for contrast, makes new arrays and a new solution every tick. (The target
    is where the hand is: no limit is met, so a cascade stays on the fused path.)"""
    fused, ordinary = controllers if levels == 1 else cascade_controllers
    q = Q0 + 0.05
    for ctrl in (fused, ordinary):
        ctrl.set_references(ee=robot.frame_pose(q, "ee"))
    buffer = np.empty(robot.nv)
    assert fused.step(q, out=buffer) is buffer and fused.last_command is buffer
    assert fused.last_solution is fused.last_solution  # one snapshot per tick, when read
    fallbacks = fused.workspace.fallback_solves

    def blocks_and_peak(ctrl):
        for _ in range(10):  # warm caches
            ctrl.step(q, out=buffer)
        tracemalloc.start()
        try:
            before = tracemalloc.take_snapshot()
            base, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            for _ in range(1000):
                ctrl.step(q, out=buffer)
            _, peak = tracemalloc.get_traced_memory()
            after = tracemalloc.take_snapshot()
        finally:
            tracemalloc.stop()
        measuring = [tracemalloc.Filter(False, tracemalloc.__file__),
                     tracemalloc.Filter(False, __file__)]
        after, before = after.filter_traces(measuring), before.filter_traces(measuring)
        grown = sum(max(stat.count_diff, 0) for stat in after.compare_to(before, "lineno"))
        return grown, peak - base

    grown, peak = blocks_and_peak(fused)
    assert fused.last_solution.ok and fused.workspace.fallback_solves == fallbacks  # all fused
    assert grown == 0
    assert peak < 512  # bytes: no array, no solution object
    _, ordinary_peak = blocks_and_peak(ordinary)
    assert ordinary_peak > peak + 512  # the check can tell


def test_the_generated_daqp_code_is_patched_or_refused():
    """CasADi's generated daqp code leaves the QP's success flag unset when daqp's setup fails
    (see :func:`wbc.passes.initialise_success`): the patch sets it, and code of another shape
    is refused rather than compiled."""
    from wbc.fused import initialise_success

    source = "int f(void) {\n  flag = setup_daqp(a, b, c);\n  if (flag<0) return 1;\n}\n"
    assert "d_qp->success = 0; return 1;" in initialise_success(source)
    with pytest.raises(RuntimeError, match="has changed"):
        initialise_success(source.replace("if (flag<0) return 1;", "if (flag < 0) return 2;"))
