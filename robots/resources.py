"""Locate example-robot-data's URDF files offline, without its Python loader.

example-robot-data ships its robots in a folder ``share/example-robot-data/robots``. Where that
folder lives depends on how the package was installed (pip/cmeel wheel, conda, robotpkg, ROS), so
:func:`robots_dir` looks in several places, in this order:

1. the environment variable ``EXAMPLE_ROBOT_DATA_MODEL_DIR`` (a ``robots`` folder);
2. the installed ``example-robot-data`` Python distribution's own file list (pip / cmeel wheels);
3. the ``example_robot_data.path`` module, when the Python loader happens to be importable;
4. ``<prefix>/share/example-robot-data/robots`` for every prefix in ``sys.prefix``,
   ``<site-packages>/cmeel.prefix``, ``$CONDA_PREFIX``, ``$CMAKE_PREFIX_PATH``,
   ``$AMENT_PREFIX_PATH``, ``/opt/openrobots``, ``/usr/local`` and ``/usr``.

The first folder that exists wins; the answer is cached for the process.
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import site
import sys
from pathlib import Path

__all__ = ["robots_dir", "urdf_path"]

_SUFFIX = Path("share") / "example-robot-data" / "robots"


def _from_environment() -> list[Path]:
    value = os.environ.get("EXAMPLE_ROBOT_DATA_MODEL_DIR")
    return [Path(value)] if value else []


def _from_distribution() -> list[Path]:
    try:
        files = importlib.metadata.distribution("example-robot-data").files or []
    except importlib.metadata.PackageNotFoundError:
        return []
    dist = importlib.metadata.distribution("example-robot-data")
    for entry in files:
        parts = Path(str(entry)).parts
        for k in range(len(parts) - 2):
            if parts[k : k + 3] == ("share", "example-robot-data", "robots"):
                located = Path(str(dist.locate_file(Path(*parts[: k + 3]))))
                return [located]
    return []


def _from_python_loader() -> list[Path]:
    try:
        from example_robot_data import path as erd_path  # type: ignore[import-not-found]
    except ImportError:
        return []
    value = getattr(erd_path, "EXAMPLE_ROBOT_DATA_MODEL_DIR", None)
    return [Path(value)] if value else []


def _from_prefixes() -> list[Path]:
    prefixes: list[Path] = [Path(sys.prefix)]
    site_dirs = list(site.getsitepackages()) if hasattr(site, "getsitepackages") else []
    site_dirs += [p for p in sys.path if p.endswith("site-packages")]
    prefixes += [Path(p) / "cmeel.prefix" for p in site_dirs]
    for variable in ("CONDA_PREFIX", "CMAKE_PREFIX_PATH", "AMENT_PREFIX_PATH"):
        prefixes += [Path(p) for p in os.environ.get(variable, "").split(os.pathsep) if p]
    prefixes += [Path("/opt/openrobots"), Path("/usr/local"), Path("/usr")]
    return [p / _SUFFIX for p in prefixes]


@functools.cache
def robots_dir() -> Path:
    """Return the folder holding example-robot-data's robot descriptions.

    Raises:
        FileNotFoundError: no candidate folder exists; the message lists every place searched.
    """
    searched: list[Path] = []
    for source in (_from_environment, _from_distribution, _from_python_loader, _from_prefixes):
        for candidate in source():
            searched.append(candidate)
            if candidate.is_dir():
                return candidate
    listing = "\n  ".join(str(p) for p in searched)
    raise FileNotFoundError(
        "example-robot-data's 'share/example-robot-data/robots' folder was not found; install "
        "the 'example-robot-data' package or set EXAMPLE_ROBOT_DATA_MODEL_DIR. Searched:\n  "
        + listing
    )


def urdf_path(relative: str | os.PathLike[str]) -> Path:
    """Absolute path of a file inside example-robot-data's robots folder.

    Args:
        relative: path below the robots folder, e.g. ``"panda_description/urdf/panda.urdf"``.

    Raises:
        FileNotFoundError: the file does not exist (the message names the full path).
    """
    path = robots_dir() / Path(relative)
    if not path.is_file():
        raise FileNotFoundError(f"example-robot-data file not found: {path}")
    return path
