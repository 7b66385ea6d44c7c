"""The fused tick: parameters → command as one generated C function (model, assembly, solve).

For a stack on daqp whose cascade has no task-scaling LP (one or several least-squares levels,
and the minimum-norm level), the compiled level functions ``p -> (H, g, A, lA, uA, lb, ub,
E)`` (which hold the compiled kinematics, see :func:`wbc.passes.compiled_kinematics`) are
chained with one CasADi ``daqp`` conic node per QP and the clipping of ``x`` into its bounds,
into one CasADi function ``p -> x`` (the compile pass :func:`wbc.passes.fused_function`, with
the constants this docstring explains). CasADi generates its C code; it is compiled against the
daqp headers and static library that ship inside the casadi wheel (``casadi/include/daqp``,
``casadi/libdaqpstat.a``), kept in the JIT cache (:mod:`wbc.cbuild`), and called every tick
through :meth:`casadi.Function.buffer` on the workspace's own parameter vector: one C call per
tick, no conversion, no allocation in Python. :class:`FusedWorkspace` is that call with its
bookkeeping (:meth:`FusedWorkspace.solve`, or the callable :meth:`FusedWorkspace.solver` hands
a caller that solves every tick, as :meth:`wbc.Controller.step` does). It also hands out a
handle on the compiled function (:attr:`FusedWorkspace.c_call`), armed while the last tick
was fused, through which :meth:`wbc.Controller.step` makes the call from the C extension that
stages its inputs (:data:`wbc.checks.STAGE_SOURCE`): same function, same buffers, no Python
between the inputs and the command.

Cascades: the frozen rows
-------------------------
Level ``k+1`` keeps what the levels above achieved, as the ordinary path does: their soft rows
at their optimal slacks (``l + w* <= C x <= u + w*``, inequalities as they are) and their task
rows ``E`` where the level above left them. The ordinary path eliminates the task rows (the
level solves in their null space, found by a QR with column pivoting, a numerical rank
decision; see :mod:`wbc.workspace`), skips a level they leave a single point, and looks for a
failed level's implicit equalities. A generated expression cannot take such data-dependent
decisions, and daqp refuses linearly dependent equalities (``EXIT_OVERDETERMINED_INITIAL``) —
which cascades have as a rule (an orientation level below a position level, a posture below
both). The fused cascade
therefore keeps every frozen task row, without the variables the level fixes (``lb == ub``)
and scaled to unit norm, as a two-sided band ``|r·x − r·x*| <= FROZEN_BAND·(1 + |r·x*|)``
(:data:`FROZEN_BAND` = 1e-11) — an inequality pair daqp's dual active-set method adds only
when violated and handles when dependent — and its generated daqp gets ``primal_tol`` at most
:data:`CASCADE_PRIMAL_TOL` (1e-10, the ``"tight"`` profile's) so that the rows hold to that
much. Each level moves the rows of the levels above by at most ``FROZEN_BAND·(1 + |r·x*|) +
primal_tol`` from where the level above left them (unit rows); how much ``x`` moves for it
depends on the angle between the rows and the active bounds. Measured: the equivalence
suite's cascades on the fused path (``tests/test_fused_equivalence.py``, tolerance 1e-7 and
KKT checks) pass; fused against ordinary on random three-level cascades with active bounds
(``tests/test_fused.py``) at most ≈ 6e-9 apart (1e-9 band: ≈ 6e-7, 1e-10: ≈ 6e-8 — the
difference scales with the band; a 1e-12 band failed in daqp on some instances); the
three-level stack of ``wbc bench`` on ``mecanum_gen3`` over 1000 closed-loop ticks (default
profile): commands at most 6e-11 apart, no fallback. A level the levels above leave a point is
solved too (within the band), where the ordinary path skips it.

A frozen row whose norm is at most ``max(1e-12, rank_tol·ρ)`` (``ρ`` the largest frozen row
norm) is left out (made zero): it is zero for the ordinary path's rank decision, and scaled to
unit norm it froze rounding noise (ur5 on the omni base at ``neutral()``: an orientation row of
norm 1.4e-11 became a constraint; commands 0.16 apart).

Cascades: the certificate
-------------------------
The band is exact where daqp ends on a non-degenerate active set; at a degenerate vertex (frozen
rows through active bounds, dependent rows: as soon as limits saturate) its answer can be far
off (measured: up to 5e-4), although daqp reports "optimal". So the generated function checks,
for every level below the first, the KKT conditions of the *exact* level problem (frozen task
rows as equalities) on daqp's ``z`` and multipliers, and writes ``done`` (the tick is
answered) only when they hold; else the ordinary path answers the tick, as after a failed
call. With ``t`` = :data:`CERTIFICATE_TOL` (1e-9) and sides ``s``:

* *primal*: every bound, row (hard, own soft, frozen soft) and frozen task row (its band) is
  met to ``t·(1 + |s|)``;
* *complementarity and sign*: a bound or row (frozen task rows excepted: equalities, either
  sign) with a positive multiplier is within ``t·(1 + |s|)`` of its upper side, one with a
  negative multiplier of its lower side (a pinned variable meets both; a multiplier of an
  infinite side fails);
* *stationarity* ``H z + g + Aᵀ y + z_b = 0`` is not evaluated: daqp computes ``z`` from its
  multipliers, so it holds by construction — measured ≤ 4e-13 relative to ``1 + max(|g|,
  |H z|)`` on every answer below, the inexact ones included; evaluating it cost ≈ 0.5 µs
  (7 %) of a three-level tick and rejected nothing.

Why 1e-9, measured with the certificate off (every tick answered by the fused call, against the
referee of ``wbc exactness``, seed 0, 300 states per family; 657 multi-level answers the
referees agree on): the inexact answers are not caught by a sign or a residual but by where daqp
leaves ``z`` — a multiplier held on a bound 1e-8–4e-5 off it, a bound violated by 1e-9–6e-6,
frozen task rows 1e-8 outside their band (daqp's own ``primal_tol`` is 1e-10). Accepted, and the
largest deviation among them (max|v − v_ref|), per tolerance:

==========  ===============  ===============  ===============
``t``       random (168)     saturating (258) priorities (231)
==========  ===============  ===============  ===============
1e-10       14, 5.4e-9       157, 2.3e-8      0
1e-9        82, 7.2e-8       234, 1.7e-7      16, 2.6e-8
3e-9        105, 9.5e-8      247, 1.7e-7      44, 3.2e-7
1e-8        126, 3.2e-7      254, 6.5e-7      105, 3.2e-7
3e-8        153, 2.6e-6      257, 5.0e-6      177, 6.7e-7
none        168, 1.0e-4      258, 1.7e-2      231, 5.0e-4
==========  ===============  ===============  ===============

28, 8 and 95 of those answers are more than 1e-7 off. Bounds alone (3e-9 absolute, band rows
unchecked) accepted xarm7 on the omni base, ``ahead`` tick 2: bounds violated by 2.6e-9, band
rows by 1e-8, off by 5e-6 — a vertex where rows and a bound are nearly dependent amplifies a
violation 2000×. 1e-9 (10× daqp's ``primal_tol``) keeps the accepted answers within 1.7e-7, a
factor 30 below the first tolerance that lets an answer 1e-6 off through. The bound is
empirical: at a vertex where active rows are nearly dependent, how far a violation or a gap of
``t`` moves the exact optimum has no bound the generated code can evaluate; nor has the effect
of a residual ``r`` along the Hessian's weak directions (``damping²`` = 1e-6 on a level's null
space: ``|Δx| <= |r|/1e-6``; but what the levels below keep of a level is ``E x`` and its
slacks, ``|E Δx| <= ||Δz||_H <= 2|r|/damping``, ≤ 1e-9 for the residuals of the accepted
answers, at most 2.5e-13). ``wbc exactness --states 300 --backends daqp,daqp/ordinary`` (seed 0;
``fused_fallbacks``: ticks the ordinary path answered, skipped ones included):

==========  ==========================  ==========================
family      before (anything active)    with the certificate
==========  ==========================  ==========================
random      200 fell back, 5.4e-8       124 fell back, 7.2e-8
saturating  282 fell back, 6.2e-8       110 fell back, 1.7e-7
priorities  300 fell back, 2.0e-7       300 fell back, 2.0e-7
==========  ==========================  ==========================

No false failure either way (the ordinary path: 5.4e-8, 6.2e-8, 2.0e-7). ``random`` holds 100
single-level states (never checked), so its multi-level ticks went from 0 to 76 of 200 fused;
``saturating`` from 38 to 210 of 320. On 1000 states per family (seed 1): 672, 860, 996 fell
back before, 453, 369, 993 with it, the same largest deviations as the ordinary path (1.2e-7,
3.9e-7, 1.6e-6 — the last one the ordinary path's own answer). ``priorities`` (position ≻ pose ≻
posture, a velocity bound active on every tick, the pose's position rows repeating level 0's)
stays on the ordinary path: 93 % of its fused answers fail the certificate, rightly (four in ten
are more than 1e-7 off), and after consecutive failures the back-off skips the call. The
certificate costs ≈ 0.4 µs (≈ 5 %) on a fused three-level tick (tiago_panda, 7.1 → 7.6 µs,
medians of 8 alternated runs of 3000 calls each).

What keeps its meaning
----------------------
* **Statuses.** The generated function returns non-zero when any of its daqp calls does not
  report "optimal" (it then writes no later output). That tick is solved again, from the first
  level, by the ordinary path (:meth:`Workspace.solve` with the Python daqp backend): the
  status, message, diagnosis of a conflict, partial solution and frozen-row retries are
  exactly today's, never a silent zero, and :attr:`FusedWorkspace.fallback_solves` counts such
  ticks. (DAQP's "soft optimal" is a failure for the generated code and a success for the
  backend: such a tick is reported solved.) Crossed sides (a lower bound above its upper one,
  which the bundled daqp does not check) make the call fail too. A failed call writes no
  command: the previous one stays.
* **Clipping.** Every level's ``x`` is clipped into its ``[lb, ub]`` inside the generated
  function, as :meth:`Workspace.solve` does.
* **Fallbacks** of :class:`~wbc.Controller` follow a failed solve, which always comes from the
  ordinary path: the variable bounds they read are that tick's.
* **Levels.** The :class:`~wbc.Solution` lists every QP with its ``x``;
  ``LevelResult.iterations`` is −1 (not reported by the generated code), ``frozen_rank`` −1 for
  a level under frozen task rows (no rank is computed) and ``frozen_band`` the band.

What stays in Python, and why
-----------------------------
* **Task-scaling LPs** (``stack.add(..., scaling=True)``): a stack with a scaling level keeps
  the ordinary path as a whole. The ordinary path compresses the task's equality rows by an
  SVD and declares the task inconsistent when its target leaves their range (a decision on the
  data), and the LP's zero Hessian needs daqp's proximal-point iterations. One such cascade
  has a fast path of its own, AMP's (``wbc study xing``, :mod:`wbc.papers.xing.fast`: a
  :class:`FusedWorkspace` whose generated tick it supplies through :meth:`_attach`): where its
  3-row task is not saturated — ``s = 1``, decided exactly from the facets of the zonotope the
  joint bounds map the task into — and its undamped levels reach zero, the cascade's answer is
  one strictly convex QP; the other ticks stay on the ordinary path, because there the
  ordinary path is not exact (its undamped levels, on daqp's proximal iterations, are up to
  1.3e-4 from the cascade's optimum and depend on the ticks before), so no exact tick equals
  it.
* **Singular Hessians.** The generated daqp's proximal iterations are off (``eps_prox = 0``,
  see below), so its setup refuses a level whose Hessian is singular (``damping`` 0 and a
  rank-deficient task) and that tick takes the ordinary path — correct, only slower. (On 200
  random three-level cascades with such a level: 193 fell back, the 7 the setup accepted
  agreed with the ordinary path to 6e-11.) A stack whose fused call keeps failing would pay
  for a failed call on top of the ordinary path every tick (the whole-body stack of ``wbc
  study petric`` on this generic path, level 1 covering only the base: 2490 of 2490 ticks —
  it now has a fast tick of its own, :mod:`wbc.papers.petric.fast`); so after ``k``
  consecutive failures the next ``min(2^(k−1) − 1, 63)`` ticks take the ordinary path without
  trying (:attr:`FusedWorkspace.skipped_solves`; that stack's quick run here: 50 failed calls
  in 2490 ticks), and a success resets that: one isolated failure (an infeasible tick) costs
  nothing later. Variables fixed by their bounds
  (``lb == ub``, pinned by a zero mobility, whose metric ``M⁺`` is 0 there) get 1 on the
  diagonal of ``H`` in the fused QP: constant on the feasible set, so the same optimum, and
  the Hessian daqp factorises stays regular (the ψ-shared stacks of ``wbc study sorour``:
  477 of 800 ticks fell back without it, none with it, commands within 3.6e-9 of the ordinary
  path's ``"tight"`` answer); their bound multipliers are those of that QP.

Tried and left out, with the numbers: proximal iterations in the generated daqp
(``eps_prox`` 1e-6) for the LPs (posed as ``min ½(1 − s)²``, which has the LP's optimal
``s``: as an LP the bundled DAQP missed ``s`` by up to 5e-8, posed so by 2e-10, as the Python
backend) and for undamped levels, each answer checked by a symbolic KKT certificate (residual
≤ 1e-6, else the ordinary path). The equivalence suite passed on it, SNS and AMP tests
included; but on the AMP stack of ``wbc study xing`` (mecanum_gen3, 1000 random states, the
study's own state sampler) the fused command differed from the ordinary one by more than 1e-6
in 84 states with the ``"tight"`` profile (at most 3.8e-3) and 341 with the default one (at
most 4.7): at saturated vertices a level solved to the proximal tolerance (level 0 left
≈ 1e-6 from its optimum) lets the levels below move far. Not exact: not fused. An exact
cascade instead (``s`` as a ratio over the zonotope's facets, the undamped levels as strictly
convex QPs over its half-spaces) equals the ordinary path where the task is not saturated and
misses it by up to 1.3e-4 where it is (30 of 293 saturated states, the ordinary path the
inexact one): AMP's fast path answers only the former (:mod:`wbc.papers.xing.fast`).

Differences from the backend path
---------------------------------
* **No warm start.** The generated daqp call sets its workspace up and solves from an empty
  active set every tick (the C code keeps no state between calls). The Python backend restarts
  from the previous active set. Whether that matters, measured on the 3000 QPs of the
  ``wbc pink`` closed loop (daqp 0.11, same QPs both ways): a median of 1 iteration warm and
  cold alike (at most 8 warm, 9 cold); what a cold start costs is daqp's setup (allocation,
  factorisation), which the generated code does in C.
* **DAQP version.** The casadi wheel bundles its own (older) DAQP. Its settings are those of
  :data:`DAQP_SETTINGS`; the backend's profile options (``"tight"``: ``primal_tol`` and
  ``eta_prox`` 1e-10) are passed on (a cascade's ``primal_tol`` capped, see above).
* The timing split: the whole generated call is ``timings.solve``, ``timings.assembly`` is 0.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import TypeVar

import casadi as ca
import numpy as np

from .cbuild import DEFAULT_FLAGS, compiled_extension, compiled_library, compiler_available
from .checks import STAGE_SOURCE
from .compiler import CompiledStack
from .errors import WbcError
from .passes import (
    CASCADE_PRIMAL_TOL,
    CERTIFICATE_TOL,
    DAQP_PRIMAL_TOL,
    DAQP_SETTINGS,
    FROZEN_BAND,
    FUSED_KINDS,
    daqp_link_arguments,
    fused_function,
    fused_qps,
    fused_settings,
    initialise_success,
    why_not_fused,
)
from .qp import QPResult, Status
from .solution import LevelResult, RecordedTimings, Solution, TaskResiduals, Timings
from .workspace import Workspace

W = TypeVar("W", bound=Workspace)

def build_fused(fused: bool | str, why_not: Callable[[], str | None], build: Callable[[], W],
                what: str, on_compiler: Callable[[str], None] | None = None
                ) -> tuple[W | None, str | None]:
    """Whether a fused (or fast) path is taken, decided the same way everywhere
    (:meth:`wbc.Controller.build_fused_workspace` and the papers' controllers and
    distributions): ``(build(), None)``, or ``(None, why not)``.

    Args:
        fused: ``True``, ``False`` or ``"auto"`` (the caller's argument, checked by it).
        why_not: why the path does not apply to this problem, ``None`` if it does (called
            unless ``fused`` is ``False``).
        build: makes the workspace; a ``RuntimeError`` from it is a failed C compilation.
        what: the subject of the error ``fused=True`` raises, e.g. ``"the tick cannot be
            fused"``: ``f"fused=True, but {what}: {why}"``.
        on_compiler: called with the reason when only the compiler is missing or failed (the
            controller warns there), if given.

    Raises:
        WbcError: ``fused=True`` and the path is not taken.
    """
    if fused is False:
        return None, "turned off (fused=False)"
    reason = why_not()
    if reason is None and not compiler_available():
        reason = "no C compiler found ($CC, default cc)"
        if on_compiler is not None:
            on_compiler(reason)
    if reason is None:
        try:
            return build(), None
        except RuntimeError as err:  # the compiler failed
            reason = f"C compilation failed: {err}"
            if on_compiler is not None:
                on_compiler(reason)
    if fused is True:
        raise WbcError(f"fused=True, but {what}: {reason}")
    return None, reason


@cache
def stage_extension(compiler: str) -> ModuleType | None:
    """The extension module of :data:`wbc.checks.STAGE_SOURCE` (``stage``, ``tick``, ``fused_call``,
    ``arm``) built by ``compiler`` (once per machine, ≈ 0.5 s, then cached, see
    :mod:`wbc.cbuild`; loaded once per process), or ``None`` if it cannot be built or loaded
    here (no compiler, no Python headers, no ``dlopen``)."""
    source = f"/* numpy {np.__version__} */\n{STAGE_SOURCE}"
    try:
        return compiled_extension("wbc_stage", source,
                                  (*DEFAULT_FLAGS, f"-I{np.get_include()}"), ("-ldl",))
    except (RuntimeError, ImportError):
        return None


#: After ``k`` consecutive failed fused calls, the next ``min(2^(k−1) − 1, MAX_SKIPPED_TICKS)``
#: ticks take the ordinary path without trying (see the module docstring).
MAX_SKIPPED_TICKS = 63


class FusedWorkspace(Workspace):
    """A :class:`~wbc.Workspace` on daqp whose :meth:`solve` is one call of the fused C function
    (see the module docstring); a tick the generated daqp does not solve takes the ordinary
    path.

    Args:
        compiled: a compiled stack without task-scaling LPs (:func:`why_not_fused` is
            ``None``).
        profile: daqp tolerance profile, ``"default"`` or ``"tight"``.
        warm_start: for the ordinary path's backend (the generated solver cold-starts).
        compile: ``True`` — compiled C (needs a C compiler; built once per machine, cached);
            ``False`` — the same function on CasADi's virtual machine (for tests; slow).
        **options: daqp options overriding the profile.

    Raises:
        WbcError: not fusable; ``RuntimeError`` if the C compiler fails.

    The :class:`~wbc.Solution` a fused tick returns is one object reused every tick
    (:attr:`fused_solution`), and its arrays buffers the next tick overwrites: copy what you
    keep.

    Attributes:
        function: the fused CasADi function (compiled C, or the virtual machine's).
        fallback_solves: ticks the generated daqp did not solve (taken by the ordinary path).
        skipped_solves: ticks taken by the ordinary path without a fused call, after
            consecutive failures (see the module docstring).
        bare_call: one call of the generated function on the current parameters, nothing
            else (no checks, no solution) — what benchmarks compare a tick with.
        c_call: a handle on the compiled function for :data:`wbc.checks.STAGE_SOURCE`'s
            ``tick`` (:meth:`wbc.Controller.step`'s whole tick in one C call), or ``None``
            (CasADi's virtual machine, a tick supplied without its library, no C extension).
        times: ``(started, called, model, solve)`` [s], the clock buffer the fused solution's
            :class:`~wbc.solution.RecordedTimings` read (see :data:`wbc.checks.STAGE_SOURCE`).
    """

    #: The back-off's longest run of skipped ticks (module docstring); a subclass whose failed
    #: call costs little may lower it (0: always try).
    max_skipped_ticks = MAX_SKIPPED_TICKS

    def __init__(self, compiled: CompiledStack, profile: str = "default",
                 warm_start: bool = True, compile: bool = True, **options) -> None:
        super().__init__(compiled, "daqp", profile, warm_start, **options)
        # the profile, resolved (a registered daqp backend: a BackendBase, which has options)
        settings = fused_settings(
            compiled, self._blocks[0].backend.options)  # type: ignore[attr-defined]
        function = fused_function(compiled, settings)
        library = None
        if compile:
            library = compiled_library(function, DEFAULT_FLAGS, daqp_link_arguments(),
                                       initialise_success)
            function = ca.external(function.name(), str(library))
        self._qps: ca.Function | None = None  # fused_qps, made when last_qps first asks
        n, blocks = compiled.n, compiled.blocks
        x = np.zeros(n)
        level_x = [np.zeros(n) for _ in blocks[:-1]] + [x]
        self._results = [QPResult(np.zeros(b.n_z), Status.SOLVED,
                                  np.zeros(b.m_top + b.n_frozen_soft + b.n_frozen_cost),
                                  np.zeros(b.n_z)) for b in blocks]
        outputs = [x, np.zeros(1)]
        for i, result in enumerate(self._results):
            outputs += [level_x[i]] if i < len(blocks) - 1 else []
            outputs += [result.x, result.y, result.z]
        band = FROZEN_BAND
        # frozen_rank −1: the fused tick keeps every frozen row and computes no rank
        solution = Solution(
            x, Status.SOLVED,
            [LevelResult(b.label, Status.SOLVED, level_x[i], -1 if b.n_frozen_cost else 0,
                         -1, "", band if b.n_frozen_cost else 0.0)
             for i, b in enumerate(blocks)],
            compiled.variables, {}, Timings(),
            task_residuals=None if compiled.residuals is None
            else TaskResiduals(compiled, self.p, x))
        self._attach(function, outputs, solution, library)

    def _attach(self, function: ca.Function, outputs: list[np.ndarray],
                solution: Solution, library: Path | None = None) -> None:
        """Make ``function`` (``p -> (x, done, ...)``, C or CasADi's virtual machine) this
        workspace's tick: it reads the workspace's ``p`` and writes its outputs into
        ``outputs`` (``outputs[0]`` is ``solution.x``, ``outputs[1]`` the one-entry ``done``,
        finite only when the call answered the tick); ``solution`` is what an answered tick
        returns (its ``timings`` become the tick's :class:`~wbc.solution.RecordedTimings`).
        ``library``: the shared library ``function`` was loaded from
        (:func:`wbc.cbuild.compiled_library`), if any: then :attr:`c_call` is a handle on it
        for :meth:`wbc.Controller.step`. Subclasses that generate a tick of their own call it
        from their ``__init__`` (:class:`wbc.papers.xing.fast.AMPFastWorkspace`)."""
        self.function = function
        self.fallback_solves = 0  # ticks the generated daqp did not solve
        self.skipped_solves = 0  # ticks the ordinary path took without trying the fused call
        self.times = np.zeros(4)  # (started, called, model, solve), see wbc.checks.STAGE_SOURCE
        solution.timings = RecordedTimings(self.times)
        extension = None if library is None else stage_extension(os.environ.get("CC", "cc"))
        self.c_call = None if extension is None else extension.fused_call(
            str(library), function.name(), self.p, list(outputs))
        self._arm = (None if extension is None else partial(extension.arm, self.c_call))
        self._buffer, self._evaluate = function.buffer()
        self.bare_call = self._evaluate  # the generated function alone, for benchmarks
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res, and
        # numpy's, for Python < 3.12, no buffer protocol of ndarray)
        self._buffer.set_arg(0, memoryview(self.p))  # type: ignore[call-arg, arg-type]
        for i, out in enumerate(outputs):
            if out.size:
                self._buffer.set_res(i, memoryview(out))  # type: ignore[call-arg, arg-type]
        # Reading the call's return code through SWIG costs ≈ 0.8 µs; instead, "done" is set to
        # NaN before each call and only a solved call overwrites it (with the finite cost).
        # Items as Python floats: cheaper than numpy scalars.
        self._done = memoryview(outputs[1])  # type: ignore[arg-type]
        self._solution = solution
        self._no_qps: list = []  # self._solved after a fused tick: no backend solved a QP
        self._solve = self._solve_function()

    def solve(self) -> Solution:
        """One call of the fused function; the ordinary path when it reports a failure, or
        after consecutive failures (see the module docstring). The same as calling
        :meth:`solver`'s callable."""
        return self._solve(None)

    def solver(self) -> Callable[..., Solution]:
        """:meth:`solve` as a callable bound to this workspace, for a caller that solves every
        tick (:meth:`wbc.Controller.step` takes it once): a closure over the buffers, without
        the method around it. ``solver()(started)`` returns :attr:`fused_solution` when the
        fused call answered, else the ordinary path's new :class:`~wbc.Solution`; ``started``,
        a :func:`time.perf_counter` reading taken when the caller's tick began (or ``None``:
        ``timings.model`` 0), makes ``timings.model`` the time from it to the solve (the
        caller's model stage). ``solver()(started, True)``: the caller made the fused call
        itself, through :attr:`c_call` armed (:data:`wbc.checks.STAGE_SOURCE`'s ``tick``, which
        wrote the call's start into ``times[1]``), and it did not answer — counted as a failed
        call, and the ordinary path solves the tick."""
        return self._solve

    @property
    def fused_solution(self) -> Solution:
        """The :class:`~wbc.Solution` a fused call answers with: one object for the workspace's
        life, whose arrays every answered tick rewrites (copy what you keep)."""
        return self._solution

    def _solve_function(self) -> Callable[..., Solution]:
        """The fused tick as a closure over the workspace's buffers, see :meth:`solver`. It
        keeps the back-off's counters (module docstring) in its own cells: the hot path reads
        no attribute (built once; ≈ 1 % of a Panda tick against attribute reads). It arms
        :attr:`c_call` exactly while the last tick was the fused call's: then no tick is
        being skipped and nothing is left to record, so a tick the C call answers needs no
        Python."""
        workspace, unset, call, done = self, self._unset, self._evaluate, self._done
        solution, no_qps = self._solution, self._no_qps
        times = memoryview(self.times)  # type: ignore[arg-type]  # (items as Python floats)
        arm = self._arm
        ordinary, clock, nan = super().solve, time.perf_counter, math.nan
        most = self.max_skipped_ticks
        failures = 0  # consecutive failed fused calls
        skip = 0  # ticks left that take the ordinary path without trying the fused call
        fused_last = False  # the last tick was the fused call's (self._solved is no_qps)

        def solve(started: float | None, tried: bool = False) -> Solution:
            nonlocal failures, skip, fused_last
            if unset:
                raise WbcError(f"parameters never set: {sorted(unset)}")
            if skip:  # the fused call failed on the last ticks (never armed then: not tried)
                skip -= 1
                workspace.skipped_solves += 1
                t0 = clock()
            else:
                if tried:  # the caller's call, which did not answer
                    t0 = times[1]
                else:
                    done[0] = nan  # type: ignore[call-overload]  # NaN unless answered
                    t0 = clock()
                    try:
                        call()
                    except RuntimeError:  # CasADi's virtual machine raises where C returns 1
                        pass
                    t1 = clock()
                    if done[0] == done[0]:  # not NaN: every level solved (and certified)
                        times[2] = 0.0 if started is None else t0 - started  # type: ignore
                        times[3] = t1 - t0  # type: ignore[call-overload]
                        if not fused_last:
                            workspace._solved = no_qps  # (what last_qps, variable_bounds read)
                            failures, fused_last = 0, True
                            if arm is not None:
                                arm(True)
                        return solution
                workspace.fallback_solves += 1
                failures += 1
                skip = min(2 ** (failures - 1) - 1, most)
            # the ordinary path (the model stage ended at t0: before the failed call, if any)
            if fused_last:
                fused_last = False
                if arm is not None:
                    arm(False)
            answer = ordinary()
            if started is not None:
                answer.timings.model = t0 - started
            return answer

        return solve

    def variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`Workspace.variable_bounds`; after a fused tick they are evaluated again
        (the fused call keeps them inside C; without this they were a previous tick's)."""
        if self._solved is self._no_qps:
            if self._x_above is not None:  # 0 at the first level, as in the fused call
                self._x_above[:] = 0.0
            self._blocks[0].evaluate()
        return super().variable_bounds()

    def last_qps(self) -> list[tuple]:
        """As :meth:`Workspace.last_qps`; after a fused tick, the QPs the generated daqp solved
        (frozen rows in their band, see the module docstring), evaluated again on CasADi's
        virtual machine, with the fused solve's results."""
        if self._solved is not self._no_qps:
            return super().last_qps()
        if self._qps is None:
            self._qps = fused_qps(self.compiled)
        arrays = [np.asarray(a, float) for a in
                  self._qps(self.p, *[result.x for result in self._results])]
        qps = []
        for i, (block, result) in enumerate(zip(self.compiled.blocks, self._results,
                                                strict=True)):
            H, g, A, lA, uA, lb, ub = arrays[7 * i:7 * i + 7]
            qps.append((block.label, (H, g.ravel(), A, lA.ravel(), uA.ravel(), lb.ravel(),
                                      ub.ravel()), result))
        return qps


# (the fused pass's names, defined in wbc.passes, stay importable from here)
__all__ = ["CASCADE_PRIMAL_TOL", "CERTIFICATE_TOL", "DAQP_PRIMAL_TOL", "DAQP_SETTINGS",
           "FROZEN_BAND", "FUSED_KINDS", "MAX_SKIPPED_TICKS", "FusedWorkspace", "build_fused",
           "compiler_available", "daqp_link_arguments", "fused_function", "fused_qps",
           "fused_settings", "initialise_success", "why_not_fused"]
