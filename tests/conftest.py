"""Test configuration: deterministic hypothesis, offline; the outputs of ``wbc reproduce
--quick`` computed once per session (:class:`QuickReproduction`)."""

import atexit
import importlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# Deterministic and offline: the same examples every run, no example database on disk.
settings.register_profile(
    "wbc", derandomize=True, database=None, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("wbc")

# JIT libraries of the test run go to a fresh folder, not the user's cache, removed at the end
# (subprocesses of the tests inherit the variable, so their libraries land there too).
if "WBC_JIT_CACHE" not in os.environ:
    os.environ["WBC_JIT_CACHE"] = tempfile.mkdtemp(prefix="wbc-test-jit-")
    atexit.register(shutil.rmtree, os.environ["WBC_JIT_CACHE"], ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    """``test_fused_equivalence`` reuses ``test_equivalence``'s functions, parametrised over
    every backend; the fused path is daqp's only, so the other backends' items are deselected
    (not collected as skips)."""
    deselected = [item for item in items if item.module.__name__ == "test_fused_equivalence"
                  and getattr(item, "callspec", None) is not None
                  and item.callspec.params.get("backend") != "daqp"]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if item not in deselected]


class QuickReproduction:
    """The outputs of ``wbc reproduce --quick``'s steps (:func:`wbc.experiments.reproduce.plan`:
    the quick paper studies on both plants, ``wbc study NAME --quick [--plant mujoco]``, and
    their quick sweeps), each computed at most once per test session and read by every test that
    checks one (the tests only read them; a JSON is parsed afresh for each caller).

    When the session also runs the whole ``wbc reproduce --quick`` (``tests/test_reproduce.py``,
    the ``quick_report`` fixture), every output is read from that run, so the suite computes each
    once instead of two or three times. Otherwise (a test file run alone) a step runs by itself
    on first use, through the same entry point with the same arguments."""

    def __init__(self, root: Path, whole: bool) -> None:
        self.root, self.whole = root, whole
        self._report: tuple[int, Path] | None = None
        self._done: set[str] = set()

    def report(self) -> tuple[int, Path]:
        """``wbc reproduce --quick``, run once: ``(exit code, output folder)``."""
        if self._report is None:
            from wbc.experiments import reproduce

            out = self.root / "report"
            self._report = reproduce.main(["--quick", "--out", str(out)]), out
        return self._report

    def _output(self, step: str) -> Path:
        """The folder reproduce's output is in (``OUT``) once the step ``step`` has run."""
        if self.whole:
            _, out = self.report()
            report = (out / "REPORT.md").read_text()
            # exit code 0, as when the step runs alone: the report lists failed (and skipped)
            # steps
            assert f"- `{step}`:" not in report, report[:3000]
            return out
        out = self.root / "steps"
        if step not in self._done:
            from wbc.experiments import reproduce

            (planned,) = [s for s in reproduce.plan(out, quick=True) if s.name == step]
            assert importlib.import_module(planned.module).main(planned.argv) == 0
            self._done.add(step)
        return out

    def study(self, name: str, plant: str = "kinematic") -> Path:
        """The folder of ``wbc study NAME --quick [--plant P]`` (its JSON, markdown, figures)."""
        if plant == "kinematic":
            return self._output(f"study {name}") / name
        return self._output(f"study {name} ({plant})") / plant / name

    def data(self, name: str, plant: str = "kinematic") -> dict:
        """The JSON of ``wbc study NAME --quick [--plant P]``."""
        return json.loads((self.study(name, plant) / f"{name}.json").read_text())

    def sweep(self, name: str) -> Path:
        """The JSON file of the quick sweep of study ``name`` (``wbc sweep NAME --seeds
        reproduce.SWEEP_SEEDS_QUICK --quick`` on a local cluster of one worker per core)."""
        return self._output(f"sweep {name}") / "sweeps" / f"sweep_{name}" / f"sweep_{name}.json"


@pytest.fixture(scope="session")
def quick_studies(request, tmp_path_factory) -> QuickReproduction:
    """The session's quick studies and sweeps (:class:`QuickReproduction`)."""
    whole = any("quick_report" in getattr(item, "fixturenames", ())
                for item in request.session.items)
    return QuickReproduction(tmp_path_factory.mktemp("quick_studies"), whole)


@pytest.fixture(scope="session")
def quick_report(quick_studies) -> tuple[int, Path]:
    """``wbc reproduce --quick`` of this session: ``(exit code, output folder)``."""
    return quick_studies.report()
