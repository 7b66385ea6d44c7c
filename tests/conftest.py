"""Test configuration: deterministic hypothesis, offline."""

import atexit
import os
import shutil
import tempfile

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
