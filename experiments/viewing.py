"""``wbc view`` and ``wbc play``: the viewer's command-line verbs (:mod:`wbc.viz`).

``wbc view DIR [--run NAME] [--port N] [--host H] [--seconds S]`` replays the runs a study
recorded under ``DIR`` (``wbc study NAME --out DIR`` or ``wbc reproduce``: the
``<study>_replay.npz`` files, :mod:`wbc.viz.record`), a dropdown switching between them.

``wbc play ROBOT [--backend NAME] [--port N] [--host H] [--seconds S]`` serves the live
playground (:class:`wbc.viz.Playground`): ROBOT is a catalogue name, ``panda`` (the fixed-base
Panda) or a robot file (TOML, as ``wbc bench --robot`` takes it).

Both bind 127.0.0.1 unless ``--host`` says otherwise and print the URL; ``--seconds S`` serves
S seconds and exits 0, otherwise until Ctrl-C (exit 0). Errors are one line on stderr: exit 2
for a bad argument (an unknown run or robot, a folder without records), 1 at run time (the
``[viz]`` extra missing, the port in use).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from wbc.errors import UnknownNameError, WbcError

__all__ = ["play_main", "view_main"]


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (``wbc VERB: error: ...``), exit 2."""

    def error(self, message: str):  # type: ignore[override]
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", type=int, default=8080, help="TCP port (default 8080)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to bind (default 127.0.0.1: this machine only; "
                             "0.0.0.0 exposes the control page to the network)")
    parser.add_argument("--seconds", type=float, default=None,
                        help="serve this many seconds, then exit 0 (default: until Ctrl-C)")


def _fail(prog: str, message: str, code: int) -> int:
    print(f"{prog}: error: {message}".splitlines()[0], file=sys.stderr)
    return code


def _serve(seconds: float | None) -> None:
    try:
        if seconds is not None:
            time.sleep(max(0.0, seconds))
        else:
            while True:
                time.sleep(3600)
    except KeyboardInterrupt:
        pass


def _open_and_serve(prog: str, seconds: float | None, open_server) -> int:
    """Open the server ``open_server()`` makes (viser needed), serve it ``seconds`` [s] (or
    until Ctrl-C) and close it; returns the exit code: 2 for an unknown name, 1 for another
    :class:`~wbc.WbcError` (a port in use, the missing ``[viz]`` extra)."""
    try:
        from wbc.viz import require_viser

        require_viser()
        server = open_server()
    except UnknownNameError as err:
        return _fail(prog, str(err), 2)
    except WbcError as err:
        return _fail(prog, str(err), 1)
    try:
        _serve(seconds)
    finally:
        server.close()
    return 0


def view_main(argv: Sequence[str] | None = None) -> int:
    """``wbc view DIR [--run NAME] [--port N] [--host H] [--seconds S]`` (module docstring)."""
    parser = _Parser(prog="wbc view", description="Replay the runs a study recorded under DIR "
                     "in the browser (3-D, time slider, play/pause, speed, status per tick).")
    parser.add_argument("dir", metavar="DIR",
                        help="a study's --out folder (or a study folder, or a *_replay.npz)")
    parser.add_argument("--run", default=None,
                        help="the run shown first, e.g. xing/circle_r010/amp_qp (default: the "
                             "first; a unique suffix such as circle_r010/amp_qp is enough)")
    _common(parser)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    from wbc.viz.record import load_recordings

    try:
        recordings = load_recordings(args.dir)
    except WbcError as err:
        return _fail(parser.prog, str(err), 2)
    name = None
    if args.run is not None:
        matches = [k for k in recordings if k == args.run or k.endswith("/" + args.run)]
        if len(matches) != 1:
            what = "ambiguous" if matches else "unknown"
            return _fail(parser.prog, f"{what} run {args.run!r}; runs: {sorted(recordings)}", 2)
        name = matches[0]
    first = recordings[name or next(iter(recordings))]
    if not first.robot:
        return _fail(parser.prog, "the records name no robot", 2)

    def replay():
        import wbc.robots
        from wbc.viz.viewer import Viewer

        viewer = Viewer(wbc.robots.load(first.robot), args.host, args.port)
        try:
            viewer.replay(recordings, name)
        except BaseException:
            viewer.close()  # the port is not left held by a viewer nobody serves
            raise
        return viewer

    return _open_and_serve(parser.prog, args.seconds, replay)


def load_robot(spec: str):
    """A robot by name: a catalogue name, ``"panda"``, or a robot file (``*.toml``)."""
    import wbc.robots

    if spec.endswith(".toml"):
        from wbc.experiments.benchmarks.user_inputs import load_robot_file

        return load_robot_file(spec)
    if spec == "panda":
        return wbc.robots.load_panda()
    try:
        return wbc.robots.load(spec)
    except UnknownNameError:
        raise UnknownNameError(f"unknown robot {spec!r}: a catalogue name "
                               f"{wbc.robots.names()}, 'panda', or a robot file (.toml)") \
            from None


def play_main(argv: Sequence[str] | None = None) -> int:
    """``wbc play ROBOT [--backend NAME] [--port N] [--host H] [--seconds S]`` (module
    docstring)."""
    parser = _Parser(prog="wbc play", description="A live playground in the browser: the "
                     "README's frame + posture + limits stack in closed loop, a gizmo on the "
                     "target, the backend and the priority mode switchable live.")
    parser.add_argument("robot", metavar="ROBOT",
                        help="a catalogue robot, 'panda', or a robot file (.toml)")
    parser.add_argument("--backend", default="daqp", help="QP backend to start with (daqp)")
    _common(parser)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    from wbc.solvers import available_backends

    if args.backend not in available_backends():
        return _fail(parser.prog, f"unknown or unavailable backend {args.backend!r}; "
                     f"available: {available_backends()}", 2)
    try:
        robot = load_robot(args.robot)
    except WbcError as err:
        return _fail(parser.prog, str(err), 2)

    def playground():
        from wbc.viz.playground import Playground

        return Playground(robot, args.backend, args.host, args.port)

    return _open_and_serve(parser.prog, args.seconds, playground)

