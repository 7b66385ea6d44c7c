"""The pink comparison runs end to end (tiny tick counts; no timing is asserted)."""

from __future__ import annotations

import json
import sys

import pytest

from wbc.errors import MissingDependencyError
from wbc.experiments.peers import vs_pink

KEYS = {"wbc_median_s", "pink_median_s", "ratio", "command_diff_max", "agree",
        "final_position_diff_m"}


def test_vs_pink_writes_its_json(tmp_path, capsys):
    pytest.importorskip("pink")
    code = vs_pink.main(["--ticks", "30", "--backends", "daqp", "quadprog", "--no-jit",
                         "--out", str(tmp_path)])
    assert code == 0
    report = json.loads((tmp_path / "vs_pink.json").read_text())
    assert set(report["backends"]) == {"daqp", "quadprog"}
    for result in report["backends"].values():
        assert KEYS <= set(result)
        assert result["wbc_median_s"] > 0 and result["pink_median_s"] > 0
        assert result["wbc_failures"] == 0
        assert result["command_diff_max"] < 1e-6  # exact solvers: the same QP
        dedicated = result["dedicated"]  # the loops again, each in blocks of its own
        assert dedicated["wbc_median_s"] > 0 and dedicated["pink_median_s"] > 0
        assert dedicated["block"] == 100
    # the fused tick's bare call, timed in blocks too
    assert report["backends"]["daqp"]["dedicated"]["step_over_bare"] > 0
    assert "step_over_bare" not in report["backends"]["quadprog"]["dedicated"]
    assert {"platform", "cpu", "python", "packages"} <= set(report["machine"])
    out = capsys.readouterr().out
    assert "| daqp |" in out and "| quadprog |" in out and "wbc / pink" in out


def test_vs_pink_without_pink_is_an_error_with_the_install_hint(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pink", None)  # import pink -> ImportError
    with pytest.raises(MissingDependencyError, match=r"pip install 'wbc\[pink\]'"):
        vs_pink.main(["--ticks", "5", "--out", str(tmp_path)])
    assert not (tmp_path / "vs_pink.json").exists()


# ----------------------------------------------------------- the loops of the report's second part
def test_the_ur5_loop_agrees_with_pink_while_both_limits_bind():
    pytest.importorskip("pink")
    from wbc.experiments.peers import scenarios

    result = scenarios.ur5_loop("pink", ticks=scenarios.UR5_TICKS)
    assert result["wbc_failures"] == 0
    assert result["velocity_bound_ticks"] >= 50  # saturated first ...
    assert result["position_bound_ticks"] >= 30  # ... then the elbow held at π
    # both on quadprog: the same QP, to round-off (max at a tick where the active set changes)
    assert result["command_diff_max"] <= 1e-9
    assert result["command_diff_median"] <= 1e-12
    assert result["wbc_median_s"] > 0 and result["pink_median_s"] > 0
    assert result["ratio"] == result["wbc_median_s"] / result["pink_median_s"]


def test_the_mobile_base_loop_agrees_with_pink():
    pytest.importorskip("pink")
    from wbc.experiments.peers import scenarios

    result = scenarios.mobile_loop(ticks=scenarios.MOBILE_TICKS)
    assert result["wbc_failures"] == 0
    assert result["command_diff_max"] <= 1e-8  # pink's q̇ seen as Sᵀ q̇ (module docstring)
    assert result["command_diff_median"] <= 1e-12
    assert result["final_hand_error_m"] <= 1e-6  # the loop does what it is asked
    assert result["ratio"] > 0


def test_the_report_holds_the_loops_and_their_ratios(tmp_path, capsys, monkeypatch):
    pytest.importorskip("pink")
    from wbc.experiments.peers import scenarios

    monkeypatch.setattr(scenarios, "UR5_TICKS", 20)
    monkeypatch.setattr(scenarios, "MOBILE_TICKS", 20)
    assert vs_pink.main(["--ticks", "20", "--backends", "quadprog", "--no-jit",
                         "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "vs_pink.json").read_text())
    assert set(report["scenarios"]) == {"ur5_limits", "mobile_relative_com"}
    for loop in report["scenarios"].values():
        assert {"wbc_median_s", "pink_median_s", "ratio", "command_diff_max"} <= set(loop)
        assert loop["ticks"] == 20
    assert KEYS <= set(report["backends"]["quadprog"])  # the Panda study's keys are kept
    out = capsys.readouterr().out
    assert "UR5, configuration and velocity limits binding" in out and "wbc / pink" in out
