"""wbc fuzz: a fast subset of the campaign finds no defect on any backend (the fused tick
included), the classifier flags every kind of defect, and the CLI writes its contract."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

import wbc
from wbc.experiments.campaigns import fuzz
from wbc.solvers import available_backends


@pytest.mark.parametrize("backend", available_backends())
def test_stack_cases_have_no_defect(backend):
    cases = list(fuzz.stack_cases(backend, seed=1, structures=4, draws=1))
    assert len(cases) == 4 * fuzz.TICKS
    defects = [(c, d, m) for c, _, d, m in cases if d]
    assert defects == []
    # the injected defects do reach the classes: some refused, some solved
    classes = {outcome for _, outcome, _, _ in cases}
    assert {"error", "success"} <= classes


def test_stack_cases_have_no_defect_on_the_fused_cascade():
    cases = list(fuzz.stack_cases("daqp", seed=1, structures=6, draws=1, fused=True))
    assert {c["backend"] for c, *_ in cases} == {"daqp (fused)"}
    assert [(c, d, m) for c, _, d, m in cases if d] == []
    assert {"error", "success"} <= {outcome for _, outcome, _, _ in cases}


def test_robot_cases_have_no_defect_on_the_fused_tick():
    cases = list(fuzz.robot_cases("daqp", seed=1, ticks=12))
    assert [d for *_, d, _ in cases if d] == []
    assert {c["robot"] for c, *_ in cases} == set(wbc.robots.names())


def test_constructor_cases_have_no_raw_exception():
    """Every public constructor, stack method, robot loader and reference, fed bad arguments:
    each call returns or raises a WbcError, never another exception."""
    cases = list(fuzz.constructor_cases(seed=1, count=800))
    assert [(c, m) for c, _, d, m in cases if d] == []
    assert {c["constructor"] for c, *_ in cases} == set(fuzz.constructor_specs())
    assert {"error", "success"} <= {outcome for _, outcome, _, _ in cases}
    injected = " ".join(c["injected"] for c, *_ in cases)
    assert all(f"={kind}" in injected for kind in fuzz.BAD_VALUES)


#: public names of wbc.tasks that build no task: a scalar helper of the velocity field
NOT_TASK_BUILDERS = {"smoothstep"}
#: the robots' public loaders the family covers (each a key of constructor_specs)
LOADERS = ["robots.load", "robots.make_base", "robots.from_urdf",
           *(f"robots.from_urdf(root={root})" for root in ("free_flyer", "planar", "fixed",
                                                             "differential")),
           "arms.arm_from_urdf", "arms.arm_from_model", "robots.CollisionModel",
           "robots.Obstacle.box", "robots.Obstacle.sphere", "robots.Obstacle.capsule"]


@pytest.fixture(scope="module")
def specs():
    return fuzz.constructor_specs()


def test_every_public_task_and_loader_has_a_constructor_case(specs):
    """Every Task subclass and task-building function of wbc.tasks.__all__ (the papers' moved
    names included), and every loader, is fuzzed; a campaign calls each at least once."""
    import inspect

    import wbc.tasks as tasks
    from wbc.terms import Task

    builders = [name for name in tasks.__all__
                if (isinstance(getattr(tasks, name), type)
                    and issubclass(getattr(tasks, name), Task))
                or (inspect.isfunction(getattr(tasks, name)) and name not in NOT_TASK_BUILDERS)]
    assert {"ComTask", "CollisionAvoidance", "SafeDisplacement", "ManipulabilityTask",
            "ManipulabilityAccelerationTask", "joint_acceleration_bounds"} <= set(builders)
    missing = [name for name in builders
               if not any(key == name or key.startswith(f"{name}.") for key in specs)]
    assert missing == []
    assert [name for name in LOADERS if name not in specs] == []
    assert len(specs) <= fuzz.CONSTRUCTOR_MIN


def test_every_constructor_case_is_valid_as_given(specs):
    """The valid arguments of each case do build (and compile): a case refused as given would
    fuzz its argument checks only, never the task's terms."""
    rng = np.random.default_rng(3)
    refused = {name: fuzz.classify_call(call, valid(rng))
               for name, (call, valid) in specs.items()}
    assert {name: r for name, r in refused.items() if r[0] != "success"} == {}


def _pendulum():
    from wbc.robots.resources import urdf_path

    return urdf_path("double_pendulum_description/urdf/double_pendulum_simple.urdf")


def _regression_calls():
    """Each call raised numpy's, CasADi's or Python's own exception before it was fixed (found
    by the constructor family); now the library's error naming the argument."""
    import wbc.robots
    from wbc.robots import CollisionModel
    from wbc.tasks.body_spherical_barrier import BodySphericalBarrier
    from wbc.tasks.dof_freezing import DofFreezing
    from wbc.tasks.position_barrier import PositionBarrier

    robot = wbc.robots.load("omni4_arm6")
    panda = wbc.robots.load_panda()
    ragged = [[1.0, 2.0], [3.0]]
    return [
        # `root in ROOTS` on an array: numpy's "truth value ... is ambiguous"
        (lambda: wbc.robots.from_urdf(_pendulum(), root=np.ones(3)), wbc.UnknownNameError,
         "unknown root"),
        (lambda: wbc.robots.from_urdf(_pendulum(), root=np.zeros(0)), wbc.UnknownNameError,
         "unknown root"),
        # a free flyer's joint limits of the wrong length: numpy's broadcast error
        (lambda: wbc.robots.from_urdf(_pendulum(), root="free_flyer", v_max=np.ones(4)),
         wbc.ShapeError, "v_max"),
        (lambda: wbc.robots.from_urdf(_pendulum(), root="free_flyer", a_max=np.zeros((0, 0))),
         wbc.ShapeError, "a_max"),
        # CollisionModel's paths, switches and lists: os.fspath's / iter's TypeError, CasADi's
        # and numpy's truth-value errors
        (lambda: CollisionModel(panda, srdf={"a": 1.0}), wbc.InvalidValueError, "srdf"),
        (lambda: CollisionModel(panda, urdf=0), wbc.InvalidValueError, "urdf"),
        (lambda: CollisionModel(panda, self_collision=np.ones(2)), wbc.InvalidValueError,
         "self_collision"),
        (lambda: CollisionModel(panda, convex=ca.SX.sym("s")), wbc.InvalidValueError,
         "convex"),
        (lambda: CollisionModel(panda, package_dirs=None), wbc.InvalidValueError,
         "package_dirs"),
        (lambda: CollisionModel(panda, obstacles=1j), wbc.InvalidValueError, "obstacles"),
        (lambda: CollisionModel(panda, obstacles=ca.SX.sym("s", 2)), wbc.InvalidValueError,
         "obstacles"),
        # DofFreezing's form as an array: `form in FORMS` is ambiguous
        (lambda: DofFreezing(robot, dofs=[0], form=np.zeros(0)), wbc.InvalidValueError,
         "form"),
        # a barrier gain as a ragged list: np.ndim's "inhomogeneous shape"
        (lambda: PositionBarrier(robot, "ee", p_max=[1.0, 1.0, 1.0], gain=ragged),
         wbc.ShapeError, "gain"),
        (lambda: BodySphericalBarrier(robot, ("ee", "base_link"), d_min=0.1, gain=ragged),
         wbc.ShapeError, "gain"),
    ]


def test_defects_the_constructor_family_found_raise_the_library_errors():
    for call, error, argument in _regression_calls():
        with pytest.raises(error, match=argument):
            call()


def test_the_constructor_family_flags_a_raw_exception():
    def broken(value):
        return np.asarray(value, dtype=float)  # numpy's own ValueError on a str

    assert fuzz.classify_call(broken, {"value": "abc"})[:2] == ("defect", "exception")
    assert fuzz.classify_call(broken, {"value": 1.0})[:2] == ("success", None)
    assert fuzz.classify_call(wbc.Variables, {"blocks": "abc"})[:2] == ("error", None)


class _Solved:
    status = wbc.Status.SOLVED
    message = ""

    def __init__(self, x):
        self.x = np.asarray(x, dtype=float)


def test_classify_reads_the_message_so_a_broken_diagnosis_is_a_defect():
    class Failed(_Solved):
        status = wbc.Status.INFEASIBLE

        @property
        def message(self):
            raise IndexError("the conflict search broke")

    outcome, defect, message = fuzz.classify(lambda: (Failed([0.0, 0.0]), BOUNDS))
    assert (outcome, defect) == ("defect", "exception") and "conflict search" in message


BOUNDS = (np.array([-1.0, -1.0]), np.array([1.0, 1.0]))


@pytest.mark.parametrize("tick, outcome, defect", [
    (lambda: (_Solved([0.5, 1.0]), BOUNDS), "success", None),
    (lambda: (_Solved([0.5, 1.0 + 1e-6]), BOUNDS), "defect", "out_of_bounds"),
    (lambda: (_Solved([np.nan, 0.0]), BOUNDS), "defect", "non_finite_x"),
    (lambda: 1 / 0, "defect", "exception"),
    (lambda: (_ for _ in ()).throw(wbc.ShapeError("x: bad shape")), "error", None),
])
def test_classify_flags_each_defect(tick, outcome, defect):
    got, flagged, _ = fuzz.classify(tick)
    assert (got, flagged) == (outcome, defect)


def test_classify_flags_a_hang(monkeypatch):
    monkeypatch.setattr(fuzz, "HANG_S", 0.01)
    import time

    def slow():
        time.sleep(0.05)
        return _Solved([0.0, 0.0]), BOUNDS

    assert fuzz.classify(slow)[:2] == ("defect", "hang")


def test_cli_writes_the_contract(tmp_path):
    from wbc.experiments.cli import main

    assert main(["fuzz", "--cases", "60", "--backends", "daqp", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "fuzz.json").read_text())
    assert result["cases"] >= 50 and result["defects"] == []
    assert set(result["outcomes"]) >= {"daqp", "constructors"}
    assert result["families"]["constructors"] == fuzz.CONSTRUCTOR_MIN
    assert sum(result["families"].values()) == result["cases"]
    assert sum(result["outcomes"]["daqp"].values()) > 0
    assert "| backend |" in (tmp_path / "fuzz.md").read_text()


def test_cli_runs_one_family(tmp_path):
    from wbc.experiments.cli import main

    assert main(["fuzz", "--cases", "70", "--families", "constructors", "--backends", "daqp",
                 "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "fuzz.json").read_text())
    assert result["families"] == {"constructors": 70} and result["defects"] == []
    assert result["parameters"]["families"] == ["constructors"]
    with pytest.raises(SystemExit) as exit_:
        main(["fuzz", "--families", "stack,typo", "--out", str(tmp_path)])
    assert exit_.value.code == 2


def test_cli_exits_1_when_the_campaign_finds_a_defect(tmp_path, monkeypatch):
    from wbc.experiments.cli import main

    found = {"cases": 1, "outcomes": {"daqp": {"defect": 1}}, "parameters": {},
             "defects": [{"family": "stack", "backend": "daqp", "defect": "nan",
                          "message": "x is NaN"}]}
    monkeypatch.setattr(fuzz, "campaign", lambda *args, **kwargs: found)
    assert main(["fuzz", "--cases", "1", "--backends", "daqp", "--out", str(tmp_path)]) == 1
    assert json.loads((tmp_path / "fuzz.json").read_text())["defects"] == found["defects"]
