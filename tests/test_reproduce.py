"""``wbc reproduce --quick`` into a temporary folder: every step runs, the report and the
studies' JSON exist and parse, every claim has a boolean ``holds``. No timing is asserted."""

from __future__ import annotations

import json
import os

from helpers import assert_study_contract

from wbc.experiments import reproduce


def test_reproduce_quick_writes_the_report(quick_report):
    # the session's run (conftest.py), whose studies the study and plant tests read too
    code, tmp_path = quick_report
    report = (tmp_path / "REPORT.md").read_text()
    logs = {p.name: p.read_text()[-2000:] for p in (tmp_path / "logs").iterdir()}
    assert code == 0, f"a step failed:\n{report[:3000]}\n{logs}"
    for name in reproduce.PAPERS:
        kinematic = json.loads((tmp_path / name / f"{name}.json").read_text())
        assert_study_contract(kinematic)
        assert f"`wbc study {name}`" in report
        # the same study on MuJoCo (same claim ids) and its sweep, side by side in the report
        physics = json.loads((tmp_path / "mujoco" / name / f"{name}.json").read_text())
        assert physics["plant"] == "mujoco" and kinematic["plant"] == "kinematic"
        assert [c["id"] for c in physics["claims"]] == [c["id"] for c in kinematic["claims"]]
        swept = json.loads((tmp_path / "sweeps" / f"sweep_{name}" /
                            f"sweep_{name}.json").read_text())
        assert swept["seeds"] == reproduce.SWEEP_SEEDS_QUICK and swept["claims"]
        assert {c["id"] for c in swept["claims"]} <= {c["id"] for c in kinematic["claims"]}
    assert "ours (MuJoCo)" in report and "holds in k of N seeds" in report
    for figure in (tmp_path / "xing").glob("*.png"):
        assert figure.stat().st_size > 0
    assert json.loads((tmp_path / "bench" / "solver_timing.json").read_text())
    assert json.loads((tmp_path / "vs_pink" / "vs_pink.json").read_text())["backends"]
    assert "## Summary" in report and "## Peers" in report and "## Solver timing" in report
    assert "| pink | daqp |" in report and "dedicated ratio" in report


def test_a_failing_step_does_not_lose_the_others(tmp_path, monkeypatch):
    """One study that raises is reported as failed with its reason; the others still run."""
    # the broken study first, then the cheapest real step (the quick sorour study)
    steps = reproduce.plan(tmp_path, quick=True)[1::-1]
    assert [s.name for s in steps] == ["study petric", "study sorour"]
    steps[0].module = "wbc.experiments.no_such_study"
    monkeypatch.setattr(reproduce, "plan", lambda out, quick: steps)
    assert reproduce.main(["--quick", "--out", str(tmp_path)]) == 1
    assert steps[0].status == "failed" and "no_such_study" in steps[0].reason
    assert steps[1].status in ("ok", "failed")  # it ran
    report = (tmp_path / "REPORT.md").read_text()
    assert "Failed steps" in report and "no_such_study" in report


def test_steps_side_by_side_run_in_single_threaded_processes(tmp_path, monkeypatch):
    """Concurrent steps (the MuJoCo studies) run in spawned processes with one BLAS thread
    each (OpenBLAS's threads, one set per process, would contend for the cores); their
    status comes back, and this process's environment is left as it was."""
    monkeypatch.setattr(reproduce, "cores", lambda: 2)
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    steps = [reproduce.Step(f"step {code}", "reproduce_steps", [str(code)], concurrent=True)
             for code in (0, 3)]
    finished = []
    reproduce.run_concurrently(steps, tmp_path, finished.append)
    assert sorted(s.name for s in finished) == ["step 0", "step 3"]
    assert [s.status for s in steps] == ["ok", "failed"] and "exit code 3" in steps[1].reason
    for step in steps:
        log = (tmp_path / f"{step.name.replace(' ', '_')}.log").read_text()
        assert log.strip() == str(reproduce.SINGLE_THREADED), log
    assert "OPENBLAS_NUM_THREADS" not in os.environ
