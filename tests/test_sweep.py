"""``wbc sweep``: a study's claims over seeds and constants (wbc.experiments.campaigns.sweep).

The aggregation is checked on hand-made claim lists; the sweep itself on the omni study's quick
runs: the same JSON in this process, on a local Dask cluster of one worker per core (`wbc
reproduce --quick`'s sweep, shared through conftest.py) and after the worker of a one-worker
cluster was killed mid-sweep; bad arguments are usage errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from wbc.errors import UnknownNameError
from wbc.experiments import reproduce
from wbc.experiments.campaigns import sweep
from wbc.experiments.cli import main


def claim(id_, ours, holds):
    return {"id": id_, "statement": f"claim {id_}", "paper": 1.0, "ours": ours, "holds": holds}


def test_aggregate_counts_holds_and_bootstraps_the_median():
    rng = np.random.default_rng(3)
    values = rng.normal(2.0, 0.5, 40)
    seeds = [[claim("a", float(v), bool(v > 1.5)), claim("b", {"x": float(v), "y": "text"},
                                                           True),
              claim("c", "words", False)] for v in values]
    seeds[5] = seeds[5][:2]  # a seed that did not compute claim c
    a, b, c = sweep.aggregate(seeds)
    assert a["seeds"] == 40 and a["holds"] == int((values > 1.5).sum())
    assert a["holds_fraction"] == pytest.approx((values > 1.5).mean())
    assert a["ours_median"] == pytest.approx(np.median(values))
    low, high = a["ours_ci95"]
    assert low < a["ours_median"] < high and high - low < 0.6  # ~ 2·1.96·1.25σ/√n
    assert sweep.aggregate(seeds)[0]["ours_ci95"] == a["ours_ci95"]  # a fixed generator
    assert set(b["ours_median"]) == {"x"} and b["holds_fraction"] == 1.0  # numbers only
    assert c["seeds"] == 39 and c["holds"] == 0 and "ours_median" not in c
    assert a["not_reproducible"] == b["not_reproducible"] == c["not_reproducible"] == 0


def test_aggregate_counts_the_seeds_the_model_could_not_reproduce():
    verdicts = ["holds", "not reproducible with this model", "fails",
                "not reproducible with this model"]
    seeds = [[{**claim("a", 1.0, v == "holds"), "verdict": v}] for v in verdicts]
    (a,) = sweep.aggregate(seeds)
    assert (a["holds"], a["not_reproducible"], a["seeds"]) == (1, 2, 4)
    assert sweep.seeds_held(a) == "1 of 4 (2 not reproducible with this model)"
    assert sweep.seeds_held({**a, "not_reproducible": 0}) == "1 of 4"


def test_plan_is_the_product_of_the_grid_times_the_seeds():
    cases = sweep.plan({"mu": [0.3, 0.5], "speed": [0.2]}, seeds=3, first_seed=4)
    assert [c["key"] for c in cases] == [f"mu={m},speed=0.2/seed{s}" for m in ("0.3", "0.5")
                                         for s in (4, 5, 6)]
    assert cases[3]["params"] == {"mu": 0.5, "speed": 0.2} and cases[3]["seed"] == 4
    assert [c["key"] for c in sweep.plan({}, 2, 0)] == ["default/seed0", "default/seed1"]


def comparable(path) -> dict:
    """A sweep's JSON without what may differ between runs: timings, the machine, the
    cluster."""
    result = json.loads(path.read_text())
    for key in ("timing", "machine", "cluster"):
        result.pop(key)
    return result


# the seeds of `wbc reproduce --quick`'s sweeps (2), whose omni sweep is the cluster run compared
# here: values that vary over the seeds need two, and so does a worker killed during the second
SEEDS = reproduce.SWEEP_SEEDS_QUICK
SWEEP = ["sweep", "omni", "--seeds", str(SEEDS), "--quick"]


@pytest.fixture(scope="module")
def here(tmp_path_factory):
    """The sweep in this process (the reference the cluster runs are compared with)."""
    pytest.importorskip("distributed")
    out = tmp_path_factory.mktemp("here")
    assert main([*SWEEP, "--out", str(out)]) == 0
    return out / "sweep_omni" / "sweep_omni.json"


def test_a_sweep_gives_the_same_json_wherever_it_runs(here, quick_studies):
    result = json.loads(here.read_text())
    assert result["seeds"] == SEEDS and result["claims"]
    assert result["figure"] == "sweep_omni.png"
    for c in result["claims"]:
        assert 0.0 <= c["holds_fraction"] <= 1.0 and c["seeds"] == SEEDS
    assert any("ours_ci95" in c for c in result["claims"])
    # the seeds draw different random elements: some numeric claim varies over them
    values = result["settings"][0]["values"]
    assert any(len({json.dumps(v) for v in series}) > 1 for series in values.values())
    # `wbc sweep omni --seeds 2 --quick --workers W`, W worker processes (one per core)
    there = quick_studies.sweep("omni")
    assert comparable(there) == comparable(here)
    assert json.loads(there.read_text())["cluster"]["workers"] == reproduce.sweep_workers()
    assert not list(there.parent.glob("*.partial.json"))


def _children(pid: int) -> list[int]:
    """Process ids under ``pid`` (Linux /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parent = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            if parent == pid:
                out += [int(entry), *_children(int(entry))]
    return out


def _cmdline(pid: int) -> str:
    """A process's command line ("" once it has ended)."""
    try:
        with open(f"/proc/{pid}/cmdline") as f:
            return f.read()
    except OSError:
        return ""


def test_a_sweep_survives_a_killed_worker(tmp_path, here):
    """The worker process of a one-worker cluster is killed (SIGKILL) while it runs a case: the
    case is re-run on its restarted worker and the JSON equals the one computed in this process.
    The kill waits for the partial file, written when the first case finishes: the worker is
    then running the second (it gets it at once); killing a worker still starting up instead
    re-runs no case (or fails the nanny's start), which flaked under load."""
    if not os.path.isdir("/proc"):
        pytest.skip("finding the worker processes needs Linux's /proc")
    argv = SWEEP
    process = subprocess.Popen([sys.executable, "-m", "wbc.experiments.cli", *argv, "--workers",
                                "1", "--out", str(tmp_path / "killed")],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    partial = tmp_path / "killed" / "sweep_omni" / "sweep_omni.partial.json"
    killed = None
    deadline = time.time() + 120
    while killed is None and time.time() < deadline and process.poll() is None:
        # a worker is a spawned Python process (spawn_main; not the resource tracker) under the
        # nanny under the command's process
        workers = [p for p in _children(process.pid) if "spawn_main" in _cmdline(p)]
        if workers and partial.exists():
            time.sleep(0.5)  # the worker receives the second case
            (killed,) = workers
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.1)
    _, stderr = process.communicate(timeout=300)
    assert killed is not None, "no worker process was found to kill"
    assert process.returncode == 0, stderr[-2000:]
    result = tmp_path / "killed" / "sweep_omni" / "sweep_omni.json"
    assert comparable(result) == comparable(here)
    # the killed worker was running a case: it was run again
    assert max(json.loads(result.read_text())["cluster"]["attempts"].values()) >= 2


@pytest.mark.parametrize("argv, message", [
    (["sweep", "omni", "--seeds", "0"], "--seeds must be >= 1"),
    (["sweep", "omni", "--param", "no_such_key=1"], "unknown parameter 'no_such_key'"),
    (["sweep", "omni", "--param", "mu=a,b"], "must be numbers"),
    (["sweep", "omni", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed"),
    (["sweep", "nosuch"], "invalid choice"),
])
def test_bad_sweep_arguments_are_usage_errors(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2 and message in capsys.readouterr().err


def test_an_unknown_case_key_is_refused():
    with pytest.raises(UnknownNameError, match="default/seed0"):
        sweep.sweep("omni", 2, quick=True, only="nosuch/seed9", progress=False)
