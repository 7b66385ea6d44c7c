"""The petric controllers' fast path (``fused="auto"``: the arm's fused QPs, the TEE point and
the velocity field as generated C) computes what their ordinary path (``fused=False``)
computes: commands, statuses and the field's state, on the study's recorded states and on
random states of the Tiago + Panda. Equality only; speed is measured by ``wbc study petric``."""

from __future__ import annotations

import math
from functools import partial

import numpy as np
import pytest

from wbc.cbuild import compiler_available
from wbc.errors import NonFiniteError, ShapeError
from wbc.experiments.studies import petric as study
from wbc.experiments.studies.study import interleaved_timing
from wbc.papers.petric import (
    DecoupledController,
    FieldDriver,
    VelocityField,
    WholeBodyController,
)
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
    rng = np.random.default_rng(28)
    retreat = latched = 0
    for _ in range(1000):
        q, target, field_state = _random_state(robot, rng)
        for controller in (fast, ordinary):
            controller.driver.field.state[:] = field_state
        a, b = fast.step(q, None, ee=target), ordinary.step(q, None, ee=target)
        np.testing.assert_allclose(a, b, rtol=0.0, atol=TOL)
        fields = fast.driver.field, ordinary.driver.field
        # (v, ω, heading, latched): the heading latched or released alike
        np.testing.assert_allclose(fields[0].state, fields[1].state, rtol=0.0, atol=FIELD_TOL)
        assert fast.last_solution.status == ordinary.last_solution.status
        assert fast.last_solution.fallback == ordinary.last_solution.fallback
        retreat += fields[1].heading is not None
        latched += fields[1].heading is not None and bool(field_state[3])
    # every branch of the field was taken: retreat zone entered, and with a latched heading
    assert retreat > 100 and latched > 50


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
    ordinary one replayed on the recorded states gives the same commands and statuses."""
    staging = study.stagings(robot, None)[scenario]
    reference = study._staged_trajectory(robot, scenario, 0.4, staging)[1]
    for make in (DecoupledController, WholeBodyController):
        fast = make(robot, VelocityField())
        run = study._simulate(robot, fast, scenario, 0.4, staging)
        ordinary = make(robot, VelocityField(), fused=False)
        for k, t in enumerate(run.t):
            command = ordinary.step(run.q_est[k], run.v_est[k], **reference(t))
            np.testing.assert_allclose(run.command[k], command, rtol=0.0, atol=TOL)
            assert run.status[k] == ordinary.last_solution.status.value


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
