"""Compose a stack once, then solve it on every installed QP backend.

A 10-variable decision vector (3 base + 7 arm velocities) with
  priority 0: a 6-row end-effector-like task  ||J x − v||²,
  priority 1: an arm posture task              ||x_arm||²,
  hard, at every level: velocity bounds        −1 <= x <= 1 [rad/s].
The stack is compiled once; each backend gets its own workspace (buffers + a live solver per
level). Every tick only numbers change: ``ws.set(...)`` then ``ws.solve()``.

Run:  python examples/compose_and_swap_backends.py [--ticks 50] [--backends daqp osqp ...]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import wbc
from wbc.solvers import available_backends
from wbc.tasks import Bounds, LinearTask


def build_stack(rng: np.random.Generator) -> wbc.Stack:
    x = wbc.Variables(qd_base=3, qd_arm=7)            # named blocks of the decision vector
    stack = wbc.Stack(x, damping=1e-3)                # ρ = 1e-3: ρ²/2·||x||² on every level
    J, v = rng.standard_normal((6, 10)), rng.standard_normal(6)
    stack.add(LinearTask(J, v, name="ee"), priority=0)
    stack.add(LinearTask(np.eye(7), np.zeros(7), name="posture", block="qd_arm"), priority=1)
    stack.constrain(Bounds(-1.0, 1.0, name="qd_limits"))
    return stack


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=50, help="random instances per backend")
    parser.add_argument("--backends", nargs="+", default=available_backends(),
                        choices=available_backends(), help="default: every installed one")
    args = parser.parse_args(argv)

    rng = np.random.default_rng(0)
    stack = build_stack(rng)
    # The same instances for every backend: (J, v) drawn once.
    instances = [(rng.standard_normal((6, 10)), rng.standard_normal(6))
                 for _ in range(args.ticks)]

    # daqp with its tight profile is the reference the others are compared with.
    reference = stack.workspace("daqp", profile="tight")
    expected = [reference.set(**{"ee.A": J, "ee.b": v}).solve().x.copy() for J, v in instances]

    results = {}
    for backend in args.backends:
        ws = stack.workspace(backend, profile="tight")  # same compiled stack, new solvers
        worst, solve_s, failed = 0.0, [], 0
        for (J, v), x_ref in zip(instances, expected, strict=True):
            t0 = time.perf_counter()
            sol = ws.set(**{"ee.A": J, "ee.b": v}).solve()
            solve_s.append(time.perf_counter() - t0)
            if not sol.ok:                   # failure is a status, never NaN
                failed += 1
                continue
            worst = max(worst, float(np.abs(sol.x - x_ref).max()))
        results[backend] = {"max_abs_diff": worst, "median_us": 1e6 * float(np.median(solve_s)),
                            "failed": failed}

    print(f"{'backend':14s} {'max |x − x_daqp|':>18s} {'median tick [µs]':>17s} failed")
    for backend, r in results.items():
        print(f"{backend:14s} {r['max_abs_diff']:18.1e} {r['median_us']:17.1f} {r['failed']:6d}")
    return results


if __name__ == "__main__":
    main()
