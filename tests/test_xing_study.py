"""`wbc study xing --quick` keeps the output contract (short horizons; the claims are still
computed from the runs)."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")

from helpers import assert_study_contract

from wbc.experiments.studies import xing  # noqa: E402
from wbc.solvers import available_backends  # noqa: E402

CLAIMS = {"base_still_r010_amp_qp", "base_still_r010_amp_closed_form",
          "traditional_base_circle_r010", "traditional_base_circle_r025",
          "traditional_base_pose", "max_error_circle_r010", "max_error_circle_r025",
          "max_error_axes_r025", "base_time_reduction_r025", "base_activation_r025",
          "base_rms_r025", "base_time_reduction_pose", "max_error_pose",
          "max_error_pose_rotation",
          "singularity_avoidance", "no_limit_violation", "xing_bounds_as_printed", "tick_time",
          "tick_target", "qp_equals_closed_form"}


def test_quick_study_writes_the_contract(tmp_path):
    assert xing.main(["--quick", "--out", str(tmp_path)]) == 0
    folder = tmp_path / "xing"
    data = json.loads((folder / "xing.json").read_text())
    assert_study_contract(data)
    assert {c["id"] for c in data["claims"]} == CLAIMS
    assert set(data["runs"]) == {"circle_r010", "circle_r025", "pose", "singularity"}
    for key in ("circle_r010", "circle_r025", "pose"):
        assert set(data["runs"][key]) == {"traditional", "amp_closed_form", "amp_qp"}
    for methods in data["runs"].values():
        for series in methods.values():
            n = len(series["t"])
            assert len(series["ee_error"]) == n and len(series["base_velocity"][0]) == 3
            assert len(series["base_velocity_command"]) == n
    # the AMP runs of the scenarios never violate a limit; the QP never fails
    assert next(c for c in data["claims"] if c["id"] == "no_limit_violation")["holds"]
    assert all(s["failures"] == 0 for s in (data["runs"][k]["amp_qp"]
                                            for k in ("circle_r010", "circle_r025", "pose")))
    assert "daqp" in data["timing"] and set(data["timing"]) <= set(available_backends())
    assert {"tick_median_s", "tick_p95_s"} <= set(data["timing"]["daqp"])
    for figure in ("xing_circle_r010.png", "xing_circle_r025.png", "xing_pose.png",
                   "xing_sigma_min.png"):
        assert (folder / figure).stat().st_size > 0
    assert "claims reproduced" in (folder / "xing.md").read_text()
