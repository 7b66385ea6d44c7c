"""`wbc study sorour` on both plants, with seeds, parameter overrides and main-only runs; the
paper's steering controller driving the MuJoCo plant's steer and drive joints."""

from __future__ import annotations

import math

import numpy as np
import pytest

import wbc
from wbc.experiments.studies import sorour
from wbc.experiments.studies.study import StudyOptions
from wbc.robots import load


def _claims(result) -> dict:
    return {c.id: (c.ours, c.holds) for c in result.claims}


@pytest.fixture(scope="module")
def kinematic(quick_studies):
    # the session's quick run (conftest.py), which the other study tests read too
    return quick_studies.data("sorour")


def test_default_run_keeps_its_claims(kinematic):
    """The claims of the documented quick run (the LWR's limits, damped eq. 14, issue #29)."""
    assert kinematic["plant"] == "kinematic" and kinematic["seed"] is None
    claims = {c["id"]: c for c in kinematic["claims"]}
    assert claims["pinv_faster_far"]["ours"] == {"pinv": [11.849], "proposed": [25.202],
                                                 "compensated": [38.085]}
    assert claims["pinv_larger_footprint"]["ours"] == {"pinv": 0.814, "proposed": 0.733,
                                                       "compensated": 0.71}
    assert claims["compensation_lowers_steady_error"]["ours"] == {"proposed": [0.0515],
                                                                  "compensated": [2.52]}
    assert claims["steer_acceleration_limit"]["ours"] == {"ticks_over": 2, "max": 3.441}
    assert [c["holds"] for c in kinematic["claims"]] == [True, True, True, False, False, False,
                                                         False, True, False]
    assert kinematic["plant_timing"]["plant"] == "kinematic"
    assert "step_median_s" not in kinematic["plant_timing"]


def test_mujoco_run_has_the_same_claims_and_records_physics(kinematic, quick_studies):
    pytest.importorskip("mujoco")
    folder = quick_studies.study("sorour", "mujoco")
    data = quick_studies.data("sorour", "mujoco")
    assert data["plant"] == "mujoco"
    assert [c["id"] for c in data["claims"]] == [c["id"] for c in kinematic["claims"]]
    assert data["figures"] == kinematic["figures"]
    for figure in data["figures"]:
        assert (folder / figure).stat().st_size > 0
    timing = data["plant_timing"]
    assert timing["steps"] == 3 * 400 and 0 < timing["step_median_s"] <= timing["step_p95_s"]
    run = data["runs"]["table_ii"]["compensated"]
    n = len(run["t"])
    assert np.shape(run["wheel_slip"]) == (n, 4) and np.shape(run["normal_forces"]) == (n, 4)
    # the robot stands on its four wheels, weighing what MuJoCo's model weighs (not zero)
    assert np.median(np.sum(run["normal_forces"], axis=1)) > 500.0
    # the base moves on the floor (not at the commanded twist): odometry drifts from the truth
    assert max(run["odometry_error"]) > 0.0
    # the steer joints track the steering controller's angles within a few degrees
    error = np.abs(np.asarray(run["steer_angles"]) - np.asarray(run["steer_reference"]))
    assert math.degrees(error.max()) < 10.0
    assert "**Plant: MuJoCo.**" in data["summary"]


def test_seed_restages_the_runs_reproducibly(tmp_path, kinematic):
    options = StudyOptions(seed=3, main_only=True)
    first = sorour.run("daqp", tmp_path / "a", True, options)
    second = sorour.run("daqp", tmp_path / "b", True, options)
    assert _claims(first) == _claims(second)
    initial, poses, base = sorour.staging(3)
    assert first.parameters["initial_pose"] == initial.tolist()
    assert first.parameters["poses"] == [[s, list(p)] for s, p in poses]
    # a re-staging within the stated magnitudes, and another seed draws another one
    assert np.abs(base[:2]).max() <= 0.02 and abs(base[2]) <= math.radians(2.0)
    moved = np.array([p for _, p in poses]) - np.array([p for _, p in sorour.POSES])
    assert 0 < np.abs(moved[:, :3]).max() <= 0.02
    assert np.abs(moved[:, 3:]).max() <= math.radians(2.0)
    other = sorour.staging(4)
    assert not np.allclose(other[2], base) and other[1] != poses
    # the documented run's start (the session's quick run: main_only leaves the staging as is)
    assert first.parameters["q0"] != kinematic["parameters"]["q0"]
    # main_only: no figures, no timing replays, no replay record, nothing written meanwhile
    assert first.figures == [] and first.timing == {} and first.replays == {}
    assert not (tmp_path / "a").exists()
    assert sorour.staging(None)[1] is sorour.POSES


def test_parameters_are_checked_and_used(tmp_path):
    with pytest.raises(wbc.UnknownNameError):
        sorour.run("daqp", tmp_path, True, StudyOptions(params={"damping": 0.1}))
    result = sorour.run("daqp", tmp_path, True, StudyOptions(
        params={"steer_rate_max": 0.5, "compensation_damping": 0.1}, main_only=True))
    assert result.parameters["steer_rate_max"] == 0.5
    assert result.parameters["compensation_damping"] == 0.1
    claim = next(c for c in result.claims if c.id == "steer_rate_limit")
    # the steer joints now turn at up to 0.5 rad/s, the limit the claim checks
    assert claim.ours == pytest.approx(0.5, abs=1e-4) and claim.holds
    assert set(sorour.PARAMETERS_SWEPT) >= {"icr_gain", "steer_rate_max",
                                            "steer_acceleration_max"}


class _Twist:
    """A whole-body controller stub: a constant base twist, the arm still."""

    last_solution = None

    def __init__(self, twist, nv: int) -> None:
        self.command = np.r_[twist, np.zeros(nv - 3)]

    def step(self, q, v=None, ee=None):
        return self.command


# the turn's tolerance: the paper's wheel model puts the contact d = 0.045 m beside the steer
# axis, the plant's trails it by d; on the spot that is d / |h| = 15 % of each hip's speed
@pytest.mark.parametrize(("twist", "tolerance"),
                         [((0.1 * math.cos(1.0), 0.1 * math.sin(1.0), 0.0), 0.05),
                          ((0.0, 0.0, 0.3), 0.2)])
def test_steering_controller_drives_the_plant_joints(twist, tolerance):
    """Wheel order and steer-angle convention agree between the paper's steering controller and
    the plant: a translation at 57° and a turn on the spot move the MuJoCo base as asked."""
    pytest.importorskip("mujoco")
    from wbc.sim import MujocoPlant, Simulation

    robot = load("mpo700_lwr4")
    plant = MujocoPlant(robot)
    options = StudyOptions(plant="mujoco")
    joints = sorour.SteeredJoints(_Twist(twist, robot.nv),
                                  sorour.base_steering(robot, "daqp", options))
    sim = Simulation(robot, joints, dt=sorour.PARAMETERS["ts"], command="joints", plant=plant)
    q0 = sorour.within_joint_limits(robot, sorour.initial_configuration(robot))
    run = sim.run(seconds=3.0, q0=q0)
    # the plant's steer joints, in the order it takes their rates, sit on robot.base.hips in
    # the steering controller's order (the base turned by its heading θ)
    c, s = math.cos(run.q_final[2]), math.sin(run.q_final[2])
    axes = np.array([plant.data.body(f"steer{i}").xpos[:2] for i in range(4)])
    hips = (axes - run.q_final[:2]) @ np.array([[c, -s], [s, c]])
    assert plant.mjcf.steer_joints == ("steer0", "steer1", "steer2", "steer3")
    assert hips == pytest.approx(joints.steering.hips, abs=0.005)
    feasible = joints.last_step.twist
    measured = run.v[-20:, :3].mean(axis=0)
    # the steering controller reached the asked twist (its drive controller: K_p = 2 1/s)
    assert feasible == pytest.approx(np.asarray(twist), abs=0.01)
    # MuJoCo's base moves with it: a wrong wheel order or steer sign would turn or stop it
    assert measured == pytest.approx(feasible, abs=tolerance * np.linalg.norm(twist))
    steering = np.array([plant.data.joint(n).qpos[0] for n in plant.mjcf.steer_joints])
    # within 5°: on the turn the floor pushes the trailing wheels off the paper's angles
    assert np.abs(steering - joints.steering.steering).max() < math.radians(5.0)
