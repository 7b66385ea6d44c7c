"""The ``wbc`` command line: exit codes, output files, clear messages (no timing asserted)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from wbc.experiments import cli
from wbc.experiments.benchmarks import microbench, solver_timing


def test_list_names_robots_tasks_and_backends(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert "mecanum_gen3" in out and "FrameTask" in out and "daqp" in out


def test_no_command_prints_help_and_fails(capsys):
    assert cli.main([]) == 2
    assert "COMMAND" in capsys.readouterr().out


def test_unknown_command_is_an_argparse_error(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["frobnicate"])
    assert exc.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def test_demo_writes_a_table_and_json(tmp_path, capsys):
    assert cli.main(["demo", "--ticks", "5", "--backends", "daqp", "quadprog",
                     "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "| daqp |" in captured.out and "| quadprog |" in captured.out
    assert "] 2/3  quadprog" in captured.err  # progress on stderr, tables on stdout
    report = json.loads((tmp_path / "microbench.json").read_text())
    assert set(report["backends"]) == {"daqp", "quadprog", "daqp (fused)"}  # C compiler here
    assert report["backends"]["daqp (fused)"]["max_abs_diff_vs_reference"] < 1e-9
    assert report["backends"]["daqp"]["failures"] == 0
    assert report["backends"]["daqp"]["max_abs_diff_vs_reference"] < 1e-5


def test_bench_writes_json_markdown_and_plots(tmp_path, capsys):
    code = cli.main(["bench", "--robots", "mecanum_gen3", "--stacks", "one_level",
                     "acceleration", "--scenarios", "circle", "--backends", "proxqp", "daqp",
                     "--ticks", "5", "--warmup", "2",
                     "--scaling-ticks", "3", "--scaling-joints", "7", "--out", str(tmp_path)])
    assert code == 0
    progress = capsys.readouterr().err.splitlines()
    assert progress == ["[########................] 1/3  mecanum_gen3 / one_level / circle",
                        "[################........] 2/3  mecanum_gen3 / acceleration / circle",
                        "[########################] 3/3  scaling: 7-joint chain"]
    report = json.loads((tmp_path / "solver_timing.json").read_text())
    for kind in ("one_level", "acceleration"):
        per_backend = report["results"]["mecanum_gen3"][kind]["circle"]
        for result in per_backend.values():
            assert len(result["samples"]["tick"]) == 5
            assert result["success_rate"] == 1.0
        # daqp (the default) is also timed alone, over the same ticks after the warm-up
        assert per_backend["daqp"]["dedicated"]["median"] > 0
        assert "dedicated" not in per_backend["proxqp"]
    assert report["scaling"]["proxqp"]["7"]["success_rate"] == 1.0
    assert report["scaling"]["daqp"]["7"]["dedicated"]["median"] > 0
    markdown = (tmp_path / "solver_timing.md").read_text()
    assert "### mecanum_gen3 — one_level — circle" in markdown and "| daqp alone |" in markdown
    for png in ("solver_timing.png", "scaling.png"):
        assert (tmp_path / png).read_bytes()[:4] == b"\x89PNG"
    assert "cpu" in report["machine"]


@pytest.mark.parametrize("argv, message", [
    (["--robots", "r2d2"], "unknown robot"),
    (["--stacks", "four_levels"], "unknown stack"),
    (["--backends", "cplex"], "not available"),
    (["--ticks", "0"], "--ticks"),
    (["--ticks", "many"], "invalid int value"),
])
def test_bench_bad_options_give_a_clear_message(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        solver_timing.main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_demo_bad_option(capsys):
    with pytest.raises(SystemExit) as exc:
        microbench.main(["--ticks", "0"])
    assert exc.value.code == 2
    assert "--ticks" in capsys.readouterr().err


def test_module_entry_point():
    done = subprocess.run([sys.executable, "-m", "wbc.experiments.cli", "list"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
