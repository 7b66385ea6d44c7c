"""Collision avoidance: distances and normal Jacobians (closed forms, finite differences), SRDF
pairs, static obstacles, errors, closed loops that must stay above ``d_min``, and pink's
``SelfCollisionBarrier`` on the same scenes."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
import wbc.robots
from wbc.errors import InvalidValueError, ModelLoadError, ShapeError, UnknownNameError
from wbc.robots.collision import INERT_DISTANCE, CollisionModel, Obstacle
from wbc.robots.fixed_base import FixedBaseRobot
from wbc.robots.resources import urdf_path
from wbc.sim import Simulation
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit
from wbc.tasks.collision import CollisionAvoidance

PANDA_URDF = urdf_path("panda_description/urdf/panda.urdf")
PANDA_SRDF = urdf_path("panda_description/srdf/panda.srdf")
DT = 0.01
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])  # "ready"
D_MIN = 0.02  # [m]
GAIN = 0.3
#: How far below d_min a closed loop may go [m]. The damper bounds the *linearised* distance
#: rate, so a tick can undershoot by the second-order remainder ½ Δqᵀ ∇²d Δq of the distance over
#: one step, which grows with the step: measured 4.3e-6 m in the simulated loops below (hand
#: gain 0.2) and 4.5e-5 m in the pink-matched loop into the base (gain 0.5, joints at their
#: velocity limits, Δq up to 0.026 rad a tick). 1e-4 m — a tenth of a millimetre, 0.5 % of
#: d_min — covers both and still catches a wrong sign or a wrong row (those go through d_min
#: by millimetres to centimetres: see the unconstrained runs and mink read per step).
LOOP_TOL = 1e-4
#: A wall 5 cm thick in front of the Panda, its face at x = 0.5 m.
WALL = Obstacle.box("wall", (0.05, 1.0, 1.0), np.array([[1.0, 0, 0, 0.525], [0, 1, 0, 0],
                                                        [0, 0, 1, 0.5], [0, 0, 0, 1]]))

# A two-joint arm whose only collision body is a sphere of 5 cm at its tip (frame "tip"),
# for closed-form distances to obstacles.
TIP_RADIUS = 0.05
ARM_URDF = """<?xml version="1.0"?>
<robot name="stick">
  <link name="root"/>
  <link name="upper"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01"
    iyz="0" izz="0.01"/></inertial></link>
  <link name="fore"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01"
    iyz="0" izz="0.01"/></inertial>
    <collision><origin xyz="0.4 0 0"/><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="root"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1"
    velocity="2"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="fore"/><child link="tip"/>
    <origin xyz="0.4 0 0"/></joint>
</robot>
"""


def pose(x: float, y: float, z: float, rotation=None) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    if rotation is not None:
        T[:3, :3] = rotation
    return T


@pytest.fixture(scope="module")
def stick_urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("stick") / "stick.urdf"
    path.write_text(ARM_URDF)
    return path


def panda_model(robot, **options) -> CollisionModel:
    return CollisionModel(robot, urdf=PANDA_URDF, **options)


def rates(model: CollisionModel, robot, q, v, eps: float = 1e-6) -> np.ndarray:
    """Central differences of every watched distance along ``v`` [m/s]."""
    robot.update(robot.integrate(q, v, eps))
    plus = model.compute().copy()
    robot.update(robot.integrate(q, v, -eps))
    minus = model.compute().copy()
    return (plus - minus) / (2 * eps)


def all_rows(model: CollisionModel, robot, q) -> tuple[np.ndarray, np.ndarray]:
    """Distances and rows of every pair, in pair order (k = n_pairs selects them all)."""
    robot.update(q)
    d, J = model.closest(model.n_pairs)
    return d.copy(), J.copy()


# ------------------------------------------------------------------ distances and Jacobians
@pytest.mark.parametrize("mounted", [False, True], ids=["fixed", "from_urdf_on_mecanum"])
def test_closed_form_distances_and_rows_to_a_sphere_a_box_and_a_capsule(stick_urdf, mounted):
    """A 5 cm sphere at the arm's tip against each obstacle: d and ḋ = J v in closed form
    (fixed base, and the same arm put on a mecanum base by ``from_urdf``: the rows then hold
    the base's columns, through S(q))."""
    if mounted:
        robot = wbc.robots.from_urdf(stick_urdf, base="mecanum", ee_frame="tip")
    else:
        robot = FixedBaseRobot(pin.buildModelFromUrdf(str(stick_urdf)), {"ee": "tip"})
    tilt = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    obstacles = [Obstacle.sphere("ball", 0.1, position=(0.2, 0.5, 0.4)),
                 Obstacle.box("crate", (0.2, 0.3, 0.4), pose(-0.5, 0.1, 0.2, tilt)),
                 Obstacle.capsule("pole", 0.04, 0.6, pose(0.1, -0.6, 0.3, tilt))]
    model = CollisionModel(robot, urdf=stick_urdf, obstacles=obstacles)
    assert model.pair_names == [("fore_0", "ball"), ("fore_0", "crate"), ("fore_0", "pole")]
    rng = np.random.default_rng(0)
    checked = 0
    while checked < 20:
        q = np.concatenate([rng.uniform(-0.3, 0.3, robot.nq - 2), rng.uniform(-2.5, 2.5, 2)])
        c = robot.frame_pose(q, "tip")[:3, 3]
        J_c = robot.frame_jacobian(q, "tip")[:3]  # per unit v: S(q) included
        # closest points of each obstacle to the sphere's centre, in the world
        ball = np.array([0.2, 0.5, 0.4])
        local = tilt.T @ (c - np.array([-0.5, 0.1, 0.2]))
        crate = np.array([-0.5, 0.1, 0.2]) + tilt @ np.clip(local, [-0.1, -0.15, -0.2],
                                                            [0.1, 0.15, 0.2])
        axis_point = tilt.T @ (c - np.array([0.1, -0.6, 0.3]))
        pole = np.array([0.1, -0.6, 0.3]) + tilt @ np.array([0, 0, np.clip(axis_point[2],
                                                                          -0.3, 0.3)])
        if np.linalg.norm(c - crate) < 1e-3:  # the centre inside the box: no closed form here
            continue
        expected = np.array([np.linalg.norm(c - ball) - TIP_RADIUS - 0.1,
                             np.linalg.norm(c - crate) - TIP_RADIUS,
                             np.linalg.norm(c - pole) - TIP_RADIUS - 0.04])
        rows = np.array([(c - p) / np.linalg.norm(c - p) @ J_c for p in (ball, crate, pole)])
        d, J = all_rows(model, robot, q)
        np.testing.assert_allclose(d, expected, atol=1e-8)
        np.testing.assert_allclose(J, rows, atol=1e-7)
        checked += 1


def test_rows_are_distance_rates_on_the_panda_hulls():
    """ḋ = J v against central differences (step 1e-6), every pair — penetrating ones
    included — of 20 random configurations (measured: 2.5e-9 at worst over 60 of them)."""
    robot = wbc.robots.load_panda()
    model = panda_model(robot, srdf=PANDA_SRDF, obstacles=[WALL])
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.uniform(robot.limits.q_lower, robot.limits.q_upper)
        v = rng.standard_normal(robot.nv)
        d, J = all_rows(model, robot, q)
        np.testing.assert_allclose(J @ v, rates(model, robot, q, v), atol=1e-7)


def test_rows_include_the_base_of_a_mobile_manipulator():
    """tiago_panda: the Panda's URDF geometry mapped onto the whole-body model; rows per unit
    of the base's own (v, ω) through S(q), checked by moving along the base's arc."""
    robot = wbc.robots.load("tiago_panda")
    wall = Obstacle.box("wall", (0.05, 2.0, 2.0), pose(0.9, 0.0, 1.0))
    model = panda_model(robot, srdf=PANDA_SRDF, obstacles=[wall])
    rng = np.random.default_rng(2)
    for _ in range(20):
        q = robot.neutral() + 0.3 * rng.standard_normal(robot.nq)
        v = rng.standard_normal(robot.nv)
        d, J = all_rows(model, robot, q)
        np.testing.assert_allclose(J @ v, rates(model, robot, q, v), atol=1e-7)
        assert np.abs(J[:, :2]).max() > 0  # the base moves the arm's bodies


def test_the_k_closest_pairs_are_selected_and_extra_rows_are_inert():
    robot = wbc.robots.load_panda()
    model = panda_model(robot, obstacles=[WALL], self_collision=False)
    assert model.n_pairs == 16  # the wall against each of the 16 robot bodies but link0's ...
    robot.update(Q0)
    everything = model.compute().copy()
    d, J = model.closest(3)
    np.testing.assert_array_equal(np.sort(d), np.sort(everything)[:3])
    d, J = model.closest(20)
    np.testing.assert_array_equal(d[:16], everything)
    assert (d[16:] == INERT_DISTANCE).all() and (J[16:] == 0).all()


# ------------------------------------------------------------------------------------ pairs
def test_srdf_disabled_pairs_are_left_out():
    robot = wbc.robots.load_panda()
    with_srdf = set(panda_model(robot, srdf=PANDA_SRDF).pair_names)
    without = set(panda_model(robot).pair_names)
    assert ("panda_link0_0", "panda_link2_0") in without  # "Never" in the SRDF
    assert ("panda_link0_0", "panda_link2_0") not in with_srdf
    assert ("panda_link0_0", "panda_link5_0") in with_srdf
    assert len(with_srdf) == 44 and with_srdf < without
    # adjacent links and the hand with its (locked) fingers never appear
    for pairs in (with_srdf, without):
        assert ("panda_link3_0", "panda_link4_0") not in pairs
        assert not any("hand" in a and "finger" in b for a, b in pairs)


def test_the_robots_own_urdf_is_the_default():
    robot = wbc.robots.load_panda()
    if getattr(robot, "urdf_path", None) is None:
        pytest.skip("this wbc's robots do not record their URDF")
    assert CollisionModel(robot, srdf=PANDA_SRDF).pair_names == \
        panda_model(robot, srdf=PANDA_SRDF).pair_names


def test_listed_pairs_by_link_geometry_and_obstacle_names():
    robot = wbc.robots.load_panda()
    model = panda_model(robot, obstacles=[WALL],
                        pairs=[("panda_hand", "panda_link0"), ("panda_leftfinger", "wall"),
                               ("panda_link7_0", "wall")])
    assert model.pair_names == [("panda_link0_0", "panda_hand_0"),
                                *[(f"panda_leftfinger_{i}", "wall") for i in range(4)],
                                ("panda_link7_0", "wall")]


# ----------------------------------------------------------------------------------- errors
def test_bad_inputs_raise_clear_errors(stick_urdf, tmp_path):
    robot = wbc.robots.load_panda()
    with pytest.raises(UnknownNameError, match="unknown name 'panda_tail'"):
        panda_model(robot, pairs=[("panda_hand", "panda_tail")])
    model = panda_model(robot, srdf=PANDA_SRDF)
    with pytest.raises(InvalidValueError, match="d_min"):
        CollisionAvoidance(robot, model, d_min=-0.01)
    with pytest.raises(InvalidValueError, match="max_pairs"):
        CollisionAvoidance(robot, model, max_pairs=0)
    with pytest.raises(InvalidValueError, match="gain"):
        CollisionAvoidance(robot, model, gain=1.5)
    with pytest.raises(InvalidValueError, match="collision model"):
        CollisionAvoidance(robot, "self")
    with pytest.raises(InvalidValueError, match="another robot"):
        CollisionAvoidance(wbc.robots.load_panda(), model)
    # robots without collision geometry
    bare = tmp_path / "bare.urdf"
    bare.write_text(ARM_URDF.replace(
        '<collision><origin xyz="0.4 0 0"/><geometry><sphere radius="0.05"/></geometry>'
        '</collision>', ""))
    stick = FixedBaseRobot(pin.buildModelFromUrdf(str(bare)), {"ee": "tip"})
    with pytest.raises(ModelLoadError, match="no <collision> geometry"):
        CollisionModel(stick, urdf=bare)
    built_in_code = wbc.robots.load("mpo700_lwr4")  # the LWR from published parameters
    if getattr(built_in_code, "urdf_path", None) is None:
        with pytest.raises(ModelLoadError, match="no collision geometry"):
            CollisionModel(built_in_code)
    with pytest.raises(ModelLoadError, match="does not exist"):
        CollisionModel(robot, urdf=tmp_path / "missing.urdf")
    with pytest.raises(UnknownNameError, match="no body frame"):
        CollisionModel(robot, urdf=stick_urdf)  # another robot's URDF
    with pytest.raises(InvalidValueError, match="size of box"):
        Obstacle.box("b", (0.1, -0.1, 0.1), np.eye(4))
    with pytest.raises(ShapeError):
        Obstacle.box("b", (0.1, 0.1), np.eye(4))
    with pytest.raises(InvalidValueError, match="homogeneous"):
        Obstacle.sphere("s", 0.1, pose=np.full((4, 4), 0.5))
    with pytest.raises(InvalidValueError, match="unique"):
        panda_model(robot, obstacles=[WALL, WALL])
    with pytest.raises(InvalidValueError, match="no pair"):
        panda_model(robot, pairs=[("panda_hand", "panda_leftfinger")])  # rigidly attached


# ------------------------------------------------------------------------------ closed loops
def build_controller(robot, model, collision: bool = True, **options) -> wbc.Controller:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.2, name="ee"))
    stack.add(PostureTask(robot, gain=0.1, weight=1e-3, name="posture"))
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    if collision:
        stack.constrain(CollisionAvoidance(robot, model, d_min=D_MIN, gain=GAIN, max_pairs=4,
                                           name="collision"))
    return wbc.Controller(robot, stack, dt=DT, **options)


def scene(robot, which: str) -> tuple[CollisionModel, np.ndarray]:
    """The collision model and the hand's target: into the robot's own base (a point inside
    link0), or through the wall (10 cm behind its face)."""
    hand = robot.frame_pose(Q0, "ee")
    target = hand.copy()
    if which == "base":
        target[:3, 3] = (0.0, 0.0, 0.05)
        return panda_model(robot, srdf=PANDA_SRDF), target
    target[:3, 3] = (0.6, 0.0, 0.5)
    return panda_model(robot, obstacles=[WALL], self_collision=False), target


@pytest.mark.parametrize("which", ["base", "wall"])
def test_closed_loop_stays_above_d_min_on_both_paths(which):
    robot = wbc.robots.load_panda()
    model, target = scene(robot, which)
    finals = []
    for fused in (True, False):
        controller = build_controller(robot, model, fused=fused, jit=False)
        assert controller.fused is fused
        run = Simulation(robot, controller, dt=DT).run(seconds=3.0, q0=Q0,
                                                       references={"ee": target})
        assert all(status == "solved" for status in run.status)
        closest = np.array([model.min_distance(q) for q in run.q])
        assert closest.min() >= D_MIN - LOOP_TOL
        assert closest[-1] < D_MIN + 1e-3  # pressed against it: the constraint did the work
        finals.append(run.q[-1])
    np.testing.assert_allclose(finals[0], finals[1], atol=1e-6)  # fused = ordinary path
    # without the constraint the same loop goes through (the scene tests something)
    free = build_controller(robot, model, collision=False, fused=False, jit=False)
    run = Simulation(robot, free, dt=DT).run(seconds=3.0, q0=Q0, references={"ee": target})
    assert min(model.min_distance(q) for q in run.q) < 0.0


# ------------------------------------------------------------------------------------- pink
PINK_DAMPING = 1e-12  # pink's default; wbc ρ = √damping
PINK_POSTURE_COST = 1e-2  # wbc weight = cost²


def pink_problem(robot, model: CollisionModel, k: int):
    """pink's solve_ik on the same geometry and pairs: frame and posture tasks, both limits,
    SelfCollisionBarrier with gain γ = GAIN / dt [1/s] and no safe-displacement cost."""
    pink = pytest.importorskip("pink")
    from pink.barriers import SelfCollisionBarrier
    from pink.limits import ConfigurationLimit as PinkConfigurationLimit
    from pink.limits import VelocityLimit as PinkVelocityLimit
    from pink.tasks import FrameTask as PinkFrameTask
    from pink.tasks import PostureTask as PinkPostureTask

    geometry_data = pin.GeometryData(model.geometry)
    for request in geometry_data.distanceRequests:  # the tolerances wbc's model uses
        request.gjk_tolerance = request.epa_tolerance = 1e-9
    configuration = pink.Configuration(robot.model, robot.model.createData(), Q0.copy(),
                                       collision_model=model.geometry,
                                       collision_data=geometry_data)
    frame = PinkFrameTask("panda_hand", position_cost=1.0, orientation_cost=1.0, gain=0.5)
    posture = PinkPostureTask(cost=PINK_POSTURE_COST, gain=0.5)
    posture.set_target(Q0.copy())
    limits = [PinkConfigurationLimit(robot.model, 0.5), PinkVelocityLimit(robot.model)]

    def tick(q, target):
        # a new barrier each tick: pink's caches its rows while q stays np.allclose to the
        # cached q (rtol 1e-5), so near rest it would reuse an earlier tick's rows
        barrier = SelfCollisionBarrier(n_collision_pairs=k, gain=GAIN / DT,
                                       safe_displacement_gain=0.0, d_min=D_MIN)
        configuration.update(q)
        frame.set_target(pin.SE3(target[:3, :3].copy(), target[:3, 3].copy()))
        return pink.solve_ik(configuration, [frame, posture], DT, solver="quadprog",
                             damping=PINK_DAMPING, limits=limits, barriers=[barrier],
                             safety_break=False)

    return tick


def wbc_problem(robot, model: CollisionModel, k: int) -> wbc.Controller:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(PINK_DAMPING))
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=PINK_POSTURE_COST ** 2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    stack.constrain(CollisionAvoidance(robot, model, d_min=D_MIN, gain=GAIN, max_pairs=k,
                                       name="collision"))
    controller = wbc.Controller(robot, stack, backend="quadprog", dt=DT, jit=False)
    controller.set_references(posture=Q0)
    return controller


def referee(robot, controller: wbc.Controller) -> wbc.Controller:
    """The same stack on daqp, tight, the ordinary path: the exact answer the README's peer
    comparisons refer to (another active-set solver than both sides' quadprog)."""
    judge = wbc.Controller(robot, controller.stack, backend="daqp", profile="tight", dt=DT,
                           fused=False, jit=False)
    judge.set_references(posture=Q0)
    return judge


def assert_as_good_as_pink(v_wbc, v_pink, exact, tol: float = 1e-8) -> None:
    """The two commands agree to ``tol``, or — where they differ more — wbc's is the one at
    the exact answer (the README's criterion for the peers)."""
    if np.abs(v_wbc - v_pink).max() > tol:
        assert np.abs(v_wbc - exact).max() <= max(tol, np.abs(v_pink - exact).max())


@pytest.mark.parametrize("which", ["base", "wall"])
def test_pink_self_collision_barrier_gives_the_same_loop(which):
    """Same scene, geometry and pairs, two independent closed loops: the same closest
    distances and final hand poses. (Commands differ by up to 1e-5 rad/s on ticks where three
    velocity bounds are active: pink's quadprog on its Δq problem; wbc's matches the exact
    answer there, see the next test.)"""
    robot = wbc.robots.load_panda()
    model, target = scene(robot, which)
    k = 4
    pink_tick = pink_problem(robot, model, k)
    controller = wbc_problem(robot, model, k)
    q_wbc, q_pink = Q0.copy(), Q0.copy()
    closest_wbc, closest_pink, command_gap = [], [], 0.0
    for _ in range(250):
        v_wbc = controller.step(q_wbc, ee=target)
        v_pink = pink_tick(q_pink, target)
        command_gap = max(command_gap, np.abs(v_wbc - v_pink).max())
        q_wbc, q_pink = q_wbc + DT * v_wbc, q_pink + DT * v_pink
        closest_wbc.append(model.min_distance(q_wbc))
        closest_pink.append(model.min_distance(q_pink))
    assert command_gap < 1e-4
    assert min(closest_wbc) >= D_MIN - LOOP_TOL
    assert closest_wbc[-1] < D_MIN + 1e-6  # held at d_min, the target out of reach
    assert abs(min(closest_wbc) - min(closest_pink)) < 1e-9
    np.testing.assert_allclose(robot.frame_pose(q_wbc, "ee"), robot.frame_pose(q_pink, "ee"),
                               atol=1e-9)


def test_pink_agrees_on_random_states():
    """20 random states within 6 cm of a collision, targets behind the wall or in the base, one
    tick each: the two commands to 1e-8 rad/s, or wbc's at the exact answer where they
    differ."""
    robot = wbc.robots.load_panda()
    model = panda_model(robot, srdf=PANDA_SRDF, obstacles=[WALL])
    k = 6
    pink_tick = pink_problem(robot, model, k)
    controller = wbc_problem(robot, model, k)
    judge = referee(robot, controller)
    rng = np.random.default_rng(3)
    active = 0
    states = 0
    while states < 20:
        q = np.clip(Q0 + 0.6 * rng.standard_normal(7), robot.limits.q_lower + 0.05,
                    robot.limits.q_upper - 0.05)
        if not D_MIN < model.min_distance(q) < 0.06:  # near a collision, not in one
            continue
        states += 1
        target = robot.frame_pose(q, "ee").copy()  # behind the wall, or in the base
        target[:3, 3] = rng.normal((0.7, 0.0, 0.5) if states % 2 else (0.0, 0.0, 0.05), 0.1)
        v_wbc = controller.step(q, ee=target)
        v_pink = pink_tick(q, target)
        exact = judge.step(q, ee=target)
        assert np.abs(v_wbc - exact).max() < 1e-8
        assert_as_good_as_pink(v_wbc, v_pink, exact)
        robot.update(q)
        d, J = model.closest(k)
        active += np.any(-J @ v_wbc >= GAIN * (d - D_MIN) / DT - 1e-9)
    assert active >= 5  # the collision rows bind on a good share of them


def test_pink_rows_equal_ours_apart_and_opposite_when_overlapping():
    """pink's barrier row for the closest pair is ours while the bodies are apart, and its
    negative when they overlap (its normal points from b to a: the module doc's caveat)."""
    pink = pytest.importorskip("pink")
    from pink.barriers import SelfCollisionBarrier

    robot = wbc.robots.load_panda()
    model = panda_model(robot, srdf=PANDA_SRDF)
    rng = np.random.default_rng(4)
    seen = {True: 0, False: 0}
    while min(seen.values()) < 3:
        q = rng.uniform(robot.limits.q_lower, robot.limits.q_upper)
        robot.update(q)
        d, J = model.closest(1)
        configuration = pink.Configuration(robot.model, robot.model.createData(), q,
                                           collision_model=model.geometry,
                                           collision_data=pin.GeometryData(model.geometry))
        barrier = SelfCollisionBarrier(1, d_min=0.0)
        np.testing.assert_allclose(barrier.compute_barrier(configuration), d, atol=1e-6)
        apart = bool(d[0] > 1e-3)
        np.testing.assert_allclose(barrier.compute_jacobian(configuration),
                                   J if apart else -J, atol=1e-6)
        seen[apart] += 1


def test_the_example_runs_and_stops_at_the_wall():
    import runpy
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "collision_avoidance.py"
    result = runpy.run_path(str(path), run_name="example")["main"](["--seconds", "1.5"])
    assert result["without"]["min_distance_m"] < 0  # through the wall
    assert result["with"]["min_distance_m"] >= D_MIN - LOOP_TOL
    assert result["with"]["failed"] == 0 and result["with"]["ticks"] > 100


# ------------------------------------------------------------------------------------- mink
def mujoco_wall_scene():
    """MuJoCo model of the same scene: wbc's Panda URDF with its collision meshes (MuJoCo
    collides meshes as their convex hulls too), fingers fixed closed as in ``load_panda``, and
    the wall as a box geom of the world."""
    import xml.etree.ElementTree as ET

    mujoco = pytest.importorskip("mujoco")
    from wbc.robots.resources import robots_dir

    root = ET.parse(PANDA_URDF).getroot()
    for link in root.findall("link"):
        for element in link.findall("visual"):
            link.remove(element)
        for mesh in link.iter("mesh"):
            mesh.set("filename", mesh.get("filename").replace(
                "package://example-robot-data/robots", str(robots_dir())))
    for joint in root.findall("joint"):
        if joint.get("name") in ("panda_finger_joint1", "panda_finger_joint2"):
            joint.set("type", "fixed")
            for tag in ("limit", "axis", "mimic", "dynamics", "safety_controller"):
                for element in joint.findall(tag):
                    joint.remove(element)
    ET.SubElement(ET.SubElement(root, "mujoco"), "compiler", discardvisual="true",
                  fusestatic="false", autolimits="true", angle="radian")
    spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    wall = spec.worldbody.add_geom()
    wall.name, wall.type = "wall", mujoco.mjtGeom.mjGEOM_BOX
    wall.size, wall.pos = [0.025, 0.5, 0.5], [0.525, 0.0, 0.5]
    return spec.compile()


def test_mink_collision_avoidance_limit_on_the_wall():
    """mink's CollisionAvoidanceLimit on the same wall. mink's QP is over Δq = v·dt but its
    bound is ``gain (d − d_min) / dt``: per tick the gap may close by ``gain / dt`` of itself,
    so mink's gain g is wbc's g / dt. Matched (g = GAIN·dt), the two loops end at the same hand
    pose and closest distance, wbc's command being the exact answer (daqp) at every tick; read
    as its docstring reads (g = GAIN per step), mink goes through d_min by millimetres."""
    mink = pytest.importorskip("mink")
    m = mujoco_wall_scene()
    robot = wbc.robots.load_panda()
    model, target = scene(robot, "wall")
    names = [m.joint(i).name for i in range(m.njnt)]
    assert names == [f"panda_joint{i}" for i in range(1, 8)]
    robot_geoms = [i for i in range(m.ngeom) if m.geom_bodyid[i] != 0]

    def mink_loop(gain: float):
        limit = mink.CollisionAvoidanceLimit(m, [(robot_geoms, ["wall"])], gain=gain,
                                             minimum_distance_from_collisions=D_MIN,
                                             collision_detection_distance=10.0)
        configuration = mink.Configuration(m, Q0.copy())
        frame = mink.FrameTask("panda_hand", "body", position_cost=1.0, orientation_cost=1.0,
                               gain=0.5)
        frame.set_target(mink.SE3.from_matrix(target))
        posture = mink.PostureTask(m, cost=PINK_POSTURE_COST, gain=0.5)
        posture.set_target(Q0.copy())
        limits = [mink.ConfigurationLimit(m, gain=0.5),
                  mink.VelocityLimit(m, dict(zip(names, robot.model.velocityLimit,
                                                 strict=True))), limit]
        q, closest = Q0.copy(), []
        for _ in range(250):
            configuration.update(q)
            q = q + DT * mink.solve_ik(configuration, [frame, posture], DT, solver="quadprog",
                                       damping=PINK_DAMPING, limits=limits)
            closest.append(model.min_distance(q))
        return q, closest

    controller = wbc_problem(robot, model, model.n_pairs)  # every pair, as mink
    judge = referee(robot, controller)
    q, closest = Q0.copy(), []
    for _ in range(250):
        v = controller.step(q, ee=target)
        assert np.abs(v - judge.step(q, ee=target)).max() < 1e-8
        q = q + DT * v
        closest.append(model.min_distance(q))
    q_mink, closest_mink = mink_loop(GAIN * DT)
    assert min(closest) >= D_MIN - LOOP_TOL
    assert abs(min(closest) - min(closest_mink)) < 1e-6
    np.testing.assert_allclose(robot.frame_pose(q, "ee"), robot.frame_pose(q_mink, "ee"),
                               atol=1e-6)
    _, naive = mink_loop(GAIN)
    assert min(naive) < D_MIN - 1e-3
