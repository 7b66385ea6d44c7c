"""`wbc.Controller`: closed loops on the Panda, fallback policies, references and errors."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import wbc
from wbc.robots.fixed_base import load_panda
from wbc.tasks import (
    Bounds,
    ConfigurationLimit,
    FrameTask,
    LinearConstraint,
    LinearTask,
    PostureTask,
    VelocityLimit,
)

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

DT = 0.01
BACKEND = "daqp"
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def panda_stack(robot, frame_gain=0.5, limit_gain=0.5, posture_target=None):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-4)
    stack.add(FrameTask(robot, "ee", gain=frame_gain, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-4, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=limit_gain, name="qlim"))
    stack.constrain(VelocityLimit(robot, name="vlim"))
    return stack


def test_closed_loop_reaches_the_target_without_violating_limits(robot):
    stack = panda_stack(robot, frame_gain=1.0)
    ctrl = wbc.Controller(robot, stack, backend=BACKEND, dt=DT)
    # joint 1 would turn by ≈ 0.25 rad; its (tightened) limit at 0.05 rad makes the other
    # joints take over, and dead-beat gains saturate the velocity limits at first
    lim, q = robot.limits, Q0.copy()
    q_upper = lim.q_upper.copy()
    q_upper[0] = 0.05
    ctrl.set_references(posture=Q0, **{"qlim.upper": q_upper})
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += [0.15, 0.20, -0.10]
    saturated = at_limit = 0
    for _ in range(400):
        v = ctrl.step(q, ee=target)
        assert ctrl.last_solution.ok, ctrl.last_solution.message
        assert np.all(v <= lim.v_upper + 1e-9) and np.all(v >= lim.v_lower - 1e-9)
        q = q + DT * v
        assert np.all(q <= q_upper + 1e-9) and np.all(q >= lim.q_lower - 1e-9)
        saturated += np.any(np.abs(v) >= lim.v_upper - 1e-6)
        at_limit += q[0] >= q_upper[0] - 1e-4
    assert saturated > 0 and at_limit > 0  # both kinds of limits were active
    T = robot.frame_pose(q, "ee")
    assert np.linalg.norm(T[:3, 3] - target[:3, 3]) < 1e-3
    np.testing.assert_allclose(T[:3, :3], target[:3, :3], atol=1e-3)
    timings = ctrl.last_solution.timings
    assert timings.model > 0 and timings.solve > 0
    assert ctrl.last_solution.fallback is None
    np.testing.assert_array_equal(ctrl.last_command, v)


def infeasible_state(robot):
    """Joint 1 far beyond its upper limit: the position bound asks for v < −10 rad/s, the
    velocity limit allows ≥ −2.175 rad/s: no admissible velocity."""
    q = Q0.copy()
    q[0] = robot.limits.q_upper[0] + 0.1
    return q


@pytest.mark.parametrize("policy", ["hold", "last", "decelerate"])
def test_fallback_on_an_infeasible_tick(robot, policy):
    ctrl = wbc.Controller(robot, panda_stack(robot, limit_gain=1.0), backend=BACKEND, dt=DT,
                          fallback=policy)
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += 0.1
    first = ctrl.step(Q0, ee=target).copy()
    assert ctrl.last_solution.ok and np.abs(first).max() > 0
    command = ctrl.step(infeasible_state(robot))
    solution = ctrl.last_solution
    assert not solution.ok
    assert solution.status is not wbc.Status.SOLVED
    assert solution.fallback == policy
    assert f"fallback {policy!r}" in solution.message
    lower, upper = ctrl.workspace.variable_bounds()
    assert np.any(lower > upper)  # inconsistent bounds: "decelerate" cannot clip into them
    expected = {"hold": 0.0, "last": first, "decelerate": 0.5 * first}[policy]
    np.testing.assert_array_equal(command, expected)
    assert np.isfinite(command).all()
    # back to a feasible state: normal operation resumes
    ctrl.step(Q0)
    assert ctrl.last_solution.ok and ctrl.last_solution.fallback is None


def test_decelerate_stays_within_consistent_bounds(robot):
    """The halved previous command is clipped into this tick's bounds when the failure lies
    elsewhere (here an unreachable hard constraint)."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(LinearTask(np.eye(robot.nv), np.full(robot.nv, 0.9), name="track"))
    stack.constrain(Bounds(-1.0, 1.0, name="box"))
    stack.constrain(LinearConstraint(np.ones((1, robot.nv)), -10.0, 10.0, name="sum"))
    ctrl = wbc.Controller(robot, stack, backend=BACKEND, dt=DT, fallback="decelerate")
    first = ctrl.step(Q0).copy()
    np.testing.assert_allclose(first, 0.9, atol=1e-3)
    box = np.full(robot.nv, 0.2)
    command = ctrl.step(Q0, **{"box.lower": -box, "box.upper": box, "sum.lower": 5.0})
    assert not ctrl.last_solution.ok and ctrl.last_solution.fallback == "decelerate"
    np.testing.assert_array_equal(command, 0.2)  # 0.45 clipped to the new upper bound


def test_fallback_raise(robot):
    ctrl = wbc.Controller(robot, panda_stack(robot, limit_gain=1.0), backend=BACKEND, dt=DT,
                          fallback="raise")
    ctrl.set_references(ee=robot.frame_pose(Q0, "ee"))
    with pytest.raises(wbc.InfeasibleError):
        ctrl.step(infeasible_state(robot))
    assert ctrl.last_solution.fallback == "raise"
    with pytest.raises(wbc.WbcError, match="fallback"):
        wbc.Controller(robot, panda_stack(robot), backend=BACKEND, fallback="pray")


def test_references_keys_and_errors(robot):
    ctrl = wbc.Controller(robot, panda_stack(robot), backend=BACKEND, dt=DT,
                          kinematics="numeric")
    assert {"ee", "ee.target", "posture", "qlim.upper", "vlim.lower"} <= set(
        ctrl.reference_names)
    assert set(ctrl.model_parameters) == {"q", "dt", "pose[ee]", "J[ee]"}
    with pytest.raises(wbc.WbcError, match="ee.target"):
        ctrl.step(Q0)  # the frame target has no default
    with pytest.raises(wbc.UnknownNameError) as info:
        ctrl.step(Q0, ee=np.eye(4), hand=np.eye(4))
    assert "'hand'" in str(info.value) and "ee.target" in str(info.value)
    with pytest.raises(wbc.UnknownNameError, match="model quantities"):
        ctrl.step(Q0, **{"pose[ee]": np.eye(4)})
    with pytest.raises(wbc.ShapeError, match="ee"):
        ctrl.step(Q0, ee=np.eye(3))
    with pytest.raises(wbc.NonFiniteError):
        ctrl.step(Q0, ee=np.full((4, 4), np.nan))
    with pytest.raises(wbc.ShapeError):
        ctrl.step(Q0[:6])
    with pytest.raises(wbc.NonFiniteError):
        ctrl.step(np.full(7, np.nan))
    # full parameter names work too, and a reference keeps its value between ticks
    T = robot.frame_pose(Q0, "ee")
    ctrl.step(Q0, posture=Q0, **{"ee.target": T, "vlim.upper": robot.limits.v_upper * 0.5})
    np.testing.assert_allclose(ctrl.workspace.view("ee.target"), T)
    v = ctrl.step(Q0)  # at both targets already: no motion
    assert np.abs(v).max() < 1e-9
    np.testing.assert_allclose(ctrl.workspace.view("vlim.upper").ravel(),
                               robot.limits.v_upper * 0.5)


def test_model_stage_fills_drift_and_velocity(robot):
    """A custom task reading ``"v"`` and ``"Jdot_v[ee]"``: the controller fills both."""

    class Accel(wbc.Task):
        def terms(self, stack):
            x = stack.variables.symbol
            J = stack.parameter("J[ee]", (6, robot.nv))
            drift = stack.parameter("Jdot_v[ee]", 6)
            stack.parameter("v", robot.nv)
            return [wbc.Cost(J @ x + drift, 0.0, 1.0, self.name)]

    stack = wbc.Stack(wbc.Variables(a=robot.nv), damping=1e-3)
    stack.add(Accel(), priority=0)
    ctrl = wbc.Controller(robot, stack, backend=BACKEND, dt=DT, kinematics="numeric")
    rng = np.random.default_rng(0)
    q, v = Q0 + 0.1 * rng.standard_normal(7), rng.standard_normal(7)
    a = ctrl.step(q, v).copy()
    np.testing.assert_allclose(ctrl.workspace.view("Jdot_v[ee]").ravel(),
                               robot.frame_drift(q, v, "ee"), atol=1e-12)
    np.testing.assert_array_equal(ctrl.workspace.view("v").ravel(), v)
    # compiled kinematics: the drift comes from robot.symbolic_drift inside the level function
    compiled = wbc.Controller(robot, stack, backend=BACKEND, dt=DT, kinematics="compiled")
    assert set(compiled.workspace.parameter_names) == {"q", "v"}
    np.testing.assert_allclose(compiled.step(q, v), a, atol=1e-10)
    ctrl.step(q)  # no velocity given: zeros
    assert not ctrl.workspace.view("v").any()


def test_unknown_frame_in_a_model_parameter(robot):
    class Bad(wbc.Task):
        def terms(self, stack):
            pose = stack.parameter("pose[nowhere]", (4, 4))
            return [wbc.Cost(stack.variables.symbol[:3] - pose[:3, 3])]

    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(Bad())
    with pytest.raises(wbc.UnknownNameError, match="nowhere"):
        wbc.Controller(robot, stack, backend=BACKEND)


@pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                    reason="JIT needs a C compiler")
def test_jit_gives_the_same_commands(robot):
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += [0.1, -0.1, 0.05]
    vm = wbc.Controller(robot, panda_stack(robot), backend=BACKEND, dt=DT)
    jit = wbc.Controller(robot, panda_stack(robot), backend=BACKEND, dt=DT, jit=True)
    q = Q0.copy()
    for _ in range(20):
        v = vm.step(q, ee=target)
        np.testing.assert_allclose(jit.step(q, ee=target), v, atol=1e-12)
        q = q + DT * v


def test_mobile_manipulator_closed_loop():
    robots = pytest.importorskip("wbc.robots")
    robot = robots.load("tiago_panda")
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, position_only=True, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-3, name="posture"))
    stack.constrain(ConfigurationLimit(robot, name="qlim"))
    stack.constrain(VelocityLimit(robot, name="vlim"))
    ctrl = wbc.Controller(robot, stack, backend=BACKEND, dt=DT)
    q = robot.neutral()
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += [0.8, 0.3, 0.0]  # beyond the arm's reach from here: the base must move
    for _ in range(400):
        v = ctrl.step(q, ee=target)
        assert ctrl.last_solution.ok
        q = robot.integrate(q, v, DT)
    assert np.linalg.norm(robot.frame_pose(q, "ee")[:3, 3] - target[:3, 3]) < 1e-2


def test_compiled_kinematics_give_the_same_commands(robot):
    target = robot.frame_pose(Q0, "ee").copy()
    target[:3, 3] += [0.1, -0.1, 0.05]
    numeric = wbc.Controller(robot, panda_stack(robot), backend=BACKEND, dt=DT,
                             kinematics="numeric")
    compiled = wbc.Controller(robot, panda_stack(robot), backend=BACKEND, dt=DT,
                              kinematics="compiled")
    assert numeric.kinematics == "numeric" and "pose[ee]" in numeric.workspace.parameter_names
    assert "pose[ee]" not in compiled.workspace.parameter_names
    assert set(compiled.model_parameters) == {"dt", "q"}
    q = Q0.copy()
    for _ in range(20):
        v = numeric.step(q, ee=target)
        np.testing.assert_allclose(compiled.step(q, ee=target), v, atol=1e-10)
        q = q + DT * v
    with pytest.raises(wbc.WbcError, match="kinematics"):
        wbc.Controller(robot, panda_stack(robot), backend=BACKEND, kinematics="magic")

    class NoSymbols:  # the protocol without symbolic_frame
        nq = nv = robot.nv

    with pytest.raises(wbc.WbcError, match="symbolic_frame"):
        wbc.Controller(NoSymbols(), panda_stack(robot), backend=BACKEND,
                       kinematics="compiled")
    # the default takes the compiled path when the robot offers it, the getters otherwise
    assert wbc.Controller(robot, panda_stack(robot), backend=BACKEND).kinematics == "compiled"

    class Unsupported:  # the Panda, but its symbolic_frame refuses the model's joints
        quantities = None  # the getter-only protocol: the registry comes from the getters

        def __getattr__(self, name):
            return getattr(robot, name)

        def symbolic_frame(self, frame):
            raise wbc.WbcError("symbolic kinematics support 1-DoF joints only")

    auto = wbc.Controller(Unsupported(), panda_stack(robot), backend=BACKEND, dt=DT)
    assert auto.kinematics == "numeric" and "J[ee]" in auto.model_parameters
    np.testing.assert_allclose(auto.step(Q0, ee=target), numeric.step(Q0, ee=target),
                               atol=1e-12)
