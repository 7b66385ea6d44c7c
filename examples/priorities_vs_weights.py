"""Strict priorities versus weights, on two tasks that conflict.

Task 1 asks 3 velocity directions of a 5-variable system for one value, task 2 asks 3 other
(overlapping) directions for another; together they are 6 equations in 5 unknowns, so both
cannot hold. Two ways to rank them:

* **strict priority** (``priority=0`` and ``priority=1``): a cascade of QPs; task 1 holds
  exactly and task 2 does the best it can without disturbing it. This equals recursive
  null-space projection (``wbc.solvers.reference.hierarchy``), checked below.
* **weights** (both at ``priority=0``, task 1 weighted ``w`` times more): one QP; task 1's error
  shrinks as ``w`` grows but never reaches zero — weights only approach strict priorities.

Run:  python examples/priorities_vs_weights.py [--out DIR]   (writes priorities_vs_weights.png)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no window needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import wbc  # noqa: E402
from wbc.solvers.reference import hierarchy  # noqa: E402
from wbc.tasks import LinearTask  # noqa: E402

N = 5
RNG = np.random.default_rng(1)
J1, v1 = RNG.standard_normal((3, N)), RNG.standard_normal(3)
J2, v2 = RNG.standard_normal((3, N)), RNG.standard_normal(3)


def strict() -> np.ndarray:
    stack = wbc.Stack(N)  # undamped: a final minimum-norm level makes x unique
    stack.add(LinearTask(J1, v1, name="task1"), priority=0)
    stack.add(LinearTask(J2, v2, name="task2"), priority=1)
    return stack.solve("daqp").x


def weighted(ratio: float) -> np.ndarray:
    stack = wbc.Stack(N)
    stack.add(LinearTask(J1, v1, weight=ratio, name="task1"), priority=0)
    stack.add(LinearTask(J2, v2, weight=1.0, name="task2"), priority=0)
    return stack.solve("daqp").x


def error(J: np.ndarray, v: np.ndarray, x: np.ndarray) -> float:
    return float(np.linalg.norm(J @ x - v))


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="folder for the PNG")
    args = parser.parse_args(argv)

    x_strict = strict()
    x_projection = hierarchy([(J1, v1), (J2, v2)], 0.0)  # the closed form of the same thing
    print(f"strict priority: |J1 x − v1| = {error(J1, v1, x_strict):.1e}, "
          f"|J2 x − v2| = {error(J2, v2, x_strict):.3f}; "
          f"max |x − x_null-space projection| = {np.abs(x_strict - x_projection).max():.1e}")

    ratios = np.logspace(0, 6, 13)
    rows = [(r, error(J1, v1, x), error(J2, v2, x)) for r in ratios for x in [weighted(r)]]
    print(f"{'w1/w2':>8s} {'|J1 x − v1|':>12s} {'|J2 x − v2|':>12s}")
    for r, e1, e2 in rows:
        print(f"{r:8.0e} {e1:12.2e} {e2:12.4f}")

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(ratios, [e1 for _, e1, _ in rows], "o-", label="weighted: task 1 error")
    ax.loglog(ratios, [e2 for _, _, e2 in rows], "s-", label="weighted: task 2 error")
    ax.axhline(error(J2, v2, x_strict), color="k", ls="--",
               label="strict priority: task 2 error (task 1 error ≈ 0)")
    ax.set_xlabel("weight ratio w1 / w2 [-]")
    ax.set_ylabel("task error |J x − v| [rad/s]")
    ax.set_title("Weights approach strict priority, never reach it")
    ax.legend()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "priorities_vs_weights.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return {"strict": x_strict, "projection": x_projection, "weighted": rows}


if __name__ == "__main__":
    main()
