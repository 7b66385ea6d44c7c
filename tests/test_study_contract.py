"""The output contract every paper study keeps (wbc.experiments.study)."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from helpers import assert_study_contract  # noqa: E402

from wbc.errors import InvalidValueError, UnknownNameError  # noqa: E402
from wbc.experiments.studies.study import (  # noqa: E402
    Claim,
    StudyOptions,
    StudyResult,
    parse_params,
    save_figure,
    study_main,
    timing_summary,
    verdict_cell,
)


def fake_run(backend, out_dir, quick, options=None):
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("error [m]")
    figure = save_figure(fig, out_dir / "error.png")
    error = np.array([0.3, 0.1, np.nan])
    return StudyResult(
        "fake", [Claim("drops", "the error drops", 0.5, float(error[1] / error[0]),
                       np.bool_(error[1] < error[0]), "ratio of the two samples")],
        runs={"line": {"daqp": {"t": np.arange(3) * 0.1, "ee_error": error}}},
        timing={backend: timing_summary([1e-5, 2e-5, 3e-5])}, figures=[figure],
        summary_md="A fake study.", parameters={"quick": quick})


def test_study_main_writes_the_contract(tmp_path, capsys):
    assert study_main("fake", fake_run, ["--out", str(tmp_path), "--quick"]) == 0
    data = json.loads((tmp_path / "fake" / "fake.json").read_text())
    assert {"claims", "runs", "timing", "machine", "parameters", "summary"} <= set(data)
    claim = data["claims"][0]
    assert set(claim) == {"id", "statement", "paper", "ours", "holds", "note", "missing",
                          "verdict"}
    assert claim["holds"] is True and claim["verdict"] == "holds"
    assert claim["ours"] == pytest.approx(1 / 3)
    assert data["runs"]["line"]["daqp"]["ee_error"] == [0.3, 0.1, None]  # NaN has no JSON form
    assert data["timing"]["daqp"] == {"tick_median_s": 2e-5, "tick_p95_s": pytest.approx(2.9e-5),
                                      "ticks": 3}
    assert (tmp_path / "fake" / "error.png").stat().st_size > 0
    markdown = (tmp_path / "fake" / "fake.md").read_text()
    assert "1 of 1 claims reproduced" in markdown and "![error.png](error.png)" in markdown
    assert "the error drops" in capsys.readouterr().out


def test_bad_arguments_and_unlabelled_figures_are_refused(tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        study_main("fake", fake_run, ["--backend", "nosuch"])
    assert exit_info.value.code == 2
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set_xlabel("t [s]")
    with pytest.raises(ValueError, match="y label"):
        save_figure(fig, tmp_path / "bad.png")
    with pytest.raises(ValueError):
        timing_summary([])


def test_study_main_passes_the_plant_seed_and_params_and_records_them(tmp_path):
    seen = []

    def run(backend, out_dir, quick, options):
        seen.append(options)
        return fake_run(backend, out_dir, quick, options)

    assert study_main("fake", run, ["--out", str(tmp_path), "--plant", "mujoco",
                                    "--seed", "3"]) == 0
    assert seen[0] == StudyOptions(plant="mujoco", seed=3)
    data = json.loads((tmp_path / "fake" / "fake.json").read_text())
    assert data["seed"] == 3 and data["params"] == {} and "plant" in data
    assert data["plant_timing"]["wall_s"] > 0
    with pytest.raises(SystemExit) as exit_info:  # this study sweeps no constant
        study_main("fake", run, ["--out", str(tmp_path), "--param", "mu=0.5"])
    assert exit_info.value.code == 2
    with pytest.raises(InvalidValueError):
        StudyOptions(plant="gazebo")
    with pytest.raises(InvalidValueError):
        StudyOptions(seed=-1)


def test_parse_params_reads_lists_and_refuses_unknown_keys_and_bad_values():
    swept = {"mu": (0.3, "friction [-]"), "gain": (10.0, "gain [1/s]")}
    assert parse_params(["mu=0.3,0.5", "gain=4"], swept) == {"mu": [0.3, 0.5], "gain": [4.0]}
    for bad, error in ((["mu"], InvalidValueError), (["mu=a"], InvalidValueError),
                       (["mu=1", "mu=2"], InvalidValueError), (["mu=inf"], InvalidValueError),
                       (["speed=1"], UnknownNameError)):
        with pytest.raises(error):
            parse_params(bad, swept)
    assert StudyOptions(params={"gain": 4.0}).value("gain", swept) == 4.0
    assert StudyOptions().value("gain", swept) == 10.0


def test_verdicts_follow_holds_and_missing():
    assert Claim("a", "s", 1, 1, True).verdict == "holds"
    assert Claim("b", "s", 1, 2, False).verdict == "fails"
    unreachable = Claim("c", "s", 1, 2, False, "n", missing="roller compliance")
    assert unreachable.verdict == "not reproducible with this model"
    assert verdict_cell(unreachable) == "**not reproducible** (lacks roller compliance)"
    assert verdict_cell(Claim("b", "s", 1, 2, False)) == "**no**"


def test_a_claim_that_holds_lacks_nothing():
    with pytest.raises(ValueError, match="holds, so nothing is missing"):
        Claim("a", "s", 1, 1, True, missing="rollers")


def test_the_json_and_the_table_carry_the_verdict():
    result = StudyResult("x", claims=[Claim("a", "s", 1, 1, True),
                                      Claim("c", "s", 1, 2, False, missing="rollers")],
                         runs={}, timing={})
    data = json.loads(json.dumps(result.to_json()))
    assert_study_contract(data)
    assert [c["verdict"] for c in data["claims"]] == ["holds",
                                                      "not reproducible with this model"]
    table = result.markdown()
    assert "1 of 2 claims reproduced" in table and "1 not reproducible with this model" in table
    assert "**not reproducible** (lacks rollers)" in table
    # an older JSON without the fields still renders
    assert verdict_cell({"holds": False}) == "**no**"
