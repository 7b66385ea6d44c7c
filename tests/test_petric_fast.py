"""The petric controllers' fast path (``fused="auto"``: the QPs — the arm's fused cascade, the
whole-body cascade's tick of :mod:`wbc.papers.petric.fast` — the TEE point and the velocity
field as generated C) computes what their ordinary path (``fused=False``) computes: commands,
statuses and the field's state, on the study's recorded states and on random states of the
Tiago + Panda. Equality only; speed is measured by ``wbc study petric``."""

from __future__ import annotations

import math
from functools import partial

import numpy as np
import pytest

import wbc
from wbc.cbuild import compiler_available
from wbc.errors import NonFiniteError, ShapeError
from wbc.experiments.studies import petric as study
from wbc.experiments.studies.study import interleaved_timing
from wbc.papers.petric import (
    DecoupledController,
    FieldDriver,
    VelocityField,
    WholeBodyController,
    WholeBodyQPController,
    arm_stack,
    whole_body_stack,
)
from wbc.papers.petric.fast import FAST_QP_LABELS, WholeBodyFastWorkspace
from wbc.robots import load

pytestmark = pytest.mark.skipif(not compiler_available(), reason="no C compiler")

TOL = 1e-6  # the project's equality tolerance for a fast path
FIELD_TOL = 1e-12  # the field alone: the same floating-point operations, C against Python


@pytest.fixture(scope="module")
def robot():
    return load("tiago_panda")


def _random_state(robot, rng):
    """A random configuration, a TCP target within 0.3 m of the TCP per axis, and a random
    field state: previous command, latched heading (or none)."""
    q = robot.random_configuration(rng)
    target = np.eye(4)
    target[:3, 3] = robot.frame_pose(q, "ee")[:3, 3] + rng.uniform(-0.3, 0.3, 3)
    field_state = np.r_[rng.uniform(-1.0, 1.0, 2), rng.uniform(-math.pi, math.pi),
                        float(rng.integers(2))]
    return q, target, field_state


@pytest.mark.parametrize("make", [DecoupledController, WholeBodyController,
                                  partial(DecoupledController, projector="damped")],
                         ids=["decoupled", "whole_body", "decoupled_eq26"])
def test_random_states_fast_equals_ordinary(robot, make):
    fast, ordinary = make(robot, VelocityField()), make(robot, VelocityField(), fused=False)
    assert fast.driver.fused and not ordinary.driver.fused
    whole_body = make is WholeBodyController
    if whole_body:
        assert isinstance(fast.qp.workspace, WholeBodyFastWorkspace)
    rng = np.random.default_rng(28)
    retreat = latched = answered = 0
    for _ in range(1000):
        q, target, field_state = _random_state(robot, rng)
        for controller in (fast, ordinary):
            controller.driver.field.state[:] = field_state
        handed_over = fast.qp.workspace.fallback_solves if whole_body else 0
        a, b = fast.step(q, None, ee=target), ordinary.step(q, None, ee=target)
        np.testing.assert_allclose(a, b, rtol=0.0, atol=TOL)
        fields = fast.driver.field, ordinary.driver.field
        # (v, ω, heading, latched): the heading latched or released alike
        np.testing.assert_allclose(fields[0].state, fields[1].state, rtol=0.0, atol=FIELD_TOL)
        assert fast.last_solution.status == ordinary.last_solution.status
        assert fast.last_solution.fallback == ordinary.last_solution.fallback
        retreat += fields[1].heading is not None
        latched += fields[1].heading is not None and bool(field_state[3])
        if whole_body:
            # the fast tick answers exactly where the ordinary cascade reaches the field's
            # twist (level 1 at 0), and hands every other tick over
            fast_answered = fast.qp.workspace.fallback_solves == handed_over
            assert fast_answered == (np.abs(b[:2] - fields[1].command).max() <= TOL)
            answered += fast_answered
    # every branch of the field was taken: retreat zone entered, and with a latched heading
    assert retreat > 100 and latched > 50
    if whole_body:  # (212 of 1000 measured)
        assert 150 < answered < 850


def test_field_alone_on_points_of_every_mode(robot):
    """The compiled field (reached through q) against ``VelocityField.step`` at the same TEE
    point, along random configurations with the state carried from tick to tick."""
    fast, ordinary = (FieldDriver(robot, VelocityField(), fused) for fused in (True, False))
    rng = np.random.default_rng(1)
    q = robot.neutral()
    modes = set()
    for _ in range(2000):
        q = q + rng.normal(0.0, 0.15, robot.nq)  # a random walk: the state carries over
        a, b = fast.base_command(q), ordinary.base_command(q)
        np.testing.assert_allclose(a, b, rtol=0.0, atol=FIELD_TOL)
        np.testing.assert_array_equal(fast.field.state[3], ordinary.field.state[3])
        d_f, d_r, _ = ordinary.field.distances(ordinary.tee(q))
        modes.add("retreat" if d_r < ordinary.field.delta_r else
                  "forward" if d_f < ordinary.field.delta_f else "still")
    assert modes == {"retreat", "forward", "still"}


@pytest.mark.parametrize("scenario", list(study.SCENARIOS))
def test_study_recorded_states(robot, scenario):
    """The study's quick runs (decoupled and whole-body) with the fast controller; the
    ordinary one replayed on the recorded states gives the same commands and statuses. The
    whole-body fast tick, replayed too, answers exactly the ticks on which the ordinary cascade
    reaches the field's twist (2317 of the 2720 quick ticks; the rest, saturated, it hands
    over)."""
    staging = study.stagings(robot, None)[scenario]
    reference = study._staged_trajectory(robot, scenario, 0.4, staging)[1]
    for make in (DecoupledController, WholeBodyController):
        fast = make(robot, VelocityField())
        run = study._simulate(robot, fast, scenario, 0.4, staging)
        ordinary = make(robot, VelocityField(), fused=False)
        replay = WholeBodyController(robot, VelocityField())
        answered = 0
        for k, t in enumerate(run.t):
            command = ordinary.step(run.q_est[k], run.v_est[k], **reference(t))
            np.testing.assert_allclose(run.command[k], command, rtol=0.0, atol=TOL)
            assert run.status[k] == ordinary.last_solution.status.value
            if make is WholeBodyController:
                handed_over = replay.qp.workspace.fallback_solves
                replay.step(run.q_est[k], run.v_est[k], **reference(t))
                fast_answered = replay.qp.workspace.fallback_solves == handed_over
                reached = np.abs(command[:2] - ordinary.driver.field.command).max() <= TOL
                assert fast_answered == reached
                answered += fast_answered
        if make is WholeBodyController:
            assert answered >= len(run.t) // 3  # (at least 161 of 240 measured, forward)


def test_interleaved_timing_reports_both_paths(robot):
    staging = study.stagings(robot, None)["forward"]
    reference = study._staged_trajectory(robot, "forward", 1.0, staging)[1]
    q = staging.q0
    states = [(q, np.zeros(robot.nv), reference(0.02 * k)) for k in range(12)]
    timing = interleaved_timing(DecoupledController(robot, VelocityField()),
                                DecoupledController(robot, VelocityField(), fused=False),
                                states, passes=2, warm_up=5,
                                reset=lambda controller: controller.driver.reset())
    assert timing["ticks"] == 2 * 12 - 5 and timing["passes"] == 2
    assert timing["ordinary_tick_median_s"] > 0 and timing["tick_median_s"] > 0
    assert timing["max_command_difference"] <= TOL


def test_whole_body_fast_tick_solution_and_qps(robot):
    """A fast tick's solution (levels, x within the bounds) and the QPs it reports: the
    command solves the last one (its equality rows: the TCP rows where level 0 left them and
    the base at the field's twist)."""
    controller = WholeBodyController(robot, VelocityField())
    q, target, _ = _random_state(robot, np.random.default_rng(3))
    target[:3, 3] = robot.frame_pose(q, "ee")[:3, 3] + 0.01  # near: nothing saturates
    command = controller.step(q, None, ee=target)
    workspace = controller.qp.workspace
    assert workspace.fallback_solves == 0
    solution = controller.last_solution
    assert [level.label for level in solution.levels] == [
        block.label for block in controller.qp.compiled.blocks]
    np.testing.assert_array_equal(solution.levels[2].x, command)
    (label0, qp0, _), (label, (H, g, A, lower_a, upper_a, lower, upper), result) = (
        workspace.last_qps())
    assert (label0, label) == FAST_QP_LABELS
    np.testing.assert_array_equal(lower_a, upper_a)
    np.testing.assert_allclose(A @ command, lower_a, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(command[:2], controller.driver.field.command, atol=1e-9)
    assert np.all(command >= lower) and np.all(command <= upper)
    np.testing.assert_array_equal(qp0[5], lower)  # level 0's bounds: the same limits


def test_whole_body_fast_path_applies_only_to_its_cascade(robot):
    def make(stack, backend="daqp", fused="auto"):
        return WholeBodyQPController(robot, stack, backend=backend, dt=0.02,
                                     missing_limits="ignore", fused=fused)

    assert make(whole_body_stack(robot)).fused
    assert not make(whole_body_stack(robot), fused=False).fused
    other = make(whole_body_stack(robot), backend="quadprog")
    assert not other.fused and "backend" in other.fused_reason
    with pytest.raises(wbc.WbcError, match="three least-squares levels"):
        make(arm_stack(robot), fused=True)
    damped = whole_body_stack(robot)
    damped._damping[1] = 0.01  # level 1's optimum is then not its target reached
    assert "damped" in make(damped).fused_reason
    with pytest.raises(wbc.WbcError, match="damped"):
        WholeBodyFastWorkspace(damped, damped.compile())


def test_switch(robot):
    controller = DecoupledController(robot, VelocityField(), fused=False)
    assert not controller.arm.fused and not controller.driver.fused
    controller = DecoupledController(robot, VelocityField(), fused=True)
    assert controller.arm.fused and controller.driver.fused
    with pytest.raises(Exception, match="fused"):
        FieldDriver(robot, VelocityField(), fused="yes")


def test_fast_driver_refuses_bad_q_and_keeps_its_state(robot):
    driver = FieldDriver(robot, VelocityField())
    q = robot.neutral()
    driver.base_command(q)
    before = driver.field.state.copy()
    bad = q.copy()
    bad[4] = math.nan
    with pytest.raises(NonFiniteError):
        driver.base_command(bad)
    with pytest.raises(ShapeError):
        driver.base_command(q[:-1])
    np.testing.assert_array_equal(driver.field.state, before)


def test_reset_clears_the_compiled_state(robot):
    """``reset`` writes the field's state in place, which the compiled tick reads."""
    driver, fresh = FieldDriver(robot, VelocityField()), FieldDriver(robot, VelocityField())
    q = robot.neutral()
    q[robot.nq - robot.n_arm:] = [0.0, 1.2, 0.0, -0.4, 0.0, 1.6, 0.8]  # reaching far: forward
    for _ in range(5):
        driver.base_command(q)
    assert driver.field.command[0] > 0.0
    driver.reset()
    assert driver.field.heading is None and np.all(driver.field.command == 0.0)
    np.testing.assert_array_equal(driver.base_command(q), fresh.base_command(q))
