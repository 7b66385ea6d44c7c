"""The whole-body QP's tick in generated C where the field's base twist is reachable: the fast
path of :class:`~wbc.papers.petric.WholeBodyController` (``fused="auto"``,
:class:`WholeBodyQPController`); the ordinary path (Python around the cascade's three QPs)
answers every other tick.

Why not :mod:`wbc.fused`'s cascade
----------------------------------
:func:`~wbc.papers.petric.whole_body_stack` is, over ``x = q̇ = [u; w]`` (``u`` the base's
``(v, ω)``, ``w`` the arm's joints) with the velocity limits ``l <= x <= h`` as its only hard
constraints:

* level 0: ``min ||E₀ x − t₀||² + ρ²||x||²`` (the TCP task, damped: strictly convex, one
  answer ``x₀``);
* level 1: ``min ||E₁ x − t₁||²`` (``E₁ = [I 0]``, ``t₁`` the field's twist) keeping
  ``E₀ x = E₀ x₀``; no damping: its Hessian ``E₁ᵀE₁`` covers the base alone;
* level 2: ``min ||w − w_t||²`` (the posture, arm columns only) keeping ``E₀ x`` and ``E₁ x``.

The generated daqp has no proximal iterations, so its setup refuses level 1's singular Hessian
(and level 2's, zero on the base): on :mod:`wbc.fused`'s cascade every tick failed and took the
ordinary path after the failed call (``wbc study petric``: 2490 of 2490 ticks).

What the cascade computes where the twist is reachable
------------------------------------------------------
Level 1's cost is at least 0, and is 0 at every ``x`` of level 0's set (the box and
``E₀ x = E₀ x₀``) with ``E₁ x = t₁``. When there is such an ``x``, level 1's optimal set is
exactly those, and ``E₁ x = t₁`` is what level 2 keeps of it; level 2 is then the one QP

    min ½ xᵀ (H₂ + E₁ᵀE₁) x + g₂ᵀ x   s.t.   E₀ x = E₀ x₀,   E₁ x = t₁,   l <= x <= h

(``E₁ᵀE₁`` adds ``½||E₁ x||² = ½||t₁||²``, a constant on the feasible set: the same optimum,
and a positive definite Hessian — the posture covers the arm, ``E₁`` the base). The tick
(:func:`reachable_tick`) is two generated daqp calls: level 0, then this QP; each ``x`` clipped
into the bounds as :meth:`wbc.Workspace.solve` does. ``t₁`` comes from level 1's own QP data,
``t₁ = −(E₁E₁ᵀ)⁻¹E₁ g₁`` (its ``g₁ = −E₁ᵀt₁``; no damping, no soft rows: :func:`why_not_fast`).

Where the twist is not reachable (a base bound, or an arm that cannot keep the TCP task with
the base at ``t₁`` within its limits), the QP is infeasible. The bundled daqp does not always
say so (measured: "optimal" with a bound violated by 2e-2 and multipliers of 1e15), so the
answer must pass :func:`certified` (:mod:`wbc.fused`'s certificate: bounds and rows met, bound
multipliers on their side); after a failed daqp call (no output written) or a failed
certificate (``done`` NaN) the ordinary path answers the tick with its own status, message,
fallback and diagnosis (:class:`~wbc.fused.FusedWorkspace`'s failed call, counted in
``fallback_solves``; no back-off: :attr:`WholeBodyFastWorkspace.max_skipped_ticks` is 0, the
next tick is tried). So does a tick whose equality rows daqp finds dependent or whose Hessian
it finds singular.

Measured (``tests/test_petric_fast.py``): on the study's scenario runs at full length (6700
ticks) every tick is answered, commands within 1.3e-9 of the ordinary path's; on its quick runs
(2720 ticks, faster trajectories) 2317 are answered and 403, saturated, handed over — exactly
the ticks where the ordinary path does not reach the twist — within 5.0e-7: there
(``sine_large``) the ordinary path's level 1, undamped, solved by daqp's proximal iterations,
leaves the base 3.6e-9 off the twist, and the ordinary path on quadprog's ``"tight"`` profile
agrees with the fast tick to 6.2e-12. On 1000 random states (random configuration, TCP target,
field state; seed 28) the ordinary path reaches the twist on 212, the fast tick answers exactly
those (within 6.2e-8) and hands the 788 others over. Tick on daqp, interleaved with the
ordinary path over the full ``forward`` run's states (3 passes): 13.9 µs against 213 µs
(0.065×); in the study's scenario runs (the simulation loop) 11.5 µs, 176 µs on
:mod:`wbc.fused`'s cascade before.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

import wbc
from wbc.cbuild import DEFAULT_FLAGS, compiled_library
from wbc.compiler import LEVEL, CompiledStack
from wbc.errors import WbcError
from wbc.fused import (
    CERTIFICATE_TOL,
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

__all__ = ["WholeBodyFastWorkspace", "WholeBodyQPController", "certified", "fast_qps",
           "reachable_tick", "why_not_fast"]

#: The labels of the two QPs a fast tick solves (:meth:`WholeBodyFastWorkspace.last_qps`).
FAST_QP_LABELS = ("level 0 (fast tick)",
                  "level 2 under level 0 and level 1's reached target (fast tick)")


def why_not_fast(stack: wbc.Stack, compiled: CompiledStack, backend, options: dict) -> str | None:
    """Why ``compiled`` (``stack`` compiled, a :func:`~wbc.papers.petric.whole_body_stack`)
    cannot take the fast path on ``backend`` with ``options``, or ``None`` if it can."""
    if backend != "daqp":
        return f"the backend is {backend!r}; the fast tick solves with daqp"
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    kinds = [block.kind for block in compiled.blocks]
    if kinds != [LEVEL, LEVEL, LEVEL] or compiled.x_above_offset is not None:
        return f"not the whole-body cascade (three least-squares levels): {kinds}"
    if any(block.m_hard or block.m_soft for block in compiled.blocks):
        return "the cascade has hard or soft rows; the fast tick knows only the bounds"
    below = sorted(stack.levels)[1:]
    if any(stack.damping(k) for k in below):
        return (f"a level below the first is damped (levels {below}): level 1's optimum is not "
                "its target reached")
    return None


def fast_qps(compiled: CompiledStack) -> ca.Function:
    """``(p, x0) -> (h0, g0, lbx0, ubx0, h, g, a, b, lbx, ubx)``: level 0's QP (``min ½ zᵀ h0
    z + g0ᵀ z`` over its bounds), and, with ``x0`` level 0's answer, the QP of level 2 under
    level 0's rows and level 1's reached target (``a z = b``; module docstring). One SX
    function, common subexpressions eliminated (:func:`casadi.cse`)."""
    p = ca.SX.sym("p", compiled.defaults.shape[0])
    x0 = ca.SX.sym("x0", compiled.n)
    level0, level1, level2 = compiled.blocks
    H0, g0, _, _, _, lower0, upper0, E0T = level0.function(p)
    _, g1, _, _, _, _, _, E1T = level1.function(p)
    H2, g2, _, _, _, lower, upper, _ = level2.function(p)
    E0, E1 = E0T.T, E1T.T
    target = -ca.solve(E1 @ E1T, E1 @ g1)  # t₁ from g₁ = −E₁ᵀ t₁
    outputs = ca.cse([H0, g0, lower0, upper0, H2 + E1T @ E1, g2, ca.vertcat(E0, E1),
                      ca.vertcat(E0 @ x0, target), lower, upper])
    return ca.Function("petric_whole_body_qps", [p, x0], outputs, ["p", "x0"],
                       ["h0", "g0", "lbx0", "ubx0", "h", "g", "a", "b", "lbx", "ubx"])


def certified(z, z_bounds, rows, target, lower, upper) -> ca.MX:
    """1 if the reached-target QP's answer passes :mod:`wbc.fused`'s certificate (its rule,
    to :data:`wbc.fused.CERTIFICATE_TOL` relative to ``1 + |side|``): the bounds and the
    equality ``rows = a z`` at ``target`` met, and a bound with a positive (negative) multiplier
    at its upper (lower) side; else 0. An infeasible QP is not always reported so by the
    bundled daqp: measured on random states, it returned "optimal" with bounds violated by 2e-2
    and multipliers of 1e15 — this test sends such ticks to the ordinary path."""
    tol_l, tol_u = (CERTIFICATE_TOL * (1 + ca.fabs(side)) for side in (lower, upper))
    tol_t = CERTIFICATE_TOL * (1 + ca.fabs(target))
    outside = (ca.sum1((z < lower - tol_l) + (z > upper + tol_u))
               + ca.sum1(ca.fabs(rows - target) > tol_t))
    # (written so that a multiplier of an infinite side counts as off)
    off = ca.sum1((z_bounds > 0) * (z < upper - tol_u) + (z_bounds < 0) * (z > lower + tol_l))
    return outside + off == 0


def reachable_tick(compiled: CompiledStack, options: dict) -> ca.Function:
    """``p -> (x, done, x0, z0, z0_bounds, z, y, z_bounds)`` of the fast tick (module
    docstring): level 0 and the reached-target QP (:func:`fast_qps`; daqp, CasADi's conic node
    with ``options``), ``x0`` and ``x`` their solutions ``z0`` and ``z`` clipped into the
    bounds, ``y`` and ``z_bounds`` the multipliers (rows, bounds). A failed QP makes the call
    fail and write no output, ``done`` (the last QP's cost) included; an answer that fails
    :func:`certified` leaves ``done`` NaN. ``compiled`` must pass
    :func:`why_not_fast`; evaluates on CasADi's virtual machine as it is
    (:func:`wbc.cbuild.compiled_library` makes it C)."""
    n = compiled.n
    m = sum(block.m_cost for block in compiled.blocks[:2])
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    qps = fast_qps(compiled)

    def daqp(name: str, rows: int) -> ca.Function:
        return ca.conic(name, "daqp", {"h": ca.Sparsity.dense(n, n),
                                       "a": ca.Sparsity.dense(rows, n)},
                        {"daqp": dict(options), "error_on_fail": True})

    h0, g0, lower0, upper0 = qps(p, ca.MX.zeros(n))[:4]
    first = daqp("petric_level_0", 0)(h=h0, g=g0, a=ca.MX(0, n), lba=ca.MX(0, 1),
                                      uba=ca.MX(0, 1), lbx=lower0, ubx=upper0)
    x0 = ca.fmin(ca.fmax(first["x"], lower0), upper0)
    _, _, _, _, h, g, a, b, lower, upper = qps(p, x0)
    last = daqp("petric_level_2", m)(h=h, g=g, a=a, lba=b, uba=b, lbx=lower, ubx=upper)
    z = last["x"]
    x = ca.fmin(ca.fmax(z, lower), upper)
    done = ca.if_else(certified(z, last["lam_x"], a @ z, b, lower, upper), last["cost"],
                      math.nan)
    return ca.Function("petric_whole_body_tick", [p],
                       [x, done, x0, first["x"], first["lam_x"], z, last["lam_a"],
                        last["lam_x"]],
                       ["p"], ["x", "done", "x0", "z0", "z0_bounds", "z", "y", "z_bounds"])


class WholeBodyFastWorkspace(FusedWorkspace):
    """The workspace of :class:`WholeBodyQPController` on its fast path: :meth:`solve` is one
    call of :func:`reachable_tick` in C; a tick it does not answer takes the ordinary path (see
    the module docstring and :class:`~wbc.fused.FusedWorkspace`, whose solve, counters and
    reused :class:`~wbc.Solution` it shares; not its back-off).

    Args:
        stack: the whole-body stack ``compiled`` was compiled from.
        compiled: ``stack`` compiled, passing :func:`why_not_fast` (not JIT-compiled: the tick
            is generated from its functions).
        profile: daqp tolerance profile of both paths (the generated daqp's ``primal_tol`` at
            most :data:`wbc.fused.CASCADE_PRIMAL_TOL`).
        warm_start: for the ordinary path's backends.
        jit: the ordinary path's level functions as compiled C (:func:`wbc.passes.jit_compiled`).
        compile: the tick as compiled C (``False``: CasADi's virtual machine, for tests).
        **options: daqp options overriding the profile.

    Raises:
        WbcError: the stack cannot take the fast path; ``RuntimeError`` if the compiler fails.

    A fast tick's :class:`~wbc.Solution` lists the three levels: level 0 with ``x0``, levels 1
    and 2 with the command (level 1's optimal set holds many points; the command is one of
    them), ``frozen_rank`` and ``iterations`` −1 (not computed).
    """

    #: No back-off: a tick the QP refuses costs one failed call (a few µs), and the next one
    #: is often reachable again.
    max_skipped_ticks = 0

    def __init__(self, stack: wbc.Stack, compiled: CompiledStack, profile: str = "default",
                 warm_start: bool = True, jit: bool = True, compile: bool = True,
                 **options) -> None:
        reason = why_not_fast(stack, compiled, "daqp", options)
        if reason is not None:
            raise WbcError(f"the whole-body fast tick does not apply: {reason}")
        # not FusedWorkspace's __init__: that one generates the cascade of least-squares levels
        Workspace.__init__(self, jit_compiled(compiled) if jit else compiled, "daqp", profile,
                           warm_start, **options)
        self._symbolic = compiled
        settings = fused_settings(
            compiled, self._blocks[0].backend.options)  # type: ignore[attr-defined]
        function = reachable_tick(compiled, settings)
        library = None
        if compile:  # (the library also gives wbc.Controller.step its direct C call)
            library = compiled_library(function, DEFAULT_FLAGS, daqp_link_arguments(),
                                       initialise_success)
            function = ca.external(function.name(), str(library))
        n = compiled.n
        m = sum(block.m_cost for block in compiled.blocks[:2])
        x, x0 = np.zeros(n), np.zeros(n)
        self._results = [QPResult(np.zeros(n), Status.SOLVED, np.zeros(0), np.zeros(n)),
                         QPResult(np.zeros(n), Status.SOLVED, np.zeros(m), np.zeros(n))]
        self._qps: ca.Function | None = None  # fast_qps, made when last_qps asks
        first, last = self._results
        outputs = [x, np.zeros(1), x0, first.x, first.z, last.x, last.y, last.z]
        levels = [x0, x, x]
        solution = Solution(
            x, Status.SOLVED,
            [LevelResult(block.label, Status.SOLVED, level, -1)
             for block, level in zip(compiled.blocks, levels, strict=True)],
            compiled.variables, {}, Timings(),
            task_residuals=None if compiled.residuals is None
            else TaskResiduals(compiled, self.p, x))
        self._attach(function, outputs, solution, library)

    def last_qps(self) -> list[tuple]:
        """As :meth:`Workspace.last_qps`; after a fast tick, the two QPs the generated daqp
        solved (evaluated again on CasADi's virtual machine), with their results."""
        if self._solved is not self._no_qps:
            return Workspace.last_qps(self)
        if self._qps is None:
            self._qps = fast_qps(self._symbolic)
        (H0, g0, lb0, ub0, H, g, A, b, lb, ub) = (
            np.asarray(a, dtype=float) for a in self._qps(self.p, self._solution.levels[0].x))
        n = H0.shape[0]
        none = np.zeros(0)
        first, last = self._results
        return [(FAST_QP_LABELS[0], (H0, g0.ravel(), np.zeros((0, n)), none, none, lb0.ravel(),
                                     ub0.ravel()), first),
                (FAST_QP_LABELS[1], (H, g.ravel(), A, b.ravel(), b.ravel(), lb.ravel(),
                                     ub.ravel()), last)]


class WholeBodyQPController(wbc.Controller):
    """A :class:`wbc.Controller` of :func:`~wbc.papers.petric.whole_body_stack` whose fused
    path is the fast tick of this module (:class:`WholeBodyFastWorkspace`).

    Args:
        robot, stack: as :class:`wbc.Controller`'s (``stack`` a whole-body stack).
        fused: ``"auto"`` (default) — the fast path when the backend is ``"daqp"``, the stack
            passes :func:`why_not_fast` and a C compiler is present; ``True`` — the same, but a
            stack that cannot take it is a :class:`~wbc.WbcError`; ``False`` — the ordinary
            path. ``self.fused`` says which is used and ``self.fused_reason`` why not.
        **kwargs: :class:`wbc.Controller`'s other arguments.
    """

    def build_fused_workspace(self, fused, backend, profile, warm_start, options):
        """A :class:`WholeBodyFastWorkspace` if the fast path applies (``fused`` in the class
        docstring), else ``None`` with ``self.fused_reason`` saying why (the hook of
        :meth:`wbc.Controller.build_fused_workspace`)."""
        workspace, self.fused_reason = build_fused(
            fused, lambda: why_not_fast(self.stack, self.compiled, backend, options),
            lambda: WholeBodyFastWorkspace(self.stack, self.compiled, profile, warm_start,
                                           self.jit_c, **options),
            "the whole-body tick cannot take the fast path")
        return workspace
