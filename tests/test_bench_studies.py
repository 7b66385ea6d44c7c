"""``wbc bench`` repeats the papers' controllers' ticks (fast path and ordinary path, daqp) from
the studies' JSONs (:mod:`wbc.experiments.benchmarks.study_ticks`): the figures each study
wrote, the study missing when its JSON or its daqp timing is."""

from __future__ import annotations

import json

import numpy as np
import pytest

from wbc.experiments.benchmarks import solver_timing
from wbc.experiments.benchmarks.study_ticks import CONTROLLERS, markdown, study_ticks
from wbc.experiments.studies.study import StudyResult, interleaved_timing, timing_summary


class _Echo:
    """A controller whose command is ``q`` plus an offset."""

    def __init__(self, offset: float) -> None:
        self.offset = offset

    def step(self, q, v=None, **references):
        return q + self.offset


def _timing(difference: float) -> dict:
    """A real :func:`interleaved_timing` dict: 20 states, commands ``difference`` apart."""
    states = [(np.full(3, float(k)), None, {}) for k in range(20)]
    return interleaved_timing(_Echo(0.0), _Echo(difference), states, passes=2)


def _write_studies(folder, names=("sorour", "petric", "omni", "xing")) -> dict:
    """Each study's JSON as :meth:`StudyResult.write` writes it, with a daqp timing (petric's
    whole-body QP's in its parameters, as the study keeps it); returns them by row label."""
    written = {}
    for k, name in enumerate(names):
        timing = _timing(10.0 ** -(k + 8))
        parameters = {}
        if name == "petric":
            parameters["timing_whole_body"] = {"daqp": _timing(1e-12)}
            written["petric (whole-body)"] = parameters["timing_whole_body"]["daqp"]
        StudyResult(name, [], {}, {"daqp": timing, "quadprog": timing_summary([1e-5])}, [],
                    "", parameters).write(folder)
        written[name] = timing
    return written


def test_study_ticks_are_the_studies_own_figures(tmp_path):
    written = _write_studies(tmp_path)
    found = study_ticks(tmp_path)
    assert list(found) == [label for _, label, _, _ in CONTROLLERS]
    for label, timing in written.items():
        row = found[label]
        assert row["fast_tick_median_s"] == timing["tick_median_s"]
        assert row["ordinary_tick_median_s"] == timing["ordinary_tick_median_s"]
        assert row["ratio"] == pytest.approx(timing["tick_median_s"]
                                             / timing["ordinary_tick_median_s"])
        assert row["max_command_difference"] == timing["max_command_difference"] > 0
        assert (row["ticks"], row["passes"]) == (40, 2)
    lines = markdown(found, tmp_path)
    table = [line for line in lines if line.startswith("| petric (whole-body) |")]
    whole_body = written["petric (whole-body)"]
    assert len(table) == 1 and f"| {1e6 * whole_body['tick_median_s']:.1f} |" in table[0]
    assert not any("No timing found" in line for line in lines)


def test_missing_studies_are_named_with_the_command_that_writes_them(tmp_path):
    _write_studies(tmp_path, names=("petric", "omni"))
    # a study run without its timing (main_only): no daqp timing in its JSON
    StudyResult("xing", [], {}, {}, [], "", {}).write(tmp_path)
    found = study_ticks(tmp_path)
    assert found["sorour"] is None and found["xing"] is None
    assert found["petric"] is not None and found["petric (whole-body)"] is not None
    lines = markdown(found, tmp_path)
    assert "| sorour | " in "\n".join(lines) and lines[-2].startswith("No timing found for "
                                                                     "`sorour`, `xing`")
    assert f"`wbc study sorour --out {tmp_path}`" in lines[-2]


def test_bench_reports_the_study_ticks(tmp_path):
    studies, out = tmp_path / "studies", tmp_path / "bench"
    written = _write_studies(studies)
    code = solver_timing.main([
        "--robots", "mecanum_gen3", "--stacks", "one_level", "--scenarios", "circle",
        "--backends", "daqp", "--ticks", "2", "--warmup", "0", "--scaling-joints",
        "--studies", str(studies), "--out", str(out)])
    assert code == 0
    report = json.loads((out / "solver_timing.json").read_text())
    rows = report["study_ticks"]["rows"]
    assert rows["xing"]["fast_tick_median_s"] == written["xing"]["tick_median_s"]
    assert rows["xing"]["source"] == str(studies / "xing" / "xing.json")
    text = (out / "solver_timing.md").read_text()
    assert "### The papers' controllers on daqp" in text and "No timing found" not in text
