"""`wbc study omni` beyond its documented run: on MuJoCo (`--plant mujoco`), one Monte-Carlo draw
per `--seed`, `main_only` (what `wbc sweep` runs per seed) and `--param` overrides; the
documented run's claims are the ones computed before these options existed."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import pytest  # noqa: E402

from wbc.errors import UnknownNameError  # noqa: E402
from wbc.experiments.studies import omni  # noqa: E402
from wbc.experiments.studies.study import StudyOptions  # noqa: E402

#: claims of `wbc study omni --quick` computed before the plant options were added (key numbers;
#: the position-control anchors as issue #29 re-measured them: at the paper's speed, with the
#: magnitude criterion)
BEFORE = {"two_wheel_shortfall": ({"true_cm": 40.02, "odometry_cm": 40.18, "shortfall_cm": 0.16,
                                   "shortfall_pct": 0.4, "goal_offset_cm": 0.02}, False),
          "four_wheel_error_reference": ({"error_cm": 0.24, "error_pct": 0.42}, False),
          "unequal_normal_forces": ({"max_over_min": 18.1}, True),
          "proportional_less_slip_y": ({"min_norm_mm": 29.39, "proportional_mm": 0.204,
                                        "ratios_mm": 3.351, "minmax_mm": 0.537}, True),
          "minmax_at_most_proportional_diagonal": ({"minmax_mm": 13.3,
                                                    "proportional_mm": 24.342}, True)}
SWEEP_CLAIMS = {"proportional_less_slip_sweep", "minmax_at_most_proportional_sweep"}


def _claims(data) -> dict:
    return {c["id"]: (c["ours"], c["holds"]) for c in data["claims"]}


@pytest.fixture(scope="module")
def kinematic(quick_studies):
    # the session's quick run (conftest.py), which the other study tests read too
    return quick_studies.data("omni")


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    """Main-only runs: seed 3 twice, seed 4: ``(results, out_dir)``."""
    out = tmp_path_factory.mktemp("seeded")
    results = [omni.run("daqp", out / str(k), True, StudyOptions(seed=seed, main_only=True))
               for k, seed in enumerate((3, 3, 4))]
    return results, out


def test_default_options_give_the_claims_computed_before(kinematic):
    assert kinematic["plant"] == "kinematic" and kinematic["seed"] is None
    claims = _claims(kinematic)
    for claim_id, (ours, holds) in BEFORE.items():
        assert claims[claim_id] == (ours, holds), claim_id
    assert kinematic["parameters"]["gain_error"] == omni.PARAMETERS["gain_error"]


def test_the_quick_study_on_mujoco_keeps_the_claim_ids(kinematic, quick_studies):
    pytest.importorskip("mujoco")
    folder = quick_studies.study("omni", "mujoco")
    data = quick_studies.data("omni", "mujoco")
    assert data["plant"] == "mujoco"
    assert [c["id"] for c in data["claims"]] == [c["id"] for c in kinematic["claims"]]
    timing = data["plant_timing"]
    assert timing["plant"] == "mujoco" and timing["steps"] > 0 and timing["step_median_s"] > 0
    for figure in ("omni_paths.png", "omni_slip.png", "omni_utilisation.png"):
        assert (folder / figure).stat().st_size > 0
    # physics, not the kinematic plant's model: slip from the rollers, saturation recorded,
    # the unpowered wheels of the y runs produce no torque
    y = data["runs"]["y_paper_speed"]["position"]
    assert len(y["wheel_saturation"]) == len(y["t"])
    assert all(row[0] == 0.0 and row[2] == 0.0 for row in y["wheel_torque"])
    assert data["runs"]["diagonal"]["min_norm"]["summary"]["total_slip_m"] > 0.0
    assert data["runs"] != kinematic["runs"]
    assert "Plant: MuJoCo" in data["summary"]


def test_a_seed_draws_the_random_elements_reproducibly(seeded):
    (first, again, other), _ = seeded
    assert [(c.id, c.ours, c.holds) for c in first.claims] == \
        [(c.id, c.ours, c.holds) for c in again.claims]
    assert first.parameters["gain_error"] == again.parameters["gain_error"]
    for key in ("gain_error", "radius_error", "seed"):
        assert first.parameters[key] != other.parameters[key]
        assert first.parameters[key] != omni.PARAMETERS[key]
    assert max(abs(e) for e in first.parameters["gain_error"]) <= 0.05
    assert [c.ours for c in first.claims] != [c.ours for c in other.claims]


def test_main_only_skips_figures_timing_replays_and_the_sweep(seeded, kinematic):
    (first, _, _), out = seeded
    assert first.figures == [] and first.timing == {} and first.replays == {}
    assert not list(out.rglob("*.png"))
    ids = [c.id for c in first.claims]
    assert ids == [c["id"] for c in kinematic["claims"] if c["id"] not in SWEEP_CLAIMS]


def test_params_are_checked_and_change_the_run(tmp_path):
    with pytest.raises(UnknownNameError, match="nope"):
        omni.run("daqp", tmp_path, True, StudyOptions(params={"nope": 1.0}))
    with pytest.raises(SystemExit):
        omni.main(["--quick", "--param", "nope=1", "--out", str(tmp_path)])
    default = omni.run("daqp", tmp_path, True, StudyOptions(main_only=True))
    slower = omni.run("daqp", tmp_path, True,
                      StudyOptions(params={"acceleration_m_s2": 0.5}, main_only=True))
    assert default.parameters["acceleration_m_s2"] == 1.0
    assert slower.parameters["acceleration_m_s2"] == 0.5
    # gentler ramps: the runs are longer (the trapezoid's ramps take 0.4 s instead of 0.2 s)
    assert len(slower.runs["y"]["min_norm"]["t"]) == len(default.runs["y"]["min_norm"]["t"]) + 20
    assert [c.ours for c in slower.claims] != [c.ours for c in default.claims]
