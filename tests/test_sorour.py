"""Sorour et al.: closed forms, the ψ-shared task and the dexterous posture as QP stacks, the
arm compensation QP, the analytic RPY Jacobian (finite differences).

Equivalences run on every installed backend with the ``"tight"`` profile.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import assert_kkt, random_matrix
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.papers.sorour import (
    ArmCompensation,
    DexterousPosture,
    arm_compensation,
    share_task,
    sharing_factor,
    sharing_mobility,
    task_sharing_factor,
    task_sharing_velocity,
)
from wbc.robots import load
from wbc.solvers import available_backends
from wbc.tasks import LinearTask, RpyPoseTask
from wbc.tasks.rpy_pose import base_rotation_6, pose_error, rpy, rpy_jacobian

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

BACKENDS = available_backends()
TOL = 1e-7
Q_DEX = np.array([math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0])


# ----------------------------------------------------------------------------- closed forms
def test_task_sharing_factor_is_eq_11():
    assert task_sharing_factor(0.0) == 1.0
    assert task_sharing_factor(0.25) == 1.0
    assert task_sharing_factor(0.2500001) == 0.5
    assert task_sharing_factor(0.9) == 0.5
    assert task_sharing_factor(0.9000001) == 0.0
    assert task_sharing_factor(0.5, r_fm=0.6, r_mm=0.7) == 1.0
    with pytest.raises(wbc.InvalidValueError, match="error_norm"):
        task_sharing_factor(-0.1)
    with pytest.raises(wbc.InvalidValueError, match="r_fm must be < r_mm"):
        task_sharing_factor(0.1, r_fm=0.9, r_mm=0.25)


def test_psi_one_moves_the_arm_only_and_zero_the_base_only():
    """The erratum on eq. 10: ψ = 1 is fine manipulation (arm only)."""
    rng = np.random.default_rng(1)
    J, v = random_matrix(rng, 6, 10), rng.standard_normal(6)
    arm_only = task_sharing_velocity(J, v, 1.0, 0.001, 3)
    base_only = task_sharing_velocity(J, v, 0.0, 0.001, 3)
    np.testing.assert_array_equal(arm_only[:3], 0.0)
    np.testing.assert_array_equal(base_only[3:], 0.0)
    assert np.abs(arm_only[3:]).max() > 1e-3 and np.abs(base_only[:3]).max() > 1e-3
    np.testing.assert_array_equal(sharing_mobility(0.3, 3, 5), [0.7, 0.7, 0.7, 0.3, 0.3])
    with pytest.raises(wbc.InvalidValueError, match="psi"):
        task_sharing_velocity(J, v, 1.5, 0.001, 3)


def test_nullspace_term_does_not_disturb_the_task():
    rng = np.random.default_rng(2)
    J, v, z = random_matrix(rng, 6, 10, 5), rng.standard_normal(6), rng.standard_normal(10)
    with_z = task_sharing_velocity(J, v, 0.5, 0.01, 3, lam=3.5, z=z)
    without = task_sharing_velocity(J, v, 0.5, 0.01, 3)
    np.testing.assert_allclose(J @ with_z, J @ without, atol=1e-12)
    assert np.linalg.norm(with_z - without) > 1e-3
    with pytest.raises(wbc.ShapeError, match="z"):
        task_sharing_velocity(J, v, 0.5, 0.01, 3, lam=1.0, z=np.ones(9))


def test_arm_compensation_restores_the_missed_end_tip_velocity():
    rng = np.random.default_rng(3)
    J_arm, J_base = random_matrix(rng, 6, 7), rng.standard_normal((6, 3))
    ref, feasible = rng.standard_normal(3), rng.standard_normal(3)
    delta = arm_compensation(J_arm, J_base, ref, feasible)
    np.testing.assert_allclose(J_base @ feasible + J_arm @ delta, J_base @ ref, atol=1e-12)
    np.testing.assert_array_equal(arm_compensation(J_arm, J_base, ref, ref), 0.0)
    with pytest.raises(wbc.ShapeError, match="same rows"):
        arm_compensation(J_arm, J_base[:5], ref, feasible)
    with pytest.raises(wbc.ShapeError, match="qd_base_feasible"):
        arm_compensation(J_arm, J_base, ref, feasible[:2])


# ----------------------------------------------------------------------------- QP = closed form
@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1), st.sampled_from([10, 6]), st.sampled_from([6, 5, 3]),
       st.sampled_from([0.0, 0.3, 0.5, 1.0, None]), st.sampled_from([0.05, 0.5]),
       st.booleans())
def test_shared_stack_equals_task_sharing_velocity(backend, seed, n, rank, psi, rho, nullspace):
    """Level 0: the task with ``share_task``'s mobility (ψ a parameter); level 1 (optional):
    ``DexterousPosture``'s exact form ``||q̇ − q̇₁* − λz||²`` — as a generic cost here."""
    rng = np.random.default_rng(seed)
    psi = rng.uniform() if psi is None else psi
    J = random_matrix(rng, 6, n, min(rank, n))
    v, z, lam = rng.standard_normal(6), rng.standard_normal(n), 3.5
    stack = wbc.Stack(wbc.Variables(qd_base=3, qd_arm=n - 3), damping={0: rho},
                      min_norm=False)
    stack.add(LinearTask(J, v, name="task"), priority=0)
    share_task(stack, "psi", 3, priority=0)
    if nullspace:
        stack.add(wbc.Cost(stack.variables.symbol, stack.x_above() + lam * z, name="dex"),
                  priority=1)
    ws = stack.workspace(backend, "tight")
    ws.set(psi=[psi])
    sol = ws.solve()
    assert sol.ok, sol.message
    expected = task_sharing_velocity(J, v, psi, rho, 3, lam, z if nullspace else None)
    np.testing.assert_allclose(sol.x, expected, atol=TOL)
    assert_kkt(ws)


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.sampled_from([6, 4]))
def test_arm_compensation_qp_equals_closed_form(backend, seed, rank):
    rng = np.random.default_rng(seed)
    J_arm, J_base = random_matrix(rng, 6, 7, rank), rng.standard_normal((6, 3))
    ref, feasible = rng.standard_normal(3), rng.standard_normal(3)
    qp = ArmCompensation(7, backend=backend, profile="tight")
    np.testing.assert_allclose(qp(J_arm, J_base, ref, feasible),
                               arm_compensation(J_arm, J_base, ref, feasible), atol=TOL)


def test_robot_stack_equals_closed_form_and_compensated_command():
    """The study's eq. 9 stack on the MPO700 + LWR-IV (RPY pose task, ψ from the error,
    dexterous posture) = ``task_sharing_velocity`` of the numeric J_mm and ṗ_ref, with ψ
    taking 0, 0.5 and 1; and the compensated command = the closed form of eq. 14."""
    robot = load("mpo700_lwr4")
    stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping={0: 0.001}, min_norm=False)
    pose = RpyPoseTask(robot, "ee", 1.7, name="ee")
    stack.add(pose, priority=0)
    share_task(stack, sharing_factor(pose.position_error_norm), 3)
    stack.add(DexterousPosture(robot, Q_DEX, 3.5, name="dex"), priority=1)
    controller = wbc.Controller(robot, stack, backend="daqp", profile="tight", dt=0.025)
    compensation = ArmCompensation(7, profile="tight")
    rng = np.random.default_rng(4)
    seen = set()
    for offset in (4.0, 0.5, 0.1, 0.0):
        q = robot.neutral()
        q[:3] = rng.uniform(-1, 1, 3)
        q[3:] += rng.uniform(-0.3, 0.3, 7)
        T = robot.frame_pose(q, "ee")
        target = np.r_[T[:3, 3] + offset * np.array([0.6, 0.8, 0.0]), rpy(T[:3, :3]) + 0.1]
        command = controller.step(q, ee=target)
        J = rpy_jacobian(robot.frame_jacobian(q, "ee"), T[:3, :3], q[2])
        e = pose_error(T, target)
        psi = task_sharing_factor(np.linalg.norm(e[:3]))
        seen.add(psi)
        z = np.r_[np.zeros(3), -(q[3:] - Q_DEX)]
        expected = task_sharing_velocity(J, 1.7 * base_rotation_6(q[2])(e), psi, 0.001, 3, 3.5,
                                         z)
        np.testing.assert_allclose(command, expected, atol=TOL)
        feasible = 0.5 * command[:3]
        delta = compensation(J[:, 3:], J[:, :3], command[:3], feasible)
        np.testing.assert_allclose(delta, arm_compensation(J[:, 3:], J[:, :3], command[:3],
                                                           feasible), atol=TOL)
    assert seen == {0.0, 0.5, 1.0}


# ----------------------------------------------------------------------------- RPY Jacobian
def test_rpy_jacobian_is_the_derivative_of_the_world_pose_in_base_axes():
    robot = load("mpo700_lwr4")
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = robot.neutral()
        q[:3] = rng.uniform(-1, 1, 3)
        q[3:] += rng.uniform(-0.5, 0.5, 7)
        v = rng.standard_normal(robot.nv)
        T = robot.frame_pose(q, "ee")
        J = rpy_jacobian(robot.frame_jacobian(q, "ee"), T[:3, :3], q[2])
        h = 1e-6
        ahead = robot.frame_pose(robot.integrate(q, v, h), "ee")
        behind = robot.frame_pose(robot.integrate(q, -v, h), "ee")
        # p(ahead) − p(behind) = e(behind → ahead) = −pose_error(ahead, p(behind))
        rate = -pose_error(ahead, np.r_[behind[:3, 3], rpy(behind[:3, :3])]) / (2 * h)
        np.testing.assert_allclose(J @ v, base_rotation_6(q[2])(rate), atol=1e-6)


def test_rpy_pose_task_refuses_bad_gain_and_frame():
    robot = load("mpo700_lwr4")
    with pytest.raises(wbc.InvalidValueError, match="gain"):
        RpyPoseTask(robot, "ee", 0.0)
    with pytest.raises(wbc.UnknownNameError, match="nowhere"):
        RpyPoseTask(robot, "nowhere")
    with pytest.raises(wbc.ShapeError, match="q_dex"):
        DexterousPosture(robot, np.zeros(11))
    with pytest.raises(wbc.ShapeError, match="n_base"):
        share_task(wbc.Stack(4), "psi", 5)
