"""`wbc study petric --quick` keeps the output contract and computes its claims from the runs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import assert_study_contract

from wbc.experiments.studies import petric
from wbc.papers.petric import VelocityField


@pytest.fixture(scope="module")
def study(quick_studies):
    # the session's quick run (conftest.py), which the other study tests read too
    return quick_studies.study("petric"), quick_studies.data("petric")


def test_contract(study):
    folder, data = study
    assert_study_contract(data)
    for name in petric.SCENARIOS:
        methods = data["runs"][name]
        assert {"decoupled", "decoupled_exact", "whole_body"} <= set(methods)
        for series in methods.values():
            n = len(series["t"])
            assert n > 10
            assert np.shape(series["base_velocity"]) == (n, 2)
            assert np.shape(series["ee_error"]) == (n,)
            assert np.all(np.isfinite(series["ee_error"]))
    assert {"fixed_base", "fixed_base_exact"} <= set(data["runs"]["forward"])
    for timing in data["timing"].values():
        assert timing["tick_median_s"] > 0 and timing["tick_p95_s"] >= timing["tick_median_s"]
    assert data["figures"]
    for figure in data["figures"]:
        assert (folder / figure).stat().st_size > 0
    assert data["parameters"]["lambda"] == 0.05 and data["parameters"]["quick"] is True
    slices = data["runs"]["field_slices"]["raw"]
    assert np.shape(slices["v"]) == (len(petric.SLICES_Z), len(slices["y"]), len(slices["x"]))
    field = VelocityField()
    for i, j, k in ((0, 20, 20), (2, 5, 30), (4, 35, 12)):
        p = [slices["x"][k], slices["y"][j], slices["z"][i]]
        assert (slices["v"][i][j][k], slices["omega"][i][j][k]) == pytest.approx(field.raw(p))


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def test_claims_are_computed_from_the_runs(study):
    _, data = study
    runs = data["runs"]
    claims = {c["id"]: c for c in data["claims"]}
    fixed = _rms(runs["forward"]["fixed_base"]["ee_error"])
    moving = _rms(runs["forward"]["decoupled"]["ee_error"])
    ours = claims["fixed_base_error"]["ours"]
    assert ours["rms_fixed_m"] == pytest.approx(fixed) and ours["rms_moving_m"] == \
        pytest.approx(moving)
    assert claims["fixed_base_error"]["holds"] == (fixed >= 3 * moving)

    commands = np.concatenate([runs[s]["decoupled"]["command_base"] for s in petric.SCENARIOS])
    assert claims["bounds"]["ours"]["v"] == pytest.approx(np.abs(commands[:, 0]).max())
    assert claims["bounds"]["holds"] == bool(np.abs(commands[:, 0]).max() <= 1.0 + 1e-9
                                             and np.abs(commands[:, 1]).max() <= 1.0 + 1e-9
                                             and claims["bounds"]["ours"]["dv"] <= 1.0 + 1e-9
                                             and claims["bounds"]["ours"]["domega"] <= 1.0
                                             + 1e-9)

    low = np.asarray(runs["retreat_low"]["decoupled"]["base_pose"])
    turn = math.degrees(np.abs(low[:, 2] - low[0, 2]).max())
    assert claims["retreat_low"]["ours"]["turn_deg"] == pytest.approx(turn)

    leak = np.concatenate([runs[s]["decoupled"]["leak"] for s in petric.SCENARIOS])
    assert claims["damped_projector_leak"]["ours"]["max_mm_s"] == pytest.approx(1e3 * leak.max())
    # the leak of eq. 26's damped projector is real and within its bound √λ/2·||q̇_n||
    assert claims["damped_projector_leak"]["holds"] is False and leak.max() > 1e-4
    tracking = claims["damped_projector_leak"]["ours"]["rms_tcp_error"]
    for name in petric.SCENARIOS:  # the paper's controller (eq. 26) and ours (exact)
        assert tracking[name]["paper_eq26_mm"] == pytest.approx(
            1e3 * _rms(runs[name]["decoupled"]["ee_error"]))
        assert tracking[name]["exact_mm"] == pytest.approx(
            1e3 * _rms(runs[name]["decoupled_exact"]["ee_error"]))

    wb = {s: _rms(runs[s]["whole_body"]["ee_error"]) for s in petric.SCENARIOS}
    de = {s: _rms(runs[s]["decoupled"]["ee_error"]) for s in petric.SCENARIOS}
    better = sum(wb[s] <= de[s] for s in petric.SCENARIOS)
    assert claims["whole_body_vs_decoupled"]["ours"]["scenarios_better_or_equal"] == better


def test_fidelity_claims_are_computed_from_the_runs(study):
    """Issue #29's claims: each behaviour claim also for ours (``*_exact``), the lateral run's
    onsets, the settling hold, both readings of the rate limits, the invariance campaign."""
    _, data = study
    runs, claims = data["runs"], {c["id"]: c for c in data["claims"]}
    for claim in petric.RECONSTRUCTED[:-1]:
        assert f"{claim}_exact" in claims and "reconstructed trajectory" in claims[claim]["note"]
    lateral = runs["lateral"]["decoupled"]
    t, v = np.asarray(lateral["t"]), np.asarray(lateral["base_velocity"])
    ours = claims["lateral_retreat_first"]["ours"]
    if ours["t_backward_onset_s"] is not None:
        back = np.maximum(-v[:, 0], 0.0)
        assert ours["t_backward_onset_s"] == t[np.argmax(back >= 0.1 * back.max())]
    square = runs["square"]["decoupled_exact"]
    assert claims["settling_exact"]["ours"]["square_end_error_mm"] == pytest.approx(
        1e3 * square["ee_error"][-1])
    steps = np.concatenate([np.diff(runs[s]["decoupled"]["command_base"], axis=0)
                            for s in petric.SCENARIOS])
    per_second = claims["rate_limits_per_second"]["ours"]
    assert per_second["ticks"] == len(steps)
    assert per_second["ticks_over_domega"] == int(np.sum(np.abs(steps[:, 1]) / petric.DT > 1.0))
    assert per_second["domega_dt_max"] == pytest.approx(np.abs(steps[:, 1]).max() / petric.DT)
    invariance = claims["retreat_invariance"]
    assert invariance["holds"] == (invariance["ours"]["entered"] == 0)
    assert invariance["ours"]["placements"] == 720
    assert invariance["ours"]["entered_above_touch"] == 0


def test_fixed_base_run_keeps_the_base_still(study):
    _, data = study
    fixed = data["runs"]["forward"]["fixed_base"]
    np.testing.assert_array_equal(fixed["base_velocity"], 0.0)
    assert np.abs(np.asarray(data["runs"]["forward"]["decoupled"]["base_velocity"])).max() > 0.05


def test_trajectories_start_at_the_tcp_and_carry_the_feed_forward():
    start = np.array([0.5, 0.0, 0.6])
    desired, reference = petric.trajectory("sine_large", start)
    np.testing.assert_allclose(desired(0.0), start)
    # x_d + ẋ_d / K_p: the sine's lateral velocity at t = 0 is 0.5·2π/6 m/s
    target = reference(0.0)["ee"][:3, 3]
    np.testing.assert_allclose(target - start, np.array([0.1, 0.5 * 2 * math.pi / 6, 0.0])
                               / petric.KP, atol=1e-6)
    for name, scenario in petric.SCENARIOS.items():
        np.testing.assert_allclose(scenario.offset(0.0), 0.0, atol=1e-12, err_msg=name)
