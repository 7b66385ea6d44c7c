"""The timing helper of the peer comparisons (experiments.loops): who runs when, and what a
closed-loop turn integrates. No time is asserted."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.experiments.benchmarks.loops import (
    call_turn,
    closed_loop_turn,
    goal_schedule,
    median_ratio,
    timed_turns,
)


def recording_turns(log: list):
    """Two contestants that log ``(name, k)`` and report 1 s and 2 s."""
    return {name: (lambda k, name=name, t=t: log.append((name, k)) or t)
            for name, t in (("a", 1.0), ("b", 2.0))}


def test_tick_by_tick_rotates_the_order_every_round():
    log: list = []
    times = timed_turns(recording_turns(log), 3)
    assert log == [("a", 0), ("b", 0), ("b", 1), ("a", 1), ("a", 2), ("b", 2)]
    np.testing.assert_array_equal(times["a"], [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(times["b"], [2.0, 2.0, 2.0])


def test_blocks_run_consecutive_ticks_and_rotate_per_round():
    log: list = []
    timed_turns(recording_turns(log), 5, block=2)
    assert log == [("a", 0), ("a", 1), ("b", 0), ("b", 1),   # round 0: a first
                   ("b", 2), ("b", 3), ("a", 2), ("a", 3),   # round 1: b first
                   ("a", 4), ("b", 4)]                       # the last, short block


def test_a_bad_block_is_refused():
    with pytest.raises(ValueError, match="block"):
        timed_turns(recording_turns([]), 3, block=0)


def test_goal_schedule_sets_each_goal_once_when_its_share_starts():
    goals = [np.full((4, 4), float(i)) for i in range(3)]
    schedule = goal_schedule(goals, 7)  # shares of 2 ticks; the last goal keeps the rest
    assert [None if g is None else g[0, 0] for g in schedule] == [0, None, 1, None, 2, None,
                                                                   None]
    assert goal_schedule(goals, 2)[0] is goals[0]  # fewer ticks than goals: one tick each


def test_a_closed_loop_turn_integrates_its_own_state_and_passes_the_schedule():
    seen = []

    def tick(q, goal):
        seen.append((q.copy(), goal))
        return np.ones(2)

    turn = closed_loop_turn(tick, ["first", None, None], np.zeros(2), dt=0.5)
    for k in range(3):
        assert turn(k) >= 0.0
    np.testing.assert_array_equal([q for q, _ in seen], [[0, 0], [0.5, 0.5], [1, 1]])
    assert [goal for _, goal in seen] == ["first", None, None]


def test_a_call_turn_calls_and_the_ratio_is_of_the_medians():
    calls = []
    turn = call_turn(lambda: calls.append(1))
    assert turn(0) >= 0.0 and calls == [1]
    result = median_ratio({"x": np.array([1.0, 2.0, 9.0]), "y": np.array([4.0, 4.0, 4.0])},
                          "x", "y")
    assert result["ratio"] == 0.5 and result["x_median_s"] == 2.0 and result["y_p95_s"] == 4.0
