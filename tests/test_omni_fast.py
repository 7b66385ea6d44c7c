"""The omni force controller's fast path (generated model stage + fused distribution QP) against
its ordinary path: the same commands, attributes and errors, on the study's recorded states and
on random states of ``omni4_arm6``. Equality and behaviour only; speed is measured by
``wbc study omni`` (``timing["daqp"]``), never asserted here."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wbc.robots as robots
from wbc.cbuild import compiler_available
from wbc.errors import WbcError
from wbc.experiments.studies.omni import PARAMETERS, SCENARIOS, simulate
from wbc.papers.omni import DISTRIBUTIONS, FUSED_METHODS, OmniForceControl, TorqueDistribution
from wbc.papers.omni import closed_form as ref

pytestmark = pytest.mark.skipif(not compiler_available(), reason="needs a C compiler")

TOL = 1e-6
MU = PARAMETERS["mu"]


@pytest.fixture(scope="module")
def robot():
    return robots.load("omni4_arm6")


def _pair(robot, method: str) -> tuple[OmniForceControl, OmniForceControl, list[int]]:
    """The default controller, the ordinary one (``fused=False`` throughout) and a counter of
    the default controller's ticks the ordinary path answered."""
    J = robot.base.jacobian
    fast = OmniForceControl(robot, mu=MU, distribution=TorqueDistribution(J, method, MU))
    ordinary = OmniForceControl(robot, mu=MU, fused=False,
                                distribution=TorqueDistribution(J, method, MU, fused=False))
    assert fast.fused and not ordinary.fused
    assert fast.distribution.fused == (method in FUSED_METHODS)
    handed_over = [0]
    step = fast._ordinary_step

    def counted(*args):
        handed_over[0] += 1
        return step(*args)

    fast._ordinary_step = counted  # type: ignore[method-assign]
    return fast, ordinary, handed_over


def _outcome(control: OmniForceControl, q, v, references: dict):
    """``(command, wrench, normal forces, status)`` of one tick, or the exception's type and
    message."""
    try:
        tau = control.step(q, v, **references)
    except (WbcError, ValueError) as err:
        return type(err), str(err)
    status = None if control.last_solution is None else control.last_solution.status
    return tau, control.last_wrench, control.last_normal_forces, status


def _same(a, b) -> float:
    """Largest difference of two outcomes (they must be of the same kind)."""
    if isinstance(a[0], type):
        assert a == b
        return 0.0
    assert a[3] == b[3]
    return max(float(np.abs(x - y).max()) for x, y in zip(a[:3], b[:3], strict=True))


@pytest.fixture(scope="module")
def recorded(robot):
    """Every tick's ``(q, v, references)`` of the study's proportional runs (the states its
    timing replays are every fourth of these), quick sub-steps."""
    states = []
    for scenario in SCENARIOS:
        run, references, _ = simulate(robot, scenario, "proportional", "daqp", 5)
        states += [(q, v, references(t)) for q, v, t in zip(run.q_est, run.v_est, run.t,
                                                            strict=True)]
    return states


@pytest.mark.parametrize("method", DISTRIBUTIONS)
def test_recorded_states(robot, recorded, method):
    fast, ordinary, handed_over = _pair(robot, method)
    worst = max(_same(_outcome(fast, *state), _outcome(ordinary, *state)) for state in recorded)
    assert worst <= TOL
    assert handed_over[0] == 0  # every tick took the fast path


@pytest.mark.parametrize("method", DISTRIBUTIONS)
def test_random_states(robot, method):
    """≥ 1000 answered random states (arm anywhere in ±π: many lift a wheel, which both paths
    refuse alike), wrenches up to a few kN."""
    fast, ordinary, handed_over = _pair(robot, method)
    rng = np.random.default_rng(7)
    answered = refused = 0
    worst = 0.0
    while answered < 1000:
        q = np.concatenate([rng.uniform(-3, 3, 3), rng.uniform(-math.pi, math.pi, 6)])
        v = rng.normal(0.0, 0.5, robot.nv)
        references = {"target": rng.uniform(-3, 3, 3), "velocity": rng.normal(0.0, 0.5, 3),
                      "acceleration": rng.normal(0.0, 1.0, 3)}
        a, b = _outcome(fast, q, v, references), _outcome(ordinary, q, v, references)
        worst = max(worst, _same(a, b))
        if isinstance(a[0], type):
            refused += 1
        else:
            answered += 1
    assert worst <= TOL
    assert refused > 0 and handed_over[0] == refused  # only the refused ticks left the fast path


def test_edge_inputs(robot):
    """Inputs the fast path hands to the ordinary path, and a heading tie: same outcome."""
    fast, ordinary, handed_over = _pair(robot, "proportional")
    q, v = robot.neutral(), np.zeros(robot.nv)
    target = np.array([0.1, -0.2, math.pi])  # from heading 0: math.remainder's tie, +π
    cases = [
        (q, v, {"target": target}),  # velocity and acceleration default to zero
        (q, v, {"target": [0.1, -0.2, 0.3]}),  # a list: ordinary path
        (q, v, {"target": target, "velocity": None}),  # refused by the ordinary path
        (q, v, {}),  # no target
        (q, np.full(robot.nv, np.nan), {"target": target}),  # NaN velocity
        (np.r_[q[:2], np.inf, q[3:]], v, {"target": target}),  # math.remainder raises
        (np.r_[q[:3], 0.0, -1.0, 2.5, 0.0, 0.0, 0.0], v, {"target": target}),  # lifts a wheel
        (q, v, {"target": target, "acceleration": np.full(3, 1e308)}),  # f_d overflows
    ]
    for state in cases:
        assert _same(_outcome(fast, *state), _outcome(ordinary, *state)) <= TOL
    assert handed_over[0] == len(cases) - 1


def test_switches(robot):
    J = robot.base.jacobian
    assert OmniForceControl(robot).fused is False  # closed forms: nothing to fuse
    with pytest.raises(WbcError, match="not a TorqueDistribution"):
        OmniForceControl(robot, fused=True)
    off = OmniForceControl(robot, distribution=TorqueDistribution(J), fused=False)
    assert not off.fused and off.fused_reason == "turned off (fused=False)"
    three_wheels = OmniForceControl(robot, distribution=TorqueDistribution(J[:3]))
    assert not three_wheels.fused and "3 wheels" in three_wheels.fused_reason
    minmax = TorqueDistribution(J, "minmax")
    assert not minmax.fused and "minmax" in minmax.fused_reason
    with pytest.raises(WbcError, match="cannot be fused"):
        TorqueDistribution(J, "minmax", fused=True)
    assert not TorqueDistribution(J, backend="quadprog").fused
    with pytest.raises(WbcError, match="fused must be"):
        OmniForceControl(robot, fused="yes")


@pytest.mark.parametrize("method", FUSED_METHODS)
def test_fused_distribution(robot, method):
    """The fused QP alone against the ordinary backend and the closed form."""
    J = robot.base.jacobian
    fused, ordinary = TorqueDistribution(J, method, MU), TorqueDistribution(J, method, MU,
                                                                            fused=False)
    rng = np.random.default_rng(3)
    for _ in range(1000):
        f_d = rng.normal(size=3) * 10 ** rng.uniform(0, 3.5)
        forces = rng.uniform(5.0, 400.0, 4)
        tau = fused(f_d, forces)
        assert np.abs(tau - ordinary(f_d, forces)).max() <= TOL
        assert np.abs(tau - ref.torque_distribution(J, f_d, forces, MU, method)).max() <= TOL
    assert fused.workspace.fallback_solves == 0


def test_a_solution_read_is_not_rewritten_by_the_next_solve(robot):
    # the fused workspace reuses one solution object: what a caller read stays as it was
    distribution = TorqueDistribution(robot.base.jacobian, "proportional", MU)
    assert distribution.fused
    forces = np.full(4, 110.0)
    tau = distribution([20.0, 0.0, 0.0], forces)
    first = distribution.last_solution
    kept = first.x.copy()
    distribution([0.0, 30.0, 1.0], forces)
    assert np.array_equal(first.x, kept) and np.array_equal(first.x[:4], tau)
    assert distribution.last_solution is not first
    assert not np.array_equal(distribution.last_solution.x, kept)
