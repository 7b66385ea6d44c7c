"""Every verb of the ``wbc`` command line answers a user's mistake with a one-line message and an
honest exit code (2: bad argument, 1: failure at run time), in a process of its own, without a
traceback unless ``--debug`` asks for one.

Each case runs in a child process forked from this one after the verbs' modules are imported
(what the console script does after its imports: ``raise SystemExit(main(argv))``), so that a
case costs milliseconds instead of a second of importing numpy, CasADi and pinocchio; a few
cases also run in a fresh interpreter and must give the same answer.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import pytest

from wbc.experiments.cli import COMMANDS, STUDIES, main


@dataclass
class Done:
    returncode: int
    stdout: str
    stderr: str


def forked_wbc(args: tuple[str, ...], hide: str | None = None) -> Done:
    """Run ``wbc ARGS`` in a forked child; ``hide`` makes a package unimportable there."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        pid = os.fork()
        if pid == 0:  # the child: never returns into pytest
            code = 1
            try:
                os.dup2(out.fileno(), 1)
                os.dup2(err.fileno(), 2)
                sys.stdout, sys.stderr = open(1, "w", closefd=False), open(2, "w", closefd=False)
                if hide:
                    sys.modules[hide] = None
                try:
                    code = main(list(args))
                except SystemExit as exit_:  # as the interpreter treats it
                    code = exit_.code if isinstance(exit_.code, int) else int(bool(exit_.code))
                except BaseException:  # an uncaught exception: traceback, exit 1
                    traceback.print_exc()
                    code = 1
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
        status = _wait(pid, timeout=60.0)
        out.seek(0)
        err.seek(0)
        return Done(os.waitstatus_to_exitcode(status), out.read(), err.read())


def _wait(pid: int, timeout: float) -> int:
    """The wait status of child ``pid``; killed (and the test failed) after ``timeout`` [s]."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return status
        time.sleep(0.005)
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    pytest.fail(f"the forked child {pid} did not exit within {timeout} s")


def fresh_wbc(args: tuple[str, ...], hide: str | None = None) -> Done:
    """Run ``wbc ARGS`` in a fresh interpreter (as the console script does)."""
    code = "import sys\n"
    if hide:
        code += f"sys.modules[{hide!r}] = None\n"
    code += ("from wbc.experiments.cli import main\n"
             f"raise SystemExit(main({list(args)!r}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    return Done(done.returncode, done.stdout, done.stderr)


BAD_ARGUMENTS = [
    (["frobnicate"], "invalid choice"),
    (["list", "extra"], "unrecognized arguments: extra"),
    (["demo", "--ticks", "0"], "--ticks must be >= 1"),
    (["demo", "--backends", "nosuch"], "['nosuch'] not available"),
    (["bench", "--ticks", "-1"], "--ticks"),
    (["bench", "--robots", "r2d2"], "unknown robot"),
    (["pink", "--ticks", "0"], "--ticks must be >= 1"),
    (["pink", "--ticks", "-1"], "--ticks must be >= 1"),
    (["pink", "--backends", "nosuch"], "['nosuch'] not available"),
    (["mink", "--ticks", "many"], "invalid int value"),
    (["mink", "--backends", "cplex"], "['cplex'] not available"),
    (["placo", "--ticks", "0"], "--ticks must be >= 1"),
    (["reproduce", "--bogus"], "unrecognized arguments: --bogus"),
    (["exactness", "--states", "0"], "--states must be >= 1"),
    (["fuzz", "--cases", "0"], "--cases must be >= 1"),
    (["fuzz", "--seconds", "-1"], "--seconds must be > 0"),
    (["fuzz", "--backends", "nosuch"], "unknown or unavailable QP backend 'nosuch'"),
    (["audit", "--ticks", "0"], "--runs and --ticks must be >= 1"),
    (["audit", "--levels", "torque"], "unknown level 'torque'"),
    (["audit", "--backends", "nosuch"], "unknown or unavailable QP backend 'nosuch'"),
    (["view", "/nonexistent/results"], "no such file or folder"),
    (["play", "r2d2", "--seconds", "1"], "unknown robot"),
    (["sweep", "omni", "--seeds", "0"], "--seeds must be >= 1"),
    (["sweep", "omni", "--param", "nosuch=1"], "unknown parameter 'nosuch'"),
    (["study"], "the study NAME is missing"),
    (["study", "nosuch"], "unknown study 'nosuch'"),
]


AVAILABLE_STUDIES = [name for name in STUDIES
                     if importlib.util.find_spec(f"wbc.experiments.{name}")]
VERBS = ["list", "study", *COMMANDS]
CASES = ([(tuple(args), None) for args, _ in BAD_ARGUMENTS]
         + [(("study", name, "--backend", "nosuch"), None) for name in AVAILABLE_STUDIES]
         + [((peer, "--ticks", "5"), peer) for peer in ("pink", "mink")]
         + [(("--debug", "mink", "--ticks", "5"), "mink"),
            (("mink", "--ticks", "5", "--debug"), "mink"), (("--version",), None)]
         + [((verb, "--help"), None) for verb in VERBS])


@pytest.fixture(scope="module")
def ran() -> dict:
    """``(args, hide) -> Done`` for every case, each in a forked child."""
    for module in [*(m.partition(":")[0] for m, _ in COMMANDS.values()),
                   *(f"wbc.experiments.{name}" for name in AVAILABLE_STUDIES)]:
        importlib.import_module(module)  # imported once, here, not in every child
    return {case: forked_wbc(*case) for case in CASES}


@pytest.fixture
def wbc(ran):
    return lambda *args, hide=None: ran[(args, hide)]


@pytest.mark.parametrize("args, message", BAD_ARGUMENTS, ids=" ".join)
def test_bad_argument_exits_2_with_a_message(wbc, args, message):
    done = wbc(*args)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr
    assert "Traceback" not in done.stderr


def test_every_verb_is_covered_by_a_bad_argument_case():
    assert {args[0] for args, _ in BAD_ARGUMENTS} >= set(VERBS)


@pytest.mark.parametrize("name", AVAILABLE_STUDIES)
def test_study_with_an_unknown_backend_exits_2(wbc, name):
    done = wbc("study", name, "--backend", "nosuch")
    assert done.returncode == 2
    assert "nosuch" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("peer", ["pink", "mink"])
def test_a_missing_peer_is_a_failure_with_the_install_hint(wbc, peer):
    done = wbc(peer, "--ticks", "5", hide=peer)
    assert done.returncode == 1
    assert f"wbc {peer}: error:" in done.stderr
    assert f"pip install 'wbc[{peer}]'" in done.stderr
    assert "Traceback" not in done.stderr


def test_debug_shows_the_traceback(wbc):
    done = wbc("--debug", "mink", "--ticks", "5", hide="mink")
    assert done.returncode == 1
    assert "Traceback" in done.stderr and "MissingDependencyError" in done.stderr
    after_the_verb = wbc("mink", "--ticks", "5", "--debug", hide="mink")
    assert "Traceback" in after_the_verb.stderr


def test_version(wbc):
    done = wbc("--version")
    assert done.returncode == 0
    assert done.stdout.strip() == f"wbc {importlib.metadata.version('wbc')}"


@pytest.mark.skipif(shutil.which("wbc") is None, reason="console script not on PATH")
def test_console_script():
    done = subprocess.run(["wbc", "--version"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.startswith("wbc ")


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_help_shows_its_wbc_usage(wbc, verb):
    done = wbc(verb, "--help")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"usage: wbc {verb}")


FRESH = [(("demo", "--ticks", "0"), None), (("pink", "--help"), None),
         (("mink", "--ticks", "5"), "mink"), (("--debug", "mink", "--ticks", "5"), "mink")]


def test_a_fresh_interpreter_gives_the_same_answers(ran):
    with ThreadPoolExecutor(max_workers=len(FRESH)) as pool:
        fresh = list(pool.map(lambda case: fresh_wbc(*case), FRESH))
    for case, done in zip(FRESH, fresh, strict=True):
        forked = ran[case]
        assert done.returncode == forked.returncode, (case, done.stderr)
        assert done.stdout == forked.stdout, case
        first_line = forked.stderr.splitlines()[0] if forked.stderr else ""
        assert done.stderr.startswith(first_line), case
