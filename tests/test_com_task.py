"""`ComTask` (wbc.tasks.com): pink's ComTask at the velocity level — its command against pink
4.4's on 20 random states of a free-flyer quadruped (Solo-12) and of the Panda (both QPs solved
by quadprog, to 1e-8), compiled and numeric kinematics alike, its default target and name, and
bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.robots.resources import urdf_path
from wbc.tasks.com import ComTask

DT = 0.01
STATES = 20
TOL = 1e-8  # |v_wbc − v_pink|∞, both QPs solved by quadprog
PEER_DAMPING = 1e-6  # pink's `damping` d = wbc's ρ² (ρ = 1e-3)
SEED = 5


@pytest.fixture(scope="module")
def solo():
    return wbc.robots.from_urdf(urdf_path("solo_description/robots/solo12.urdf"),
                                root="free_flyer", ee_frame="FL_FOOT")


@pytest.fixture(scope="module")
def panda():
    return load_panda()


def controller(robot, task, kinematics="auto"):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(PEER_DAMPING))
    stack.add(task)
    return wbc.Controller(robot, stack, backend="quadprog", dt=DT, jit=False,
                          missing_limits="ignore", fallback="raise", kinematics=kinematics)


def random_state(robot, rng):
    q = robot.random_configuration(rng)
    if robot.nq != robot.nv:  # the free flyer: anywhere near the origin
        q[:3] = rng.uniform(-0.5, 0.5, 3)
    target = robot.com(q) + 0.1 * rng.standard_normal(3)
    return q, target


@pytest.mark.parametrize("which", ["solo", "panda"])
def test_command_equals_pinks(which, request):
    pink = pytest.importorskip("pink")
    from pink.tasks import ComTask as PinkComTask

    robot = request.getfixturevalue(which)
    cost, gain, lm = np.array([1.0, 2.0, 0.5]), 0.7, 0.3
    ours = controller(robot, ComTask(robot, gain=gain, weight=cost ** 2, lm_damping=lm,
                                     name="balance"))
    theirs = PinkComTask(cost=cost, gain=gain, lm_damping=lm)
    rng = np.random.default_rng(SEED)
    worst = 0.0
    for _ in range(STATES):
        q, target = random_state(robot, rng)
        v = ours.step(q, **{"balance.target": target})
        configuration = pink.Configuration(robot.model, robot.model.createData(), q)
        theirs.set_target(target)
        dq = pink.solve_ik(configuration, [theirs], DT, solver="quadprog",
                           damping=PEER_DAMPING, limits=[])
        worst = max(worst, float(np.abs(v - dq).max()))
    assert worst < TOL, worst


def test_compiled_and_numeric_kinematics_agree_on_a_free_flyer(solo):
    rng = np.random.default_rng(SEED + 1)
    numeric = controller(solo, ComTask(solo, gain=0.5, name="c"), kinematics="numeric")
    compiled = controller(solo.clone(), ComTask(solo, gain=0.5, name="c"),
                          kinematics="compiled")
    for _ in range(5):
        q, target = random_state(solo, rng)
        np.testing.assert_allclose(compiled.step(q, **{"c.target": target}),
                                   numeric.step(q, **{"c.target": target}), rtol=0, atol=1e-9)


def test_dead_beat_reaches_a_reachable_target_to_first_order(solo):
    """gain 1, a tiny step: ``J_com v = (c* − c) / dt`` holds (the task is the only one and
    ``J_com`` has full row rank), and one tick moves the CoM by ``c* − c`` to second order."""
    rng = np.random.default_rng(SEED + 2)
    ctrl = controller(solo, ComTask(solo, gain=1.0, name="c"))
    q, _ = random_state(solo, rng)
    target = solo.com(q) + np.array([1e-4, -2e-4, 1e-4])
    v = ctrl.step(q, **{"c.target": target})
    np.testing.assert_allclose(solo.com_jacobian(q) @ v, (target - solo.com(q)) / DT,
                               rtol=0, atol=1e-6)
    moved = solo.com(solo.integrate(q, v, DT))
    assert np.linalg.norm(moved - target) < 1e-6


def test_default_target_is_the_com_at_neutral_and_the_default_name_is_not_com(solo):
    task = ComTask(solo)
    np.testing.assert_allclose(task.default_target, solo.com(solo.neutral()), rtol=0,
                               atol=1e-15)
    stack = wbc.Stack(wbc.Variables(v=solo.nv))
    stack.add(task)
    assert task.name is not None and task.name != "com"
    assert f"{task.name}.target" in stack.parameters
    ctrl = wbc.Controller(solo, stack, backend="quadprog", dt=DT, jit=False,
                          missing_limits="ignore")
    v = ctrl.step(solo.neutral())  # at the default target: nothing to do
    assert np.abs(v).max() < 1e-9


def test_bad_inputs(solo):
    with pytest.raises(wbc.ShapeError, match="weight"):
        ComTask(solo, weight=[1.0, 2.0])
    with pytest.raises(wbc.InvalidValueError, match="gain"):
        ComTask(solo, gain=-1.0)
    with pytest.raises(wbc.InvalidValueError, match="robot"):
        ComTask(object())
    with pytest.raises(wbc.WbcError):
        ComTask(solo, name=3)
    task = ComTask(solo, name="c")
    ctrl = controller(solo, task)
    with pytest.raises(wbc.ShapeError):
        ctrl.step(solo.neutral(), **{"c.target": np.zeros(4)})
    with pytest.raises(wbc.NonFiniteError):
        ctrl.step(solo.neutral(), **{"c.target": np.array([0.0, np.nan, 0.0])})
