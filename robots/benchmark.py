"""Cost of one kinematics update per robot (the catalogue and the fixed-base Panda):
``python -m wbc.robots.benchmark``.

Two tick patterns, each timed over many ticks on slowly changing configurations:

* ``update+J``: ``robot.update(q)`` then ``robot.frame_jacobian(None, "ee", out=J)``;
* ``full``: ``robot.update(q, v)`` then the ee Jacobian, drift ``J̇ v``, pose and the centre of
  mass, all written into preallocated arrays.

Prints the median and 95th percentile [µs] and the machine. Timing is reported, never asserted.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from .catalogue import load, names
from .fixed_base import load_panda


def _measure(robot, ticks: int) -> dict[str, tuple[float, float]]:
    rng = np.random.default_rng(0)
    q = robot.neutral()
    v = rng.normal(size=robot.nv) * 0.1
    jac = np.empty((6, robot.nv))
    drift = np.empty(6)
    pose = np.empty((4, 4))
    com = np.empty(3)
    light, full = [], []
    clock = time.perf_counter
    for _ in range(ticks):
        q = q + 1e-4  # a new configuration every tick: no cache hit
        t0 = clock()
        robot.update(q)
        robot.frame_jacobian(None, "ee", out=jac)
        t1 = clock()
        robot.update(q, v)
        robot.frame_jacobian(None, "ee", out=jac)
        robot.frame_drift(None, None, "ee", out=drift)
        robot.frame_pose(None, "ee", out=pose)
        robot.com(None, out=com)
        t2 = clock()
        light.append(t1 - t0)
        full.append(t2 - t1)
    return {
        "update+J": (float(np.median(light)) * 1e6, float(np.percentile(light, 95)) * 1e6),
        "full": (float(np.median(full)) * 1e6, float(np.percentile(full, 95)) * 1e6),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=5000)
    args = parser.parse_args(argv)
    machine = f"{platform.machine()} {platform.processor() or ''}".strip()
    print(f"machine: {machine}, python {platform.python_version()}")
    print(f"{'robot':<14} {'update+J median/p95 [us]':>26} {'full median/p95 [us]':>24}")
    robots = [load(name) for name in names()] + [load_panda()]
    for robot in robots:
        result = _measure(robot, args.ticks)
        light, full = result["update+J"], result["full"]
        print(f"{robot.name:<14} {light[0]:>14.1f} / {light[1]:<9.1f} "
              f"{full[0]:>12.1f} / {full[1]:<9.1f}")


if __name__ == "__main__":
    main()
