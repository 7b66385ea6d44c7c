"""Test configuration: deterministic hypothesis, offline."""

import os
import tempfile

from hypothesis import HealthCheck, settings

# Deterministic and offline: the same examples every run, no example database on disk.
settings.register_profile(
    "wbc", derandomize=True, database=None, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("wbc")

# JIT libraries of the test run go to a fresh folder, not the user's cache.
os.environ.setdefault("WBC_JIT_CACHE", tempfile.mkdtemp(prefix="wbc-test-jit-"))
