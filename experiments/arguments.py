"""Checks of the ``--backends`` argument shared by the ``wbc`` verbs: a bad name is a usage
error (argparse's exit code 2, one line), never a traceback at run time."""

from __future__ import annotations

import argparse
from collections.abc import Iterable


def installed_backends(parser: argparse.ArgumentParser, names: Iterable[str]) -> list[str]:
    """``names`` (each item may be a comma-separated list) as a list of names of
    :func:`wbc.solvers.available_backends`; a usage error if it is empty or names a backend
    that is not installed."""
    from wbc.solvers import available_backends

    backends = [b for item in names for b in item.split(",") if b]
    if not backends:
        parser.error("--backends needs at least one name")
    available = available_backends()
    unknown = [b for b in backends if b not in available]
    if unknown:
        parser.error(f"backend(s) {unknown} not available; available: {available}")
    return backends


def constructible_backends(parser: argparse.ArgumentParser, text: str) -> list[str]:
    """A comma-separated list of any names :func:`wbc.solvers.make_backend` accepts (also
    ``"qpsolvers:<solver>"`` and ``"casadi:<plugin>"``); a usage error naming the first it
    refuses, with the installed ones."""
    from wbc.errors import BackendUnavailableError
    from wbc.solvers import make_backend

    backends = [b for b in text.split(",") if b]
    for name in backends:
        try:
            make_backend(name)
        except BackendUnavailableError as err:
            parser.error(str(err))
    return backends


def user_robots_and_stack(robot_files, stack_spec: str | None) -> tuple[list | None, object]:
    """``--robot FILE.toml`` (repeatable) and ``--stack module:function`` of ``wbc fuzz`` and
    ``wbc audit``: ``([(name, load), ...] or None, build or None)`` — ``load()`` a new
    instance of the file's robot, ``build(robot)`` the user's stack, checked
    (:mod:`wbc.experiments.benchmarks.user_inputs`). Each file is read once here, so a bad
    one is a :class:`~wbc.WbcError` before the campaign starts."""
    from wbc.experiments.benchmarks.user_inputs import load_robot_file, load_stack

    robots = None
    if robot_files:
        robots = []
        for path in robot_files:
            robot = load_robot_file(path)
            robots.append((getattr(robot, "name", None) or str(path),
                           lambda path=path: load_robot_file(path)))
    build = load_stack(stack_spec) if stack_spec else None
    return robots, build
