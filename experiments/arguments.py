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


def add_cluster_arguments(parser: argparse.ArgumentParser) -> None:
    """``--workers N``, ``--scheduler ADDRESS``, ``--time-limit S`` and ``--case KEY`` of the
    campaigns that run on Dask (:mod:`wbc.experiments.campaigns.cluster`)."""
    from wbc.experiments.campaigns.cluster import INSTALL_HINT, TIME_LIMIT_S

    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="run on a local Dask cluster of N worker processes (default: in "
                            f"this process; needs {INSTALL_HINT})")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on the Dask cluster of this scheduler, e.g. tcp://host:8786 "
                            "(its workers need wbc, and any --robot/--stack file at the same "
                            "path)")
    parser.add_argument("--time-limit", type=float, default=TIME_LIMIT_S, metavar="S",
                        help="on a cluster, a case running longer is stopped and recorded as "
                             f"a defect [s] (default {TIME_LIMIT_S:g})")
    parser.add_argument("--case", default=None, metavar="KEY",
                        help="run only the case KEY of this campaign, in this process (the "
                             "reproduction line of a defect gives it)")


def cluster_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict:
    """The checked options of :func:`add_cluster_arguments` as keyword arguments of the
    campaigns: ``workers``, ``scheduler``, ``time_limit``, ``only``; a usage error for
    ``--workers`` below 1 or a ``--time-limit`` not above 0."""
    import math

    if args.workers is not None and args.workers < 1:
        parser.error("--workers must be >= 1")
    if not (math.isfinite(args.time_limit) and args.time_limit > 0):
        parser.error("--time-limit must be > 0")
    if args.case is not None and (args.workers is not None or args.scheduler is not None):
        parser.error("--case runs one case in this process: drop --workers/--scheduler")
    return {"workers": args.workers, "scheduler": args.scheduler,
            "time_limit": args.time_limit, "only": args.case}
