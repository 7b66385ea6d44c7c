"""The ``wbc`` command line: ``wbc list``, ``wbc demo``, ``wbc bench``, ``wbc pink``, ``wbc mink``,
``wbc placo``, ``wbc fuzz``, ``wbc audit``, ``wbc sweep``, ``wbc exactness``, ``wbc reproduce``,
``wbc study NAME``, ``wbc view DIR``, ``wbc play ROBOT``.

Each sub-command forwards its remaining arguments to the ``main(argv)`` of its experiment
module (or the function a ``"module:function"`` entry names), so ``wbc bench --help`` shows
that study's own options; ``wbc study NAME ...`` forwards to the paper study
``wbc.experiments.studies.NAME`` (see :mod:`wbc.experiments.studies.study`).

Exit codes, for every verb: 0 when the job ran; 2 for a bad argument (argparse's message, on
stderr); 1 when it failed at run time — a :class:`~wbc.WbcError` (e.g. a missing optional peer,
with its install hint), a file that cannot be written, or a bug. Errors are one line
``wbc VERB: error: ...`` on stderr; ``wbc --debug VERB ...`` (or ``--debug`` anywhere) shows the
traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from collections.abc import Callable
from importlib.metadata import version

COMMANDS = {
    "demo": ("wbc.experiments.benchmarks.microbench",
             "one stack on every backend: agreement and timing"),
    "bench": ("wbc.experiments.benchmarks.solver_timing",
              "solver-timing study: time, accuracy and settings per backend, on the "
              "catalogue or your own robot (--robot FILE.toml) and stack (--stack mod:fn)"),
    "pink": ("wbc.experiments.peers.vs_pink", "head-to-head with pink on the Panda"),
    "mink": ("wbc.experiments.peers.vs_mink", "head-to-head with mink on the Panda"),
    "placo": ("wbc.experiments.peers.vs_placo", "head-to-head with placo (C++) on the Panda"),
    "fuzz": ("wbc.experiments.campaigns.fuzz",
             "fuzz campaign: bad stacks, data, states on every backend"),
    "audit": ("wbc.experiments.campaigns.audit",
              "closed-loop limit audits: every robot, exact backends"),
    "sweep": ("wbc.experiments.campaigns.sweep", "Monte-Carlo sweep of a paper study: its "
              "claims over seeds and constants, with their spread (--workers on Dask)"),
    "exactness": ("wbc.experiments.campaigns.exactness", "every backend against an exact referee "
                  "on random, saturating and strict-priority states"),
    "reproduce": ("wbc.experiments.reproduce", "every paper study, bench and peers in one "
                  "report (REPORT.md)"),
    "view": ("wbc.experiments.viewing:view_main",
             "replay the runs a study wrote, in the browser (needs the [viz] extra)"),
    "play": ("wbc.experiments.viewing:play_main",
             "a live playground: a robot following a gizmo, backends swapped live ([viz])"),
}


STUDIES = {
    "sorour": "Sorour et al.: ψ task sharing on a steerable base (MPO700 + LWR-IV)",
    "petric": "Petrič & Žlajpah: velocity field for a differential-drive base (Tiago)",
    "omni": "omni platform: slip-avoiding wheel-torque distribution",
    "xing": "Xing et al.: adaptive motion planning at the acceleration level (mecanum + Gen3)",
}


def run_study(argv: list[str]) -> int:
    """``wbc study NAME [options]``: one paper study (``wbc study NAME --help`` for options)."""
    usage = ("usage: wbc study NAME [--backend B] [--out DIR] [--quick] [--plant P] [--seed N] "
             "[--param KEY=V]")
    if argv and argv[0] in ("-h", "--help"):
        print(f"{usage}\n\nstudies:")
        for name, what in STUDIES.items():
            print(f"  {name:8s} {what}")
        return 0
    if not argv or argv[0] not in STUDIES:
        problem = f"unknown study {argv[0]!r}" if argv else "the study NAME is missing"
        print(f"{usage}\nwbc study: error: {problem}; studies: {', '.join(STUDIES)}",
              file=sys.stderr)
        return 2
    name, rest = argv[0], argv[1:]
    module = f"wbc.experiments.studies.{name}"
    if importlib.util.find_spec(module) is None:
        from wbc.errors import WbcError

        raise WbcError(f"study {name!r} is not part of this installation ({module} is missing)")
    return importlib.import_module(module).main(rest)


def list_everything() -> int:
    """Print the robot catalogue, the task library and the available backends."""
    import wbc.robots
    import wbc.tasks
    from wbc.solvers import available_backends

    print("robots:  ", ", ".join(wbc.robots.names()))
    print("tasks:   ", ", ".join(sorted(wbc.tasks.__all__)))
    print("backends:", ", ".join(available_backends()))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``wbc COMMAND ...``; returns the exit code (see the module docstring)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(
        prog="wbc", description="Whole-body control task stacks on swappable QP backends.")
    parser.add_argument("--version", action="version", version=f"wbc {version('wbc')}")
    parser.add_argument("--debug", action="store_true",
                        help="show the full traceback when a command fails")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.add_parser("list", help="robots, tasks and available backends")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    sub.add_parser("study", help=f"rerun a paper study: {', '.join(STUDIES)}", add_help=False)
    args, rest = parser.parse_known_args(argv)
    debug = args.debug or "--debug" in rest  # accepted after the verb too
    rest = [arg for arg in rest if arg != "--debug"]
    if args.command is None:
        parser.print_help()
        return 2
    if args.command == "list":
        if rest:
            parser.error(f"unrecognized arguments: {' '.join(rest)}")
        return guarded("list", list_everything, debug)
    if args.command == "study":
        return guarded("study", lambda: run_study(rest), debug)
    module, _, function = COMMANDS[args.command][0].partition(":")
    return guarded(args.command,
                   lambda: getattr(importlib.import_module(module), function or "main")(rest),
                   debug)


def guarded(command: str, job: Callable[[], int | None], debug: bool = False) -> int:
    """Run ``job`` and turn what it raises into a one-line message and an exit code (1; 130 on
    Ctrl-C). argparse's ``SystemExit`` (exit 2, or 0 for ``--help``) passes through. With
    ``debug`` the exception propagates with its traceback."""
    try:
        code = job()
    except KeyboardInterrupt:
        print(f"wbc {command}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:
        if debug:
            raise
        from wbc.errors import WbcError

        if isinstance(err, (WbcError, OSError)):  # the user's to fix: no traceback
            print(f"wbc {command}: error: {err}", file=sys.stderr)
        else:
            print(f"wbc {command}: internal error: {type(err).__name__}: {err}\n"
                  f"(rerun with --debug for the traceback and report it)", file=sys.stderr)
        return 1
    return 0 if code is None else int(code)


if __name__ == "__main__":
    raise SystemExit(main())
