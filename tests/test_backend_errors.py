"""A QP library's own exceptions never leak: a rejected option or a crash inside a solver is a
:class:`wbc.BackendError` (a :class:`wbc.WbcError`) naming the backend."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc.solvers import available_backends, make_backend
from wbc.tasks import Bounds, LinearTask

NATIVE = [name for name in available_backends() if not name.startswith("qpsolvers:")]
# quadprog's options are its adapter's own numbers (proximal iterations for a singular H), not
# settings handed to the library: a string there surfaces only when such a problem is solved
LIBRARY_OPTIONS = [name for name in NATIVE if name != "quadprog"]


def workspace(backend: str, **options) -> wbc.Workspace:
    stack = wbc.Stack(3).add(LinearTask(np.eye(3), np.ones(3), name="t"))
    stack.constrain(Bounds(-1.0, 1.0, name="b"))
    return stack.workspace(backend, **options)


@pytest.mark.parametrize("backend", LIBRARY_OPTIONS)
def test_an_option_of_the_wrong_type_is_a_wbc_error_naming_the_backend(backend):
    option = next(iter(make_backend(backend, "tight").options))  # one the backend knows
    with pytest.raises(wbc.WbcError, match=f"QP backend '{backend}'") as caught:
        workspace(backend, **{option: "not a number"}).solve()
    assert isinstance(caught.value, (wbc.BackendError, wbc.UnknownNameError))


@pytest.mark.parametrize("backend", NATIVE)
def test_an_unknown_option_is_a_wbc_error_naming_the_backend(backend):
    with pytest.raises(wbc.WbcError, match=f"QP backend '{backend}'"):
        workspace(backend, no_such_option=1).solve()


@pytest.mark.parametrize("stage", ["setup", "update", "solve"])
def test_a_crash_inside_the_solver_is_a_backend_error(stage, monkeypatch):
    ws = workspace("daqp")
    ws.solve()  # set up
    backend = ws._blocks[0].backend

    def crash(*args, **kwargs):
        raise RuntimeError("segfault averted")

    monkeypatch.setattr(backend, f"_{stage}", crash)
    qp = ws._blocks[0].qp
    call = {"setup": lambda: backend.setup(*qp), "update": lambda: backend.update(*qp),
            "solve": lambda: backend.solve(None)}[stage]
    with pytest.raises(wbc.BackendError,
                       match=f"QP backend 'daqp' failed in {stage}: RuntimeError: segfault"):
        call()


@pytest.mark.parametrize("solver", ["daqp", "quadprog", "clarabel"])
def test_a_setting_qpsolvers_rejects_is_a_backend_error(solver):
    # the stateless adapter reports a solver's failure as a status, but a rejected setting
    # (TypeError / AttributeError) is no failure of the problem
    with pytest.raises(wbc.BackendError, match=f"QP backend 'qpsolvers:{solver}' failed in"):
        workspace(f"qpsolvers:{solver}", no_such_option=1).solve()
