"""Barriers, limits and pointing tasks of `wbc.tasks` against their closed forms and their peers.

`AccelerationLimit`, `PositionBarrier`, `BodySphericalBarrier`, `ManipulabilityTask`
against pink 4.4, `AxisAlignTask`, `LookAtTask` against mink 1.3: the same QP at >= 20 random
Panda states, solved by quadprog on both sides, the commands equal to 1e-8 rad/s. Then closed
forms (finite differences, the numpy bounds), closed loops on `wbc.sim.Simulation` that must
keep their bounds, and bad inputs.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest

import wbc
from wbc.errors import InvalidValueError, ShapeError, UnknownNameError, WbcError
from wbc.robots.fixed_base import load_panda
from wbc.sim import Simulation
from wbc.tasks import FrameTask, PostureTask
from wbc.tasks.acceleration_limit import AccelerationLimit, acceleration_limit_bounds
from wbc.tasks.axis_align import AxisAlignTask
from wbc.tasks.body_spherical_barrier import BodySphericalBarrier
from wbc.tasks.look_at import LookAtTask
from wbc.tasks.manipulability import ManipulabilityTask
from wbc.tasks.position_barrier import PositionBarrier, SafeDisplacement

DT = 0.01
DAMPING = 1e-6  # pink's / mink's Tikhonov damping d; wbc ρ = √d
TOL = 1e-8  # [rad/s]
STATES = 20
HAND = "panda_hand"
ROBOT = load_panda()


def _controller(stack, backend="quadprog", robot=ROBOT):
    # the stacks hold only the limits under test, as the peers' problems do (limits=[]): the
    # controller's warning about the robot's other limits is expected
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*no hard constraint of the stack bounds")
        return wbc.Controller(robot, stack, backend=backend, dt=DT, jit=False, fused=False)


def _stack():
    return wbc.Stack(wbc.Variables(v=ROBOT.nv), damping=np.sqrt(DAMPING))


def _states(seed, count=STATES, margin=0.05):
    """Random configurations strictly inside the limits (pink refuses others)."""
    rng = np.random.default_rng(seed)
    lo, up = ROBOT.limits.q_lower + margin, ROBOT.limits.q_upper - margin
    return rng, [rng.uniform(lo, up) for _ in range(count)]


def _evaluate(stack, expr, values):
    """``expr`` (SX of the stack's parameters) at ``values`` (others: their defaults)."""
    params = list(stack.parameters.values())
    f = ca.Function("f", [p.symbol for p in params], [expr])
    args = [values[p.name] if p.name in values else p.default for p in params]
    return np.array(f(*args), dtype=float)


def _quantities(q):
    pose = ROBOT.frame_pose(q, "ee").copy()
    return {"q": q, "dt": DT, "pose[ee]": pose, "J[ee]": ROBOT.frame_jacobian(q, "ee").copy()}


# ---------------------------------------------------------------------------- pink
pink = pytest.importorskip("pink")


def _pink_configuration(q):
    return pink.Configuration(ROBOT.model, ROBOT.model.createData(), q.copy())


def _pink_hand_task(target, position_cost=1.0, orientation_cost=0.1):
    task = pink.tasks.FrameTask(HAND, position_cost=position_cost,
                                orientation_cost=orientation_cost)
    task.set_target(pink_se3(target))
    return task


def pink_se3(T):
    import pinocchio as pin

    return pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())


def _hand_and_posture(stack, orientation_cost=0.1, posture_cost=0.1):
    stack.add(FrameTask(ROBOT, "ee", weight=[1.0] * 3 + [orientation_cost ** 2] * 3, name="ee"))
    stack.add(PostureTask(ROBOT, weight=posture_cost ** 2, name="posture"))


def _pink_posture(q_ref, cost=0.1):
    task = pink.tasks.PostureTask(cost=cost)
    task.set_target(q_ref)
    return task


def _pink_solve(q, tasks, limits=(), barriers=()):
    return pink.solve_ik(_pink_configuration(q), list(tasks), DT, solver="quadprog",
                         damping=DAMPING, limits=list(limits), barriers=list(barriers))


def test_position_barrier_equals_pinks_at_random_states():
    rng, states = _states(1)
    active = 0
    for k, q in enumerate(states):
        T = ROBOT.frame_pose(q, "ee").copy()
        p = T[:3, 3].copy()
        indices = [[0, 1, 2], [2], [0, 2]][k % 3]
        p_min = p[indices] - rng.uniform(0.002, 0.05, len(indices))
        p_max = p[indices] + rng.uniform(0.002, 0.05, len(indices))
        # one gain, or one per axis (both sides: pink tiles it)
        gain = float(rng.uniform(0.5, 5.0)) if k % 4 else rng.uniform(0.5, 5.0, len(indices))
        r = 0.0 if k % 2 else float(rng.uniform(0.5, 3.0))
        target = T.copy()
        target[:3, 3] += rng.normal(0, 0.3, 3)
        stack = _stack()
        _hand_and_posture(stack)
        barrier = PositionBarrier(ROBOT, "ee", p_min, p_max, indices=indices, gain=gain,
                                  safe_displacement_gain=r, name="box")
        stack.constrain(barrier)
        if r > 0:
            stack.add(barrier.safe_displacement())
        v = _controller(stack).step(q, ee=target)
        pink_barrier = pink.barriers.PositionBarrier(HAND, indices=indices, p_min=p_min,
                                                     p_max=p_max, gain=gain,
                                                     safe_displacement_gain=r)
        v_pink = _pink_solve(q, [_pink_hand_task(target), _pink_posture(ROBOT.neutral())],
                             barriers=[pink_barrier])
        assert np.abs(v - v_pink).max() <= TOL, k
        J = ROBOT.frame_jacobian(q, "ee")[indices]
        slack = np.concatenate([J @ v + gain * (p[indices] - p_min),
                                -J @ v + gain * (p_max - p[indices])])  # gain broadcasts
        assert slack.min() >= -1e-9
        active += slack.min() < 1e-7
    assert active >= STATES // 2  # the barrier shaped most of the commands


def test_body_spherical_barrier_equals_pinks_at_random_states():
    rng, states = _states(2)
    active = 0
    for k, q in enumerate(states):
        other = ["panda_link2", "panda_link0", "panda_link3"][k % 3]
        p_hand = ROBOT.frame_pose(q, "ee")[:3, 3].copy()
        p_other = ROBOT.frame_pose(q, other)[:3, 3].copy()
        distance = np.linalg.norm(p_hand - p_other)
        d_min = distance * float(rng.uniform(0.7, 0.98))
        gain = float(rng.uniform(0.5, 5.0))
        r = [0.0, 3.0, float(rng.uniform(0.5, 5.0))][k % 3]
        target = ROBOT.frame_pose(q, "ee").copy()
        target[:3, 3] = p_other + 0.3 * (p_hand - p_other)  # pull the hand towards the other
        stack = _stack()
        _hand_and_posture(stack)
        barrier = BodySphericalBarrier(ROBOT, ("ee", other), d_min, gain=gain,
                                       safe_displacement_gain=r, name="sphere")
        stack.constrain(barrier)
        if r > 0:
            stack.add(barrier.safe_displacement())
        v = _controller(stack).step(q, ee=target)
        pink_barrier = pink.barriers.BodySphericalBarrier((HAND, other), d_min, gain=gain,
                                                          safe_displacement_gain=r)
        v_pink = _pink_solve(q, [_pink_hand_task(target), _pink_posture(ROBOT.neutral())],
                             barriers=[pink_barrier])
        assert np.abs(v - v_pink).max() <= TOL, k
        J_h = 2 * (p_hand - p_other) @ (ROBOT.frame_jacobian(q, "ee")[:3]
                                        - ROBOT.frame_jacobian(q, other)[:3])
        h = distance ** 2 - d_min ** 2
        row = J_h @ v + gain * h / (1 + abs(h))
        assert row >= -1e-9
        active += row < 1e-7
    assert active >= STATES // 2


def test_acceleration_limit_pink_method_equals_pinks_at_random_states():
    rng = np.random.default_rng(3)
    lo, up = ROBOT.limits.q_lower, ROBOT.limits.q_upper
    compared = braking = 0
    for k in range(40):
        # half the joints within 0.05 rad of a limit: the braking bound matters there
        q = rng.uniform(lo + 0.01, up - 0.01)
        near = rng.random(7) < 0.5
        q[near] = np.where(rng.random(near.sum()) < 0.5, lo[near] + rng.uniform(0.001, 0.05),
                           up[near] - rng.uniform(0.001, 0.05))
        a_max = rng.uniform(2.0, 20.0, 7)
        v_prev = rng.normal(0, 0.3, 7)
        target = ROBOT.frame_pose(q, "ee").copy()
        target[:3, 3] += rng.normal(0, 0.3, 3)
        # the posture pulls every joint past the limit it is nearest to
        q_ref = np.where(up - q < q - lo, up + 0.5, lo - 0.5)
        limit = pink.limits.AccelerationLimit(ROBOT.model, a_max)
        limit.set_last_integration(v_prev, DT)
        try:
            v_pink = _pink_solve(q, [_pink_hand_task(target), _pink_posture(q_ref, 1.0)],
                                 limits=[limit])
        except pink.exceptions.NoSolutionFound:  # pink's bounds cross (module docstring)
            continue
        stack = _stack()
        _hand_and_posture(stack, posture_cost=1.0)
        stack.constrain(AccelerationLimit(ROBOT, a_max=a_max, method="pink", name="acc"))
        v = _controller(stack).step(q, v_prev, ee=target, posture=q_ref)
        assert np.abs(v - v_pink).max() <= TOL, k
        brake = np.concatenate([v - np.sqrt(2 * a_max * (up - q)),
                                v + np.sqrt(2 * a_max * (q - lo))])
        braking += np.any(np.abs(brake) < 1e-9)
        compared += 1
    assert compared >= STATES and braking >= 3


def test_manipulability_velocity_task_equals_pinks_at_random_states():
    rng, states = _states(4)
    for k, q in enumerate(states):
        cost, gain = float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.2, 1.0))
        rho, lm = float(rng.uniform(-0.05, 0.1)), [0.0, 1.0][k % 2]
        task = pink.tasks.ManipulabilityTask(HAND, ROBOT.model, cost=cost, gain=gain,
                                             manipulability_rate=rho, lm_damping=lm)
        # pink's ∇m is wbc's ∇H / (2 sqrt H) from the robot's quantities
        H, grad = ROBOT.manipulability(q), ROBOT.manipulability_gradient(q).copy()
        row_pink = task.compute_jacobian(_pink_configuration(q)).ravel()
        assert np.abs(row_pink - grad / (2 * np.sqrt(H))).max() <= 1e-12
        stack = _stack()
        stack.add(ManipulabilityTask(ROBOT, "ee", rate=gain * rho / DT,
                                             weight=cost ** 2, lm_damping=lm, name="m"))
        stack.add(PostureTask(ROBOT, weight=0.01, name="posture"))
        v = _controller(stack).step(q)
        v_pink = _pink_solve(q, [task, _pink_posture(ROBOT.neutral())])
        assert np.abs(v - v_pink).max() <= TOL, k


def test_manipulability_velocity_task_closed_form_and_reference():
    """One row, damping ρ: ``v = w ṁ* ∇m / (w ‖∇m‖² + ρ²)`` (gradient ascent at the rate
    asked), the rate set per tick as the task's reference."""
    rng, states = _states(5, count=5)
    rho = 1e-2
    stack = wbc.Stack(wbc.Variables(v=ROBOT.nv), damping=rho)
    stack.add(ManipulabilityTask(ROBOT, "ee", rate=0.3, weight=2.0, name="m"))
    ctrl = _controller(stack, backend="daqp")
    for q in states:
        for rate in (0.3, -0.2):
            g = ROBOT.manipulability_gradient(q) / (2 * np.sqrt(ROBOT.manipulability(q)))
            v = ctrl.step(q, m=rate)
            np.testing.assert_allclose(v, 2.0 * rate * g / (2.0 * g @ g + rho ** 2),
                                       atol=1e-9)


# ---------------------------------------------------------------------------- mink
def _mink():
    mink = pytest.importorskip("mink")
    from wbc.experiments.peers.vs_mink import mujoco_panda

    model = mujoco_panda()
    return mink, model


@pytest.mark.parametrize("kind", ["axis_align", "look_at"])
def test_pointing_tasks_equal_minks_at_random_states(kind):
    mink, model = _mink()
    configuration = mink.Configuration(model)
    rng, states = _states(6)
    for k, q in enumerate(states):
        axis = rng.normal(size=3)
        cost, gain = float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.2, 1.0))
        lm = [0.0, 1.0][k % 2]
        p = ROBOT.frame_pose(q, "ee")[:3, 3]
        target = rng.normal(size=3) if kind == "axis_align" else p + rng.normal(0, 0.5, 3)
        cls, mink_cls = ((AxisAlignTask, mink.AxisAlignTask) if kind == "axis_align"
                         else (LookAtTask, mink.LookAtTask))
        stack = _stack()
        stack.add(cls(ROBOT, "ee", axis=axis, gain=gain, weight=cost ** 2, lm_damping=lm,
                      name="point"))
        stack.add(PostureTask(ROBOT, weight=0.01, name="posture"))
        v = _controller(stack).step(q, point=target)
        task = mink_cls(HAND, "body", axis=axis, cost=cost, gain=gain, lm_damping=lm)
        task.set_target(target)
        posture = mink.PostureTask(model, cost=0.1)
        posture.set_target(ROBOT.neutral())
        configuration.update(q)
        v_mink = mink.solve_ik(configuration, [task, posture], DT, solver="quadprog",
                               damping=DAMPING, limits=[])
        assert np.abs(v - v_mink).max() <= TOL, k


@pytest.mark.parametrize("kind", ["axis_align", "look_at"])
def test_pointing_errors_and_jacobians_against_finite_differences(kind):
    """``e`` in closed form (``a − Rᵀt``, ``a − r/‖r‖``) and ``J_e v`` = the central difference
    of ``e`` along ``v``."""
    rng, states = _states(7, count=5)
    cls = AxisAlignTask if kind == "axis_align" else LookAtTask
    axis = np.array([0.3, -0.2, 1.0])
    a = axis / np.linalg.norm(axis)
    for q in states:
        target = rng.normal(size=3) + (0 if kind == "axis_align" else 0.5)

        def error(config, target=target):
            T = ROBOT.frame_pose(config, "ee")
            R, p = T[:3, :3], T[:3, 3]
            if kind == "axis_align":
                return a - R.T @ target / np.linalg.norm(target)
            r = R.T @ (target - p)
            return a - r / np.linalg.norm(r)

        stack = _stack()
        task = cls(ROBOT, "ee", axis=axis, name="point")
        stack.add(task)
        values = {**_quantities(q), "point.target": target}
        e = _evaluate(stack, task.error, values).ravel()
        J_e = _evaluate(stack, task.jacobian, values)
        np.testing.assert_allclose(e, error(q), atol=1e-12)
        v, h = rng.normal(size=7), 1e-6
        fd = (error(q + h * v) - error(q - h * v)) / (2 * h)
        np.testing.assert_allclose(J_e @ v, fd, atol=1e-7)
        assert np.linalg.matrix_rank(J_e, tol=1e-9) == 2  # the roll about the axis is free


def test_axis_align_converges_and_look_at_follows_references():
    """Closed loops: the hand's z axis turns down (‖e‖ → 0), and the hand's z axis tracks a
    point given each tick as the task's reference."""
    stack = _stack()
    stack.add(AxisAlignTask(ROBOT, "ee", axis=(0, 0, 1), gain=0.2, name="down"))
    stack.add(PostureTask(ROBOT, weight=1e-4, name="posture"))
    run = Simulation(ROBOT, _controller(stack, backend="daqp"), DT).run(
        ticks=150, references={"down": np.array([0.0, 0.0, -1.0])})
    z = ROBOT.frame_pose(run.q_final, "ee")[:3, 2]
    assert z @ np.array([0.0, 0.0, -1.0]) > 1 - 1e-6
    stack = _stack()
    stack.add(LookAtTask(ROBOT, "ee", gain=0.2, name="look"))
    stack.add(PostureTask(ROBOT, weight=1e-4, name="posture"))
    point = np.array([0.6, 0.3, 0.2])
    run = Simulation(ROBOT, _controller(stack, backend="daqp"), DT).run(
        ticks=150, references={"look": point})
    T = ROBOT.frame_pose(run.q_final, "ee")
    gaze = (point - T[:3, 3]) / np.linalg.norm(point - T[:3, 3])
    assert gaze @ T[:3, 2] > 1 - 1e-6


# ---------------------------------------------------------------------------- closed forms
def test_body_spherical_barrier_jacobian_against_finite_differences():
    rng, states = _states(8, count=5)
    for q in states:
        stack = _stack()
        barrier = BodySphericalBarrier(ROBOT, ("ee", "panda_link3"), 0.2, name="sphere")
        stack.constrain(barrier)
        h_sx, J_sx = barrier.barrier(stack)
        values = {**_quantities(q), "pose[panda_link3]": ROBOT.frame_pose(q, "panda_link3"),
                  "J[panda_link3]": ROBOT.frame_jacobian(q, "panda_link3")}

        def h(config):
            d = ROBOT.frame_pose(config, "ee")[:3, 3] - ROBOT.frame_pose(config,
                                                                        "panda_link3")[:3, 3]
            return d @ d - 0.04

        assert abs(_evaluate(stack, h_sx, values).item() - h(q)) <= 1e-12
        v, step = rng.normal(size=7), 1e-6
        fd = (h(q + step * v) - h(q - step * v)) / (2 * step)
        assert abs((_evaluate(stack, J_sx, values) @ v).item() - fd) <= 1e-7


@pytest.mark.parametrize("method", ["pink", "viable"])
def test_acceleration_limit_compiled_bounds_equal_the_closed_form(method):
    """A cost pulling every joint to ±100 rad/s ends on the bounds: the compiled ones equal
    :func:`acceleration_limit_bounds`, and pink's are ``min(v_prev + a T, sqrt(2 a gap))``."""
    rng = np.random.default_rng(9)
    a = rng.uniform(2.0, 20.0, 7)
    lo, up = ROBOT.limits.q_lower, ROBOT.limits.q_upper
    for sign in (1.0, -1.0):
        stack = wbc.Stack(wbc.Variables(v=7), damping=0.0)
        stack.add(wbc.Cost(stack.variables.symbol, sign * 100.0 * np.ones(7), name="push"))
        stack.constrain(AccelerationLimit(ROBOT, a_max=a, method=method, name="acc"))
        ctrl = _controller(stack, backend="daqp")
        for _ in range(10):
            q = rng.uniform(lo + 1e-3, up - 1e-3)
            v_prev = rng.normal(0, 1.0, 7)
            lower, upper = acceleration_limit_bounds(q, v_prev, lo, up, -a, a, DT, method)
            v = ctrl.step(q, v_prev)
            np.testing.assert_allclose(v, upper if sign > 0 else lower, atol=1e-9)
            if method == "pink":
                expected = np.minimum(v_prev + a * DT, np.sqrt(2 * a * (up - q)))
                np.testing.assert_allclose(upper, np.maximum(expected, v_prev - a * DT))


def test_acceleration_limit_on_a_mobile_base_bounds_the_base_by_acceleration_only():
    """tiago_panda (differential drive, nq = 10 != nv = 9), the robot's own limits: the base
    rows are ``v_prev ± a T``, the arm's the closed form with the arm's position limits."""
    from wbc.robots import load

    robot = load("tiago_panda")
    rng = np.random.default_rng(11)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=0.0)
    stack.add(wbc.Cost(stack.variables.symbol, 100.0 * np.ones(robot.nv), name="push"))
    stack.constrain(AccelerationLimit(robot, name="acc"))
    ctrl = _controller(stack, backend="daqp", robot=robot)
    limits, nb = robot.limits, robot.nv - robot.n_arm
    q_min = np.concatenate([np.full(nb, -np.inf), limits.q_lower[-robot.n_arm:]])
    q_max = np.concatenate([np.full(nb, np.inf), limits.q_upper[-robot.n_arm:]])
    for _ in range(5):
        q = robot.random_configuration(rng)
        v_prev = rng.normal(0, 0.5, robot.nv)
        positions = np.concatenate([np.zeros(nb), q[-robot.n_arm:]])
        _, upper = acceleration_limit_bounds(positions, v_prev, q_min, q_max, limits.a_lower,
                                             limits.a_upper, DT)
        v = ctrl.step(q, v_prev)
        np.testing.assert_allclose(v, upper, atol=1e-9)
        np.testing.assert_allclose(v[:nb], v_prev[:nb] + limits.a_upper[:nb] * DT)


def test_viable_bounds_are_invariant():
    """From any state inside the kernel (``v T + v² / 2a <= gap`` both ways), every command
    inside the bounds keeps the next state inside it, with the bounds ordered: 10⁵ samples."""
    rng = np.random.default_rng(10)
    n, T = 100_000, 0.01
    a = rng.uniform(1.0, 50.0, n)
    q_min, q_max = -1.0, 1.0
    q = rng.uniform(q_min, q_max, n)
    # previous velocities inside the kernel: |v| within the stopping speed
    v_up = -a * T + np.sqrt(a * a * T * T + 2 * a * (q_max - q))
    v_lo = a * T - np.sqrt(a * a * T * T + 2 * a * (q - q_min))
    v_prev = rng.uniform(v_lo, v_up)
    lower, upper = acceleration_limit_bounds(q, v_prev, q_min, q_max, -a, a, T, "viable")
    assert np.all(lower <= upper + 1e-12)
    for v in (lower, upper, rng.uniform(lower, upper)):
        q_next = q + v * T
        assert np.all((q_next <= q_max + 1e-12) & (q_next >= q_min - 1e-12))
        assert np.all(np.abs(v - v_prev) <= a * T * (1 + 1e-12))
        lo2, up2 = acceleration_limit_bounds(q_next, v, q_min, q_max, -a, a, T, "viable")
        assert np.all(lo2 <= up2 + 1e-12)


# ---------------------------------------------------------------------------- closed loops
def _posture_push(stack, beyond):
    """A posture pulling every joint past a limit at full gain."""
    target = np.where(beyond > 0, ROBOT.limits.q_upper + 0.5, ROBOT.limits.q_lower - 0.5)
    stack.add(PostureTask(ROBOT, gain=1.0, name="posture"))
    return {"posture": target}


@pytest.mark.parametrize("method", ["viable", "pink"])
def test_acceleration_limit_closed_loop_keeps_its_limits(method):
    """120 ticks driving every joint into a limit from 0.3 rad away: accelerations never above
    ``a``; positions never past a limit ("viable"), or by at most ``v T / 2 + a T² / 2``
    ("pink", ``v`` the top speed)."""
    a = 8.0
    sign = np.array([1, -1, 1, -1, 1, -1, 1.0])
    stack = _stack()
    refs = _posture_push(stack, sign)
    stack.constrain(AccelerationLimit(ROBOT, a_max=a, method=method, name="acc"))
    lo, up = ROBOT.limits.q_lower, ROBOT.limits.q_upper
    q0 = np.where(sign > 0, up - 0.3, lo + 0.3)
    run = Simulation(ROBOT, _controller(stack, backend="daqp"), DT).run(
        ticks=120, q0=q0, references=refs)
    assert all(s == "solved" for s in run.status)
    dv = np.diff(np.vstack([np.zeros(7), run.v]), axis=0)
    assert np.abs(dv).max() <= a * DT + 1e-9
    q = np.vstack([run.q, run.q_final])
    overshoot = max((q - up).max(), (lo - q).max())
    # pink's kernel ignores that the command is held for T: braking from v takes v T / 2
    # more than v² / 2a (module docstring)
    speed = np.abs(run.v).max()
    allowed = 1e-9 if method == "viable" else speed * DT / 2 + a * DT ** 2 / 2 + 1e-9
    assert overshoot <= allowed
    assert np.abs(q[-1] - np.where(sign > 0, up, lo)).max() < 0.02  # it got there


def _hand_loop(barrier, target, safe=False):
    stack = _stack()
    stack.add(FrameTask(ROBOT, "ee", gain=0.3, weight=[1, 1, 1, 0.01, 0.01, 0.01], name="ee"))
    stack.add(PostureTask(ROBOT, weight=1e-3, name="posture"))
    stack.constrain(barrier)
    if safe:
        stack.add(barrier.safe_displacement())
    run = Simulation(ROBOT, _controller(stack, backend="daqp"), DT).run(
        ticks=150, references={"ee": target})
    assert all(s == "solved" for s in run.status)
    return np.vstack([run.q, run.q_final])


def test_barriers_closed_loop_keep_their_sets():
    """The hand pulled 0.3 m ahead towards a wall 5 cm ahead of it, then towards ``panda_link2``
    through a sphere: the wall and the sphere hold (discrete-time CBF: within 1e-5 m, the
    second-order term of one tick), and the hand ends pressed against them."""
    q0 = ROBOT.neutral()
    T0 = ROBOT.frame_pose(q0, "ee").copy()
    x_max = T0[0, 3] + 0.05
    ahead = T0.copy()
    ahead[0, 3] += 0.3
    q = _hand_loop(PositionBarrier(ROBOT, "ee", p_max=[x_max], indices=[0], gain=20.0), ahead)
    x = np.array([ROBOT.frame_pose(c, "ee")[0, 3] for c in q])
    assert x_max - 1e-3 < x.max() <= x_max + 1e-5

    p2 = ROBOT.frame_pose(q0, "panda_link2")[:3, 3]
    d_min = 0.9 * np.linalg.norm(T0[:3, 3] - p2)
    towards = T0.copy()
    towards[:3, 3] = p2 + 0.3 * (T0[:3, 3] - p2)
    sphere = BodySphericalBarrier(ROBOT, ("ee", "panda_link2"), d_min, gain=20.0)
    q = _hand_loop(sphere, towards)
    d = np.array([np.linalg.norm(ROBOT.frame_pose(c, "ee")[:3, 3]
                                 - ROBOT.frame_pose(c, "panda_link2")[:3, 3]) for c in q])
    assert d_min - 1e-5 <= d.min() < d_min + 1e-3


def test_position_barrier_box_is_a_reference():
    """``"<name>.p_max"`` is set through ``step`` like any reference: a lower lid, a slower
    hand."""
    stack = _stack()
    stack.add(FrameTask(ROBOT, "ee", position_only=True, name="ee"))
    p = ROBOT.frame_pose(ROBOT.neutral(), "ee")[:3, 3]
    stack.constrain(PositionBarrier(ROBOT, "ee", p_max=[p[2] + 1.0], indices=[2], gain=1.0,
                                    name="box"))
    ctrl = _controller(stack, backend="daqp")
    target = ROBOT.frame_pose(ROBOT.neutral(), "ee").copy()
    target[2, 3] += 0.5
    J_z = ROBOT.frame_jacobian(ROBOT.neutral(), "ee")[2]
    ctrl.step(ROBOT.neutral(), ee=target, **{"box.p_max": [p[2] + 0.01]})
    assert J_z @ ctrl.last_command == pytest.approx(0.01, abs=1e-9)  # ż = γ (p_max − z)


# ---------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("build, error, match", [
    (lambda: AccelerationLimit(ROBOT), InvalidValueError, "pass a_max"),
    (lambda: AccelerationLimit(ROBOT, a_max=-1.0), InvalidValueError, "a_min < 0 < a_max"),
    (lambda: AccelerationLimit(ROBOT, a_max=np.ones(3)), ShapeError, "a_max"),
    (lambda: AccelerationLimit(ROBOT, a_max=1.0, method="flacco"), InvalidValueError, "method"),
    (lambda: acceleration_limit_bounds(0, 0, 1, -1, -1, 1, 0.01), InvalidValueError, "q_min"),
    (lambda: acceleration_limit_bounds(0, np.nan, -1, 1, -1, 1, 0.01), WbcError, "finite"),
    (lambda: PositionBarrier(ROBOT, "ee"), InvalidValueError, "p_min, p_max"),
    (lambda: PositionBarrier(ROBOT, "nope", p_max=[1, 1, 1]), UnknownNameError, "nope"),
    (lambda: PositionBarrier(ROBOT, "ee", p_max=[1, 1]), ShapeError, "p_max"),
    (lambda: PositionBarrier(ROBOT, "ee", p_max=[1], indices=[3]), InvalidValueError,
     "indices"),
    (lambda: PositionBarrier(ROBOT, "ee", p_min=[2.0] * 3, p_max=[1.0] * 3),
     InvalidValueError, "p_min > p_max"),
    (lambda: PositionBarrier(ROBOT, "ee", p_max=[1.0] * 3, gain=0.0), InvalidValueError,
     "gain"),
    (lambda: PositionBarrier(ROBOT, "ee", p_max=[1.0] * 3).safe_displacement(),
     InvalidValueError, "safe_displacement_gain"),
    (lambda: SafeDisplacement("box"), InvalidValueError, "barrier"),
    (lambda: BodySphericalBarrier(ROBOT, ("ee", "ee"), 0.1), InvalidValueError, "differ"),
    (lambda: BodySphericalBarrier(ROBOT, "ee", 0.1), InvalidValueError, "two frame names"),
    (lambda: BodySphericalBarrier(ROBOT, ("ee", "panda_link2"), -0.1), InvalidValueError,
     "d_min"),
    (lambda: AxisAlignTask(ROBOT, "ee", axis=(0, 0, 0)), InvalidValueError, "non-zero"),
    (lambda: AxisAlignTask(ROBOT, "ee", axis=(0, 1)), ShapeError, "axis"),
    (lambda: LookAtTask(ROBOT, "ee", weight=-1.0), InvalidValueError, "weight"),
    (lambda: ManipulabilityTask(ROBOT, "ee", rate=np.inf), WbcError, "rate"),
    (lambda: ManipulabilityTask(ROBOT, "nope"), UnknownNameError, "nope"),
])
def test_bad_inputs_raise_clear_errors(build, error, match):
    with pytest.raises(error, match=match):
        build()


def test_pointing_target_must_be_set_and_shaped():
    stack = _stack()
    stack.add(LookAtTask(ROBOT, "ee", name="look"))
    ctrl = _controller(stack, backend="daqp")
    with pytest.raises(WbcError):
        ctrl.step(ROBOT.neutral())  # no target yet
    with pytest.raises(ShapeError):
        ctrl.step(ROBOT.neutral(), look=np.ones(4))
