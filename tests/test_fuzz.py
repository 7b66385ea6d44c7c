"""wbc fuzz: a fast subset of the campaign finds no defect on any backend (the fused tick
included), the classifier flags every kind of defect, and the CLI writes its contract."""

from __future__ import annotations

import json

import numpy as np
import pytest

import wbc
from wbc.experiments.campaigns import fuzz
from wbc.solvers import available_backends


@pytest.mark.parametrize("backend", available_backends())
def test_stack_cases_have_no_defect(backend):
    cases = list(fuzz.stack_cases(backend, seed=1, structures=4, draws=1))
    assert len(cases) == 4 * fuzz.TICKS
    defects = [(c, d, m) for c, _, d, m in cases if d]
    assert defects == []
    # the injected defects do reach the classes: some refused, some solved
    classes = {outcome for _, outcome, _, _ in cases}
    assert {"error", "success"} <= classes


def test_stack_cases_have_no_defect_on_the_fused_cascade():
    cases = list(fuzz.stack_cases("daqp", seed=1, structures=6, draws=1, fused=True))
    assert {c["backend"] for c, *_ in cases} == {"daqp (fused)"}
    assert [(c, d, m) for c, _, d, m in cases if d] == []
    assert {"error", "success"} <= {outcome for _, outcome, _, _ in cases}


def test_robot_cases_have_no_defect_on_the_fused_tick():
    cases = list(fuzz.robot_cases("daqp", seed=1, ticks=12))
    assert [d for *_, d, _ in cases if d] == []
    assert {c["robot"] for c, *_ in cases} == set(wbc.robots.names())


def test_constructor_cases_have_no_raw_exception():
    """Every public constructor, stack method, robot loader and reference, fed bad arguments:
    each call returns or raises a WbcError, never another exception."""
    cases = list(fuzz.constructor_cases(seed=1, count=600))
    assert [(c, m) for c, _, d, m in cases if d] == []
    assert {c["constructor"] for c, *_ in cases} == set(fuzz.constructor_specs())
    assert {"error", "success"} <= {outcome for _, outcome, _, _ in cases}
    injected = " ".join(c["injected"] for c, *_ in cases)
    assert all(f"={kind}" in injected for kind in fuzz.BAD_VALUES)


def test_the_constructor_family_flags_a_raw_exception():
    def broken(value):
        return np.asarray(value, dtype=float)  # numpy's own ValueError on a str

    assert fuzz.classify_call(broken, {"value": "abc"})[:2] == ("defect", "exception")
    assert fuzz.classify_call(broken, {"value": 1.0})[:2] == ("success", None)
    assert fuzz.classify_call(wbc.Variables, {"blocks": "abc"})[:2] == ("error", None)


class _Solved:
    status = wbc.Status.SOLVED
    message = ""

    def __init__(self, x):
        self.x = np.asarray(x, dtype=float)


def test_classify_reads_the_message_so_a_broken_diagnosis_is_a_defect():
    class Failed(_Solved):
        status = wbc.Status.INFEASIBLE

        @property
        def message(self):
            raise IndexError("the conflict search broke")

    outcome, defect, message = fuzz.classify(lambda: (Failed([0.0, 0.0]), BOUNDS))
    assert (outcome, defect) == ("defect", "exception") and "conflict search" in message


BOUNDS = (np.array([-1.0, -1.0]), np.array([1.0, 1.0]))


@pytest.mark.parametrize("tick, outcome, defect", [
    (lambda: (_Solved([0.5, 1.0]), BOUNDS), "success", None),
    (lambda: (_Solved([0.5, 1.0 + 1e-6]), BOUNDS), "defect", "out_of_bounds"),
    (lambda: (_Solved([np.nan, 0.0]), BOUNDS), "defect", "non_finite_x"),
    (lambda: 1 / 0, "defect", "exception"),
    (lambda: (_ for _ in ()).throw(wbc.ShapeError("x: bad shape")), "error", None),
])
def test_classify_flags_each_defect(tick, outcome, defect):
    got, flagged, _ = fuzz.classify(tick)
    assert (got, flagged) == (outcome, defect)


def test_classify_flags_a_hang(monkeypatch):
    monkeypatch.setattr(fuzz, "HANG_S", 0.01)
    import time

    def slow():
        time.sleep(0.05)
        return _Solved([0.0, 0.0]), BOUNDS

    assert fuzz.classify(slow)[:2] == ("defect", "hang")


def test_cli_writes_the_contract(tmp_path):
    from wbc.experiments.cli import main

    assert main(["fuzz", "--cases", "60", "--backends", "daqp", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "fuzz.json").read_text())
    assert result["cases"] >= 50 and result["defects"] == []
    assert set(result["outcomes"]) >= {"daqp", "constructors"}
    assert result["families"]["constructors"] == fuzz.CONSTRUCTOR_MIN
    assert sum(result["families"].values()) == result["cases"]
    assert sum(result["outcomes"]["daqp"].values()) > 0
    assert "| backend |" in (tmp_path / "fuzz.md").read_text()


def test_cli_exits_1_when_the_campaign_finds_a_defect(tmp_path, monkeypatch):
    from wbc.experiments.cli import main

    found = {"cases": 1, "outcomes": {"daqp": {"defect": 1}}, "parameters": {},
             "defects": [{"family": "stack", "backend": "daqp", "defect": "nan",
                          "message": "x is NaN"}]}
    monkeypatch.setattr(fuzz, "campaign", lambda *args, **kwargs: found)
    assert main(["fuzz", "--cases", "1", "--backends", "daqp", "--out", str(tmp_path)]) == 1
    assert json.loads((tmp_path / "fuzz.json").read_text())["defects"] == found["defects"]
