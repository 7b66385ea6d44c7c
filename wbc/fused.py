"""The fused tick: parameters → command as one generated C function (model, assembly, solve).

For a stack on daqp whose cascade has no task-scaling LP (one or several least-squares levels,
and the minimum-norm level), the compiled level functions ``p -> (H, g, A, lA, uA, lb, ub,
E)`` (which hold the compiled kinematics, see :func:`wbc.controller.compiled_kinematics`) are
chained with one CasADi ``daqp`` conic node per QP and the clipping of ``x`` into its bounds,
into one CasADi function ``p -> x``. CasADi generates its C code; it is compiled against the
daqp headers and static library that ship inside the casadi wheel (``casadi/include/daqp``,
``casadi/libdaqpstat.a``), kept in the JIT cache (:mod:`wbc.jit`), and called every tick
through :meth:`casadi.Function.buffer` on the workspace's own parameter vector: one C call per
tick, no conversion, no allocation in Python.

Cascades: the frozen rows
-------------------------
Level ``k+1`` keeps what the levels above achieved, as the ordinary path does: their soft rows
at their optimal slacks (``l + w* <= C x <= u + w*``, inequalities as they are) and their task
rows ``E`` where the level above left them. The ordinary path makes the task rows exact
equalities on an orthonormal basis of their row space (QR with column pivoting, a numerical
rank decision), skips a level they leave a single point, and retries a failed level in a thin
band. A generated expression cannot take such data-dependent decisions, and daqp refuses
linearly dependent equalities (``EXIT_OVERDETERMINED_INITIAL``) — which cascades have as a
rule (an orientation level below a position level, a posture below both). The fused cascade
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
  data), and the LP's zero Hessian needs daqp's proximal-point iterations.
* **Singular Hessians.** The generated daqp's proximal iterations are off (``eps_prox = 0``,
  see below), so its setup refuses a level whose Hessian is singular (``damping`` 0 and a
  rank-deficient task) and that tick takes the ordinary path — correct, only slower. (On 200
  random three-level cascades with such a level: 193 fell back, the 7 the setup accepted
  agreed with the ordinary path to 6e-11.) A stack whose fused call keeps failing would pay
  for a failed call on top of the ordinary path every tick (the whole-body stack of ``wbc
  study petric``, level 1 covering only the base: 2490 of 2490 ticks); so after ``k``
  consecutive failures the next ``min(2^(k−1) − 1, 63)`` ticks take the ordinary path without
  trying (:attr:`FusedWorkspace.skipped_solves`; that study's quick run: 50 failed calls in
  2490 ticks), and a success resets that: one isolated failure (an infeasible tick) costs
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
≈ 1e-6 from its optimum) lets the levels below move far. Not exact: not fused.

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
import shutil
import time
from pathlib import Path

import casadi as ca
import numpy as np

from .compiler import LEVEL, MIN_NORM, CompiledStack
from .errors import WbcError
from .jit import DEFAULT_FLAGS, compiled_c
from .qp import QPResult, Status
from .solution import LevelResult, Solution, TaskResiduals, Timings
from .workspace import _ABS_RANK_TOL, Workspace

#: Settings of the DAQP bundled with casadi (``DAQPSettings`` in ``casadi/include/daqp``).
DAQP_SETTINGS = frozenset({"primal_tol", "dual_tol", "zero_tol", "pivot_tol", "progress_tol",
                           "cycle_tol", "iter_limit", "fval_bound", "eps_prox", "eta_prox",
                           "rho_soft", "rel_subopt", "abs_subopt"})


#: DAQP's default ``primal_tol`` (``DEFAULT_PRIM_TOL`` in ``casadi/include/daqp/constants.h``).
DAQP_PRIMAL_TOL = 1e-6
#: Relative half-width of the band the frozen task rows of a fused cascade are kept in (see the
#: module docstring).
FROZEN_BAND = 1e-11
#: The largest ``primal_tol`` of the generated daqp of a cascade (see the module docstring).
CASCADE_PRIMAL_TOL = 1e-10
#: After ``k`` consecutive failed fused calls, the next ``min(2^(k−1) − 1, MAX_SKIPPED_TICKS)``
#: ticks take the ordinary path without trying (see the module docstring).
MAX_SKIPPED_TICKS = 63
#: The certificate of a cascade's levels (see the module docstring): relative distance to its
#: side within which a bound or inequality with a multiplier counts as active, and relative
#: violation of a side it accepts.
CERTIFICATE_TOL = 1e-9
#: The kinds of QP the fused tick solves (task-scaling LPs are not fused).
FUSED_KINDS = frozenset({LEVEL, MIN_NORM})


def daqp_link_arguments() -> tuple[str, ...]:
    """Compiler arguments that build generated code calling daqp: the include folder and the
    static library shipped in the casadi wheel. Raises :class:`~wbc.WbcError` if the wheel has
    none (a casadi built without daqp)."""
    root = Path(ca.__file__).parent
    include, library = root / "include", root / "libdaqpstat.a"
    if not (include / "daqp" / "api.h").exists() or not library.exists():
        raise WbcError(f"casadi at {root} ships no daqp headers and static library "
                       "(include/daqp, libdaqpstat.a)")
    return (f"-I{include}", str(library), "-lm")


_SETUP_FAILED = "if (flag<0) return 1;"


def initialise_success(source: str) -> str:
    """Correct CasADi's generated daqp code (casadi 3.6–3.8): when daqp's setup fails (e.g. a
    Hessian that is not positive definite), ``casadi_daqp_solve`` returns before it writes the
    QP's ``success`` flag, and the caller, which ignores that return value, reads the flag
    uninitialised from the stack — a failed setup can then pass for a solved QP, with garbage
    in ``x``. The patch writes ``success = 0`` on that path.

    Raises:
        RuntimeError: the generated code does not have the expected shape (another casadi).
    """
    if source.count(_SETUP_FAILED) != 1:
        raise RuntimeError("the daqp code CasADi generates has changed (expected one "
                           f"{_SETUP_FAILED!r}); the fused tick is not built")
    return source.replace(_SETUP_FAILED, "if (flag<0) { d_qp->success = 0; return 1; }")


def why_not_fused(compiled: CompiledStack, options: dict) -> str | None:
    """Why ``compiled`` cannot take the fused path with daqp ``options``, or ``None`` if it
    can (see the module docstring)."""
    lps = [b.label for b in compiled.blocks if b.kind not in FUSED_KINDS]
    if lps:
        return (f"the cascade has task-scaling LPs ({', '.join(lps)}); only least-squares "
                "levels and the min-norm level are fused")
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    return None


def fused_settings(compiled: CompiledStack, options: dict) -> dict:
    """The daqp settings of the generated solver: ``options``, with ``primal_tol`` at most
    :data:`CASCADE_PRIMAL_TOL` in a cascade (see the module docstring)."""
    settings = dict(options)
    if len(compiled.blocks) > 1:
        settings["primal_tol"] = min(settings.get("primal_tol", DAQP_PRIMAL_TOL),
                                     CASCADE_PRIMAL_TOL)
    return settings


def _frozen_rows(E: ca.MX, x: ca.MX, lb: ca.MX, ub: ca.MX, band: float, rank_tol: float):
    """Rows ``(R, lower, upper)`` keeping ``E x`` where it is at ``x`` within a band: each row
    without the variables this level fixes (``lb == ub``, as the ordinary path does), scaled to
    unit norm, held in ``|r·y − r·x| <= band·(1 + |r·x|)``. A row whose norm is at most
    ``max(1e-12, rank_tol·ρ)`` (``ρ`` the largest row norm, 1 if a variable is fixed: the
    ordinary path's first pivot) is zero for the ordinary path's rank decision, and is made
    zero here (inert) — scaled to unit norm, rounding noise (a Jacobian row of 1e-11) would be
    frozen as a constraint the ordinary path does not have."""
    fixed = lb == ub
    free = ca.repmat((1 - fixed).T, E.shape[0], 1)
    E = E * free
    norms = ca.sqrt(ca.sum2(E * E))
    floor = ca.fmax(_ABS_RANK_TOL, rank_tol * ca.fmax(ca.mmax(norms), ca.mmax(fixed)))
    kept = norms > floor
    E = E * ca.repmat(kept / ca.if_else(kept, norms, 1.0), 1, E.shape[1])
    c = E @ x
    half = band * (1 + ca.fabs(c))
    return E, c - half, c + half


def _cascade(compiled: CompiledStack, p: ca.MX, solve) -> tuple[ca.MX, list[dict]]:
    """The fused cascade, symbolically: for every block its QP (``h, g, a, lba, uba, lbx,
    ubx``, the frozen rows of the levels above appended), solved by ``solve(index, qp) -> (z,
    cost, lam_a, lam_x)``, and the level's ``x`` (``z[:n]`` clipped into the bounds). Returns
    the last ``x`` and, per block, a dict of the QP and its results."""
    n = compiled.n
    band = FROZEN_BAND
    cost_rows: list[ca.MX] = []  # weighted task rows of the levels solved
    soft: list[tuple[ca.MX, ca.MX, ca.MX]] = []  # their soft rows, shifted by the slacks
    x = ca.MX.zeros(n)  # Stack.x_above() is 0 at the first level
    levels = []
    for i, block in enumerate(compiled.blocks):
        p_in = p if compiled.x_above_offset is None else _substituted(
            p, compiled.x_above_offset, x)
        H, g, AT, lA, uA, lb, ub, ET = block.function(p_in)
        n_z = block.n_z
        # A variable its bounds fix (lb == ub: pinned by a zero mobility, whose metric M⁺ has a
        # zero there) gets 1 on H's diagonal: constant on the feasible set, so the same
        # optimum, and the Cholesky factorisation daqp's setup needs exists.
        fixed = ca.vertcat(lb == ub, ca.DM.zeros(n_z - n))
        H = H + ca.diag(fixed)
        rows, lower, upper = [AT.T], [lA], [uA]
        if block.n_frozen_soft:
            C = ca.vertcat(*[s[0] for s in soft])
            rows.append(ca.horzcat(C, ca.MX(C.shape[0], n_z - n)))
            lower += [s[1] for s in soft]
            upper += [s[2] for s in soft]
        if block.n_frozen_cost:
            R, low, up = _frozen_rows(ca.vertcat(*cost_rows), x, lb, ub, band,
                                       compiled.rank_tol)
            rows.append(ca.horzcat(R, ca.MX(R.shape[0], n_z - n)))
            lower.append(low)
            upper.append(up)
        free = ca.DM.inf(n_z - n)  # slack columns of soft rows are free
        qp = {"h": H, "g": g, "a": ca.vertcat(*rows), "lba": ca.vertcat(*lower),
              "uba": ca.vertcat(*upper), "lbx": ca.vertcat(lb, -free),
              "ubx": ca.vertcat(ub, free)}
        z, cost, lam_a, lam_x = solve(i, qp)
        x = ca.fmin(ca.fmax(z[:n], lb), ub)
        if block.m_cost:
            cost_rows.append(ET.T)
        if block.m_soft:
            own = slice(block.m_hard, block.m_hard + block.m_soft)
            slack = z[n:]
            soft.append((AT.T[own, :n], lA[own] + slack, uA[own] + slack))
        levels.append({"qp": qp, "x": x, "z": z, "cost": cost, "lam_a": lam_a,
                       "lam_x": lam_x})
    return x, levels


def _certified(compiled: CompiledStack, levels: list[dict]) -> ca.MX:
    """1 if every level below the first passes the certificate of the module docstring (the
    generated daqp's ``z`` and multipliers meet the KKT conditions of the exact level problem,
    frozen task rows as equalities, to :data:`CERTIFICATE_TOL`; stationarity holds by daqp's
    construction and is not evaluated), else 0."""
    ok = []
    for block, level in zip(compiled.blocks[1:], levels[1:], strict=True):
        qp, z, lam_a, lam_x = level["qp"], level["z"], level["lam_a"], level["lam_x"]
        A = qp["a"]
        # primal feasibility and complementarity, bounds then rows; a pinned variable's bounds
        # are one equality (both sides met: either sign); the frozen task rows are equalities
        # of the exact problem (either sign), held in their band: feasibility only
        for value, lower, upper, lam, signed in (
                (z, qp["lbx"], qp["ubx"], lam_x, z.shape[0]),
                (A @ z, qp["lba"], qp["uba"], lam_a, block.m_top + block.n_frozen_soft)):
            if value.shape[0] == 0:
                continue
            tol_l = CERTIFICATE_TOL * (1 + ca.fabs(lower))
            tol_u = CERTIFICATE_TOL * (1 + ca.fabs(upper))
            ok.append(ca.sum1((value < lower - tol_l) + (value > upper + tol_u)) == 0)
            if signed:  # (written so that a multiplier of an infinite side counts as off)
                v, lam = value[:signed], lam[:signed]
                at_upper = v >= upper[:signed] - tol_u[:signed]
                at_lower = v <= lower[:signed] + tol_l[:signed]
                off = (lam > 0) * (1 - at_upper) + (lam < 0) * (1 - at_lower)
                ok.append(ca.sum1(off) == 0)
    return ca.sum1(ca.vertcat(*ok)) == len(ok) if ok else ca.MX(1)


def _substituted(p: ca.MX, offset: int, value: ca.MX) -> ca.MX:
    """``p`` with ``p[offset:offset + len(value)]`` replaced by ``value`` (an empty slice of an
    MX column is 1×0, which vertcat refuses: those are left out)."""
    end = offset + value.shape[0]
    return ca.vertcat(*([p[:offset]] if offset else []), value,
                      *([p[end:]] if end < p.shape[0] else []))


def fused_function(compiled: CompiledStack, options: dict) -> ca.Function:
    """The CasADi function ``p -> (x, done, [x_i,] z_i, y_i, z_bounds_i for each QP i)`` of a
    cascade of least-squares levels (and the min-norm level): every level's function, daqp
    (CasADi's conic node with ``options``) on its QP with the frozen rows of the levels above
    (see the module docstring), and ``x`` clipped into ``[lb, ub]``. ``done`` is the sum of the
    costs; unwritten, as every later output, if a daqp call fails or sides cross. Per QP ``i``:
    ``x_i`` (every QP but the last, whose ``x_i`` is ``x``), its solution ``z_i`` (slacks
    included) and its multipliers (rows, bounds; the sign convention of :mod:`wbc.qp`).
    Evaluates on CasADi's virtual machine as it is; :func:`compiled_c` makes it C.

    Raises:
        WbcError: the stack has a task-scaling LP, or an option is not a daqp setting.
    """
    reason = why_not_fused(compiled, options)
    if reason:
        raise WbcError(f"cannot fuse: {reason}")

    def solve(i: int, qp: dict):
        n_z, m = qp["h"].shape[0], qp["a"].shape[0]
        solver = ca.conic(f"daqp_{i}", "daqp", {"h": ca.Sparsity.dense(n_z, n_z),
                                                "a": ca.Sparsity.dense(m, n_z)},
                          {"daqp": dict(options), "error_on_fail": True})
        # The daqp bundled with casadi does not check lower <= upper: when sides cross, it is
        # given H = −I instead, which its setup refuses (not convex), so that the call fails as
        # a whole and writes no output (the previous command stays for the "last" fallback).
        crossed = ca.sum1(qp["lbx"] > qp["ubx"]) + ca.sum1(qp["lba"] > qp["uba"])
        result = solver(**{**qp, "h": ca.if_else(crossed == 0, qp["h"], -ca.MX.eye(n_z))})
        return result["x"], result["cost"], result["lam_a"], result["lam_x"]

    p = ca.MX.sym("p", compiled.defaults.shape[0])
    x, levels = _cascade(compiled, p, solve)
    done = sum(level["cost"] for level in levels)
    if len(levels) > 1:
        # A cascade's answer is kept when the certificate of the module docstring holds (the
        # exact lexicographic optimum, to tolerance); else "done" stays NaN, as after a failed
        # solve, and the ordinary path answers the tick.
        done = ca.if_else(_certified(compiled, levels), done, math.nan)
    outputs, names = [x, done], ["x", "done"]
    for i, level in enumerate(levels):
        if i < len(levels) - 1:
            outputs.append(level["x"])
            names.append(f"x_{i}")
        outputs += [level["z"], level["lam_a"], level["lam_x"]]
        names += [f"z_{i}", f"y_{i}", f"z_bounds_{i}"]
    # "done" is written after every solve succeeded only: see FusedWorkspace.solve
    return ca.Function("fused_tick", [p], outputs, ["p"], names)


def fused_qps(compiled: CompiledStack) -> ca.Function:
    """For diagnostics (:meth:`FusedWorkspace.last_qps`): ``(p, z_0, z_1, ...) -> (H, g, A,
    lA, uA, lb, ub)`` of every QP of the fused cascade, each solved by the given ``z_i``."""
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    zs = [ca.MX.sym(f"z_{i}", b.n_z) for i, b in enumerate(compiled.blocks)]
    _, levels = _cascade(compiled, p, lambda i, qp: (zs[i], None, None, None))
    return ca.Function("fused_qps", [p, *zs],
                       [level["qp"][key] for level in levels
                        for key in ("h", "g", "a", "lba", "uba", "lbx", "ubx")])


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

    The :class:`~wbc.Solution` a fused tick returns is one object reused every tick, and its
    arrays buffers the next tick overwrites: copy what you keep.

    Attributes:
        function: the fused CasADi function (compiled C, or the virtual machine's).
        fallback_solves: ticks the generated daqp did not solve (taken by the ordinary path).
        skipped_solves: ticks taken by the ordinary path without a fused call, after
            consecutive failures (see the module docstring).
        bare_call: one call of the generated function on the current parameters, nothing
            else (no checks, no solution) — what benchmarks compare a tick with.
    """

    def __init__(self, compiled: CompiledStack, profile: str = "default",
                 warm_start: bool = True, compile: bool = True, **options) -> None:
        super().__init__(compiled, "daqp", profile, warm_start, **options)
        # the profile, resolved (a registered daqp backend: a BackendBase, which has options)
        settings = fused_settings(
            compiled, self._blocks[0].backend.options)  # type: ignore[attr-defined]
        function = fused_function(compiled, settings)
        if compile:
            function = compiled_c(function, DEFAULT_FLAGS, daqp_link_arguments(),
                                  initialise_success)
        self.function = function
        self.fallback_solves = 0  # ticks the generated daqp did not solve
        self.skipped_solves = 0  # ticks the ordinary path took without trying the fused call
        self._failures = 0  # consecutive failed fused calls
        self._skip = 0  # ticks left before the fused call is tried again
        self._qps: ca.Function | None = None  # fused_qps, made when last_qps first asks
        self._buffer, self._evaluate = function.buffer()
        self.bare_call = self._evaluate  # the generated function alone, for benchmarks
        n, blocks = compiled.n, compiled.blocks
        self._x = np.zeros(n)
        level_x = [np.zeros(n) for _ in blocks[:-1]] + [self._x]
        # Reading the call's return code through SWIG costs ≈ 0.8 µs; instead, "done" is set to
        # NaN before each call and only a solved call overwrites it (with the finite cost).
        done = np.zeros(1)
        self._results = [QPResult(np.zeros(b.n_z), Status.SOLVED,
                                  np.zeros(b.m_top + b.n_frozen_soft + b.n_frozen_cost),
                                  np.zeros(b.n_z)) for b in blocks]
        outputs = [self._x, done]
        for i, result in enumerate(self._results):
            outputs += [level_x[i]] if i < len(blocks) - 1 else []
            outputs += [result.x, result.y, result.z]
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res, and
        # numpy's, for Python < 3.12, no buffer protocol of ndarray)
        self._buffer.set_arg(0, memoryview(self.p))  # type: ignore[call-arg, arg-type]
        for i, out in enumerate(outputs):
            if out.size:
                self._buffer.set_res(i, memoryview(out))  # type: ignore[call-arg, arg-type]
        # items as Python floats: cheaper than numpy scalars
        self._done = memoryview(done)  # type: ignore[arg-type]
        self._timings = Timings()
        band = FROZEN_BAND
        # frozen_rank −1: the fused tick keeps every frozen row and computes no rank
        self._solution = Solution(
            self._x, Status.SOLVED,
            [LevelResult(b.label, Status.SOLVED, level_x[i], -1 if b.n_frozen_cost else 0,
                         -1, "", band if b.n_frozen_cost else 0.0)
             for i, b in enumerate(blocks)],
            compiled.variables, {}, self._timings,
            task_residuals=None if compiled.residuals is None
            else TaskResiduals(compiled, self.p, self._x))
        self._no_qps: list = []

    def solve(self) -> Solution:
        """One call of the fused function; the ordinary path when it reports a failure."""
        if self._unset:
            raise WbcError(f"parameters never set: {sorted(self._unset)}")
        if self._skip:  # the fused call failed on the last ticks (see the module docstring)
            self._skip -= 1
            self.skipped_solves += 1
            return super().solve()
        done = self._done
        done[0] = math.nan  # type: ignore[call-overload]  # a view of float64: takes floats
        t0 = time.perf_counter()
        try:
            self._evaluate()
        except RuntimeError:  # CasADi's virtual machine raises where the C code returns 1
            pass
        t1 = time.perf_counter()
        cost = done[0]
        if cost == cost:  # not NaN: the solve succeeded
            self._timings.solve = t1 - t0
            self.fused_tick_solved()
            return self._solution
        return self.solve_after_failed_call()

    def call_buffers(self) -> tuple:
        """``(call, done, solution, timings)`` for a caller that makes the fused call itself
        (:class:`~wbc.Controller`'s tick): the bare call, the one-entry view it writes the
        cost into (set it to NaN before the call: still NaN after means a failed call), the
        reused :class:`~wbc.Solution` and its timings. After a solved call, the caller reports
        :meth:`fused_tick_solved`, after a failed one it takes :meth:`solve_after_failed_call`."""
        return self._evaluate, self._done, self._solution, self._timings

    def fused_tick_solved(self) -> None:
        """Bookkeeping of a solved fused call (its results are in the solution's buffers)."""
        self._solved = self._no_qps
        self._failures = 0

    def solve_after_failed_call(self) -> Solution:
        """The tick on the ordinary path after a failed fused call, counted, with the back-off
        of the module docstring."""
        self.fallback_solves += 1
        self._failures += 1
        self._skip = min(2 ** (self._failures - 1) - 1, MAX_SKIPPED_TICKS)
        return super().solve()

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


def compiler_available() -> bool:
    """Whether the C compiler of :mod:`wbc.jit` (``$CC``, default ``cc``) is on the path."""
    return shutil.which(os.environ.get("CC", "cc")) is not None


__all__ = ["CASCADE_PRIMAL_TOL", "CERTIFICATE_TOL", "DAQP_PRIMAL_TOL", "DAQP_SETTINGS",
           "FROZEN_BAND", "FUSED_KINDS", "MAX_SKIPPED_TICKS", "FusedWorkspace",
           "compiler_available", "daqp_link_arguments", "fused_function", "fused_qps",
           "fused_settings", "initialise_success", "why_not_fused"]
