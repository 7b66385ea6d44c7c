"""Exactness (issue #21): on random states, on closed loops whose limits saturate, and on strict
three-level priorities under saturation, the default path (daqp, fused tick) and quadprog give
the exact lexicographic answer of the referee (the ordinary cascade on quadprog and clarabel,
"tight") on every state where the referees agree, with no false failure."""

from __future__ import annotations

import json

import numpy as np
import pytest

import wbc.robots
from wbc.experiments.campaigns import exactness
from wbc.fused import compiler_available

STATES = 200  # per family (the saturating family's 64 loops round it up to 320 ticks)
VARIANTS = ["daqp", "quadprog"]
TOL = 1e-5  # max |v − v_ref| allowed [rad/s or m/s]


@pytest.fixture(scope="module")
def result() -> dict:
    return exactness.campaign(STATES, VARIANTS, seed=0)


@pytest.mark.parametrize("family", exactness.FAMILIES)
def test_the_referees_agree_on_almost_every_state(result, family):
    referee = result["referee"][family]
    assert referee["states"] >= STATES
    assert referee["agreed"] >= 0.95 * referee["states"], referee


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("family", exactness.FAMILIES)
def test_exact_answer_and_no_false_failure(result, family, variant):
    s = result[family][variant]
    assert s["agreed"] == result["referee"][family]["agreed"]
    assert s["errors"] == 0 and s["false_failures"] == 0, s["first_false_failure"]
    assert s["full_success_rate"] == 1.0
    assert s["max_deviation"] <= TOL, s["worst"]


def test_daqp_takes_the_fused_tick(result):
    for family in exactness.FAMILIES:
        assert result[family]["daqp"]["fused"] is compiler_available()
        assert result[family]["quadprog"]["fused"] is False


def test_the_limits_saturate(result):
    """The families test what they claim: velocity bounds active on (nearly) every state of the
    closed loops and of the priority stacks, position limits reached on the saturating loops."""
    ref = result["referee"]
    assert ref["priorities"]["velocity_bound_active"] >= 0.99
    assert ref["saturating"]["velocity_bound_active"] >= 0.5
    assert ref["saturating"]["position_bound_active"] >= 0.05
    assert ref["random"]["velocity_bound_active"] >= 0.5


def test_states_are_seeded_and_inside_the_limits():
    robot = wbc.robots.load("tiago_panda")
    draws = []
    for _ in range(2):
        rng = np.random.default_rng(7)
        draws.append([exactness.random_configuration(rng, robot) for _ in range(50)])
    assert np.array_equal(np.array(draws[0]), np.array(draws[1]))
    q = np.array(draws[0])
    assert np.all(q >= robot.limits.q_lower) and np.all(q <= robot.limits.q_upper)
    moved = np.mean(q != robot.neutral(), axis=0)[3:]  # the arm's share of perturbed joints
    assert 0.4 < moved.mean() < 0.95


def test_variant_names():
    assert exactness.parse_variant("daqp") == ("daqp", "default", False)
    assert exactness.parse_variant("casadi:osqp/tight") == ("casadi:osqp", "tight", False)
    assert exactness.parse_variant("daqp/ordinary/tight") == ("daqp", "tight", True)
    with pytest.raises(ValueError):
        exactness.parse_variant("daqp/loose")


def test_cli_writes_json_and_markdown(tmp_path):
    from wbc.experiments.cli import main

    assert main(["exactness", "--states", "4", "--backends", "daqp/ordinary",
                 "--families", "random", "--out", str(tmp_path)]) == 0
    out = json.loads((tmp_path / "exactness.json").read_text())
    assert out["random"]["daqp/ordinary"]["states"] >= 4
    assert "| daqp/ordinary |" in (tmp_path / "exactness.md").read_text()
    with pytest.raises(SystemExit) as bad:
        main(["exactness", "--backends", "daqp/loose"])
    assert bad.value.code == 2
