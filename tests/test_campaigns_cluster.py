"""Campaigns on Dask (wbc.experiments.campaigns.cluster): wbc fuzz and wbc audit give the same
JSON (timings and the cluster's description aside) in this process, on one and two local worker
processes and through a scheduler's address; a worker killed mid-campaign has its cases re-run;
a case that hangs, raises or always kills its worker is recorded with its seed; an interrupted
campaign resumes from its partial file without redoing finished cases."""

from __future__ import annotations

import json
import os
import shlex
import sys
import time

import pytest

from wbc.errors import InvalidValueError
from wbc.experiments.campaigns import audit, cluster, fuzz
from wbc.experiments.cli import main

FUZZ = ["fuzz", "--cases", "160", "--backends", "daqp,quadprog", "--seed", "5"]
AUDIT = ["audit", "--runs", "8", "--backends", "daqp", "--levels", "velocity", "--ticks", "5",
         "--seed", "4"]


def comparable(path) -> dict:
    """A campaign's JSON without what may differ between clusters: the wall time and the
    cluster's description."""
    result = json.loads(path.read_text())
    result["parameters"].pop("wall_s")
    result.pop("cluster")
    return result


@pytest.fixture(scope="module")
def scheduler():
    """A scheduler and two worker processes on 127.0.0.1, as an existing cluster."""
    distributed = pytest.importorskip("distributed")
    import logging
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        local = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                         host="127.0.0.1", dashboard_address=":0",
                                         silence_logs=logging.CRITICAL)
    with local:
        yield local.scheduler_address


def run(tmp_path, name, argv):
    out = tmp_path / name
    assert main([*argv, "--out", str(out)]) == 0
    assert not list(out.glob("*.partial.json"))  # a finished campaign leaves none
    return out


@pytest.fixture(scope="module")
def here(tmp_path_factory):
    """The fuzz campaign in this process: the reference of the cluster and resumed runs."""
    return run(tmp_path_factory.mktemp("fuzz"), "here", FUZZ)


def test_fuzz_and_audit_give_the_same_json_wherever_they_run(tmp_path, here, scheduler):
    result = comparable(here / "fuzz.json")
    assert result["cases"] > 160 and result["defects"] == []
    assert set(result["outcomes"]) == {"constructors", "daqp", "daqp (fused)", "quadprog"}
    where = {"one": ["--workers", "1"], "two": ["--workers", "2"],
             "scheduler": ["--scheduler", scheduler]}
    for name, option in where.items():
        out = run(tmp_path, name, [*FUZZ, *option])
        assert comparable(out / "fuzz.json") == result, name
    info = json.loads((tmp_path / "two" / "fuzz.json").read_text())["cluster"]
    assert info["workers"] == 2 and info["scheduler"] is None and info["attempts"] == {}
    assert len(info["machine"][0]["workers"]) == 2 and info["machine"][0]["cores"] >= 1
    info = json.loads((tmp_path / "scheduler" / "fuzz.json").read_text())["cluster"]
    assert info["scheduler"] == scheduler and info["workers"] == 2
    assert json.loads((here / "fuzz.json").read_text())["cluster"]["workers"] is None

    audit_here = comparable(run(tmp_path, "audit_here", AUDIT) / "audit.json")
    assert audit_here["runs"] == 8 and "defects" not in audit_here
    audit_there = comparable(run(tmp_path, "audit_there", [*AUDIT, "--scheduler", scheduler])
                             / "audit.json")
    assert audit_there == audit_here


# ---------------------------------------------------------------------------------------------
# test-only cases; the workers unpickle this module's functions by value


def _register_by_value():
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _square(context, case, deadline=None):
    """A case's result from its seed alone; its behaviour from ``case["do"]``."""
    marker = os.path.join(context["dir"], case["key"])
    if case.get("do") == "exit_once" and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(1)  # the worker process dies: its batch is re-run elsewhere
    if case.get("do") == "exit":
        os._exit(1)
    if case.get("do") == "hang":
        time.sleep(600)
    if case.get("do") == "raise":
        raise ValueError("a case's own bug")
    return {"value": case["seed"][0] * case["seed"][1]}


def _cases(n, **behaviour):
    return [{"key": f"c{i}", "seed": [7, i], **({"do": behaviour[f"c{i}"]}
                                                if f"c{i}" in behaviour else {})}
            for i in range(n)]


def test_a_killed_worker_has_its_cases_rerun_and_failures_keep_their_seed(tmp_path):
    """Batches of two cases: (c0, c1) … (c8, c9), (c10, c11), (c12). Case c4 kills its worker on
    its first attempt: its batch (c4, c5) is re-run and the campaign completes with every
    result, each attempt counted. c7 kills its worker every time, c9 hangs past its time limit,
    c8 (in c9's batch) raises: each is a failure with its seed, and every other case finishes.
    (The limit runs from a batch's start, a restarted worker's start-up included: 3 s once
    marked a case that shared the hanging one's batch, a hang on a loaded machine. Batches of
    two, not three: the hanging batch holds its worker for 2 × 8 s, not 3 × 8 s, before it is
    split.)"""
    pytest.importorskip("distributed")
    _register_by_value()
    cases = _cases(13, c4="exit_once", c7="exit", c8="raise", c9="hang")
    done = cluster.run_cases(_square, cases, {"dir": str(tmp_path)}, name="test",
                             out=tmp_path, workers=2, time_limit=8.0, batch_cases=2,
                             progress=False)
    failed = {f["key"]: f for f in done.failures}
    assert set(failed) == {"c7", "c8", "c9"}, failed
    assert failed["c7"]["failure"] == "killed_worker" and failed["c7"]["seed"] == [7, 7]
    assert failed["c9"]["failure"] == "hang" and failed["c9"]["seed"] == [7, 9]
    assert "time limit of 8 s" in failed["c9"]["message"]
    assert failed["c8"]["failure"] == "raised" and "a case's own bug" in failed["c8"]["message"]
    assert failed["c7"]["attempts"] >= 2  # its batch, then itself alone, killed its worker
    for i, result in enumerate(done.results):
        if f"c{i}" not in failed:
            assert result == {"value": 7 * i}, i
    # c4 and c5 ran twice (the worker that died ran their batch); c6–c7 and c8–c9 were split
    assert all(done.attempts.get(key, 1) >= 2 for key in ("c4", "c5"))
    assert done.attempts.get("c0", 1) == 1 and done.attempts.get("c12", 1) == 1
    assert done.cluster["attempts"] == done.attempts and done.cluster["workers"] == 2
    assert not (tmp_path / "test.partial.json").exists()


def test_an_interrupted_campaign_resumes_without_redoing_finished_cases(tmp_path, here,
                                                                        monkeypatch):
    fresh = comparable(here / "fuzz.json")
    real, calls = fuzz.run_piece, []

    def interrupted(context, piece, deadline=None):
        if len(calls) == 5:
            raise KeyboardInterrupt  # Ctrl-C during the sixth piece
        calls.append(piece["key"])
        return real(context, piece, deadline)

    out = tmp_path / "resumed"
    monkeypatch.setattr(fuzz, "run_piece", interrupted)
    assert main([*FUZZ, "--out", str(out)]) == 130  # wbc's exit code for Ctrl-C
    partial = json.loads((out / "fuzz.partial.json").read_text())
    assert list(partial["results"]) == calls  # what finished is kept
    first = list(calls)

    def counted(context, piece, deadline=None):
        calls.append(piece["key"])
        return real(context, piece, deadline)

    monkeypatch.setattr(fuzz, "run_piece", counted)
    assert main([*FUZZ, "--out", str(out)]) == 0
    rerun = calls[len(first):]
    assert not set(rerun) & set(first)  # no finished piece redone
    assert len(first) + len(rerun) == len(fuzz.plan(160, ["daqp", "quadprog"], 5))
    assert comparable(out / "fuzz.json") == fresh
    assert not (out / "fuzz.partial.json").exists()


def test_a_partial_file_of_another_campaign_is_not_resumed(tmp_path, capsys):
    cases = _cases(4)
    (tmp_path / "test.partial.json").write_text(json.dumps(
        {"campaign": {"name": "test", "identity": {"seed": 1}, "keys": ["c0"]},
         "results": {"c0": {"value": -1}}, "failures": [], "attempts": {}}))
    done = cluster.run_cases(_square, cases, {"dir": str(tmp_path)}, name="test",
                             out=tmp_path, identity={"seed": 2}, progress=False)
    assert done.results[0] == {"value": 0}
    assert "of another campaign: starting over" in capsys.readouterr().err


def test_a_case_that_raises_is_a_defect_with_its_reproduction_line(tmp_path, monkeypatch):
    """In this process too: a piece that raises (outside the classifier: here its robot cannot
    be loaded) is a defect naming its case, seed and a command that reruns just that piece —
    and that command does."""
    real = fuzz.run_piece

    def broken(context, piece, deadline=None):
        if piece["key"] == "robot/daqp/omni4_arm6":
            raise RuntimeError("cannot load the robot")
        return real(context, piece, deadline)

    monkeypatch.setattr(fuzz, "run_piece", broken)
    out = tmp_path / "broken"
    assert main([*FUZZ, "--out", str(out)]) == 1  # a defect fails the command
    result = json.loads((out / "fuzz.json").read_text())
    (defect,) = result["defects"]
    assert defect["defect"] == "raised" and defect["case"] == "robot/daqp/omni4_arm6"
    assert defect["case_seed"] == [5, 1002] and "cannot load the robot" in defect["message"]
    assert "--case robot/daqp/omni4_arm6" in (out / "fuzz.md").read_text()
    monkeypatch.setattr(fuzz, "run_piece", real)
    argv = shlex.split(defect["reproduce"])
    assert argv[:2] == ["wbc", "fuzz"]
    argv[argv.index("--out") + 1] = str(tmp_path / "case")
    assert main(argv[1:]) == 0
    alone = json.loads((tmp_path / "case" / "fuzz.json").read_text())
    assert alone["families"] == {"robot": alone["cases"]} and alone["cases"] >= 1


def test_audit_reruns_one_cell_by_its_key(tmp_path):
    out = tmp_path / "cell"
    assert main([*AUDIT, "--case", "velocity/daqp/tiago_panda", "--out", str(out)]) == 0
    result = json.loads((out / "audit.json").read_text())
    (key,) = result["cells"]
    assert key.endswith("/tiago_panda") and result["runs"] == 2


def test_plans_seed_each_case_from_the_campaign_seed_and_its_place():
    pieces = fuzz.plan(3000, ["daqp", "quadprog"], seed=9)
    keys = [p["key"] for p in pieces]
    assert len(set(keys)) == len(keys) and keys[0] == "constructors/0"
    assert sum(p["stop"] - p["start"] for p in pieces if p["family"] == "constructors") == 150
    assert {tuple(p["seed"]) for p in pieces if p["key"].startswith("stack/")} == \
        {(9, s) for s in range(sum(k.startswith("stack/daqp/") for k in keys))}
    cells = audit.plan(24, ["daqp", "quadprog"], ["velocity"], ["a", "b"], seed=2, ticks=5)
    assert [c["key"] for c in cells] == ["velocity/daqp/a", "velocity/daqp/b",
                                         "velocity/quadprog/a", "velocity/quadprog/b"]
    assert all(c["runs"] == 6 and c["seed"][:3] == [2, 0, c["robot"]] for c in cells)


def test_constructor_pieces_are_the_one_stream_cut_in_slices():
    specs = fuzz.constructor_specs()
    whole = list(fuzz.constructor_cases(1, 12, specs=specs))
    cut = [*fuzz.constructor_cases(1, 5, specs=specs),
           *fuzz.constructor_cases(1, 12, start=5, specs=specs)]
    assert [c[0] for c in cut] == [c[0] for c in whole]
    assert [c[1:] for c in cut] == [c[1:] for c in whole]


@pytest.mark.parametrize("argv, message", [
    (["fuzz", "--workers", "0"], "--workers must be >= 1"),
    (["fuzz", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with"),
    (["audit", "--time-limit", "0"], "--time-limit must be > 0"),
    (["fuzz", "--case", "stack/daqp/0", "--workers", "2"], "--case runs one case"),
    (["bench", "--workers", "2"], "wbc bench runs in one process"),
    (["bench", "--scheduler", "tcp://127.0.0.1:8786"], "timing needs an idle core"),
])
def test_bad_cluster_arguments_are_usage_errors(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2 and message in capsys.readouterr().err


def test_an_unknown_case_key_and_bad_runner_arguments_are_refused(tmp_path):
    with pytest.raises(Exception, match="no case 'stack/nosuch/0'"):
        fuzz.campaign(100, ["daqp"], only="stack/nosuch/0", progress=False)
    with pytest.raises(InvalidValueError, match="not both"):
        cluster.run_cases(_square, _cases(1), {}, name="t", workers=1, scheduler="tcp://x:1")
    with pytest.raises(InvalidValueError, match="workers must be an integer >= 1"):
        cluster.run_cases(_square, _cases(1), {}, name="t", workers=0)
    with pytest.raises(InvalidValueError, match="unique"):
        cluster.run_cases(_square, _cases(1) * 2, {}, name="t")
