"""Acceleration bounds from joint limits (Xing et al. eqs. 6–8, and Del Prete's viable bounds).

Measured by :func:`test_closed_loops_inside_the_bounds` (10⁴ random single-joint closed loops of
300 ticks, accelerations drawn inside the bounds, half of them bang-bang at a bound): the
``"viable"`` bounds never cross and never let a limit be violated; Xing's bounds as printed
cross in about 28 % of the loops and a limit is violated in about 55 % of them (see that test's
docstring for why).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import wbc
import wbc.robots as robots
from wbc.errors import InvalidValueError, NonFiniteError, ShapeError
from wbc.experiments.studies import xing
from wbc.tasks import JointAccelerationLimit, joint_acceleration_bounds
from wbc.tasks.joint_acceleration import _CASADI, _bounds

T = 0.01


def eqs_7_8(q, qd, q_min, q_max, v_min, v_max, a_min, a_max, dt):
    """Xing et al. eqs. (7)–(8) for one joint, written out with Python's if/else."""
    q_low = q_min - abs(qd) * qd / (2 * a_max)
    q_up = q_max + abs(qd) * qd / (2 * a_min)
    if q > q_low:
        lower = max(2 * (q_min - q - qd * dt) / dt**2, (v_min - qd) / dt, a_min)
    else:
        lower = a_max
    if q < q_up:
        upper = min(2 * (q_max - q - qd * dt) / dt**2, (v_max - qd) / dt, a_max)
    else:
        upper = a_min
    return lower, upper


joint = st.tuples(
    st.floats(-3.0, -0.1), st.floats(0.1, 3.0),  # q_min, q_max
    st.floats(0.1, 3.0), st.floats(0.2, 10.0),  # V, A (symmetric limits)
    st.floats(0.0, 1.0), st.floats(-1.0, 1.0),  # position in the range, velocity / V
)


@given(joint)
def test_xing_is_eqs_7_8_as_printed(limits):
    q_min, q_max, V, A, s, r = limits
    q, qd = q_min + s * (q_max - q_min), r * V
    lower, upper = joint_acceleration_bounds(q, qd, q_min, q_max, -V, V, -A, A, T, "xing")
    expected = eqs_7_8(q, qd, q_min, q_max, -V, V, -A, A, T)
    np.testing.assert_allclose([lower, upper], expected, rtol=1e-12, atol=1e-12)


def test_xing_braking_point_of_fig_2():
    """Fig. 2's joint (±2.5 rad, ±1.75 rad/s, ±3 rad/s²) at V_max/2 = 0.875 rad/s: the upper
    bound switches to A_min at Q_up = 2.5 − 0.875²/6 ≈ 2.3724 rad."""
    args = dict(q_min=-2.5, q_max=2.5, v_min=-1.75, v_max=1.75, a_min=-3.0, a_max=3.0, dt=T)
    q_up = 2.5 - 0.875**2 / 6
    _, before = joint_acceleration_bounds(q_up - 1e-6, 0.875, **args)
    _, after = joint_acceleration_bounds(q_up + 1e-6, 0.875, **args)
    assert before == 3.0 and after == -3.0


@given(joint, st.sampled_from(["xing", "viable"]))
def test_infinite_position_limits_leave_velocity_and_acceleration(limits, method):
    _, _, V, A, _, r = limits
    qd = r * V
    lower, upper = joint_acceleration_bounds(12.3, qd, -np.inf, np.inf, -V, V, -A, A, T,
                                             method)
    assert lower == pytest.approx(max((-V - qd) / T, -A))
    assert upper == pytest.approx(min((V - qd) / T, A))


def _viable(q, qd, q_min, q_max, A):
    return (q + max(qd, 0.0) ** 2 / (2 * A) <= q_max) and (q - min(qd, 0.0) ** 2 / (2 * A)
                                                           >= q_min)


@given(joint)
def test_viable_bounds_are_ordered_and_keep_the_next_state_viable(limits):
    q_min, q_max, V, A, s, r = limits
    q, qd = q_min + s * (q_max - q_min), r * V
    if not _viable(q, qd, q_min, q_max, A):
        q, qd = q_min + s * (q_max - q_min), 0.0
    lower, upper = joint_acceleration_bounds(q, qd, q_min, q_max, -V, V, -A, A, T, "viable")
    assert -A <= lower <= upper <= A
    for a in (lower, upper):  # both extremes lead to a viable, in-limit state
        q1, qd1 = q + qd * T + a * T * T / 2, qd + a * T
        assert q_min - 1e-12 <= q1 <= q_max + 1e-12 and -V - 1e-12 <= qd1 <= V + 1e-12
        assert _viable(q1, qd1, q_min - 1e-9, q_max + 1e-9, A)


def test_closed_loops_inside_the_bounds():
    """10⁴ random loops: "viable" never crosses nor violates. Xing's bounds as printed do
    both: the position term asks to stop at the limit within one period whatever the
    acceleration limit, and the braking points Q_low / Q_up switch to maximal deceleration
    only once the continuous braking distance is used up, one period too late."""
    crossed, violated, overshoot = xing.random_joint_loops("viable")
    assert crossed.sum() == 0 and violated.sum() == 0 and overshoot.max() <= 1e-9
    crossed, violated, overshoot = xing.random_joint_loops("xing")
    assert 0.1 < crossed.mean() < 0.5 and 0.3 < violated.mean() < 0.8
    # issue #29's figures: the violators overshoot by a median 7 mrad, at most 0.68 rad
    assert np.median(overshoot[violated]) == pytest.approx(7.0e-3, abs=1e-4)
    assert overshoot.max() == pytest.approx(0.677, abs=1e-3)


@pytest.mark.parametrize("method", ["xing", "viable"])
def test_compiled_bounds_equal_the_numpy_reference(method):
    robot = robots.load("mecanum_gen3")
    stack = wbc.Stack(wbc.Variables(qdd=robot.nv))
    stack.add(wbc.tasks.LinearTask(np.eye(robot.nv), np.zeros(robot.nv), name="zero"))
    stack.constrain(JointAccelerationLimit(robot, T, method, name="limits"))
    ws = stack.workspace("daqp")
    lim = robot.limits
    rng = np.random.default_rng(3)
    n_arm = robot.n_arm
    q_min = np.concatenate([np.full(3, -np.inf), lim.q_lower[3:]])
    q_max = np.concatenate([np.full(3, np.inf), lim.q_upper[3:]])
    for _ in range(50):
        q = robot.random_configuration(rng)
        v = rng.uniform(lim.v_lower, lim.v_upper)
        if method == "viable":  # a viable state, so that the QP is feasible
            q[3:] = np.clip(q[3:], lim.q_lower[3:] + 1.0, lim.q_upper[3:] - 1.0)
        ws.set(q=q, v=v)
        ws.solve()
        lower, upper = ws.variable_bounds()
        positions = np.concatenate([np.zeros(robot.nv - n_arm), q[-n_arm:]])
        expected = joint_acceleration_bounds(positions, v, q_min, q_max, lim.v_lower,
                                             lim.v_upper, lim.a_lower, lim.a_upper, T, method)
        np.testing.assert_allclose(lower, expected[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(upper, expected[1], rtol=1e-12, atol=1e-12)


def test_the_compiled_bounds_are_symbolic():
    """One CasADi expression of (q, qd): nothing is evaluated in numpy per tick."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    lower, upper = _bounds(_CASADI, q, qd, ca.DM([-1, -np.inf]), ca.DM([1, np.inf]),
                           ca.DM([-1, -1]), ca.DM([1, 1]), ca.DM([-2, -2]), ca.DM([2, 2]), T,
                           "viable")
    assert ca.depends_on(upper, q) and ca.depends_on(lower, qd)


def test_bad_input_is_refused_with_the_name():
    ok = dict(q_min=-1.0, q_max=1.0, v_min=-1.0, v_max=1.0, a_min=-2.0, a_max=2.0, dt=T)
    with pytest.raises(InvalidValueError, match="method"):
        joint_acceleration_bounds(0.0, 0.0, **ok, method="flacco")
    with pytest.raises(InvalidValueError, match="dt"):
        joint_acceleration_bounds(0.0, 0.0, **{**ok, "dt": 0.0})
    with pytest.raises(InvalidValueError, match="a_min < 0 < a_max"):
        joint_acceleration_bounds(0.0, 0.0, **{**ok, "a_min": 0.5})
    with pytest.raises(NonFiniteError, match="q and qd"):
        joint_acceleration_bounds(np.nan, 0.0, **ok)
    with pytest.raises(NonFiniteError, match="v_max"):
        joint_acceleration_bounds(0.0, 0.0, **{**ok, "v_max": np.inf})
    with pytest.raises(ShapeError, match="broadcast"):
        joint_acceleration_bounds(np.zeros(2), np.zeros(3), **ok)
    with pytest.raises(InvalidValueError, match="'limits'.*dt"):
        JointAccelerationLimit(robots.load("mecanum_gen3"), -1.0, name="limits")


@pytest.mark.parametrize("method", ["viable", "xing"])
def test_a_qp_pushing_a_joint_into_its_limit(method):
    """Closed loop on wbc.sim (exact actuation, acceleration commands): a task asking joint 2
    of the Gen3 (±2.2 rad) for 100 rad/s² under JointAccelerationLimit. The viable bounds stop
    it at the limit; Xing's bounds as printed overshoot it (measured: by 3.5 mrad, and their
    bounds cross once: one failed tick)."""
    from wbc.sim import Simulation

    robot = robots.load("mecanum_gen3")
    dt = 0.01
    stack = wbc.Stack(wbc.Variables(qdd=robot.nv), damping=1e-3)
    push = np.zeros((1, robot.nv))
    push[0, 4] = 1.0
    stack.add(wbc.tasks.LinearTask(push, [100.0], name="push"))
    stack.constrain(JointAccelerationLimit(robot, dt, method, name="limits"))
    controller = wbc.Controller(robot, stack, "daqp", dt=dt)
    run = Simulation(robot, controller, dt, command="acceleration").run(seconds=2.0)
    lim = robot.limits
    assert run.q[:, 4].max() > 2.0  # it got there
    overshoot = run.q[:, 4].max() - lim.q_upper[4]
    if method == "viable":
        assert overshoot <= 1e-9 and run.failures == 0
        assert np.all(np.abs(run.v) <= lim.v_upper + 1e-9)
    else:
        assert overshoot > 1e-3  # the braking point comes one period too late
