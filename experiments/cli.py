"""The ``wbc`` command line: ``wbc list``, ``wbc demo``, ``wbc bench``, ``wbc pink``, ``wbc mink``.

Each sub-command forwards its remaining arguments to the ``main(argv)`` of its experiment
module, so ``wbc bench --help`` shows that study's own options.
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
}


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
    args, rest = parser.parse_known_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    if args.command == "list":
        if rest:
            parser.error(f"unrecognized arguments: {' '.join(rest)}")
        return list_everything()
    module = importlib.import_module(COMMANDS[args.command][0])
    return module.main(rest)


if __name__ == "__main__":
    raise SystemExit(main())
