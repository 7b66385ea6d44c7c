"""`wbc study omni --quick` keeps the output contract, and its claims are the runs' numbers."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from helpers import assert_study_contract

from wbc.experiments.studies import omni  # noqa: E402

RUNS = ("y", "diagonal", "y_paper_speed", "diagonal_paper_speed")
CLAIMS = {"two_wheel_shortfall", "four_wheel_error", "four_wheels_worse_than_two",
          "two_wheel_shortfall_reference", "four_wheel_error_reference",
          "four_wheels_worse_than_two_reference", "unequal_normal_forces",
          "force_control_no_slip_paper_speed",
          *(f"proportional_{c}_{key}" for c in ("less_slip", "goal_error", "odometry_error")
            for key in RUNS),
          "minmax_at_most_proportional_y", "minmax_at_most_proportional_diagonal",
          *(f"load_transfer_{c}_{s}" for c in ("less_slip", "goal_error", "odometry_error")
            for s in ("y", "diagonal")),
          "h_reconstruction_immaterial",
          "proportional_less_slip_sweep", "minmax_at_most_proportional_sweep",
          "qp_equals_closed_form"}


@pytest.fixture(scope="module")
def study(quick_studies):
    # the session's quick run (conftest.py), which the other study tests read too
    return quick_studies.study("omni"), quick_studies.data("omni")


def test_quick_study_writes_the_contract(study):
    folder, data = study
    assert_study_contract(data)
    assert {c["id"] for c in data["claims"]} == CLAIMS
    assert set(data["runs"]) == set(RUNS)
    for key, methods in data["runs"].items():
        assert set(methods) == set(omni.REGIMES["binding" if key in omni.SCENARIOS
                                                else "paper_speed"][1])
        for series in methods.values():
            n = len(series["t"])
            assert np.shape(series["base_velocity"]) == (n, 3)
            assert np.shape(series["ee_error"]) == (n,)
            assert np.shape(series["slip"]) == (n, 4)
            assert np.all(np.diff(series["slip"], axis=0) >= 0)  # cumulative distances
            assert set(series["status"]) <= {"", "solved"}
    assert {"tick_median_s", "tick_p95_s"} <= set(data["timing"]["daqp"])
    for figure in ("omni_paths.png", "omni_slip.png", "omni_utilisation.png",
                   "omni_accuracy.png"):
        assert (folder / figure).stat().st_size > 0
    assert "claims reproduced" in (folder / "omni.md").read_text()


def test_claims_are_the_runs_numbers(study):
    _, data = study
    claims = {c["id"]: c for c in data["claims"]}
    for scenario, methods in data["runs"].items():
        total = {m: float(np.sum(s["slip"][-1])) for m, s in methods.items()}
        claim = claims[f"proportional_less_slip_{scenario}"]
        assert claim["holds"] == (total["min_norm"] - total["proportional"]
                                  > omni.SLIP_ROUND_OFF_M)
        assert claim["ours"]["min_norm_mm"] == pytest.approx(1e3 * total["min_norm"], abs=1e-3)
    position = data["runs"]["diagonal_paper_speed"]["position"]
    error = np.linalg.norm(np.subtract(position["final_true_position"],
                                       position["final_odometry_position"]))
    assert claims["four_wheel_error"]["ours"]["error_cm"] == pytest.approx(100 * error, abs=0.01)
    # the distribution stacks on daqp are the closed forms
    assert claims["qp_equals_closed_form"]["holds"]
    # the premise of the slip claims: the arm's swing loads the wheels unequally
    assert claims["unequal_normal_forces"]["holds"]
