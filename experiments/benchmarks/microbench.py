"""Micro-benchmark (and the ``wbc demo``): one 6×10 pose-like stack with bounds on every backend.

The stack is what a whole-body velocity controller solves each tick: a 6-D task
``J qd = v`` on 10 joint velocities (3 base + 7 arm), a weak posture term, damping, and velocity
bounds that are active for part of the run. Parameters drift slowly from tick to tick, as in a
closed loop, so warm starts matter. For every installed backend it reports

* agreement with the referee (quadprog, tight profile, no worker thread: exact; its status
  checked every tick, see :mod:`wbc.experiments.benchmarks.accuracy`) [max |Δx|],
* median / p95 of the assembly (compiled-function evaluation) and solve phases [µs],
* the median of a cold, stateless ``qpsolvers.solve_qp`` call on the same QP, and the ratio of
  the persistent tick (assembly + solve) to it.

With daqp and a C compiler, a row ``daqp (fused)`` times the fused tick (:mod:`wbc.fused`):
assembly and solve are one generated C call (reported as "solve"), daqp cold-started inside
it — against the ``daqp`` row (compiled assembly, daqp kept alive with its active set between
ticks) it shows what the fusion saves and what the lost warm start costs.

Run: ``wbc demo`` or ``python -m wbc.experiments.benchmarks.microbench --ticks 2000``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

import wbc
from wbc.errors import WbcError
from wbc.experiments.arguments import installed_backends
from wbc.experiments.machine import describe_machine
from wbc.experiments.progress import report_progress
from wbc.fused import FusedWorkspace, compiler_available
from wbc.solvers import available_backends
from wbc.tasks import Bounds, LinearTask

N_BASE, N_ARM, M_TASK = 3, 7, 6
REFERENCE = ("quadprog", "tight")  # the bench's referee (accuracy.REFEREE), no thread
FUSED = "daqp (fused)"  # the row of the fused tick, wbc.fused (its "solve" is the whole call)


def pose_like_stack(seed: int = 0) -> tuple[wbc.Stack, dict]:
    """The benchmark stack and its initial parameter values (all parameters are per-tick)."""
    rng = np.random.default_rng(seed)
    n = N_BASE + N_ARM
    stack = wbc.Stack(wbc.Variables(qd_base=N_BASE, qd_arm=N_ARM), damping=1e-2)
    J = rng.standard_normal((M_TASK, n))
    v = rng.standard_normal(M_TASK)
    stack.add(LinearTask(J, v, name="pose"), priority=0)
    stack.add(LinearTask(np.eye(N_ARM), np.zeros(N_ARM), weight=1e-3, name="posture",
                         block="qd_arm"), priority=0)
    stack.constrain(Bounds(-0.5, 0.5, name="velocity_limits"))
    return stack, {"pose.A": J, "pose.b": v}


def tick_parameters(values: dict, k: int) -> dict:
    """Slowly varying parameters of tick ``k`` (a deterministic closed-loop stand-in)."""
    J0, v0 = values["pose.A"], values["pose.b"]
    phase = 2 * np.pi * k / 500
    return {"pose.A": J0 * (1 + 0.05 * np.sin(phase)), "pose.b": v0 * (1.2 + np.cos(phase))}


def _qp_of(ws: wbc.Workspace) -> tuple:
    """The numeric QP the first level of ``ws`` solved (for the cold qpsolvers call)."""
    _, qp, _ = ws.last_qps()[0]
    return tuple(a.copy() for a in qp)


def run(ticks: int = 1000, warmup: int = 50, backends: list[str] | None = None,
        cold: bool = True, jit: bool = True, progress=None) -> dict:
    """Time every backend on the same tick sequence; returns a JSON-able report.
    ``progress(done, total, what)`` is called after each backend."""
    import qpsolvers

    names = backends or available_backends()
    stack, values = pose_like_stack()
    seq = [tick_parameters(values, k) for k in range(warmup + ticks)]
    reference = stack.workspace(*REFERENCE, time_limit=None)
    ref_x = []
    for params in seq[warmup:]:
        reference.set(**params)
        solution = reference.solve()
        if not solution.ok:  # the referee's own status is checked: no silent wrong reference
            raise WbcError(f"the referee {'/'.join(REFERENCE)} failed a tick: "
                           f"{solution.message}")
        ref_x.append(solution.x.copy())
    report: dict[str, Any] = {"machine": describe_machine(), "ticks": ticks, "jit": jit, "problem":
              f"{M_TASK}x{N_BASE + N_ARM} task + posture + damping + bounds", "backends": {}}
    runs = [(name, name) for name in names]
    if "daqp" in names and jit and compiler_available():
        runs.append((FUSED, "daqp"))
    for done, (label, name) in enumerate(runs, start=1):
        ws = (FusedWorkspace(stack.compile()) if label == FUSED else
              stack.workspace(name, jit=jit))
        assembly, solve, errors, failures = [], [], [], 0
        for k, params in enumerate(seq):
            ws.set(**params)
            sol = ws.solve()
            if k < warmup:
                continue
            assembly.append(sol.timings.assembly)
            solve.append(sol.timings.solve)
            failures += not sol.ok
            if ref_x:
                errors.append(float(np.max(np.abs(sol.x - ref_x[k - warmup]))))
        entry: dict[str, Any] = {
            "assembly_us": _stats(assembly), "solve_us": _stats(solve),
            "tick_us": _stats(np.add(assembly, solve)), "failures": failures,
            "max_abs_diff_vs_reference": max(errors) if errors else None,
        }
        solver = name.split(":")[-1]
        if cold and solver in qpsolvers.available_solvers:
            H, g, _, _, _, lb, ub = _qp_of(ws)
            times = []
            with warnings.catch_warnings():  # the dense QP, as a user would pass it
                warnings.simplefilter("ignore", qpsolvers.warnings.SparseConversionWarning)
                for _ in range(min(ticks, 500)):
                    t0 = time.perf_counter()
                    qpsolvers.solve_qp(H, g, lb=lb, ub=ub, solver=solver)
                    times.append(time.perf_counter() - t0)
            entry["cold_qpsolvers_us"] = _stats(times)
            entry["tick_over_cold"] = entry["tick_us"]["median"] / entry["cold_qpsolvers_us"][
                "median"]
        report["backends"][label] = entry
        if progress:
            progress(done, len(runs), label)
    return report


def _stats(samples) -> dict:
    us = np.asarray(samples) * 1e6
    return {"median": float(np.median(us)), "p95": float(np.percentile(us, 95)),
            "min": float(us.min()), "max": float(us.max())}


def table(report: dict) -> str:
    """A markdown table of a :func:`run` report."""
    lines = ["| backend | max abs diff vs daqp-tight | assembly median / p95 [µs] | "
             "solve median / p95 [µs] | tick median [µs] | cold qpsolvers median [µs] | "
             "tick / cold |", "|---|---|---|---|---|---|---|"]
    for name, e in report["backends"].items():
        diff = e["max_abs_diff_vs_reference"]
        cold = e.get("cold_qpsolvers_us")
        cells = [
            name,
            "n/a" if diff is None else f"{diff:.1e}",
            f"{e['assembly_us']['median']:.1f} / {e['assembly_us']['p95']:.1f}",
            f"{e['solve_us']['median']:.1f} / {e['solve_us']['p95']:.1f}",
            f"{e['tick_us']['median']:.1f}",
            "-" if cold is None else f"{cold['median']:.1f}",
            "-" if cold is None else f"{e['tick_over_cold']:.2f}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="wbc demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=1000, help="timed ticks per backend")
    parser.add_argument("--backends", nargs="+", default=None,
                        help="backends to run (default: all available)")
    parser.add_argument("--out", type=Path, default=None, help="folder for microbench.json")
    parser.add_argument("--no-jit", action="store_true",
                        help="evaluate the compiled stack on CasADi's virtual machine, not JIT C")
    args = parser.parse_args(argv)
    if args.ticks < 1:
        parser.error("--ticks must be >= 1")
    backends = None if args.backends is None else installed_backends(parser, args.backends)
    report = run(args.ticks, backends=backends, jit=not args.no_jit,
                 progress=report_progress)
    print(table(report))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "microbench.json").write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
