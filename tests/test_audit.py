"""wbc audit: a fast subset of the closed-loop audits on every exact backend keeps every robot
inside its position and velocity limits at both levels, and the audit does count violations."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import Constant

import wbc.robots
from wbc.experiments.campaigns import audit
from wbc.solvers import available_backends

EXACT = [b for b in audit.EXACT if b in available_backends()]


@pytest.mark.parametrize("level", audit.LEVELS)
def test_no_violation_nan_or_missing_fallback(level):
    result = audit.audit(len(wbc.robots.names()) * len(EXACT) * 2, EXACT, [level], ticks=20,
                         seed=3)
    assert result["runs"] == len(wbc.robots.names()) * len(EXACT) * 2
    assert (result["violations"], result["nans"], result["fallback_missing"]) == (0, 0, 0)
    assert set(result["by_level"]) == {level}


def test_audit_counts_violations():
    """A command past the velocity limit is one velocity violation per tick; driving a joint
    into its position limit adds position violations."""
    robot = wbc.robots.load("omni4_arm6")
    command = robot.limits.v_upper * 1.5
    q0 = robot.neutral()
    target = robot.frame_pose(q0, "ee")
    counts = audit.audit_run(robot, Constant(command), "velocity", q0, np.zeros(robot.nv),
                             target, ticks=200)
    assert counts["violations"] > 200 and counts["worst_v"] > 0 and counts["worst_q"] > 0


def test_start_states_are_inside_the_limits_and_viable():
    rng = np.random.default_rng(0)
    for name in wbc.robots.names():
        robot = wbc.robots.load(name)
        lim = robot.limits
        for _ in range(50):
            q, v = audit.random_start(rng, robot, "acceleration")
            assert np.all(q >= lim.q_lower) and np.all(q <= lim.q_upper)
            assert np.all(v >= lim.v_lower) and np.all(v <= lim.v_upper)


def test_cli_writes_the_contract(tmp_path):
    from wbc.experiments.cli import main

    assert main(["audit", "--runs", "8", "--backends", "daqp", "--ticks", "10",
                 "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "audit.json").read_text())
    # the label says whether daqp took the fused tick: "daqp" or "daqp (fused)"
    labels = [label for label in result["by_backend"] if label.startswith("daqp")]
    assert labels
    for key in ("runs", "violations", "nans"):
        assert isinstance(result[key], int)
        assert key in result["by_level"]["velocity"]
        assert all(key in result["by_backend"][label] for label in labels)
    assert result["violations"] == 0 and result["nans"] == 0


@pytest.mark.parametrize("finding", audit.FINDINGS)
def test_cli_exits_1_on_a_finding(tmp_path, monkeypatch, finding):
    from wbc.experiments.cli import main

    real = audit.audit

    def with_finding(*args, **kwargs):
        result = real(*args, **kwargs)
        result[finding] = 1
        return result

    monkeypatch.setattr(audit, "audit", with_finding)
    assert main(["audit", "--runs", "2", "--backends", "daqp", "--ticks", "3",
                 "--out", str(tmp_path)]) == 1
    assert json.loads((tmp_path / "audit.json").read_text())[finding] == 1
