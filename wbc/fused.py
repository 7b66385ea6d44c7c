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
  make the call fail too. A failed call writes no output: the previous command stays.
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
  from the previous active set. Whether that matters, measured on the 3000 QPs of the
  ``wbc pink`` closed loop (daqp 0.11, same QPs both ways): a median of 1 iteration warm and
  cold alike (at most 8 warm, 9 cold); what a cold start costs is daqp's setup (allocation,
  factorisation), which the generated code does in C.
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
from .qp import QPResult, Status
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
    blocks = compiled.blocks
    if len(blocks) != 1 or blocks[0].kind != LEVEL:
        return (f"the cascade has {len(blocks)} QPs ({', '.join(b.label for b in blocks)}); "
                "only a single QP is fused")
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    return None


def fused_function(compiled: CompiledStack, options: dict) -> ca.Function:
    """The CasADi function ``p -> (x, done, z, y, z_bounds)`` of a single-QP stack: its level
    function, daqp (CasADi's conic node with ``options``), ``x`` clipped into ``[lb, ub]``,
    ``done`` (the cost; unwritten, as every output, if daqp fails or sides cross), the QP's
    solution ``z`` (slacks included) and its multipliers (rows, bounds; the sign convention of
    :mod:`wbc.qp`).
    Evaluates on CasADi's virtual machine as it is; :func:`compiled_c` makes it C.

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
    # The daqp bundled with casadi does not check lower <= upper: when sides cross, it is given
    # H = −I instead, which its setup refuses (not convex), so that the call fails as a whole and
    # writes no output (the previous command stays in place for the "last" fallback).
    crossed = ca.sum1(lb > ub) + ca.sum1(lA > uA)
    H = ca.if_else(crossed == 0, H, -ca.MX.eye(n_z))
    qp = solver(h=H, g=g, a=AT.T, lba=lA, uba=uA, lbx=ca.vertcat(lb, -free),
                ubx=ca.vertcat(ub, free))
    x = ca.fmin(ca.fmax(qp["x"][:n], lb), ub)
    # "done" (the cost) is written after a successful solve only: see FusedWorkspace.solve
    return ca.Function("fused_tick", [p], [x, qp["cost"], qp["x"], qp["lam_a"], qp["lam_x"]],
                       ["p"], ["x", "done", "z", "y", "z_bounds"])


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

    Attributes:
        function: the fused CasADi function (compiled C, or the virtual machine's).
        fallback_solves: ticks the generated daqp did not solve (taken by the ordinary path).
        bare_call: one call of the generated function on the current parameters, nothing
            else (no checks, no solution) — what benchmarks compare a tick with.
    """

    def __init__(self, compiled: CompiledStack, profile: str = "default",
                 warm_start: bool = True, compile: bool = True, **options) -> None:
        super().__init__(compiled, "daqp", profile, warm_start, **options)
        # the profile, resolved (a registered daqp backend: a BackendBase, which has options)
        settings = dict(self._blocks[0].backend.options)  # type: ignore[attr-defined]
        function = fused_function(compiled, settings)
        if compile:
            function = compiled_c(function, DEFAULT_FLAGS, daqp_link_arguments(),
                                  initialise_success)
        self.function = function
        self.fallback_solves = 0  # ticks the generated daqp did not solve
        self._x = np.zeros(compiled.n)
        self._buffer, self._evaluate = function.buffer()
        self.bare_call = self._evaluate  # the generated function alone, for benchmarks
        # (casadi's type stubs know only the (index, buffer, size) form of set_arg/set_res, and
        # numpy's, for Python < 3.12, no buffer protocol of ndarray)
        self._buffer.set_arg(0, memoryview(self.p))  # type: ignore[call-arg, arg-type]
        self._buffer.set_res(0, memoryview(self._x))  # type: ignore[call-arg, arg-type]
        # Reading the call's return code through SWIG costs ≈ 0.8 µs; instead, "done" is set to
        # NaN before each call and only a solved call overwrites it (with the finite cost).
        done = np.zeros(1)
        self._buffer.set_res(1, memoryview(done))  # type: ignore[call-arg, arg-type]
        # items as Python floats: cheaper than numpy scalars
        self._done = memoryview(done)  # type: ignore[arg-type]
        block = compiled.blocks[0]
        self._qp_result = QPResult(np.zeros(block.n_z), Status.SOLVED, np.zeros(block.m_total),
                                   np.zeros(block.n_z))
        for i, out in enumerate((self._qp_result.x, self._qp_result.y, self._qp_result.z), 2):
            if out.size:
                self._buffer.set_res(i, memoryview(out))  # type: ignore[call-arg, arg-type]
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
            self._solved = self._no_qps
            return self._solution
        self.fallback_solves += 1
        return super().solve()

    def variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`Workspace.variable_bounds`; after a fused tick they are evaluated again
        (the fused call keeps them inside C; without this they were a previous tick's)."""
        if self._solved is self._no_qps:
            self._blocks[0].evaluate()
        return super().variable_bounds()

    def last_qps(self) -> list[tuple]:
        """As :meth:`Workspace.last_qps`; after a fused tick, the QP's arrays are evaluated
        again (the fused call keeps them inside C) and the result is the fused solve's."""
        if self._solved is not self._no_qps:
            return super().last_qps()
        state = self._blocks[0]
        state.evaluate()
        return [(state.block.label, state.qp, self._qp_result)]


def compiler_available() -> bool:
    """Whether the C compiler of :mod:`wbc.jit` (``$CC``, default ``cc``) is on the path."""
    return shutil.which(os.environ.get("CC", "cc")) is not None


__all__ = ["DAQP_SETTINGS", "FusedWorkspace", "compiler_available", "daqp_link_arguments",
           "fused_function", "initialise_success", "why_not_fused"]
