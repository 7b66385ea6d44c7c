"""Description of the machine a timing was taken on (recorded with every figure)."""

from __future__ import annotations

import os
import platform
from importlib import metadata

_PACKAGES = ("wbc", "casadi", "pin", "numpy", "scipy", "qpsolvers", "daqp", "proxsuite", "osqp",
             "clarabel", "quadprog", "pin-pink")


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def describe_machine() -> dict:
    """Platform, CPU model, core count, Python and the versions of the packages that matter."""
    versions = {}
    for name in _PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return {
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "packages": versions,
    }
