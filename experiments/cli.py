"""The ``wbc`` command line: ``wbc list``, ``wbc demo``, ``wbc bench``, ``wbc pink``, ``wbc mink``,
``wbc study NAME``.

Each sub-command forwards its remaining arguments to the ``main(argv)`` of its experiment
module, so ``wbc bench --help`` shows that study's own options; ``wbc study NAME ...`` forwards
to the paper study ``wbc.experiments.NAME`` (see :mod:`wbc.experiments.study`).
"""

from __future__ import annotations

import argparse
import importlib
import sys

COMMANDS = {
    "demo": ("wbc.experiments.microbench", "one stack on every backend: agreement and timing"),
    "bench": ("wbc.experiments.solver_timing", "solver-timing study over robots, stacks, "
              "backends"),
    "pink": ("wbc.experiments.vs_pink", "head-to-head with pink on the Panda"),
    "mink": ("wbc.experiments.vs_mink", "head-to-head with mink on the Panda"),
    "reproduce": ("wbc.experiments.reproduce", "every paper study, bench and peers in one "
                  "report (REPORT.md)"),
}


STUDIES = {
    "sorour": "Sorour et al.: ψ task sharing on a steerable base (MPO700 + LWR-IV)",
    "petric": "Petrič & Žlajpah: velocity field for a differential-drive base (Tiago)",
    "omni": "omni platform: slip-avoiding wheel-torque distribution",
    "xing": "Xing et al.: adaptive motion planning at the acceleration level (mecanum + Gen3)",
}


def run_study(argv: list[str]) -> int:
    """``wbc study NAME [options]``: one paper study (``wbc study NAME --help`` for options)."""
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: wbc study NAME [--backend B] [--out DIR] [--quick]\n\nstudies:")
        for name, what in STUDIES.items():
            print(f"  {name:8s} {what}")
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in STUDIES:
        print(f"wbc study: unknown study {name!r}; studies: {', '.join(STUDIES)}",
              file=sys.stderr)
        return 2
    module = importlib.import_module(f"wbc.experiments.{name}")
    return module.main(rest)


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
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(
        prog="wbc", description="Whole-body control task stacks on swappable QP backends.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.add_parser("list", help="robots, tasks and available backends")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    sub.add_parser("study", help=f"rerun a paper study: {', '.join(STUDIES)}", add_help=False)
    args, rest = parser.parse_known_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    if args.command == "list":
        if rest:
            parser.error(f"unrecognized arguments: {' '.join(rest)}")
        return list_everything()
    if args.command == "study":
        return run_study(rest)
    module = importlib.import_module(COMMANDS[args.command][0])
    return module.main(rest)


if __name__ == "__main__":
    raise SystemExit(main())
