"""`wbc study sorour --quick` keeps the output contract and computes its claims from the runs."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import assert_study_contract

from wbc.experiments.studies import sorour


@pytest.fixture(scope="module")
def study(quick_studies):
    # the session's quick run (conftest.py), which the other study tests read too
    return quick_studies.study("sorour"), quick_studies.data("sorour")


def test_contract(study):
    folder, data = study
    assert_study_contract(data)
    runs = data["runs"]["table_ii"]
    assert set(runs) == set(sorour.VARIANTS)
    for series in runs.values():
        n = len(series["t"])
        assert np.shape(series["base_velocity"]) == (n, 3)
        assert len(series["ee_error"]) == n and len(series["pose_error_norm"]) == n
    for timing in data["timing"].values():
        assert timing["tick_median_s"] > 0 and timing["tick_p95_s"] >= timing["tick_median_s"]
    for figure in data["figures"]:
        assert (folder / figure).stat().st_size > 0
    assert data["parameters"]["lambda_p"] == 1.7 and data["parameters"]["ts"] == 0.025


def test_claims_are_computed_from_the_runs(study):
    _, data = study
    runs = data["runs"]["table_ii"]
    claims = {c["id"]: c for c in data["claims"]}
    worst = max(max(runs[v]["steer_rate_max"]) for v in sorour.VARIANTS)
    assert claims["steer_rate_limit"]["ours"] == pytest.approx(worst, abs=1e-6)
    assert claims["steer_rate_limit"]["holds"] == (worst <= 1.0 * (1 + 1e-4))
    areas = {v: np.mean(np.asarray(runs[v]["footprint_area"])[
        np.asarray(runs[v]["footprint_t"]) < 20.0]) for v in sorour.VARIANTS}
    assert claims["pinv_larger_footprint"]["ours"]["pinv"] == pytest.approx(areas["pinv"],
                                                                             abs=1e-3)
    # the base moves at the steering controller's feasible twist, within the MPO700's limits
    for v in sorour.VARIANTS:
        assert np.all(np.abs(runs[v]["base_velocity"]) <= np.array([0.9, 0.9, 1.0]) + 1e-9)
    assert runs["pinv"]["psi"] is None and set(runs["proposed"]["psi"]) <= {0.0, 0.5, 1.0}


def test_target_schedule_is_table_ii():
    assert sorour.target_at(0.0)[0] == 5.0 and sorour.target_at(19.99)[1] == 1.5
    assert sorour.target_at(20.0)[1] == 1.3
    assert sorour.target_at(30.0)[5] == pytest.approx(-np.pi / 2)
    assert sorour.target_at(64.0)[:2].tolist() == [4.0, -0.5]
