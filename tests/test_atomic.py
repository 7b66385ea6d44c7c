"""A refused update changes nothing: ``Workspace.set``, ``Controller.set_references`` and
``Controller.step`` check every value of the call before writing any, so after a refusal (unknown
name, wrong shape, NaN, inf, crossed bounds) the parameters, the "never set" bookkeeping and the
controller's last solution are exactly as before — for every key of the call."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.tasks import Bounds, FrameTask, LinearConstraint, LinearTask

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

N = 3
GOOD = {"t.A": np.eye(N), "t.b": np.ones(N)}
# (bad key and value, the error): one per kind of refusal
REFUSALS = [
    ({"nosuch": 1.0}, wbc.UnknownNameError),
    ({"t.A": np.eye(N + 1)}, wbc.ShapeError),
    ({"t.b": [1.0, np.nan, 0.0]}, wbc.NonFiniteError),
    ({"t.b": [1.0, np.inf, 0.0]}, wbc.NonFiniteError),
    ({"lim.lower": [-1.0, 2.0, -1.0]}, wbc.BoundsOrderError),  # above lim.upper = 1
    ({"c.lower": [0.5], "c.upper": [0.2]}, wbc.BoundsOrderError),  # both sides in one call
]
IDS = ["unknown-name", "shape", "nan", "inf", "crossed-bounds", "crossed-pair"]


def workspace():
    """``t``'s parameters have no default (never set until a ``set``); ``lim`` and ``c`` do."""
    stack = wbc.Stack(N)
    A, b = stack.parameter("t.A", (N, N)), stack.parameter("t.b", N)
    stack.add(wbc.Cost(A @ stack.variables.symbol, b, name="t"))
    stack.constrain(Bounds(-1.0, 1.0, name="lim"))
    stack.constrain(LinearConstraint(np.ones((1, N)), [-2.0], [2.0], name="c"))
    return stack.workspace("daqp")


@pytest.mark.parametrize("bad, error", REFUSALS, ids=IDS)
@pytest.mark.parametrize("first", [True, False], ids=["bad-first", "bad-last"])
def test_a_refused_set_writes_no_key(bad, error, first):
    ws = workspace()
    before = ws.p.copy()
    good = {key: value for key, value in GOOD.items() if key not in bad}
    call = {**bad, **good} if first else {**good, **bad}
    with pytest.raises(error):
        ws.set(**call)
    np.testing.assert_array_equal(ws.p, before)  # NaN (never set) stays NaN too
    # the good keys of the refused call were not applied, nor marked as set
    with pytest.raises(wbc.WbcError, match="parameters never set: .*t.A"):
        ws.solve()


@pytest.mark.parametrize("bad, error", REFUSALS, ids=IDS)
def test_a_refused_set_keeps_a_solved_workspace_solving_as_before(bad, error):
    ws = workspace().set(**GOOD)
    expected = ws.solve().x.copy()
    before = ws.p.copy()
    with pytest.raises(error):
        ws.set(**{"t.b": -np.ones(N), "lim.upper": np.full(N, 0.5), **bad})
    np.testing.assert_array_equal(ws.p, before)
    np.testing.assert_array_equal(ws.solve().x, expected)


def test_both_bounds_moved_past_each_other_in_one_call_are_checked_as_a_pair():
    ws = workspace().set(**GOOD)
    # lower = 1.5 alone would cross the old upper 1; with the new upper 3 it does not
    ws.set(**{"lim.lower": np.full(N, 1.5), "lim.upper": np.full(N, 3.0), "c.upper": [10.0]})
    np.testing.assert_allclose(ws.solve().x, np.full(N, 1.5), atol=1e-9)
    with pytest.raises(wbc.BoundsOrderError, match="'lim'.lower/.upper: lower > upper"):
        ws.set(**{"lim.upper": np.ones(N)})  # below the new lower


@pytest.fixture(scope="module")
def robot():
    return load_panda()


@pytest.fixture
def controller(robot):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(LinearTask(np.eye(robot.nv), np.zeros(robot.nv), weight=1e-3, name="rest"))
    stack.constrain(LinearConstraint(np.eye(robot.nv), -np.ones(robot.nv), np.ones(robot.nv),
                                     name="vlim"))
    ctrl = wbc.Controller(robot, stack, dt=0.01)
    q = robot.neutral() + 0.1
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += 0.05
    ctrl.step(q, ee=target)
    return ctrl, q, target


CONTROLLER_REFUSALS = [
    ({"nosuch": 1.0}, wbc.UnknownNameError),
    ({"ee": np.eye(3)}, wbc.ShapeError),
    ({"rest.b": np.full(7, np.nan)}, wbc.NonFiniteError),
    ({"rest.b": np.full(7, np.inf)}, wbc.NonFiniteError),
    ({"vlim.lower": np.full(7, 2.0)}, wbc.BoundsOrderError),
]
CONTROLLER_IDS = ["unknown-name", "shape", "nan", "inf", "crossed-bounds"]


@pytest.mark.parametrize("bad, error", CONTROLLER_REFUSALS, ids=CONTROLLER_IDS)
def test_a_refused_reference_leaves_the_controller_as_it_was(controller, bad, error):
    ctrl, q, target = controller
    before, solution, command = ctrl.workspace.p.copy(), ctrl.last_solution, ctrl.last_command
    moved = target.copy()
    moved[0, 3] += 0.1
    good = {"ee": moved, "rest.b": np.full(7, 0.01)}
    with pytest.raises(error):
        ctrl.set_references(**{**good, **bad})
    np.testing.assert_array_equal(ctrl.workspace.p, before)
    with pytest.raises(error):  # the same through step, with a new state: nothing is written
        ctrl.step(q + 0.2, np.ones(7), **{**good, **bad})
    np.testing.assert_array_equal(ctrl.workspace.p, before)
    assert ctrl.last_solution is solution and ctrl.last_command is command
    np.testing.assert_allclose(ctrl.step(q), command, atol=1e-12)  # the old references hold


@pytest.mark.parametrize("bad_state", ["q-shape", "q-nan", "v-inf"])
def test_a_refused_state_leaves_the_controller_as_it_was(controller, bad_state):
    ctrl, q, target = controller
    before = ctrl.workspace.p.copy()
    q_bad, v_bad = {"q-shape": (q[:3], None), "q-nan": (np.full(7, np.nan), None),
                    "v-inf": (q, np.full(7, np.inf))}[bad_state]
    moved = target.copy()
    moved[1, 3] += 0.1
    with pytest.raises((wbc.ShapeError, wbc.NonFiniteError)):
        ctrl.step(q_bad, v_bad, ee=moved)
    np.testing.assert_array_equal(ctrl.workspace.p, before)
