"""The traps met on the way in from pink and mink, each reproduced and each closed.

* a wbc ``weight`` is pink's ``cost`` squared, over ``v`` where pink minimises over ``Δq = v·dt``
  (checked against pink on random states);
* a stack without limits on a robot that has them: pink applies the model's limits by default,
  wbc only what the stack holds — the UR5's elbow runs 0.56 rad past its limit of π in the
  loop below — so building the controller warns once, naming what is missing
  (``missing_limits=`` silences or raises);
* ``weight=`` takes a stack parameter on every built-in task (per-tick weights), for every task
  class of ``wbc.tasks.__all__`` (the recipe table below must know each one: a task without a
  recipe fails the test);
* a task named like a model quantity (``"com"``) is refused when added, with a suggestion.
"""

from __future__ import annotations

import importlib
import inspect
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

import wbc
import wbc.robots
import wbc.tasks
from wbc.errors import MissingLimitsWarning
from wbc.tasks import ConfigurationLimit, FrameTask, LinearTask, PostureTask, VelocityLimit

SEED = 20261127
DT = 0.01


@pytest.fixture(scope="module")
def mobile():
    return wbc.robots.load("mecanum_gen3")


@pytest.fixture(scope="module")
def ur5():
    from wbc.experiments.peers.scenarios import load_ur5

    return load_ur5()


# ----------------------------------------------------------------------- weight = cost²
def test_a_wbc_weight_is_pinks_cost_squared_over_v():
    pink = pytest.importorskip("pink")
    import pinocchio as pin
    from pink.tasks import FrameTask as PinkFrameTask
    from pink.tasks import PostureTask as PinkPostureTask

    from wbc.robots.fixed_base import load_panda

    robot = load_panda()
    rng = np.random.default_rng(SEED)
    position_cost, orientation_cost, posture_cost, damping = 0.7, 0.3, 0.05, 1e-6

    def controller(square: bool):
        stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(damping))
        costs = np.array([position_cost] * 3 + [orientation_cost] * 3)
        stack.add(FrameTask(robot, "ee", gain=0.5, weight=costs ** 2 if square else costs,
                            name="ee"))
        stack.add(PostureTask(robot, gain=0.5,
                              weight=posture_cost ** 2 if square else posture_cost,
                              name="posture"))
        return wbc.Controller(robot, stack, backend="quadprog", dt=DT, missing_limits="ignore")

    squared, plain = controller(True), controller(False)
    configuration = pink.Configuration(robot.model, robot.model.createData(), robot.neutral())
    frame = PinkFrameTask("panda_hand", position_cost=position_cost,
                          orientation_cost=orientation_cost, gain=0.5)
    posture = PinkPostureTask(cost=posture_cost, gain=0.5)
    worst_squared = smallest_plain = 0.0
    smallest_plain = np.inf
    lower, upper = robot.limits.q_lower, robot.limits.q_upper
    for _ in range(20):
        q = rng.uniform(lower + 0.2, upper - 0.2)
        q_posture = rng.uniform(lower + 0.2, upper - 0.2)
        T = robot.frame_pose(rng.uniform(lower + 0.2, upper - 0.2), "ee").copy()
        configuration.update(q)
        frame.set_target(pin.SE3(T[:3, :3], T[:3, 3]))
        posture.set_target(q_posture)
        # pink returns a velocity: its QP is over Δq = v·dt, solve_ik divides by dt
        v_pink = pink.solve_ik(configuration, [frame, posture], DT, solver="quadprog",
                               damping=damping, limits=[])
        v = squared.step(q, ee=T, posture=q_posture)
        worst_squared = max(worst_squared, np.abs(v - v_pink).max())
        smallest_plain = min(smallest_plain,
                             np.abs(plain.step(q, ee=T, posture=q_posture) - v_pink).max())
    assert worst_squared <= 1e-8
    assert smallest_plain > 1e-3  # weight = cost (not squared) is another controller


# ------------------------------------------------------------------------ missing limits
def _ur5_stack(robot, limits: bool):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-6)
    stack.add(FrameTask(robot, "ee", gain=1.0, name="ee"))
    stack.add(PostureTask(robot, gain=1.0, weight=1e-6, name="posture"))
    if limits:
        stack.constrain(ConfigurationLimit(robot, name="position_limit"))
        stack.constrain(VelocityLimit(robot, name="velocity_limit"))
    return stack


def _elbow_run(controller, robot) -> float:
    """The UR5 loop of the peers' report, from wbc's side: the largest elbow angle [rad]."""
    from wbc.experiments.peers.scenarios import UR5_GOAL, UR5_Q0

    goal = robot.frame_pose(UR5_GOAL, "ee").copy()
    controller.set_references(posture=UR5_Q0)
    q, elbow = UR5_Q0.copy(), -np.inf
    for _ in range(80):
        q = q + DT * controller.step(q, ee=goal)
        elbow = max(elbow, q[2])
    return elbow


def test_a_stack_without_limits_warns_once_naming_what_is_missing(ur5):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        free = wbc.Controller(ur5, _ur5_stack(ur5, limits=False), backend="quadprog", dt=DT)
    found = [w for w in caught if issubclass(w.category, MissingLimitsWarning)]
    assert len(found) == 1
    message = str(found[0].message)
    assert "position limits of 6 coordinates" in message and "elbow_joint" in message
    assert "velocity limits of 6 coordinates" in message
    assert "ConfigurationLimit(robot)" in message and "VelocityLimit(robot)" in message
    assert "missing_limits='ignore'" in message
    assert found[0].filename == __file__  # points at the line that built the controller
    # what the warning is about: the elbow (limit π) runs 0.2 rad past its limit
    assert _elbow_run(free, ur5) > ur5.limits.q_upper[2] + 0.2
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the complete stack: no warning
        bounded = wbc.Controller(ur5, _ur5_stack(ur5, limits=True), backend="quadprog", dt=DT)
    assert _elbow_run(bounded, ur5) <= ur5.limits.q_upper[2] + 1e-9


def test_the_warning_names_only_what_is_missing_and_can_be_silenced_or_raised(mobile):
    def build(*constraints, **options):
        stack = wbc.Stack(wbc.Variables(v=mobile.nv), damping=1e-3)
        stack.add(FrameTask(mobile, "ee", name="ee"))
        for constraint in constraints:
            stack.constrain(constraint)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            wbc.Controller(mobile, stack, fused=False, jit=False, **options)
        return [str(w.message) for w in caught if issubclass(w.category, MissingLimitsWarning)]

    only_velocity = build(VelocityLimit(mobile))
    assert len(only_velocity) == 1 and "position limits of 3 coordinates" in only_velocity[0]
    assert "velocity limits" not in only_velocity[0]
    assert "gen3_joint_2, gen3_joint_4, gen3_joint_6" in only_velocity[0]  # the finite ones
    only_position = build(ConfigurationLimit(mobile))
    assert len(only_position) == 1 and "velocity limits of 10 coordinates" in only_position[0]
    assert build(ConfigurationLimit(mobile), VelocityLimit(mobile)) == []
    # bounds of one's own over every coordinate count as velocity limits
    assert len(build(ConfigurationLimit(mobile), wbc.tasks.Bounds(-1.0, 1.0))) == 0
    # level-local bounds do not hold at every level: they do not count
    stack_levels = wbc.Stack(wbc.Variables(v=mobile.nv), damping=1e-3)
    stack_levels.add(FrameTask(mobile, "ee", name="ee"))
    stack_levels.constrain(ConfigurationLimit(mobile))
    stack_levels.constrain(VelocityLimit(mobile), levels=[0])
    with pytest.warns(MissingLimitsWarning, match="velocity limits"):
        wbc.Controller(mobile, stack_levels, fused=False, jit=False)
    assert build(missing_limits="ignore") == []
    with pytest.raises(wbc.WbcError, match="no hard constraint of the stack bounds"):
        build(missing_limits="raise")
    with pytest.raises(wbc.InvalidValueError, match="missing_limits"):
        build(missing_limits="sometimes")


def test_acceleration_bounds_cover_both_and_a_torque_stack_is_not_asked(mobile):
    from wbc.tasks.joint_acceleration import JointAccelerationLimit

    stack = wbc.Stack(wbc.Variables(a=mobile.nv), damping=1e-3)
    stack.add(LinearTask(np.eye(mobile.nv), np.zeros(mobile.nv), name="rest"))
    stack.constrain(JointAccelerationLimit(mobile, dt=DT, method="viable"))
    torques = wbc.Stack(wbc.Variables(tau=4, t=1), damping=1e-3)
    torques.add(LinearTask(np.eye(4), np.ones(4), name="rest", block="tau"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wbc.Controller(mobile, stack, fused=False, jit=False)
        wbc.Controller(mobile, torques, fused=False, jit=False)  # no block of nv coordinates


# ------------------------------------------------------------------------ name shadowing
def test_a_task_named_like_a_model_quantity_is_refused_when_added(mobile):
    from wbc.tasks.com import ComTask

    stack = wbc.Stack(wbc.Variables(v=mobile.nv))
    with pytest.raises(wbc.WbcError, match=r"task name 'com' shadows the model quantity 'com'"
                       r".*e\.g\. 'com_task'"):
        stack.add(ComTask(mobile, name="com"))
    assert stack.parameters == {} and stack.task_names == []  # the refused add left nothing
    for state in ("q", "v", "dt"):
        with pytest.raises(wbc.WbcError, match=f"shadows the model quantity '{state}'"):
            stack.add(LinearTask(np.eye(mobile.nv), np.zeros(mobile.nv), name=state))
    # the other order: a task "com" first, then a task that declares the quantity "com"
    stack.add(LinearTask(np.eye(mobile.nv), np.zeros(mobile.nv), name="com"))
    with pytest.raises(wbc.WbcError, match="shadows the model quantity 'com'"):
        stack.add(ComTask(mobile, name="centre"))
    assert "centre.target" not in stack.parameters
    # kinds with an argument never make a parameter of the bare name: "pose" is a fine name
    fine = wbc.Stack(wbc.Variables(v=mobile.nv))
    fine.add(LinearTask(np.eye(mobile.nv), np.zeros(mobile.nv), name="pose"))
    fine.add(FrameTask(mobile, "ee", name="ee"))
    fine.constrain(ConfigurationLimit(mobile))
    fine.constrain(VelocityLimit(mobile))
    wbc.Controller(mobile, fine, fused=False, jit=False)


def test_a_plain_parameter_the_robot_fills_may_not_be_a_task_name(mobile):
    stack = wbc.Stack(wbc.Variables(v=mobile.nv))
    com = stack.parameter("com", 3)  # a plain parameter: the robot's registry fills it
    stack.add(LinearTask(np.eye(mobile.nv), np.zeros(mobile.nv), name="com"))
    assert com.shape == (3, 1)
    with pytest.raises(wbc.WbcError, match="shadows the model quantity 'com'"):
        wbc.Controller(mobile, stack, fused=False, jit=False, missing_limits="ignore")


# ---------------------------------------------------------------- weight= on every task
@dataclass(frozen=True)
class Recipe:
    """How to build one task class for the weight test.

    kind: ``"cost"`` — its constructor takes ``weight=`` (tested there and at ``stack.add``);
    ``"stack"`` — no ``weight=`` of its own (a constraint made soft by ``stack.add``, or a
    paper's task): ``stack.add(task, weight=w)`` is tested; ``"hard"`` — variable bounds, hard
    only: ``stack.add`` refuses it.
    build: ``build(env, weight) -> (task, references)``.
    """

    module: str
    kind: str
    build: Callable
    variables: Callable | None = None  # robot -> wbc.Variables (default: v = nv)
    robot: str = "mobile"
    moves: bool = True  # the command depends on the weight at the test's state


class Env:
    """The robots and a state the recipes build on (one of each, module-wide)."""

    def __init__(self) -> None:
        rng = np.random.default_rng(SEED)
        self.mobile = wbc.robots.load("mecanum_gen3")
        q = self.mobile.neutral().copy()
        q[3:] += rng.uniform(-0.3, 0.3, q.size - 3)
        self.q = {"mobile": q}
        from wbc.robots.fixed_base import load_panda

        self.panda = load_panda()
        self.q["panda"] = self.panda.neutral() + rng.uniform(-0.2, 0.2, self.panda.nv)
        self.A = rng.standard_normal((4, self.mobile.nv))
        self.b = rng.standard_normal(4)

    def robot(self, key: str):
        return self.mobile if key == "mobile" else self.panda

    def pose(self, frame="ee", dx=(0.05, -0.03, 0.04)):
        T = self.mobile.frame_pose(self.q["mobile"], frame).copy()
        T[:3, 3] += dx
        return T


def _nv(r):
    return int(r.nv)


def _arg(w):
    return {} if w is None else {"weight": w}


def _recipes() -> dict[str, Recipe]:
    T = wbc.tasks
    return {
        "FrameTask": Recipe("wbc.tasks.frame", "cost", lambda e, w: (
            T.FrameTask(e.mobile, "ee", gain=0.5, name="t", **_arg(w)), {"t": e.pose()})),
        "PostureTask": Recipe("wbc.tasks.posture", "cost", lambda e, w: (
            T.PostureTask(e.mobile, gain=0.5, name="t", **_arg(w)), {})),
        "LinearTask": Recipe("wbc.tasks.linear", "cost", lambda e, w: (
            T.LinearTask(e.A, e.b, name="t", **_arg(w)), {})),
        "RpyPoseTask": Recipe("wbc.tasks.rpy_pose", "cost", lambda e, w: (
            T.RpyPoseTask(e.mobile, "ee", name="t", **_arg(w)),
            {"t": [1.0, 0.2, 0.8, 0.1, 0.2, -0.3]})),
        "ManipulabilityAccelerationTask": Recipe("wbc.tasks.manipulability", "cost", lambda e, w: (
            _module("wbc.tasks.manipulability").ManipulabilityAccelerationTask(e.mobile, name="t",
                                                                   **_arg(w)), {})),
        "ManipulabilityTask": Recipe("wbc.tasks.manipulability", "cost", lambda e, w: (
            _module("wbc.tasks.manipulability").ManipulabilityTask(
                e.mobile, name="t", **_arg(w)), {})),
        "ComTask": Recipe("wbc.tasks.com", "cost", lambda e, w: (
            _module("wbc.tasks.com").ComTask(e.mobile, gain=0.5, name="t", **_arg(w)),
            {"t": e.mobile.com(e.q["mobile"]).reshape(3) + [0.05, 0.02, -0.01]})),
        "RelativeFrameTask": Recipe("wbc.tasks.relative_frame", "cost", lambda e, w: (
            _module("wbc.tasks.relative_frame").RelativeFrameTask(
                e.mobile, "ee", "base", gain=0.5, name="t", **_arg(w)),
            {"t": np.linalg.inv(e.pose("base", (0, 0, 0))) @ e.pose()})),
        "AxisAlignTask": Recipe("wbc.tasks.axis_align", "cost", lambda e, w: (
            _module("wbc.tasks.axis_align").AxisAlignTask(e.mobile, "ee", gain=0.5, name="t",
                                                          **_arg(w)), {"t": [0.3, 0.1, 1.0]})),
        "LookAtTask": Recipe("wbc.tasks.look_at", "cost", lambda e, w: (
            _module("wbc.tasks.look_at").LookAtTask(e.mobile, "ee", gain=0.5, name="t",
                                                    **_arg(w)), {"t": [2.0, 1.0, 0.5]})),
        "DampingTask": Recipe("wbc.tasks.damping", "cost", lambda e, w: (
            _module("wbc.tasks.damping").DampingTask(e.mobile, name="t", **_arg(w)), {}),
            moves=False),  # pulls to zero, as the stack's damping does
        "JointVelocityTask": Recipe("wbc.tasks.joint_velocity", "cost", lambda e, w: (
            _module("wbc.tasks.joint_velocity").JointVelocityTask(e.mobile, name="t",
                                                                  **_arg(w)),
            {"t": np.linspace(-0.5, 0.5, e.mobile.nv)})),
        "LowAccelerationTask": Recipe("wbc.tasks.low_acceleration", "cost", lambda e, w: (
            _module("wbc.tasks.low_acceleration").LowAccelerationTask(e.mobile, name="t",
                                                                      **_arg(w)),
            {"t": np.linspace(0.5, -0.5, e.mobile.nv)})),
        "KineticEnergyRegularizationTask": Recipe("wbc.tasks.kinetic_energy", "cost",
                                                  lambda e, w: (
            _module("wbc.tasks.kinetic_energy").KineticEnergyRegularizationTask(
                e.mobile, name="t", **_arg(w)), {}), moves=False),  # pulls to zero too
        "JointCouplingTask": Recipe("wbc.tasks.joint_coupling", "cost", lambda e, w: (
            _module("wbc.tasks.joint_coupling").JointCouplingTask(
                e.mobile, joints=["gen3_joint_2", "gen3_joint_4"], ratios=[1.0, -1.0],
                gain=0.5, name="t", **_arg(w)), {})),
        # soft when added: the weight is the stack's
        "LinearConstraint": Recipe("wbc.tasks.linear", "stack", lambda e, w: (
            T.LinearConstraint(e.A, np.ones(4), np.full(4, 2.0), name="t"), {})),
        "DofFreezing": Recipe("wbc.tasks.dof_freezing", "stack", lambda e, w: (
            _module("wbc.tasks.dof_freezing").DofFreezing(e.mobile, [0, 1], form="equality",
                                                          name="t"), {}), moves=False),
        "PositionBarrier": Recipe("wbc.tasks.position_barrier", "stack", lambda e, w: (
            _module("wbc.tasks.position_barrier").PositionBarrier(
                e.mobile, "ee", p_min=e.pose()[:3, 3] + 0.02, name="t"), {})),
        "BodySphericalBarrier": Recipe("wbc.tasks.body_spherical_barrier", "stack",
                                       lambda e, w: (
            _module("wbc.tasks.body_spherical_barrier").BodySphericalBarrier(
                e.mobile, ["ee", "base"], d_min=5.0, name="t"), {})),
        "SafeDisplacement": Recipe("wbc.tasks.position_barrier", "stack", lambda e, w: (
            _module("wbc.tasks.position_barrier").SafeDisplacement(
                _module("wbc.tasks.position_barrier").PositionBarrier(
                    e.mobile, "ee", p_min=e.pose()[:3, 3] - 0.5, safe_displacement_gain=1.0,
                    name="barrier"), name="t"), {}), moves=False),
        "CollisionAvoidance": Recipe("wbc.tasks.collision", "stack", _collision, robot="panda",
                                     moves=False),
        # the papers' tasks (wbc.papers.*), kept in wbc.tasks under their old names
        "DexterousPosture": Recipe("wbc.papers.sorour.task_sharing", "stack", lambda e, w: (
            _module("wbc.papers.sorour.task_sharing").DexterousPosture(
                e.mobile, np.zeros(7), name="t"), {})),
        "FrictionUtilisation": Recipe("wbc.papers.omni.distribution_tasks", "stack",
                                      lambda e, w: (
            _module("wbc.papers.omni.distribution_tasks").FrictionUtilisation(4, name="t"),
            {}), variables=lambda r: wbc.Variables(tau=4), moves=False),
        "WheelWrench": Recipe("wbc.papers.omni.distribution_tasks", "stack", lambda e, w: (
            _module("wbc.papers.omni.distribution_tasks").WheelWrench(
                np.array([[1.0, 1.0, 0.2], [1.0, -1.0, -0.2], [-1.0, 1.0, 0.3],
                          [-1.0, -1.0, -0.3]]), name="t"), {"t.f_d": [1.0, 2.0, 0.5]}),
            variables=lambda r: wbc.Variables(tau=4)),
        "UtilisationBound": Recipe("wbc.papers.omni.distribution_tasks", "stack", lambda e, w: (
            _module("wbc.papers.omni.distribution_tasks").UtilisationBound(4, name="t"),
            {}), variables=lambda r: wbc.Variables(tau=4, t=1), moves=False),
        # hard only: variable bounds
        "Bounds": Recipe("wbc.tasks.linear", "hard", lambda e, w: (
            T.Bounds(-1.0, 1.0, name="t"), {})),
        "ConfigurationLimit": Recipe("wbc.tasks.limits", "hard", lambda e, w: (
            T.ConfigurationLimit(e.mobile, name="t"), {})),
        "VelocityLimit": Recipe("wbc.tasks.limits", "hard", lambda e, w: (
            T.VelocityLimit(e.mobile, name="t"), {})),
        "JointAccelerationLimit": Recipe("wbc.tasks.joint_acceleration", "hard", lambda e, w: (
            T.JointAccelerationLimit(e.mobile, DT, name="t"), {})),
        "AccelerationLimit": Recipe("wbc.tasks.acceleration_limit", "hard", lambda e, w: (
            _module("wbc.tasks.acceleration_limit").AccelerationLimit(e.mobile, a_max=10.0,
                                                                      name="t"), {})),
    }


def _collision(e, w):
    from wbc.robots.collision import CollisionModel, Obstacle
    from wbc.robots.resources import urdf_path

    hand = e.panda.frame_pose(e.q["panda"], "ee")[:3, 3]
    model = CollisionModel(e.panda, urdf=urdf_path("panda_description/urdf/panda.urdf"),
                           obstacles=[Obstacle.sphere("ball", 0.05, hand + [0.0, 0.0, 0.12])],
                           self_collision=False)
    return _module("wbc.tasks.collision").CollisionAvoidance(e.panda, model, name="t"), {}


def _module(name: str):
    return importlib.import_module(name)


RECIPES = _recipes()


def _exported_tasks() -> list[str]:
    """Every task class ``wbc.tasks.__all__`` names (papers' tasks included)."""
    names = []
    for name in wbc.tasks.__all__:
        value = getattr(wbc.tasks, name)
        if inspect.isclass(value) and issubclass(value, wbc.Task):
            names.append(name)
    return names


def test_every_exported_task_has_a_recipe():
    missing = [name for name in _exported_tasks() if name not in RECIPES]
    assert not missing, (f"wbc.tasks exports {missing} without a recipe in "
                         "tests/test_meaning_traps.py: add one (weight= must take a parameter)")


@pytest.fixture(scope="module")
def env():
    return Env()


def _command(env, recipe: Recipe, where: str, value: float, symbolic: bool):
    """One tick of a controller holding the recipe's task, weighted ``value`` — as a number, or
    through the stack parameter ``"w"`` set to ``value`` — at the task (``where="task"``) or at
    ``stack.add``."""
    robot = env.robot(recipe.robot)
    variables = (recipe.variables or (lambda r: wbc.Variables(v=r.nv)))(robot)
    stack = wbc.Stack(variables, damping=0.3)
    w = stack.parameter("w", 1, 1.0) if symbolic else value
    task, references = recipe.build(env, w if where == "task" else None)
    stack.add(task, weight=w if where == "stack" else 1.0)
    controller = wbc.Controller(robot, stack, backend="quadprog", dt=DT, fused=False,
                                jit=False, missing_limits="ignore")
    if symbolic:
        references = {**references, "w": value}
    command = controller.step(env.q[recipe.robot], **references)
    assert controller.last_solution.ok, controller.last_solution.message
    return command


def _all_recipes_to_run() -> list[str]:
    return sorted(set(_exported_tasks()) | set(RECIPES))


@pytest.mark.parametrize("name", _all_recipes_to_run())
def test_weight_takes_a_stack_parameter_on_every_task(env, name):
    if name not in RECIPES:
        pytest.fail(f"{name} has no recipe (see test_every_exported_task_has_a_recipe)")
    recipe = RECIPES[name]
    try:
        _module(recipe.module)
    except ImportError as err:  # a task another change has not brought yet
        if name in _exported_tasks():
            raise
        pytest.skip(f"{recipe.module} is not importable here: {err}")
    if recipe.kind == "hard":
        stack = wbc.Stack(wbc.Variables(v=env.mobile.nv))
        w = stack.parameter("w", 1, 1.0)
        task, _ = recipe.build(env, None)
        with pytest.raises(wbc.WbcError, match="bounds are hard; use stack.constrain"):
            stack.add(task, weight=w)
        return
    places = ["stack"] + (["task"] if recipe.kind == "cost" else [])
    if recipe.kind == "cost":  # the constructor documents and takes the weight
        cls = getattr(_module(recipe.module), name)
        assert "weight" in inspect.signature(cls).parameters
    for where in places:
        light = _command(env, recipe, where, 0.5, symbolic=True)
        heavy = _command(env, recipe, where, 3.0, symbolic=True)
        np.testing.assert_allclose(light, _command(env, recipe, where, 0.5, symbolic=False),
                                   rtol=0, atol=1e-9, err_msg=f"{name}, weight at {where}")
        np.testing.assert_allclose(heavy, _command(env, recipe, where, 3.0, symbolic=False),
                                   rtol=0, atol=1e-9, err_msg=f"{name}, weight at {where}")
        if recipe.moves:  # the per-tick weight really is a weight here
            assert np.abs(light - heavy).max() > 1e-6, f"{name}: the weight changed nothing"


def test_a_symbolic_weight_is_checked_where_it_is_given(mobile):
    import casadi as ca

    stack = wbc.Stack(wbc.Variables(v=mobile.nv))
    with pytest.raises(wbc.InvalidValueError, match=r"weight of task 'ee' uses CasADi "
                       r"symbols \['alien'\].*stack.parameter"):
        stack.add(FrameTask(mobile, "ee", weight=ca.SX.sym("alien"), name="ee"))
    assert "ee.target" not in stack.parameters  # refused: nothing declared
    with pytest.raises(wbc.NonAffineError, match="depends on the decision vector"):
        stack.add(FrameTask(mobile, "ee", name="ee"), weight=stack.variables.symbol[0])
    with pytest.raises(wbc.ShapeError, match="give per-row weights to the task"):
        stack.add(FrameTask(mobile, "ee", name="ee"), weight=np.ones(6))
    stack.add(FrameTask(mobile, "ee", weight=ca.DM([1, 1, 1, 2, 2, 2]), name="ee"),
              weight=ca.DM(0.5))  # CasADi numbers are numbers
