"""`ClosedFormPlanner` computes its whole model (task rows, command, q̈_sa with the appendix's
∇H and ∇²H q̇_m, σ_min, the joint bounds, the base transition) in one compiled CasADi call.
Its commands and readings must equal the former numpy model (kept here as the referee,
:class:`_NumpyModel`) within 1e-9 on random states and on every tick of the study's
closed loops (quick horizons)."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

import wbc.robots as robots
from wbc.errors import InvalidValueError
from wbc.experiments.studies import xing as study
from wbc.papers.xing import POSE, POSITION, ClosedFormPlanner
from wbc.papers.xing import closed_form as ref
from wbc.papers.xing.stacks import cartesian_command, symbolic_quantity
from wbc.quantities import registry_of
from wbc.tasks import joint_acceleration_bounds
from wbc.tasks.manipulability import arm_jacobian_derivatives

TOL = 1e-9


class _NumpyModel:
    """The planners' model as it was: CasADi (virtual machine) for the task rows and ``J_m``
    with its derivatives; ∇H, ∇²H q̇_m, q̈_sa, σ_min (SVD), the bounds and the base transition
    in numpy (:mod:`wbc.papers.xing.closed_form`, :func:`joint_acceleration_bounds`)."""

    def __init__(self, robot, setup):
        self.robot, self.setup = robot, setup
        self.nq, self.nv, self.n_arm = int(robot.nq), int(robot.nv), int(robot.n_arm)
        self.n_base = self.nv - self.n_arm
        registry = registry_of(robot)
        q, v = ca.SX.sym("q", self.nq), ca.SX.sym("v", self.nv)
        target = ca.SX.sym("target", 4, 4)
        tv, ta = ca.SX.sym("tv", 6), ca.SX.sym("ta", 6)
        pose = symbolic_quantity(registry, "pose[ee]")(q)
        J = symbolic_quantity(registry, "J[ee]")(q)
        drift = symbolic_quantity(registry, "Jdot_v[ee]")(q, v)
        outputs = cartesian_command(pose, J, drift, v, target, tv, ta, ca.DM(setup.kd),
                                    ca.DM(setup.kp), setup.rows)
        derivatives = arm_jacobian_derivatives(robot)(q, v[self.n_base:])
        self.function = ca.Function("reference", [q, v, target, tv, ta],
                                    [*outputs, *derivatives])
        lim = robot.limits
        self.q_min = np.concatenate([np.full(self.n_base, -np.inf), lim.q_lower[-self.n_arm:]])
        self.q_max = np.concatenate([np.full(self.n_base, np.inf), lim.q_upper[-self.n_arm:]])

    def terms(self, q, v, target, target_velocity, target_acceleration):
        """``(J_r, drift_r, ẍ_cmd, q̈_sa, σ_min)``."""
        m = self.n_arm
        J, drift, xdd, J_m, dJ, dJ_dot = (np.array(o) for o in self.function(
            q, v, target, target_velocity, target_acceleration))
        dJ = dJ.reshape(m, 3, m).transpose(2, 1, 0)  # rows i + 3j -> [k, i, j]
        dJ_dot = dJ_dot.reshape(m, 3, m).transpose(2, 1, 0)
        v_arm = v[self.n_base:]
        qdd_sa = np.zeros(self.nv)
        qdd_sa[self.n_base:] = ref.manipulability_acceleration(
            ref.manipulability_gradient(J_m, dJ),
            ref.manipulability_hessian_product(J_m, dJ, dJ_dot, v_arm), v_arm,
            self.setup.gamma1, self.setup.gamma2)
        sigma = float(np.linalg.svd(J_m, compute_uv=False)[-1])
        return J, drift[:, 0], xdd[:, 0], qdd_sa, sigma

    def bounds(self, q, v):
        positions = np.concatenate([np.zeros(self.n_base), q[-self.n_arm:]])
        lim = self.robot.limits
        return joint_acceleration_bounds(positions, v, self.q_min, self.q_max, lim.v_lower,
                                         lim.v_upper, lim.a_lower, lim.a_upper, self.setup.dt,
                                         self.setup.bounds)

    def tick(self, q, v, refs) -> dict:
        """At one state: ``terms``, ``bounds`` and each method's ``(command, AMPInfo or
        None)``, as the former ``ClosedFormPlanner`` computed them."""
        terms = self.terms(q, v, **refs)
        J, drift, xdd, qdd_sa, sigma = terms
        lower, upper = self.bounds(q, v)
        lim = self.robot.limits
        base = slice(0, self.n_base)
        transition = ref.base_transition(v[base], lim.a_lower[base], lim.a_upper[base],
                                         self.setup.dt)
        return {"terms": terms, "bounds": (lower, upper),
                "traditional": (ref.traditional(J, xdd, drift, qdd_sa), None),
                "amp": ref.amp(J, xdd, drift, lower, np.maximum(lower, upper), self.n_base,
                               qdd_sa=qdd_sa, transition=transition, sigma_min=sigma,
                               sigma_thr=self.setup.sigma_thr)}


@pytest.fixture(scope="module")
def robot():
    return robots.load(study.ROBOT)


def _assert_same_tick(planner, expected: dict, q, v, refs) -> None:
    """One state: the planner's command, ``last_info``, ``terms`` and ``bounds`` agree with
    the referee's (:meth:`_NumpyModel.tick`) within TOL."""
    command = planner.step(q, v, **refs)
    want, info = expected[planner.method]
    np.testing.assert_allclose(command, want, rtol=0, atol=TOL)
    if info is not None:
        got = planner.last_info
        assert (got.reason, got.base_enabled) == (info.reason, info.base_enabled)
        np.testing.assert_array_equal(got.free, info.free)
        np.testing.assert_allclose([got.alpha, got.beta], [info.alpha, info.beta], rtol=0,
                                   atol=TOL)
    for got, want in zip(planner.terms(q, v, **refs), expected["terms"], strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL)
    for got, want in zip(planner.bounds(q, v), expected["bounds"], strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


# the position setup in compiled C (the study's full runs; one build per test session, its
# library shared by both tests), the others in CasADi's virtual machine (no further builds)
@pytest.mark.parametrize(("setup", "states", "jit"), [
    (POSITION, 1000, True), (POSE, 300, False), (replace(POSITION, bounds="viable"), 300, False)],
    ids=["position", "pose", "viable"])
def test_equals_the_numpy_model_on_random_states(robot, setup, states, jit):
    rng = np.random.default_rng(7)
    referee = _NumpyModel(robot, setup)
    planners = [ClosedFormPlanner(robot, setup, method, jit)
                for method in ("amp", "traditional")]
    reasons = set()
    for _ in range(states):
        q, v, refs = study.random_state(rng, robot)
        expected = referee.tick(q, v, refs)
        for planner in planners:
            _assert_same_tick(planner, expected, q, v, refs)
        reasons.add(planners[0].last_info.reason)
    # the states reach both the arm-alone and the base-enabled branches of AMP
    assert {"arm", "saturation"} <= reasons


class _Refereed:
    """A controller for :func:`study.simulate`: the planner, checked against the referee at
    every tick it is asked for."""

    last_solution = None

    def __init__(self, planner, referee: _NumpyModel):
        self.planner, self.referee, self.ticks = planner, referee, 0

    def step(self, q, v, **refs):
        _assert_same_tick(self.planner, self.referee.tick(q, v, refs), q, v, refs)
        self.ticks += 1
        return self.planner.step(q, v, **refs)


def test_equals_the_numpy_model_on_the_studys_closed_loops(robot):
    """The study's circle beyond the workspace and its pose case (quick horizons: 8 s, 4 s)
    on the kinematic plant with its odometry error, every tick of both planners."""
    start = study.staging(robot, None)
    pose0 = robot.frame_pose(start.q0, "ee")
    x0, rotation0 = pose0[:3, 3].copy(), pose0[:3, :3].copy()
    scenarios = ((study.circle(x0, 0.25, rotation0), 8.0, POSITION, True),
                 (study.swing(x0, rotation0), 4.0, POSE, False))
    for references, seconds, setup, jit in scenarios:
        referee = _NumpyModel(robot, setup)
        for method in ("amp", "traditional"):
            controller = _Refereed(ClosedFormPlanner(robot, setup, method, jit), referee)
            study.simulate(robot, controller, references, seconds, setup, start,
                           study.DOCUMENTED, record=False)
            assert controller.ticks == round(seconds / setup.dt)


def test_unknown_method_is_refused(robot):
    with pytest.raises(InvalidValueError, match="'amp' or 'traditional'"):
        ClosedFormPlanner(robot, POSITION, "sns")
