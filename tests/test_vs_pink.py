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
