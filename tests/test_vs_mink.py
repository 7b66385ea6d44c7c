"""The mink comparison: the MuJoCo Panda equals wbc's pinocchio Panda, and the study runs end to
end (tiny tick counts; no timing is asserted)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from wbc.errors import MissingDependencyError
from wbc.experiments.peers import vs_mink

KEYS = {"wbc_median_s", "mink_median_s", "ratio", "command_diff_max", "wbc_error_vs_exact_max",
        "mink_error_vs_exact_max", "agree", "final_position_diff_m", "final_rotation_diff_rad"}


def test_mujoco_panda_matches_pinocchio():
    pytest.importorskip("mink")
    from wbc.robots.fixed_base import load_panda

    robot = load_panda()
    check = vs_mink.model_discrepancy(robot, configurations=25)
    assert check["nq"] == (7, 7)
    assert check["pose"] < 1e-9
    assert check["jacobian_local"] < 1e-9  # mink's body Jacobian (hand axes)
    assert check["jacobian_world"] < 1e-9  # MuJoCo's mj_jacBody (world axes)
    assert check["joint_range"] == 0.0
    loop = vs_mink.MinkLoop(robot, "quadprog")
    assert np.array_equal(loop.limits[1].limit, robot.model.velocityLimit)


def test_vs_mink_writes_its_json(tmp_path, capsys):
    pytest.importorskip("mink")
    code = vs_mink.main(["--ticks", "30", "--backends", "daqp", "quadprog", "--no-jit",
                         "--out", str(tmp_path)])
    assert code == 0
    report = json.loads((tmp_path / "vs_mink.json").read_text())
    assert set(report["backends"]) == {"daqp", "quadprog"}, report["errors"]
    for result in report["backends"].values():
        assert KEYS <= set(result)
        assert result["wbc_median_s"] > 0 and result["mink_median_s"] > 0
        assert result["wbc_failures"] == 0
        assert result["command_diff_max"] < 1e-6  # exact solvers: the same QP
        assert result["wbc_error_vs_exact_max"] < 1e-6
        assert result["agree"]
    assert report["problem"]["mink_model_vs_pinocchio_max_abs_diff"]["pose"] < 1e-9
    assert {"platform", "cpu", "python", "packages"} <= set(report["machine"])
    out = capsys.readouterr().out
    assert "| daqp |" in out and "| quadprog |" in out and "wbc / mink" in out


def test_vs_mink_without_mink_is_an_error_with_the_install_hint(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "mink", None)  # import mink -> ImportError
    with pytest.raises(MissingDependencyError, match=r"pip install 'wbc\[mink\]'"):
        vs_mink.main(["--ticks", "5", "--out", str(tmp_path)])
    assert not (tmp_path / "vs_mink.json").exists()


def test_the_ur5_loop_agrees_with_mink_while_both_limits_bind():
    pytest.importorskip("mink")
    from wbc.experiments.peers import scenarios

    result = scenarios.ur5_loop("mink", ticks=scenarios.UR5_TICKS)
    assert result["wbc_failures"] == 0
    assert result["velocity_bound_ticks"] >= 50 and result["position_bound_ticks"] >= 30
    # the same QP on quadprog; the largest differences (≤ 3e-7 rad/s, on the ticks where the
    # hand arrives) are mink's own: pink's and wbc's commands agree to 1e-13 there (the
    # module docstring of wbc.experiments.peers.scenarios)
    assert result["command_diff_max"] <= 1e-6
    assert result["command_diff_median"] <= 1e-10
    assert result["ratio"] > 0


def test_the_mink_report_holds_the_ur5_loop(tmp_path, capsys, monkeypatch):
    pytest.importorskip("mink")
    from wbc.experiments.peers import scenarios

    monkeypatch.setattr(scenarios, "UR5_TICKS", 20)
    assert vs_mink.main(["--ticks", "20", "--backends", "quadprog", "--no-jit",
                         "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "vs_mink.json").read_text())
    loop = report["scenarios"]["ur5_limits"]
    assert {"wbc_median_s", "mink_median_s", "ratio", "command_diff_max"} <= set(loop)
    assert "wbc / mink" in capsys.readouterr().out
