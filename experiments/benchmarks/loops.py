"""Timing closed loops side by side, in one process, two ways.

* **Tick by tick** (``block = 1``): every contestant ticks once per round, the order rotating
  from round to round. Machine noise hits all alike, and each tick finds the CPU caches as the
  others left them — a controller sharing its core with other work.
* **In blocks** (``block = B``): ``B`` consecutive ticks of one contestant, then ``B`` of the
  next, the order rotating from round to round. From its second tick on, a block runs with the
  caches it warmed itself — a dedicated control loop — and noise on time scales longer than a
  block still hits all alike. The first tick of every block (cold) is counted too.

A contestant is a *turn*: ``turn(k) -> seconds``, its tick ``k`` of its own closed loop,
timing the part that is compared and doing untimed work (integration) outside that.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Sequence

import numpy as np

#: Consecutive ticks per block of the dedicated-loop timing.
DEDICATED_BLOCK = 100


def timed_turns(turns: dict[str, Callable[[int], float]], ticks: int,
                block: int = 1) -> dict[str, np.ndarray]:
    """Run ``turns[name](k)`` for ``k`` in ``range(ticks)`` for every contestant, interleaved
    tick by tick (``block = 1``) or in blocks of ``block`` ticks (see the module docstring),
    with the garbage collector paused; returns ``name -> seconds`` per tick."""
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    names = list(turns)
    times = {name: np.empty(ticks) for name in names}
    gc.collect()
    gc.disable()
    try:
        for r, start in enumerate(range(0, ticks, block)):
            for i in range(len(names)):
                name = names[(r + i) % len(names)]
                turn, out = turns[name], times[name]
                for k in range(start, min(start + block, ticks)):
                    out[k] = turn(k)
    finally:
        gc.enable()
    return times


def goal_schedule(goals: Sequence[np.ndarray], ticks: int) -> list[np.ndarray | None]:
    """Per tick, the goal to set — ``goals`` held for an equal share of ``ticks`` each, set on
    the tick it starts — or ``None`` (unchanged)."""
    per_goal = max(1, ticks // len(goals))
    index = [min(k // per_goal, len(goals) - 1) for k in range(ticks)]
    return [goals[g] if k == 0 or g != index[k - 1] else None for k, g in enumerate(index)]


def closed_loop_turn(tick: Callable[[np.ndarray, np.ndarray | None], np.ndarray],
                     schedule: Sequence[np.ndarray | None], q0: np.ndarray,
                     dt: float) -> Callable[[int], float]:
    """A turn: ``v = tick(q, schedule[k])`` timed, then ``q ← q + dt·v`` (untimed); the loop
    starts at ``q0``. ``tick`` gets ``None`` when the goal is unchanged."""
    state = {"q": np.array(q0, float)}
    clock = time.perf_counter

    def turn(k: int) -> float:
        q, goal = state["q"], schedule[k]
        t0 = clock()
        v = tick(q, goal)
        elapsed = clock() - t0
        state["q"] = q + dt * v
        return elapsed

    return turn


def call_turn(call: Callable[[], object]) -> Callable[[int], float]:
    """A turn that times ``call()`` alone (e.g. the bare call of a fused tick)."""
    clock = time.perf_counter

    def turn(k: int) -> float:
        t0 = clock()
        call()
        return clock() - t0

    return turn


def wbc_tick(controller, keyword: str = "ee") -> Callable[[np.ndarray, np.ndarray | None],
                                                         np.ndarray]:
    """``(q, goal) -> controller.step(q)``, with ``keyword=goal`` when the goal changes."""
    step = controller.step

    def tick(q: np.ndarray, goal: np.ndarray | None) -> np.ndarray:
        return step(q) if goal is None else step(q, **{keyword: goal})

    return tick


def median_ratio(times: dict[str, np.ndarray], numerator: str, denominator: str) -> dict:
    """Medians and p95s [s] of two contestants and the ratio of their medians."""
    a, b = times[numerator], times[denominator]
    return {f"{numerator}_median_s": float(np.median(a)),
            f"{denominator}_median_s": float(np.median(b)),
            f"{numerator}_p95_s": float(np.percentile(a, 95)),
            f"{denominator}_p95_s": float(np.percentile(b, 95)),
            "ratio": float(np.median(a) / np.median(b))}
