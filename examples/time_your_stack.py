"""Time your own stack: where a control tick's microseconds go, per backend.

A velocity-level stack on the ``tiago_panda`` catalogue robot (differential-drive base + Franka
Panda): hand pose task, posture task at a lower priority, position and velocity limits. The
controller runs a closed loop (the robot integrates the commands) towards a moving target; every
tick's wall time is measured around ``controller.step`` and split by the solution into
``model`` (writing the state, kinematics when numeric), ``assembly`` (evaluating the compiled
level functions, frozen rows) and ``solve`` (inside the QP backend).

How to time fairly (what the project's benchmarks do):
* discard the first ticks (warm-up: caches, solver set-up on the first tick);
* report the median and the 95th percentile, not the mean (the OS adds rare long ticks);
* ``jit=True`` compiles the level functions to C once per machine (cached on disk; needs a C
  compiler): their evaluation drops from several µs to about one per level (the rest of the
  assembly, the cascade's frozen rows, stays). The library's default is ``jit=False``; the
  README's tables were measured with ``jit=True``;
* on a shared machine, compare backends within one run, not across runs.

Run:  python examples/time_your_stack.py [--ticks 2000] [--backends daqp proxqp] [--jit]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import wbc
import wbc.robots
from wbc.solvers import available_backends
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

DT = 0.01  # control period [s]
WARMUP = 20  # untimed first ticks


def build_stack(robot) -> wbc.Stack:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.2, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.2, weight=1e-2, name="posture"), priority=1)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack


def time_backend(robot, backend: str, ticks: int, jit: bool) -> dict[str, float]:
    """Median / p95 [µs] of the tick and of its parts over ``ticks`` timed ticks."""
    controller = wbc.Controller(robot, build_stack(robot), backend=backend, dt=DT, jit=jit)
    q = robot.neutral()
    home = robot.frame_pose(q, "ee")
    samples = {"tick": [], "model": [], "assembly": [], "solve": []}
    for k in range(WARMUP + ticks):
        target = home.copy()  # a 10 cm circle in the horizontal plane, one turn per 4 s
        angle = 2 * np.pi * k * DT / 4.0
        target[:2, 3] += 0.1 * np.array([np.cos(angle) - 1.0, np.sin(angle)])
        t0 = time.perf_counter()
        v = controller.step(q, ee=target, posture=robot.neutral())
        elapsed = time.perf_counter() - t0
        q = robot.integrate(q, v, DT)
        if k >= WARMUP:
            timings = controller.last_solution.timings
            samples["tick"].append(elapsed)
            samples["model"].append(timings.model)
            samples["assembly"].append(timings.assembly)
            samples["solve"].append(timings.solve)
    stats = {}
    for part, values in samples.items():
        us = 1e6 * np.asarray(values)
        stats[f"{part}_median_us"] = float(np.median(us))
        stats[f"{part}_p95_us"] = float(np.percentile(us, 95))
    return stats


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=2000, help="timed ticks per backend")
    parser.add_argument("--backends", nargs="+", default=["daqp", "quadprog", "proxqp"],
                        choices=available_backends())
    parser.add_argument("--jit", action="store_true", help="compile the stack to C first")
    args = parser.parse_args(argv)

    robot = wbc.robots.load("tiago_panda")
    results = {b: time_backend(robot, b, args.ticks, args.jit) for b in args.backends}
    print(f"tiago_panda, {args.ticks} ticks after {WARMUP} warm-up, jit={args.jit}; "
          f"median (p95) [µs]")
    print(f"{'backend':10s} {'tick':>14s} {'model':>14s} {'assembly':>14s} {'solve':>14s}")
    for backend, s in results.items():
        cells = [f"{s[f'{p}_median_us']:6.1f} ({s[f'{p}_p95_us']:5.0f})"
                 for p in ("tick", "model", "assembly", "solve")]
        print(f"{backend:10s} " + " ".join(f"{c:>14s}" for c in cells))
    return results


if __name__ == "__main__":
    main()
