"""What a QP library prints never reaches the terminal: it is captured, counted and reported
(issue 21). ``capfd`` captures at the file-descriptor level, so an empty ``readouterr()`` means
nothing reached fd 1 or 2, whether written from Python or from C.

Which backends print (surveyed on infeasible, unbounded, badly scaled, degenerate and
hot-started QPs, both profiles): qpOASES (its errors, through CasADi and Python's
``sys.stdout``, on failed calls, often ones its retry then solves), OSQP with polishing ("Polishing
not needed ...": native and through qpsolvers from Python, inside CasADi from C). daqp, proxqp,
clarabel and quadprog print nothing, and are not captured.
"""

from __future__ import annotations

import json
import re
import threading
from pathlib import Path

import numpy as np
import pytest
from helpers import PETRIC_LEVEL

import wbc
from wbc.errors import BackendUnavailableError
from wbc.solvers import make_backend
from wbc.solvers.base import CONSOLE_LINES, ConsoleCapture
from wbc.tasks import Bounds, LinearConstraint, LinearTask

NOTE = re.compile(r"(\S+) printed (\d+) lines? \(kept off the console; the first: '(.*)'\)$")



def daqp_level():
    """A wbc fuzz level (tests/data): OSQP's polishing finds no active set there."""
    qp = np.load(Path(__file__).parent / "data" / "daqp_unbounded_at_tight_eta_prox.npz")
    return [qp[k] for k in ("H", "g", "A", "lA", "uA", "lb", "ub")]


def infeasible_rows():
    """x0 + x1 + x2 = 1 and = 2."""
    H, A = np.eye(3), np.ones((2, 3))
    sides = np.array([1.0, 2.0])
    return H, np.zeros(3), A, sides, sides, -np.ones(3), np.ones(3)


def solve_twice(backend, data):
    """Solve ``data`` twice; the second result. qpOASES' errors are visible once a qpOASES
    solver has been destroyed (the adapter's restart after the first failure does)."""
    backend.setup(*data)
    backend.solve()
    return backend.solve()


def parse(message: str) -> tuple[str, int, str]:
    match = NOTE.search(message)
    assert match, message
    return match[1], int(match[2]), match[3]


def backend_or_skip(name: str, **options):
    try:
        return make_backend(name, **options)
    except BackendUnavailableError:
        pytest.skip(f"{name} not installed")


def test_qpoases_division_by_zero_is_counted_not_printed(capfd):
    backend = backend_or_skip("qpoases")
    before = backend.console_lines
    result = solve_twice(backend, PETRIC_LEVEL)
    assert capfd.readouterr() == ("", "")
    assert result.status is wbc.Status.SOLVED  # by the cold retry
    name, lines, first = parse(result.message)
    assert (name, first) == ("qpoases", "ERROR: Division by zero")
    assert lines >= 2 and backend.console_lines >= before + lines
    assert CONSOLE_LINES["qpoases"] >= backend.console_lines


def test_qpoases_prints_there_without_the_capture(capfd):
    """The premise of the test above: on that data qpOASES does print, whatever printLevel."""
    backend = backend_or_skip("qpoases")
    backend._console = None
    solve_twice(backend, PETRIC_LEVEL)
    assert "ERROR:  Division by zero" in capfd.readouterr().out


def test_a_failed_level_says_what_the_backend_printed(capfd):
    """The note reaches ``Solution.message`` of a failed tick (as part of the level's
    message); nothing reaches the terminal."""
    backend_or_skip("qpoases")
    stack = wbc.Stack(wbc.Variables(x=3), damping=1e-3)
    stack.add(LinearTask(np.eye(3), np.ones(3), name="t"))
    stack.constrain(Bounds(-0.5, 0.5, name="box"))
    stack.constrain(LinearConstraint(np.ones((1, 3)), [4.0], [5.0], name="sum"))
    ws = stack.workspace("qpoases")
    ws.solve()
    solution = ws.solve()
    assert capfd.readouterr() == ("", "")
    assert solution.status is wbc.Status.INFEASIBLE
    assert "qpoases printed" in solution.message and "infeasib" in solution.message


@pytest.mark.parametrize("name, options", [
    ("osqp", {"profile": "tight"}),
    ("qpsolvers:osqp", {"profile": "tight"}),
    ("casadi:osqp", {"osqp": {"verbose": False, "polishing": True}}),  # from C: fd capture
])
def test_osqp_polishing_is_counted_not_printed(capfd, name, options):
    backend = backend_or_skip(name, **options)
    backend.setup(*daqp_level())
    result = backend.solve()
    assert capfd.readouterr() == ("", "")
    assert parse(result.message) == (name, 1, "Polishing not needed - no active set detected "
                                              "at optimal point")
    assert backend.console_lines == 1


def test_casadi_osqp_polishing_prints_from_c(capfd):
    """The premise of the fd-level capture: a Python-level one does not catch it."""
    backend = backend_or_skip("casadi:osqp", osqp={"verbose": False, "polishing": True})
    backend._console = ConsoleCapture()
    backend.setup(*daqp_level())
    backend.solve()
    assert "Polishing not needed" in capfd.readouterr().out


@pytest.mark.parametrize("name", ["daqp", "proxqp", "clarabel", "quadprog"])
@pytest.mark.parametrize("data", [infeasible_rows(), PETRIC_LEVEL, daqp_level()],
                         ids=["infeasible", "petric_level", "fuzz_level"])
def test_backends_that_print_nothing_are_not_captured(capfd, name, data):
    backend = backend_or_skip(name)
    assert backend._console is None  # nothing to capture: no cost
    solve_twice(backend, data)
    assert capfd.readouterr() == ("", "")


def test_other_threads_print_through_a_capture(capfd):
    capture = ConsoleCapture()
    with capture:
        print("kept")
        thread = threading.Thread(target=print, args=("from another thread",))
        thread.start()
        thread.join()
    assert capture.lines == 1 and capture.first == "kept"
    assert capfd.readouterr().out == "from another thread\n"


def test_studies_report_the_lines_in_their_timing(tmp_path, capfd):
    """``study_main`` adds ``console_lines`` to the timing of a backend that printed during the
    study (``wbc study xing --quick --backend qpoases``: 246 lines, none on the terminal)."""
    backend_or_skip("qpoases")
    from wbc.experiments.studies.study import StudyResult, study_main, timing_summary

    def run(backend, out_dir, quick, options=None):
        solve_twice(make_backend(backend), PETRIC_LEVEL)
        return StudyResult("fake", [], {}, {backend: timing_summary([1e-5]),
                                            "daqp": timing_summary([1e-5])})

    assert study_main("fake", run, ["--backend", "qpoases", "--out", str(tmp_path)]) == 0
    out, err = capfd.readouterr()
    assert "ERROR" not in out + err
    timing = json.loads((tmp_path / "fake" / "fake.json").read_text())["timing"]
    assert timing["qpoases"]["console_lines"] >= 2 and "console_lines" not in timing["daqp"]
    assert "| console lines |" in out
