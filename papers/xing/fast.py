"""AMP's tick in generated C where the task is not saturated: the fast path of
:func:`~wbc.papers.xing.amp_controller` (``fused="auto"``, :class:`AMPController`); the
ordinary path (Python around the cascade's four QPs) answers every other tick.

What the cascade computes where the task is not saturated
---------------------------------------------------------
Over ``x = q̈ = [u; w]`` (``u`` the base's ``n_b`` entries, ``w`` the arm's), with the joint
bounds ``l <= x <= h`` as its only hard constraints, :func:`~wbc.papers.xing.amp_stack` is:

* the scaling LP: the largest ``s ∈ [0, 1]`` with ``J x = s t − r`` for an ``x`` in the box
  (``t`` the commanded acceleration, ``r = J̇ q̇``): the largest ``s`` for which ``s t − r``
  lies in the zonotope ``Z = {J x : l <= x <= h}``;
* level 0, ``s`` fixed: ``min ||J x − (s t − r)||²`` over the box — 0 at its optimum, whose
  set is ``X0 = {x in the box : J x = s t − r}``;
* level 1: ``min ω ||u − u_t||²`` over ``X0`` (``u_t`` the base's transition, eq. 15;
  ``ω = 1 − base_free``, 0 or 1);
* level 2: ``min ½ xᵀ H x + gᵀ x`` (the manipulability task; ``H = I``) over what level 1
  leaves: strictly convex, one answer.

When ``t − r`` lies inside ``Z``, the LP's answer is ``s = 1``. When moreover ``ω = 0``, or
``u_t`` is within the base's bounds and leaves the arm a target ``t − r − J_u u_t`` inside the
arm's zonotope ``Z_w = {J_w w : l_w <= w <= h_w}``, level 1's optimum is 0 (at ``u = u_t``
if ``ω > 0``), and the cascade's answer is the one strictly convex QP

    min ½ xᵀ H x + gᵀ x   s.t.   J x = t − r,   l <= x <= h,   u = u_t if ω > 0,

which the daqp bundled with casadi solves exactly (a dual active-set method; no proximal
iterations: ``H`` is positive definite), in one generated C function with the model, the
bounds and the tests (:func:`unsaturated_tick`). Its ``x``, clipped into the bounds, is the
command; ``s = 1``; it is each level's optimum, and every level's ``x`` in the solution.

The tests. A zonotope in 3-D is the intersection of the half-spaces of its facets, whose
normals are the cross products ``c = g_i × g_j`` of two of its generators (the columns ``g_k``
of ``J``; the box's half-widths ``d_k`` enter below); a point ``y`` is inside
by more than ``m`` along every facet normal if ``Σ_k |c·g_k| d_k − |c·(y − J x_c)| > m |c|``
for every pair that is not parallel (``x_c`` the box's centre) — 45 pairs for the mecanum
Gen3's ten columns, 21 for its arm's seven (:func:`zonotope_interior`, ≈ 2 µs for both).
``m`` is :data:`INTERIOR_MARGIN` relative to ``1 + max|y|``. A pair whose cross product is at
most :data:`PARALLEL` × the product of the two norms is parallel and spans no facet on its own
(the base's yaw and the arm's first joint turn about the same vertical axis: their columns are
opposite). A facet missed that way could only let a saturated tick through to the QP, whose
equality rows then cannot hold within the bounds: daqp fails and the ordinary path answers.
Ranks: the ordinary path decides the rank of the task rows (an SVD, relative tolerance
``rank_tol`` = 1e-9) and of the frozen rows (a pivoted QR); the fast path requires ``σ_3 >=``
:data:`RANK_MARGIN` ``σ_1`` of ``J`` (and of ``J_w`` when ``ω > 0``, for ``[J; I_u]``), from
``σ_3²/σ_1² >= 4 det(J Jᵀ) / tr(J Jᵀ)³`` — far from the tolerance, so both decide full rank.

Where the fast path does not answer, and why
--------------------------------------------
A tick that fails a test — the task saturated (``s < 1``), the base's transition out of its
bounds or out of the arm's reach while ``ω > 0``, a rank below the margin, a bound infinite or
crossed — makes the generated daqp's setup fail on purpose (its Hessian is replaced by ``−I``;
the call costs about what an answered one does, ≈ 4 µs) and takes the ordinary path, which
answers it with its own status, message, fallback and diagnosis (an infeasible tick is named
with its conflict): :class:`~wbc.fused.FusedWorkspace`'s failed call, counted in
``fallback_solves``, without its back-off (:attr:`AMPFastWorkspace.max_skipped_ticks` is 0:
the next tick is tried). The ordinary path is the workspace's own backends, warm-started from
the last tick they solved.

Saturated ticks stay on the ordinary path because there it is not exact, so no exact tick can
equal it. Measured on the study's sampler (:func:`wbc.experiments.studies.xing.random_state`;
1000 states of seed 0, 293 saturated): the ordinary path's level 0, undamped, is solved by
daqp's proximal iterations and leaves ``J x`` up to 1.8e-6 off its target at saturated states
(median 5e-10). The exact cascade there — ``s`` from the facets as a ratio, ``min (Σ_k |c·g_k|
d_k + c·(r + J x_c)) / c·t`` over the normals with ``c·t > 0`` (and 1), the levels as strictly
convex QPs over the facets' half-spaces — is more than 1e-6 from the ordinary path on 30 of
the 293 states (up to 1.3e-4), and no test on the geometry told them apart (refusing every
saturated state whose smallest ``|c·g_k|`` over the generators off the active facet is below
0.1 refuses 291 of the 293 and still misses one). The ordinary path is not a function of the
state there either: daqp keeps its active sets from tick to tick, and the same state solved
twice in a row moves by up to 9.5e-6; two ordinary controllers that saw different states
before answer the same saturated state up to 1.8e-2 apart (10 seeds × 1000 states). On 4
ticks of the study's singularity run without avoidance (full horizon) its scaling LP reports a
feasible LP infeasible (scipy's HiGHS and the facets agree on ``s ≈ 0.116``) and the command
decelerates; on 5 other saturated ticks of that run the exact cascade is up to 2.2e-5 from it.

Measured equality (``tests/test_xing_fast.py``): where the fast path answers, its command is
within 4.0e-7 of the ordinary path's, ``s`` within 3.7e-10 (10 seeds × 1000 random states:
7023 answered, 2977 handed over, statuses equal); in the study's full closed loops (14 000
ticks, the ordinary path driving) within 3.0e-8, and the 463 handed-over ticks within 2.2e-8,
statuses equal — there the workspace's backends see the same saturated stretches as the
ordinary controller's. The fast answers are the cascade's: the ordinary path on quadprog's
``"tight"`` profile agrees with them to 1.4e-9 (2427 answered states of seeds 0–3), where the
ordinary path on daqp, cold-started, once missed by 1.2e-5 (level 1's proximal iterations left
the base 2.2e-8 off its transition).
"""

from __future__ import annotations

import itertools

import casadi as ca
import numpy as np

import wbc
from wbc.cbuild import DEFAULT_FLAGS, compiled_c
from wbc.compiler import LEVEL, SCALING_LP, CompiledStack
from wbc.errors import WbcError
from wbc.fused import (
    DAQP_SETTINGS,
    FusedWorkspace,
    build_fused,
    daqp_link_arguments,
    fused_settings,
    initialise_success,
)
from wbc.passes import jit_compiled
from wbc.qp import QPResult, Status
from wbc.solution import LevelResult, Solution, TaskResiduals, Timings
from wbc.workspace import Workspace

__all__ = ["INTERIOR_MARGIN", "PARALLEL", "RANK_MARGIN", "AMPController", "AMPFastWorkspace",
           "fast_qp", "full_rank", "unsaturated_tick", "why_not_fast", "zonotope_interior"]

#: How far inside its zonotope a point must be, relative to ``1 + max|point|``, for the fast
#: path (the task's ``t − r`` in ``Z``, the arm's target in ``Z_w``; see the module docstring).
INTERIOR_MARGIN = 1e-6
#: The smallest ``σ_3/σ_1`` of the task rows (and the arm's) the fast path accepts: far above
#: the ordinary path's rank tolerance (1e-9), so that both decide full rank.
RANK_MARGIN = 1e-6
#: Two generators whose cross product is at most this times the product of their norms are
#: parallel (``sin`` of their angle): their cross product is no facet normal.
PARALLEL = 1e-12
#: The label of the QP a fast tick solves (:meth:`AMPFastWorkspace.last_qps`).
FAST_QP_LABEL = "AMP's last level under the levels above (fast tick: s = 1, level 1 exact)"


def zonotope_interior(G: ca.SX, lower: ca.SX, upper: ca.SX, point: ca.SX,
                      margin: ca.SX) -> ca.SX:
    """1 if ``point`` (3,) lies inside the zonotope ``{G x : lower <= x <= upper}`` (``G`` 3 ×
    k, finite bounds) by more than ``margin`` along every facet normal, else 0 (SX; see the
    module docstring)."""
    if G.shape[0] != 3:
        raise WbcError(f"zonotope_interior is for 3 rows, got {G.shape[0]}")
    half = (upper - lower) / 2
    offset = point - G @ ((upper + lower) / 2)
    columns = [G[:, k] for k in range(G.shape[1])]
    squares = [ca.sumsqr(column) for column in columns]
    outside = []
    for i, j in itertools.combinations(range(len(columns)), 2):
        c = ca.cross(columns[i], columns[j])
        size = ca.sumsqr(c)
        facet = size > PARALLEL ** 2 * squares[i] * squares[j]
        # the support of the zonotope along ±c, minus the point's distance from its centre
        slack = ca.dot(ca.fabs(G.T @ c), half) - ca.fabs(ca.dot(c, offset))
        outside.append(facet * ((slack <= 0) + (slack * slack <= margin * margin * size)))
    return ca.sum1(ca.vertcat(*outside)) == 0


def full_rank(G: ca.SX) -> ca.SX:
    """1 if ``σ_3 >= RANK_MARGIN σ_1`` is certain for ``G`` (3 × k), from
    ``σ_3²/σ_1² >= 4 det(G Gᵀ) / tr(G Gᵀ)³`` (SX)."""
    M = G @ G.T
    return 4 * ca.det(M) >= RANK_MARGIN ** 2 * ca.trace(M) ** 3


def why_not_fast(compiled: CompiledStack, n_base: int, backend, options: dict) -> str | None:
    """Why ``compiled`` (an :func:`~wbc.papers.xing.amp_stack` after
    :func:`wbc.passes.compiled_kinematics`) cannot take the fast path on ``backend`` with
    ``options``, or ``None`` if it can."""
    if backend != "daqp":
        return f"the backend is {backend!r}; the fast tick solves with daqp"
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    kinds = [block.kind for block in compiled.blocks]
    if kinds != [SCALING_LP, LEVEL, LEVEL, LEVEL] or compiled.x_above_offset is not None:
        return f"not AMP's cascade (scaling LP and three levels): {kinds}"
    lp, _, base_level, _ = compiled.blocks
    if lp.m_task != 3:
        return f"the task has {lp.m_task} rows; the zonotope test is for 3 (position)"
    if any(block.m_hard or block.m_soft for block in compiled.blocks):
        return "the cascade has hard or soft rows; the fast tick knows only the joint bounds"
    p = ca.SX.sym("p", compiled.defaults.shape[0])
    base_rows = base_level.function(p)[7].T  # level 1's cost rows, ET transposed
    if not 0 < n_base < compiled.n or not base_rows[:, n_base:].is_zero():
        return f"level 1's task is not on the base's first {n_base} variables alone"
    return None


def _unsaturated(n: int, n_base: int) -> ca.Function:
    """``(J, b, lower, upper, u_t, pinned) -> 1`` where the fast path answers (module
    docstring): ``b = t − r`` inside ``Z``, ``J`` of full rank, finite ordered bounds, and if
    ``pinned`` (``ω > 0``) ``u_t`` within the base's bounds, the arm's target inside ``Z_w``
    and ``J_w`` of full rank."""
    J, b = ca.SX.sym("J", 3, n), ca.SX.sym("b", 3)
    lower, upper = ca.SX.sym("lower", n), ca.SX.sym("upper", n)
    transition, pinned = ca.SX.sym("u_t", n_base), ca.SX.sym("pinned")
    bounds = ca.vertcat(lower, upper)
    valid = (ca.sum1(ca.fabs(bounds) < ca.inf) == 2 * n) * (ca.sum1(lower > upper) == 0)
    task = zonotope_interior(J, lower, upper, b, INTERIOR_MARGIN * (1 + ca.mmax(ca.fabs(b))))
    arm_target = b - J[:, :n_base] @ transition
    arm = (zonotope_interior(J[:, n_base:], lower[n_base:], upper[n_base:], arm_target,
                             INTERIOR_MARGIN * (1 + ca.mmax(ca.fabs(arm_target))))
           * full_rank(J[:, n_base:])
           * (ca.sum1(transition < lower[:n_base]) + ca.sum1(transition > upper[:n_base]) == 0))
    ok = valid * task * full_rank(J) * ca.if_else(pinned, arm, 1)
    return ca.Function("amp_unsaturated", [J, b, lower, upper, transition, pinned], [ok])


def fast_qp(compiled: CompiledStack, n_base: int) -> ca.Function:
    """``p -> (h, g, a, b, lbx, ubx)``: the QP of a fast tick (module docstring), ``min ½ zᵀ h z
    + gᵀ z`` s.t. ``a z = b``, ``lbx <= z <= ubx``, with ``h = −I`` where the tests refuse the
    tick. One SX function: the blocks' expressions inlined and their common subexpressions
    eliminated (:func:`casadi.cse`; the kinematics once instead of three times: 30 % fewer
    operations, a quarter less C to compile)."""
    n = compiled.n
    p = ca.SX.sym("p", compiled.defaults.shape[0])
    lp, _, base_level, last = compiled.blocks
    _, _, AT, lA, _, lower, upper, _ = lp.function(p)
    rows = AT.T  # [J, −t] x_s = −r
    J, b = rows[:, :n], lA - rows[:, n]  # b = t − r
    H1, g1 = base_level.function(p)[:2]  # ω I on the base, −ω u_t
    H, g = last.function(p)[:2]
    omega = H1[0, 0]
    pinned = omega > 0
    transition = -g1[:n_base] / ca.if_else(pinned, omega, 1.0)
    ok = _unsaturated(n, n_base)(J, b, lower, upper, transition, pinned)
    lbx = ca.vertcat(ca.if_else(pinned, transition, lower[:n_base]), lower[n_base:])
    ubx = ca.vertcat(ca.if_else(pinned, transition, upper[:n_base]), upper[n_base:])
    outputs = ca.cse([ca.if_else(ok, H, -ca.SX.eye(n)), g, J, b, lbx, ubx])
    return ca.Function("amp_fast_qp", [p], outputs, ["p"], ["h", "g", "a", "b", "lbx", "ubx"])


def unsaturated_tick(compiled: CompiledStack, n_base: int, options: dict) -> ca.Function:
    """``p -> (x, done, z, y, z_bounds)`` of AMP's fast tick (module docstring): the tests and
    the one QP (:func:`fast_qp`; daqp, CasADi's conic node with ``options``), ``x`` its
    solution ``z`` clipped into the bounds, ``y`` and ``z_bounds`` its multipliers (rows,
    bounds). Where the tests refuse the tick, daqp's setup refuses ``h = −I``: the call fails
    and writes no output, ``done`` (the QP's cost) included. ``compiled`` must pass
    :func:`why_not_fast`; evaluates on CasADi's virtual machine as it is
    (:func:`wbc.cbuild.compiled_c` makes it C)."""
    n = compiled.n
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    h, g, a, b, lbx, ubx = fast_qp(compiled, n_base)(p)
    solver = ca.conic("amp_last_level", "daqp", {"h": ca.Sparsity.dense(n, n),
                                                  "a": ca.Sparsity.dense(3, n)},
                      {"daqp": dict(options), "error_on_fail": True})
    result = solver(h=h, g=g, a=a, lba=b, uba=b, lbx=lbx, ubx=ubx)
    z = result["x"]
    x = ca.fmin(ca.fmax(z, lbx), ubx)
    return ca.Function("amp_tick", [p], [x, result["cost"], z, result["lam_a"], result["lam_x"]],
                       ["p"], ["x", "done", "z", "y", "z_bounds"])


class AMPFastWorkspace(FusedWorkspace):
    """The workspace of :class:`AMPController` on its fast path: :meth:`solve` is one call of
    :func:`unsaturated_tick` in C; a tick it does not answer takes the ordinary path (see the
    module docstring and :class:`~wbc.fused.FusedWorkspace`, whose solve, counters and reused
    :class:`~wbc.Solution` it shares; not its back-off).

    Args:
        compiled: an AMP stack passing :func:`why_not_fast` (not JIT-compiled: the tick is
            generated from its functions).
        n_base: the base's number of velocity coordinates (the first variables).
        profile: daqp tolerance profile of both paths (the generated daqp's ``primal_tol`` at
            most :data:`wbc.fused.CASCADE_PRIMAL_TOL`).
        warm_start: for the ordinary path's backends.
        jit: the ordinary path's level functions as compiled C (:func:`wbc.passes.jit_compiled`).
        compile: the tick as compiled C (``False``: CasADi's virtual machine, for tests).
        **options: daqp options overriding the profile.

    Raises:
        WbcError: the stack cannot take the fast path; ``RuntimeError`` if the compiler fails.

    A fast tick's :class:`~wbc.Solution` lists every QP of the cascade, each with the command as
    its ``x`` (the optimum of every level), ``scale`` 1, ``frozen_rank`` and ``iterations``
    −1 (not computed).
    """

    #: No back-off: a tick the tests refuse costs them alone (≈ 4 µs, no solve), and the next
    #: one is often not saturated.
    max_skipped_ticks = 0

    def __init__(self, compiled: CompiledStack, n_base: int, profile: str = "default",
                 warm_start: bool = True, jit: bool = True, compile: bool = True,
                 **options) -> None:
        reason = why_not_fast(compiled, n_base, "daqp", options)
        if reason is not None:
            raise WbcError(f"AMP's fast tick does not apply: {reason}")
        # not FusedWorkspace's __init__: that one generates the cascade of least-squares levels
        Workspace.__init__(self, jit_compiled(compiled) if jit else compiled, "daqp", profile,
                           warm_start, **options)
        self._symbolic, self._n_base = compiled, n_base
        settings = fused_settings(
            compiled, self._blocks[0].backend.options)  # type: ignore[attr-defined]
        function = unsaturated_tick(compiled, n_base, settings)
        if compile:
            function = compiled_c(function, DEFAULT_FLAGS, daqp_link_arguments(),
                                  initialise_success)
        n = compiled.n
        x = np.zeros(n)
        self._result = QPResult(np.zeros(n), Status.SOLVED, np.zeros(3), np.zeros(n))
        self._qp: ca.Function | None = None  # the fast tick's QP, made when last_qps asks
        outputs = [x, np.zeros(1), self._result.x, self._result.y, self._result.z]
        lp = compiled.blocks[0]
        solution = Solution(
            x, Status.SOLVED,
            [LevelResult(block.label, Status.SOLVED, x, -1) for block in compiled.blocks],
            compiled.variables, {lp.priority: 1.0}, Timings(),  # type: ignore[dict-item]
            task_residuals=None if compiled.residuals is None
            else TaskResiduals(compiled, self.p, x))
        self._attach(function, outputs, solution)

    def last_qps(self) -> list[tuple]:
        """As :meth:`Workspace.last_qps`; after a fast tick, the one QP the generated daqp
        solved (evaluated again on CasADi's virtual machine), with its result."""
        if self._solved is not self._no_qps:
            return Workspace.last_qps(self)
        if self._qp is None:
            self._qp = fast_qp(self._symbolic, self._n_base)
        H, g, A, b, lb, ub = (np.asarray(a, dtype=float) for a in self._qp(self.p))
        return [(FAST_QP_LABEL, (H, g.ravel(), A, b.ravel(), b.ravel(), lb.ravel(),
                                 ub.ravel()), self._result)]


class AMPController(wbc.Controller):
    """A :class:`wbc.Controller` of :func:`~wbc.papers.xing.amp_stack` whose fused path is
    AMP's fast tick (:class:`AMPFastWorkspace`, module docstring), made by
    :func:`~wbc.papers.xing.amp_controller`.

    Args:
        robot, stack: as :class:`wbc.Controller`'s (``stack`` an AMP stack).
        n_base: the base's number of velocity coordinates.
        fused: ``"auto"`` (default) — the fast path when the backend is ``"daqp"``, the stack
            passes :func:`why_not_fast` (a position task: 3 rows) and a C compiler is present;
            ``True`` — the same, but a stack that cannot take it is a :class:`~wbc.WbcError`;
            ``False`` — the ordinary path. ``self.fused`` says which is used and
            ``self.fused_reason`` why not.
        **kwargs: :class:`wbc.Controller`'s other arguments.
    """

    def __init__(self, robot, stack: wbc.Stack, n_base: int, **kwargs) -> None:
        self._n_base = n_base  # read by build_fused_workspace, which Controller's __init__ calls
        super().__init__(robot, stack, **kwargs)

    def build_fused_workspace(self, fused, backend, profile, warm_start, options):
        """An :class:`AMPFastWorkspace` if the fast path applies (``fused`` in the class
        docstring), else ``None`` with ``self.fused_reason`` saying why (the hook of
        :meth:`wbc.Controller.build_fused_workspace`)."""
        workspace, self.fused_reason = build_fused(
            fused, lambda: why_not_fast(self.compiled, self._n_base, backend, options),
            lambda: AMPFastWorkspace(self.compiled, self._n_base, profile, warm_start,
                                     self.jit_c, **options),
            "AMP's tick cannot take the fast path")
        return workspace
