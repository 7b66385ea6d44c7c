"""Test configuration: deterministic hypothesis, offline."""

from hypothesis import HealthCheck, settings

# Deterministic and offline: the same examples every run, no example database on disk.
settings.register_profile(
    "wbc", derandomize=True, database=None, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("wbc")
