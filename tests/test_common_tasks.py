"""The common tasks of pink and mink in wbc.tasks — RelativeFrameTask, DampingTask,
JointVelocityTask, LowAccelerationTask, JointCouplingTask, DofFreezing,
KineticEnergyRegularizationTask — and the model quantity ``"M"``: closed forms on random
instances, finite differences, each task's solution against its peer's (pink 4.4 / mink 1.3
solving the same problem with quadprog) at 20 random states of the Panda, and bad inputs."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

import wbc
import wbc.robots
from wbc.errors import InvalidValueError, ShapeError, UnknownNameError, WbcError
from wbc.robots.fixed_base import load_panda
from wbc.tasks.damping import DampingTask
from wbc.tasks.dof_freezing import DofFreezing
from wbc.tasks.frame import FrameTask
from wbc.tasks.joint_coupling import JointCouplingTask
from wbc.tasks.joint_velocity import JointVelocityTask
from wbc.tasks.kinetic_energy import KineticEnergyRegularizationTask, cholesky_factor
from wbc.tasks.linear import LinearTask
from wbc.tasks.low_acceleration import LowAccelerationTask
from wbc.tasks.relative_frame import RelativeFrameTask, relative_pose_and_jacobian

DT = 0.01
STATES = 20  # random states per comparison with a peer
TOL = 1e-8  # |v_wbc − v_peer|∞ [rad/s], both QPs solved by quadprog
PEER_DAMPING = 1e-6  # pink's / mink's `damping` d, wbc's ρ² (so ρ = 1e-3)
RHO = np.sqrt(PEER_DAMPING)
HAND, ROOT = "panda_hand", "panda_link3"  # frame and root of the relative-frame tests
SEED = 11


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def random_q(robot, rng):
    lo, up = robot.limits.q_lower, robot.limits.q_upper
    return lo + (up - lo) * rng.uniform(0.1, 0.9, robot.nq)


def random_rotation(rng, angle):
    axis = rng.standard_normal(3)
    return pin.exp3(axis / np.linalg.norm(axis) * angle)


def perturbed(T, rng, angle=0.4, distance=0.1):
    """``T`` turned by ``angle`` [rad] about a random axis and moved by ~``distance`` [m]."""
    T = T.copy()
    T[:3, :3] = T[:3, :3] @ random_rotation(rng, angle)
    T[:3, 3] += distance * rng.standard_normal(3)
    return T


def stack_of(robot, *tasks, damping=RHO):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=damping)
    for task in tasks:
        stack.add(task)
    return stack


def controller(robot, stack):
    return wbc.Controller(robot, stack, backend="quadprog", dt=DT, jit=False,
                          missing_limits="ignore", fallback="raise")


def relative_pose(robot, q, frame=HAND, root=ROOT):
    return np.linalg.solve(robot.frame_pose(q, root), robot.frame_pose(q, frame))


def pink_solve(robot, q, tasks, constraints=None):
    pink = pytest.importorskip("pink")
    configuration = pink.Configuration(robot.model, robot.model.createData(), q)
    return pink.solve_ik(configuration, tasks, DT, solver="quadprog", damping=PEER_DAMPING,
                         limits=[], constraints=constraints)


@pytest.fixture(scope="module")
def mink_side():
    """mink, the MuJoCo Panda of the mink comparison (its hand pose, Jacobians and mass
    matrix equal pinocchio's: tests/test_vs_mink.py, and the "M" test below) and a
    configuration of it."""
    mink = pytest.importorskip("mink")
    from wbc.experiments.peers.vs_mink import mujoco_panda

    model = mujoco_panda()
    return mink, model, mink.Configuration(model)


def mink_solve(mink_side, q, tasks, constraints=None):
    mink, _, configuration = mink_side
    configuration.update(q)
    return mink.solve_ik(configuration, tasks, DT, "quadprog", damping=PEER_DAMPING, limits=[],
                         constraints=constraints)


def numeric_stack(robot, A, b, *tasks, damping=1e-3):
    """A workspace of ``LinearTask(A, b)`` plus ``tasks`` over ``v`` (no controller)."""
    stack = stack_of(robot, LinearTask(A, b, name="lin"), *tasks, damping=damping)
    return stack.workspace("quadprog")


# ---------------------------------------------------------------------------- RelativeFrameTask
def test_relative_pose_error_and_jacobian_against_pinocchio_and_finite_differences(robot):
    """``P = T_r⁻¹ T_f`` equals pinocchio's; ``e = log6(P⁻¹ T_t)`` equals pinocchio's log; and
    ``de/dt = −J_e v`` by central differences along random ``v``."""
    from wbc.lie import pose_error_world_jacobian

    sym = {k: ca.SX.sym(k, *s) for k, s in
           (("Tf", (4, 4)), ("Tr", (4, 4)), ("Jf", (6, 7)), ("Jr", (6, 7)), ("Tt", (4, 4)))}
    P, J_rel = relative_pose_and_jacobian(sym["Tf"], sym["Tr"], sym["Jf"], sym["Jr"])
    e, J_e = pose_error_world_jacobian(P, sym["Tt"], J_rel)
    fn = ca.Function("rel", list(sym.values()), [P, e, J_e])
    rng = np.random.default_rng(SEED)
    h = 1e-6
    for _ in range(10):
        q, v = random_q(robot, rng), rng.standard_normal(robot.nv)
        target = perturbed(relative_pose(robot, q), rng)

        def evaluate(x, target=target):
            return [np.array(o) for o in fn(robot.frame_pose(x, HAND), robot.frame_pose(x, ROOT),
                                             robot.frame_jacobian(x, HAND),
                                             robot.frame_jacobian(x, ROOT), target)]

        P_q, e_q, J_q = evaluate(q)
        np.testing.assert_allclose(P_q, relative_pose(robot, q), atol=1e-14)
        np.testing.assert_allclose(e_q.ravel(), pin.log6(pin.SE3(P_q).actInv(pin.SE3(target)))
                                   .vector, atol=1e-12)
        rate = (evaluate(q + h * v)[1] - evaluate(q - h * v)[1]).ravel() / (2 * h)
        np.testing.assert_allclose(rate, -J_q @ v, atol=1e-6)


def test_relative_pose_on_a_mobile_base_ignores_the_base():
    """The hand's pose in the arm's mounting link of a mobile manipulator does not depend on the
    base's motion: the base columns of ``J_e`` vanish, and ``de/dt = −J_e v`` holds for a move
    of base and arm together (the base's arc integrated exactly)."""
    mobile = wbc.robots.load("tiago_panda")
    task = RelativeFrameTask(mobile, "ee", "panda_link0", name="rel")
    stack = stack_of(mobile, task)
    names = ("pose[ee]", "pose[panda_link0]", "J[ee]", "J[panda_link0]", "rel.target")
    fn = ca.Function("rel", [stack.parameters[k].symbol for k in names],
                     [task.error, task.jacobian])
    base = mobile.nv - mobile.n_arm
    rng = np.random.default_rng(SEED)
    h = 1e-6
    for _ in range(5):
        q, v = mobile.random_configuration(rng), rng.standard_normal(mobile.nv)
        target = perturbed(relative_pose(mobile, q, "ee", "panda_link0"), rng)

        def error(x, target=target):  # e = log6(P⁻¹ T_t)
            P = pin.SE3(relative_pose(mobile, x, "ee", "panda_link0"))
            return pin.log6(P.actInv(pin.SE3(target))).vector

        e, J_e = (np.array(o) for o in fn(
            mobile.frame_pose(q, "ee"), mobile.frame_pose(q, "panda_link0"),
            mobile.frame_jacobian(q, "ee"), mobile.frame_jacobian(q, "panda_link0"), target))
        np.testing.assert_allclose(e.ravel(), error(q), atol=1e-12)
        assert np.abs(J_e[:, :base]).max() < 1e-12 < np.abs(J_e[:, base:]).max()
        rate = (error(mobile.integrate(q, v, h)) - error(mobile.integrate(q, v, -h))) / (2 * h)
        np.testing.assert_allclose(rate, -J_e @ v, atol=1e-6)


def test_relative_frame_task_equals_pinks_at_random_states(robot):
    pytest.importorskip("pink")
    from pink.tasks import RelativeFrameTask as PinkRelativeFrameTask

    cost_p, cost_o, gain, lm = 1.5, 0.5, 0.7, 0.3
    task = RelativeFrameTask(robot, HAND, ROOT, gain=gain, lm_damping=lm, name="rel",
                             weight=[cost_p ** 2] * 3 + [cost_o ** 2] * 3)
    ctrl = controller(robot, stack_of(robot, task))
    peer = PinkRelativeFrameTask(HAND, ROOT, position_cost=cost_p, orientation_cost=cost_o,
                                 gain=gain, lm_damping=lm)
    rng = np.random.default_rng(SEED)
    worst = 0.0
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(relative_pose(robot, q), rng)
        peer.set_target(pin.SE3(target))
        v_peer = pink_solve(robot, q, [peer])
        v = ctrl.step(q, rel=target)
        worst = max(worst, np.abs(v - v_peer).max())
        assert np.abs(v_peer).max() > 1e-2  # a real motion, not two zeros
    assert worst <= TOL, worst


def test_relative_frame_task_equals_minks_at_random_states(robot, mink_side):
    mink = mink_side[0]
    cost_p, cost_o, gain, lm = 1.0, 0.8, 0.5, 0.2
    task = RelativeFrameTask(robot, HAND, ROOT, gain=gain, lm_damping=lm, name="rel",
                             weight=[cost_p ** 2] * 3 + [cost_o ** 2] * 3)
    ctrl = controller(robot, stack_of(robot, task))
    peer = mink.RelativeFrameTask(HAND, "body", ROOT, "body", position_cost=cost_p,
                                  orientation_cost=cost_o, gain=gain, lm_damping=lm)
    rng = np.random.default_rng(SEED + 1)
    worst = 0.0
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(relative_pose(robot, q), rng)
        peer.set_target(mink.SE3.from_matrix(target))
        v_peer = mink_solve(mink_side, q, [peer])
        worst = max(worst, np.abs(ctrl.step(q, rel=target) - v_peer).max())
    assert worst <= TOL, worst


def test_relative_frame_task_reaches_a_reachable_relative_pose(robot):
    """A closed loop (gain 0.5) brings the hand's pose in link 3 to that of another
    configuration: the position to < 1e-6 m and the rotation to < 1e-6 rad."""
    rng = np.random.default_rng(SEED + 2)
    q, q_goal = random_q(robot, rng), random_q(robot, rng)
    q_goal = q + 0.3 * (q_goal - q)
    target = relative_pose(robot, q_goal)
    ctrl = controller(robot, stack_of(robot, RelativeFrameTask(robot, HAND, ROOT, gain=0.5,
                                                               name="rel")))
    for _ in range(80):
        q = robot.integrate(q, ctrl.step(q, rel=target), DT)
    error = pin.log6(pin.SE3(relative_pose(robot, q)).actInv(pin.SE3(target))).vector
    assert np.abs(error).max() < 1e-6, error
    assert ctrl.last_solution.residuals["rel"].shape == (6,)


# ---------------------------------------------------------------------------- DampingTask
def test_damping_task_is_a_per_joint_ridge(robot):
    rng = np.random.default_rng(SEED)
    for _ in range(10):
        A, b = rng.standard_normal((4, robot.nv)), rng.standard_normal(4)
        w = rng.uniform(0.0, 2.0, robot.nv)
        w[rng.integers(robot.nv)] = 0.0  # a coordinate left free
        x = numeric_stack(robot, A, b, DampingTask(robot, w, name="damp")).solve().x
        expected = np.linalg.solve(A.T @ A + np.diag(w) + 1e-6 * np.eye(robot.nv), A.T @ b)
        np.testing.assert_allclose(x, expected, atol=1e-9)


def test_damping_task_equals_pinks_and_minks_at_random_states(robot, mink_side):
    pink = pytest.importorskip("pink")
    mink = mink_side[0]
    gain, scalar = 0.6, 0.3
    per_joint = np.linspace(0.1, 0.7, robot.nv)
    stacks = {}
    for label, cost in (("pink", scalar), ("mink", per_joint)):
        weight = np.asarray(cost) ** 2
        stacks[label] = controller(robot, stack_of(
            robot, FrameTask(robot, HAND, gain=gain, name="ee"),
            DampingTask(robot, weight, name="damp")))
    pink_tasks = [pink.tasks.FrameTask(HAND, position_cost=1.0, orientation_cost=1.0, gain=gain),
                  pink.tasks.DampingTask(cost=scalar)]
    mink_tasks = [mink.FrameTask(HAND, "body", position_cost=1.0, orientation_cost=1.0,
                                 gain=gain), mink.DampingTask(mink_side[1], per_joint)]
    rng = np.random.default_rng(SEED + 3)
    worst = {"pink": 0.0, "mink": 0.0}
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(robot.frame_pose(q, HAND), rng)
        pink_tasks[0].set_target(pin.SE3(target))
        mink_tasks[0].set_target(mink.SE3.from_matrix(target))
        peers = {"pink": pink_solve(robot, q, pink_tasks),
                 "mink": mink_solve(mink_side, q, mink_tasks)}
        for label, v_peer in peers.items():
            worst[label] = max(worst[label], np.abs(stacks[label].step(q, ee=target)
                                                    - v_peer).max())
    assert max(worst.values()) <= TOL, worst


# ---------------------------------------------------------------------------- JointVelocityTask
def test_joint_velocity_task_closed_forms(robot):
    rng = np.random.default_rng(SEED)
    w = rng.uniform(0.5, 2.0, robot.nv)
    alone = stack_of(robot, JointVelocityTask(robot, w, name="jv"), damping=1e-2)
    ws = alone.workspace("quadprog")
    for _ in range(5):
        v_ref = rng.standard_normal(robot.nv)
        ws.set(**{"jv.target": v_ref})
        np.testing.assert_allclose(ws.solve().x, w * v_ref / (w + 1e-4), atol=1e-10)
        A, b = rng.standard_normal((3, robot.nv)), rng.standard_normal(3)
        ws2 = numeric_stack(robot, A, b, JointVelocityTask(robot, w, name="jv"))
        ws2.set(**{"jv.target": v_ref})
        expected = np.linalg.solve(A.T @ A + np.diag(w) + 1e-6 * np.eye(robot.nv),
                                   A.T @ b + w * v_ref)
        np.testing.assert_allclose(ws2.solve().x, expected, atol=1e-9)


def test_pinks_joint_velocity_task_tracks_the_opposite_reference(robot):
    """The formulation difference: pink 4.4's JointVelocityTask alone returns ``−v_ref`` (its
    error ``+v_ref dt`` under ``J Δq = −e``); wbc's returns ``v_ref``."""
    pink = pytest.importorskip("pink")
    v_ref = np.linspace(-0.3, 0.3, robot.nv)
    peer = pink.tasks.JointVelocityTask(cost=1.0)
    peer.set_target(v_ref, DT)
    shrink = 1.0 / (1.0 + PEER_DAMPING)  # both sides' Tikhonov damping ρ² = d
    np.testing.assert_allclose(pink_solve(robot, robot.neutral(), [peer]), -shrink * v_ref,
                               rtol=0, atol=1e-12)
    ctrl = controller(robot, stack_of(robot, JointVelocityTask(robot, name="jv")))
    np.testing.assert_allclose(ctrl.step(robot.neutral(), jv=v_ref), shrink * v_ref, rtol=0,
                               atol=1e-12)


def test_joint_velocity_task_equals_pinks_at_random_states(robot):
    """wbc with ``v_ref`` equals pink with ``−v_ref`` (see the test above)."""
    pink = pytest.importorskip("pink")
    cost, gain = 0.4, 0.8
    ctrl = controller(robot, stack_of(robot, FrameTask(robot, HAND, gain=gain, name="ee"),
                                      JointVelocityTask(robot, cost ** 2, name="jv")))
    frame = pink.tasks.FrameTask(HAND, position_cost=1.0, orientation_cost=1.0, gain=gain)
    peer = pink.tasks.JointVelocityTask(cost=cost)
    rng = np.random.default_rng(SEED + 4)
    worst = 0.0
    for _ in range(STATES):
        q, v_ref = random_q(robot, rng), rng.standard_normal(robot.nv)
        target = perturbed(robot.frame_pose(q, HAND), rng)
        frame.set_target(pin.SE3(target))
        peer.set_target(-v_ref, DT)
        v_peer = pink_solve(robot, q, [frame, peer])
        worst = max(worst, np.abs(ctrl.step(q, ee=target, jv=v_ref) - v_peer).max())
    assert worst <= TOL, worst


def test_joint_velocity_task_needs_its_reference(robot):
    ctrl = controller(robot, stack_of(robot, JointVelocityTask(robot, name="jv")))
    with pytest.raises(WbcError, match="jv.target"):
        ctrl.step(robot.neutral())
    with pytest.raises(ShapeError):
        ctrl.step(robot.neutral(), jv=np.ones(3))


# ---------------------------------------------------------------------------- LowAcceleration
def test_low_acceleration_task_closed_form_and_default(robot):
    rng = np.random.default_rng(SEED)
    A, b = rng.standard_normal((3, robot.nv)), rng.standard_normal(3)
    w = 0.7
    ws = numeric_stack(robot, A, b, LowAccelerationTask(robot, w, name="acc"))
    # before any v_prev is set it is 0 (as pink's): the same as a DampingTask of that weight
    damped = numeric_stack(robot, A, b, DampingTask(robot, w, name="damp")).solve().x
    np.testing.assert_allclose(ws.solve().x, damped, atol=1e-12)
    for _ in range(5):
        v_prev = rng.standard_normal(robot.nv)
        ws.set(**{"acc.target": v_prev})
        expected = np.linalg.solve(A.T @ A + (w + 1e-6) * np.eye(robot.nv),
                                   A.T @ b + w * v_prev)
        np.testing.assert_allclose(ws.solve().x, expected, atol=1e-9)


def test_low_acceleration_task_equals_pinks_in_a_closed_loop(robot):
    """Both sides fed their previous command, ticks at 20 states of a loop run by wbc."""
    pink = pytest.importorskip("pink")
    cost, gain = 0.5, 0.5
    ctrl = controller(robot, stack_of(robot, FrameTask(robot, HAND, gain=gain, name="ee"),
                                      LowAccelerationTask(robot, cost ** 2, name="acc")))
    frame = pink.tasks.FrameTask(HAND, position_cost=1.0, orientation_cost=1.0, gain=gain)
    peer = pink.tasks.LowAccelerationTask(cost=cost)
    rng = np.random.default_rng(SEED + 5)
    q, v_prev, worst = random_q(robot, rng), np.zeros(robot.nv), 0.0
    for tick in range(STATES):
        if tick % 5 == 0:  # a new target now and then: the command changes
            target = perturbed(robot.frame_pose(q, HAND), rng)
            frame.set_target(pin.SE3(target))
        if tick:
            peer.set_last_integration(v_prev, DT)
        v_peer = pink_solve(robot, q, [frame, peer])
        v = ctrl.step(q, ee=target, acc=v_prev)
        worst = max(worst, np.abs(v - v_peer).max())
        q, v_prev = robot.integrate(q, v, DT), v
    assert worst <= TOL, worst


# ---------------------------------------------------------------------------- JointCoupling
def test_joint_coupling_task_is_dead_beat_and_minimum_norm(robot):
    """Alone (stack damping ρ): ``v = c · gain (r − cᵀq) / (dt (‖c‖² + ρ²))`` — along ``c``,
    the minimum-norm answer as ρ → 0 — after which the relation's error is
    ``(r − cᵀq)(1 − gain ‖c‖² / (‖c‖² + ρ²))``: 0 at gain 1 (dead-beat) up to the damping."""
    rng = np.random.default_rng(SEED)
    joints, ratios = ["panda_joint2", "panda_joint4", "panda_joint7"], [1.0, -2.0, 0.5]
    c = np.zeros(robot.nv)
    c[[1, 3, 6]] = ratios
    rho2 = 1e-4
    for gain in (1.0, 0.4):
        task = JointCouplingTask(robot, joints, ratios, gain=gain, name="couple")
        ctrl = controller(robot, stack_of(robot, task, damping=np.sqrt(rho2)))
        for _ in range(5):
            q, r = random_q(robot, rng), rng.uniform(-0.5, 0.5)
            v = ctrl.step(q, couple=r)
            np.testing.assert_allclose(v, c * gain * (r - c @ q) / (DT * (c @ c + rho2)),
                                       rtol=1e-10, atol=1e-12)
            shrink = 1 - gain * (c @ c) / (c @ c + rho2)
            np.testing.assert_allclose(r - c @ (q + DT * v), shrink * (r - c @ q), rtol=0,
                                       atol=1e-12)
            assert abs(shrink - (1 - gain)) < 1e-4


def test_joint_coupling_task_equals_pinks_at_random_states(robot):
    pink = pytest.importorskip("pink")
    from pink.tasks import JointCouplingTask as PinkCoupling

    joints, ratios, cost, gain, lm = ["panda_joint1", "panda_joint3"], [1.0, -1.0], 2.0, 0.6, 0.5
    ctrl = controller(robot, stack_of(
        robot, FrameTask(robot, HAND, gain=gain, name="ee"),
        JointCouplingTask(robot, joints, ratios, gain=gain, weight=cost ** 2, lm_damping=lm,
                          name="couple")))
    configuration = pink.Configuration(robot.model, robot.model.createData(), robot.neutral())
    peer = PinkCoupling(joints, ratios, cost, configuration, lm_damping=lm, gain=gain)
    frame = pink.tasks.FrameTask(HAND, position_cost=1.0, orientation_cost=1.0, gain=gain)
    rng = np.random.default_rng(SEED + 6)
    worst = 0.0
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(robot.frame_pose(q, HAND), rng)
        frame.set_target(pin.SE3(target))
        v_peer = pink_solve(robot, q, [frame, peer])
        worst = max(worst, np.abs(ctrl.step(q, ee=target) - v_peer).max())  # r = 0: pink's
    assert worst <= TOL, worst


# ---------------------------------------------------------------------------- DofFreezing
def test_dof_freezing_deletes_the_frozen_columns(robot):
    """Hard (bounds or equality rows): frozen coordinates are 0 and the others solve the same
    problem without them; soft (added, weight w): the cost ``w/2 ‖v_F‖²``."""
    rng = np.random.default_rng(SEED)
    frozen = [1, 4]
    free = [i for i in range(robot.nv) if i not in frozen]
    for _ in range(10):
        A, b = rng.standard_normal((5, robot.nv)), rng.standard_normal(5)
        expected = np.zeros(robot.nv)
        expected[free] = np.linalg.solve(A[:, free].T @ A[:, free] + 1e-6 * np.eye(len(free)),
                                         A[:, free].T @ b)
        for form in ("bounds", "equality"):
            stack = stack_of(robot, LinearTask(A, b, name="lin"))
            stack.constrain(DofFreezing(robot, ["panda_joint2", 4], form=form, name="frozen"))
            np.testing.assert_allclose(stack.solve("quadprog").x, expected, atol=1e-9)
        stack = stack_of(robot, LinearTask(A, b, name="lin"))
        stack.add(DofFreezing(robot, frozen, form="equality", name="soft"), weight=3.0)
        penalty = np.zeros(robot.nv)
        penalty[frozen] = 3.0
        soft = np.linalg.solve(A.T @ A + np.diag(penalty) + 1e-6 * np.eye(robot.nv), A.T @ b)
        np.testing.assert_allclose(stack.solve("quadprog").x, soft, atol=1e-9)


def test_dof_freezing_equals_minks_constraint_at_random_states(robot, mink_side):
    mink, model, _ = mink_side
    gain, frozen = 0.7, [0, 2, 5]
    frame = mink.FrameTask(HAND, "body", position_cost=1.0, orientation_cost=0.5, gain=gain)
    freeze = mink.DofFreezingTask(model, dof_indices=frozen)
    ctrls = {}
    for form in ("bounds", "equality"):
        stack = stack_of(robot, FrameTask(robot, HAND, gain=gain, name="ee",
                                          weight=[1.0] * 3 + [0.25] * 3))
        stack.constrain(DofFreezing(robot, frozen, form=form, name="frozen"))
        ctrls[form] = controller(robot, stack)
    rng = np.random.default_rng(SEED + 7)
    worst = 0.0
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(robot.frame_pose(q, HAND), rng)
        frame.set_target(mink.SE3.from_matrix(target))
        v_peer = mink_solve(mink_side, q, [frame], constraints=[freeze])
        assert np.abs(v_peer[frozen]).max() < 1e-9
        for form, ctrl in ctrls.items():
            v = ctrl.step(q, ee=target)
            # bounds: exactly zero; equality rows: to the backend's precision
            assert np.abs(v[frozen]).max() <= (0.0 if form == "bounds" else 1e-12)
            worst = max(worst, np.abs(v - v_peer).max())
    assert worst <= TOL, worst


# ---------------------------------------------------------------------------- kinetic energy
def test_mass_matrix_quantity(robot):
    """``"M"`` is pinocchio's crba, symmetric; on a planar base it is ``Sᵀ M S`` over the
    base's own velocities: ``1/2 vᵀ M_v v`` is the kinetic energy of ``q̇ = S v``."""
    rng = np.random.default_rng(SEED)
    M = np.zeros((robot.nv, robot.nv))
    for _ in range(5):
        q = random_q(robot, rng)
        robot.update(q)
        robot.quantities.get("M").fill(M)
        reference = pin.crba(robot.model, robot.model.createData(), q)
        np.testing.assert_allclose(M, np.triu(reference) + np.triu(reference, 1).T, atol=0)
        assert np.all(np.linalg.eigvalsh(M) > 0)
        # the other fillers are untouched (crba runs on its own data)
        np.testing.assert_allclose(robot.frame_pose(None, HAND), robot.frame_pose(q, HAND))
    mobile = wbc.robots.load("tiago_panda")
    M = np.zeros((mobile.nv, mobile.nv))
    for _ in range(5):
        q, v = mobile.random_configuration(rng), rng.standard_normal(mobile.nv)
        mobile.update(q)
        mobile.quantities.get("M").fill(M)
        qdot = mobile.velocity_map(q) @ v
        data = mobile.model.createData()
        pin.crba(mobile.model, data, q)
        M_pin = np.triu(data.M) + np.triu(data.M, 1).T
        np.testing.assert_allclose(M, M.T, atol=0)
        np.testing.assert_allclose(v @ M @ v, qdot @ M_pin @ qdot, rtol=1e-12)


def test_cholesky_factor_of_definite_and_semidefinite_matrices():
    M_sym = ca.SX.sym("M", 5, 5)
    factor = ca.Function("chol", [M_sym], [cholesky_factor(M_sym)])
    rng = np.random.default_rng(SEED)
    for rank in (5, 3):
        B = rng.standard_normal((5, rank))
        M = B @ B.T
        if rank == 5:
            M += 0.1 * np.eye(5)
        else:  # a semidefinite M with exact zero pivots: coordinates 3, 4 carry no inertia
            M = np.zeros((5, 5))
            M[:3, :3] = B[:3] @ B[:3].T
        R = np.array(factor(M))
        assert np.isfinite(R).all()
        np.testing.assert_allclose(R @ R.T, M, atol=1e-12)
        assert np.allclose(R, np.tril(R))


def test_kinetic_energy_task_closed_form(robot):
    rng = np.random.default_rng(SEED)
    weight = 2e-4
    for _ in range(5):
        q = random_q(robot, rng)
        A, b = rng.standard_normal((3, robot.nv)), rng.standard_normal(3)
        ws = numeric_stack(robot, A, b, KineticEnergyRegularizationTask(robot, weight, "ke"))
        M = pin.crba(robot.model, robot.model.createData(), q)
        M = np.triu(M) + np.triu(M, 1).T
        ws.set(M=M, dt=DT)
        expected = np.linalg.solve(A.T @ A + weight / DT ** 2 * M + 1e-6 * np.eye(robot.nv),
                                   A.T @ b)
        sol = ws.solve()
        np.testing.assert_allclose(sol.x, expected, atol=1e-9)
        assert sol.residuals["ke"][0] == pytest.approx(0.5 * expected @ M @ expected, rel=1e-9)


def test_kinetic_energy_task_equals_minks_at_random_states(robot, mink_side):
    mink = mink_side[0]
    cost, gain = 1e-3, 0.5
    ctrl = controller(robot, stack_of(
        robot, FrameTask(robot, HAND, gain=gain, name="ee"),
        KineticEnergyRegularizationTask(robot, weight=cost, name="ke")))
    frame = mink.FrameTask(HAND, "body", position_cost=1.0, orientation_cost=1.0, gain=gain)
    peer = mink.KineticEnergyRegularizationTask(cost=cost)
    peer.set_dt(DT)
    rng = np.random.default_rng(SEED + 8)
    worst = moved = 0.0
    for _ in range(STATES):
        q = random_q(robot, rng)
        target = perturbed(robot.frame_pose(q, HAND), rng)
        frame.set_target(mink.SE3.from_matrix(target))
        v_peer = mink_solve(mink_side, q, [frame, peer])
        worst = max(worst, np.abs(ctrl.step(q, ee=target) - v_peer).max())
        # the regularisation matters: without it the answer is another
        plain = mink_solve(mink_side, q, [frame])
        moved = max(moved, np.abs(plain - v_peer).max())
    assert worst <= TOL, worst
    assert moved > 1e-2, moved


# ---------------------------------------------------------------------------- bad inputs
BAD_INPUTS = [
    (lambda r: RelativeFrameTask(r, HAND, "nowhere"), UnknownNameError, "nowhere"),
    (lambda r: RelativeFrameTask(r, HAND, HAND), InvalidValueError, "same frame"),
    (lambda r: RelativeFrameTask(r, HAND, ROOT, weight=[1.0] * 5), ShapeError, "weight"),
    (lambda r: RelativeFrameTask(r, HAND, ROOT, gain=-1.0), InvalidValueError, "gain"),
    (lambda r: RelativeFrameTask("panda", HAND, ROOT), InvalidValueError, "robot"),
    (lambda r: DampingTask(r, weight=[1.0] * 3), ShapeError, "weight"),
    (lambda r: DampingTask(r, weight=-1.0), InvalidValueError, "weight"),
    (lambda r: DampingTask(r, weight=np.nan), WbcError, "weight"),
    (lambda r: JointVelocityTask(r, weight="heavy"), InvalidValueError, "weight"),
    (lambda r: LowAccelerationTask(r, weight=[1.0, -1.0] + [1.0] * 5), InvalidValueError,
     "weight"),
    (lambda r: JointCouplingTask(r, ["panda_joint1", "elbow"], [1, -1]), UnknownNameError,
     "elbow"),
    (lambda r: JointCouplingTask(r, ["panda_joint1"] * 2, [1, -1]), InvalidValueError, "twice"),
    (lambda r: JointCouplingTask(r, ["panda_joint1", "panda_joint2"], [1.0]), ShapeError,
     "ratios"),
    (lambda r: JointCouplingTask(r, ["panda_joint1", "panda_joint2"], [0, 0]),
     InvalidValueError, "zero"),
    (lambda r: JointCouplingTask(r, [], []), InvalidValueError, "joints"),
    (lambda r: JointCouplingTask(r, "panda_joint1", [1.0]), InvalidValueError, "joints"),
    (lambda r: DofFreezing(r, []), InvalidValueError, "non-empty"),
    (lambda r: DofFreezing(r, [7]), InvalidValueError, "<= 6"),
    (lambda r: DofFreezing(r, [-1]), InvalidValueError, ">= 0"),
    (lambda r: DofFreezing(r, [1, 1]), InvalidValueError, "twice"),
    (lambda r: DofFreezing(r, ["wheel"]), UnknownNameError, "wheel"),
    (lambda r: DofFreezing(r, [1.5]), InvalidValueError, "integer"),
    (lambda r: DofFreezing(r, [1], form="soft"), InvalidValueError, "form"),
    (lambda r: KineticEnergyRegularizationTask(r, weight=[1.0, 2.0]), ShapeError, "weight"),
    (lambda r: KineticEnergyRegularizationTask(r, weight=-1e-3), InvalidValueError, "weight"),
]


@pytest.mark.parametrize("make, error, match", BAD_INPUTS)
def test_bad_inputs_raise_clear_errors(robot, make, error, match):
    with pytest.raises(error, match=match):
        make(robot)


def test_hard_and_soft_misuse_is_refused(robot):
    stack = stack_of(robot, DampingTask(robot, name="damp"))
    with pytest.raises(WbcError, match="hard"):
        stack.add(DofFreezing(robot, [0], name="frozen"))  # bounds are hard only
    with pytest.raises(WbcError, match="cost"):
        stack.constrain(DampingTask(robot, name="damp2"))  # a cost is not a constraint
    with pytest.raises(ShapeError, match="block"):  # a block that is not the robot's nv
        wbc.Stack(wbc.Variables(v=3)).add(DampingTask(robot, name="d"))
