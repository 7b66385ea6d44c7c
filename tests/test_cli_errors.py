"""Every verb of the ``wbc`` command line answers a user's mistake with a one-line message and an
honest exit code (2: bad argument, 1: failure at run time), in a real subprocess, without a
traceback unless ``--debug`` asks for one.

Every case is its own process; they all start at once (a module fixture) because each spends
most of its second importing numpy, CasADi and pinocchio.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

from wbc.experiments.cli import COMMANDS, STUDIES


def run_wbc(args: tuple[str, ...], hide: str | None = None) -> subprocess.CompletedProcess:
    """Run ``wbc ARGS`` in a fresh interpreter; ``hide`` makes a package unimportable there."""
    code = "import sys\n"
    if hide:
        code += f"sys.modules[{hide!r}] = None\n"
    code += ("from wbc.experiments.cli import main\n"
             f"raise SystemExit(main({list(args)!r}))\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)


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
    (["reproduce", "--bogus"], "unrecognized arguments: --bogus"),
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
    """``(args, hide) -> CompletedProcess`` for every case, run concurrently."""
    with ThreadPoolExecutor(max_workers=4) as pool:
        done = list(pool.map(lambda case: run_wbc(*case), CASES))
    return dict(zip(CASES, done, strict=True))


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
