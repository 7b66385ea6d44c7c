"""The fused tick: parameters → command as one generated C function (model, assembly, solve).

For a stack whose cascade is a single QP on daqp (one priority level, no task-scaling LP, no
minimum-norm level), the compiled level function ``p -> (H, g, A, lA, uA, lb, ub)`` (which holds
the compiled kinematics, see :func:`wbc.controller.compiled_kinematics`) is composed with
CasADi's ``daqp`` conic node and the clipping of ``x`` into its bounds, into one CasADi
function ``p -> x``. CasADi generates its C code; it is compiled against the daqp headers and
static library that ship inside the casadi wheel (``casadi/include/daqp``,
``casadi/libdaqpstat.a``), kept in the JIT cache (:mod:`wbc.jit`), and called every tick
through :meth:`casadi.Function.buffer` on the workspace's own parameter vector: one C call per
tick, no conversion, no allocation in Python.

What keeps its meaning
----------------------
* **Statuses.** The generated function returns non-zero when daqp does not report "optimal"
  (it then writes no output). That tick is solved again by the ordinary path
  (:meth:`Workspace.solve` with the Python daqp backend): the status, message, diagnosis of a
  conflict and partial solution are exactly today's, never a silent zero, and
  :attr:`FusedWorkspace.fallback_solves` counts such ticks. (DAQP's "soft optimal" is a failure
  for the generated code and a success for the backend: such a tick is reported solved.)
  Crossed sides (a lower bound above its upper one, which the bundled daqp does not check)
  count as a failure too.
* **Clipping.** ``x`` is clipped into ``[lb, ub]`` inside the generated function, as
  :meth:`Workspace.solve` does.
* **Fallbacks** of :class:`~wbc.Controller` follow a failed solve, which always comes from the
  ordinary path: the variable bounds they read are that tick's.

What stays in Python, and why
-----------------------------
Cascades of several QPs (strict priorities, task-scaling LPs, the minimum-norm level) keep the
ordinary path (with JIT-compiled level functions): between two levels the workspace rank-
compresses the frozen rows of the levels above (QR with column pivoting and a numerical rank
decision), decides whether they leave a single point, and retries a failed level inside a thin
band. Those are data-dependent decisions a generated expression cannot take without giving up
the cascade's exactness, so no level of a cascade is fused.

Differences from the backend path
---------------------------------
* **No warm start.** The generated daqp call sets its workspace up and solves from an empty
  active set every tick (the C code keeps no state between calls). The Python backend restarts
  from the previous active set; on the ``wbc pink`` problem this saves little (see
  ``experiments/microbench.py``).
* **DAQP version.** The casadi wheel bundles its own (older) DAQP. Its settings are those of
  :data:`DAQP_SETTINGS`; the backend's profile options (``"tight"``: ``primal_tol`` and
  ``eta_prox`` 1e-10) are passed on. Its proximal iterations are off by default
  (``eps_prox = 0``): a singular Hessian (an undamped level) fails in the generated code and
  that tick takes the ordinary path — correct, only slower.
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

from .compiler import LEVEL, CompiledStack
from .errors import WbcError
from .jit import DEFAULT_FLAGS, compiled_c
from .qp import Status
from .solution import LevelResult, Solution, Timings
from .workspace import Workspace

#: Settings of the DAQP bundled with casadi (``DAQPSettings`` in ``casadi/include/daqp``).
DAQP_SETTINGS = frozenset({"primal_tol", "dual_tol", "zero_tol", "pivot_tol", "progress_tol",
                           "cycle_tol", "iter_limit", "fval_bound", "eps_prox", "eta_prox",
                           "rho_soft", "rel_subopt", "abs_subopt"})


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


def why_not_fused(compiled: CompiledStack, options: dict) -> str | None:
    """Why ``compiled`` cannot take the fused path with daqp ``options``, or ``None`` if it
    can (see the module docstring)."""
    blocks = compiled.blocks
    if len(blocks) != 1 or blocks[0].kind != LEVEL:
        return (f"the cascade has {len(blocks)} QPs ({', '.join(b.label for b in blocks)}); "
                "only a single QP is fused")
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    return None


def fused_function(compiled: CompiledStack, options: dict) -> ca.Function:
    """The CasADi function ``p -> x`` of a single-QP stack: its level function, daqp (CasADi's
    conic node with ``options``) and the clipping of ``x`` into ``[lb, ub]``. Evaluates on
    CasADi's virtual machine as it is; :func:`compiled_c` makes it C.

    Raises:
        WbcError: the stack is not a single QP, or an option is not a daqp setting.
    """
    reason = why_not_fused(compiled, options)
    if reason:
        raise WbcError(f"cannot fuse: {reason}")
    block = compiled.blocks[0]
    n, n_z, m = compiled.n, block.n_z, block.m_top
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    p_in = p
    if compiled.x_above_offset is not None:  # Stack.x_above() is 0 at the first level
        o = compiled.x_above_offset
        p_in = ca.vertcat(p[:o], ca.MX.zeros(n), p[o + n:])
    H, g, AT, lA, uA, lb, ub, _ = block.function(p_in)
    free = ca.DM.inf(n_z - n)  # slack columns of soft rows are free
    solver = ca.conic("daqp", "daqp", {"h": ca.Sparsity.dense(n_z, n_z),
                                       "a": ca.Sparsity.dense(m, n_z)},
                      {"daqp": dict(options), "error_on_fail": True})
    qp = solver(h=H, g=g, a=AT.T, lba=lA, uba=uA, lbx=ca.vertcat(lb, -free),
                ubx=ca.vertcat(ub, free))
    x = ca.fmin(ca.fmax(qp["x"][:n], lb), ub)
    # "done" is the cost, written after a successful solve only (see FusedWorkspace.solve), and
    # NaN when sides cross: the daqp bundled with casadi does not check lower <= upper.
    crossed = ca.sum1(lb > ub) + ca.sum1(lA > uA)
    done = ca.if_else(crossed == 0, qp["cost"], math.nan)
    return ca.Function("fused_tick", [p], [x, done], ["p"], ["x", "done"])


class FusedWorkspace(Workspace):
    """A :class:`~wbc.Workspace` on daqp whose :meth:`solve` is one call of the fused C function
    (see the module docstring); a tick the generated daqp does not solve takes the ordinary
    path.

    Args:
        compiled: a single-QP compiled stack (:func:`why_not_fused` is ``None``).
        profile: daqp tolerance profile, ``"default"`` or ``"tight"``.
        warm_start: for the ordinary path's backend (the generated solver cold-starts).
        compile: ``True`` — compiled C (needs a C compiler; built once per machine, cached);
            ``False`` — the same function on CasADi's virtual machine (for tests; slow).
        **options: daqp options overriding the profile.

    Raises:
        WbcError: not fusable; ``RuntimeError`` if the C compiler fails.

    The :class:`~wbc.Solution` a fused tick returns is one object reused every tick, and its
    ``x`` a buffer the next tick overwrites: copy what you keep.
    """

    def __init__(self, compiled: CompiledStack, profile: str = "default",
                 warm_start: bool = True, compile: bool = True, **options) -> None:
        super().__init__(compiled, "daqp", profile, warm_start, **options)
        settings = dict(self._blocks[0].backend.options)  # the profile, resolved
        function = fused_function(compiled, settings)
        if compile:
            function = compiled_c(function, DEFAULT_FLAGS, daqp_link_arguments())
        self.function = function
        self.fallback_solves = 0  # ticks the generated daqp did not solve
        n = compiled.n
        self._x = np.zeros(n)
        self._buffer, self._evaluate = function.buffer()
        self._buffer.set_arg(0, memoryview(self.p))
        self._buffer.set_res(0, memoryview(self._x))
        # Reading the call's return code through SWIG costs ≈ 0.8 µs; instead, "done" is set to
        # NaN before each call and only a solved call overwrites it (with the finite cost).
        done = np.zeros(1)
        self._buffer.set_res(1, memoryview(done))
        self._done = memoryview(done)  # items as Python floats: cheaper than numpy scalars
        block = compiled.blocks[0]
        self._timings = Timings()
        self._solution = Solution(self._x, Status.SOLVED,
                                  [LevelResult(block.label, Status.SOLVED, self._x, 0)],
                                  compiled.variables, {}, self._timings)
        self._no_qps: list = []

    def solve(self) -> Solution:
        """One call of the fused function; the ordinary path when it reports a failure."""
        if self._unset:
            raise WbcError(f"parameters never set: {sorted(self._unset)}")
        done = self._done
        done[0] = math.nan
        t0 = time.perf_counter()
        try:
            self._evaluate()
        except RuntimeError:  # CasADi's virtual machine raises where the C code returns 1
            pass
        t1 = time.perf_counter()
        cost = done[0]
        if cost == cost:  # not NaN: the solve succeeded
            self._timings.solve = t1 - t0
            self._solved = self._no_qps
            return self._solution
        self.fallback_solves += 1
        return super().solve()


def compiler_available() -> bool:
    """Whether the C compiler of :mod:`wbc.jit` (``$CC``, default ``cc``) is on the path."""
    return shutil.which(os.environ.get("CC", "cc")) is not None


__all__ = ["DAQP_SETTINGS", "FusedWorkspace", "compiler_available", "daqp_link_arguments",
           "fused_function", "why_not_fused"]
