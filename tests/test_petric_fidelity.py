"""`wbc study petric`'s fidelity pieces (issue #29): the retreat-invariance campaign equals
`wbc.sim` on the same loop, Fig. 8 left's target obeys the rule it was fixed by, the
reconstruction's documented perturbation (``TARGET_D*``) moves the trajectory's end, and the
criteria of the new claims decide as stated on hand-made series."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.experiments.studies import petric
from wbc.papers.petric import DT, DecoupledController, VelocityField, invariance
from wbc.robots import load
from wbc.sim import Simulation, actuation


@pytest.fixture(scope="module")
def robot():
    return load("tiago_panda")


class _HeldPoint:
    """The field driving the base while the TEE stays at ``world`` [m] (an ideal arm): the
    controller :func:`invariance.held_point_depths` vectorises, for `wbc.sim`."""

    def __init__(self, robot, world):
        self.field, self.world, self.nv = VelocityField(), world, robot.nv
        self.root = robot.mount.translation

    def tee(self, q) -> np.ndarray:
        c, s = math.cos(q[2]), math.sin(q[2])
        dx, dy = self.world[0] - q[0], self.world[1] - q[1]
        return np.array([c * dx + s * dy, -s * dx + c * dy, self.world[2]]) - self.root

    def step(self, q, v=None, **references):
        command = np.zeros(self.nv)
        command[:2] = self.field.step(self.tee(q))
        return command


@pytest.mark.parametrize("loop", ["kinematic", "fitted_lag"])
def test_held_point_campaign_equals_the_simulation(robot, loop):
    """Placements that enter the zone (low) and that do not, through the study's actuation
    chain (lag, then saturation) or a per-coordinate lag alone (the MuJoCo reading): the
    deepest penetration equals `wbc.sim`'s tick by tick recomputation to rounding."""
    field = VelocityField()
    points = np.array([[0.55, 0.10, -0.30], [0.47, 0.08, -0.20], [0.30, 0.35, 0.0],
                       [-0.40, 0.20, 0.30], [0.20, -0.50, -0.10]])
    if loop == "kinematic":
        kwargs = {"lag": 0.1, "velocity_limit": 1.0, "acceleration_limit": 1.0}
        chain = [actuation.Lag(0.1, joints="base"),
                 actuation.Saturation(velocity=1.0, acceleration=1.0, joints="base")]
    else:
        kwargs = {"lag": (0.03, 0.05)}
        chain = [actuation.Lag((0.03, 0.05), joints="base")]
    depth = invariance.held_point_depths(field, points, robot.mount.translation, dt=DT,
                                         seconds=3.0, **kwargs)
    for point, ours in zip(points, depth, strict=True):
        held = _HeldPoint(robot, point + robot.mount.translation)
        run = Simulation(robot, held, DT, actuation=chain).run(seconds=3.0, q0=robot.neutral())
        d_r = field.distances(np.array([held.tee(q) for q in run.q]))[1]
        assert ours == pytest.approx(field.delta_r - d_r.min(), abs=1e-12), point
    assert depth[0] > 0.01 and depth[3] < 0.0  # the grid's two behaviours are both present


def test_touch_height_and_placements():
    field = VelocityField()
    touch = invariance.touch_height(field)
    # the forward zone's boundary meets the retreat zone's there, and lies outside it above
    d_f = field.distances([field.b_d + field.delta_r, 0.0, touch])[0]
    assert d_f == pytest.approx(field.delta_f, abs=1e-12)
    assert field.distances([field.b_d + field.delta_r, 0.0, touch + 0.01])[0] > field.delta_f
    assert invariance.touch_height(VelocityField(b_d=0.6)) == math.inf
    points = invariance.placements(field)
    clearances = field.distances(points)[1] - field.delta_r
    expected = np.tile(invariance.CLEARANCES, len(invariance.HEIGHTS)
                       * len(invariance.BEARINGS_DEG))
    np.testing.assert_allclose(clearances, expected, atol=1e-12)


def test_no_placement_above_the_touch_height_enters(robot):
    """§II-A.2 where the forward zone does not reach the retreat zone: with the study's loop,
    no placement above the touch height enters (the claim's entered_above_touch)."""
    field = VelocityField()
    points = invariance.placements(field)
    above = points[points[:, 2] >= invariance.touch_height(field)]
    depth = invariance.held_point_depths(field, above, robot.mount.translation, dt=DT,
                                         seconds=petric.INVARIANCE_SECONDS, lag=0.1,
                                         velocity_limit=1.0, acceleration_limit=1.0)
    assert len(above) > 300 and np.all(depth < 0.0)


def test_lateral_target_obeys_its_rule(robot):
    """Fig. 8 left: with the base held, the arm comes to rest with the TEE 60° to the left,
    ε/2 inside the retreat zone, at its start height (within the cm the offset is rounded
    to)."""
    field = VelocityField()
    controller = DecoupledController(robot, VelocityField())
    controller.move_base = False
    staging = petric.stagings(robot, None)["lateral"]
    start = controller.driver.tee(staging.q0)
    desired, reference = petric.trajectory(
        "lateral", robot.frame_pose(staging.q0, "ee")[:3, 3])
    end = petric.SCENARIOS["lateral"].seconds
    run = Simulation(robot, controller, DT).run(seconds=end, q0=staging.q0,
                                                references=reference)
    tee = controller.driver.tee(run.q[-1])
    _, d_r, phi = field.distances(tee)
    assert math.degrees(phi) == pytest.approx(60.0, abs=2.0)
    assert field.delta_r - d_r == pytest.approx(field.epsilon / 2, abs=0.01)
    assert tee[2] == pytest.approx(start[2], abs=0.01)
    np.testing.assert_allclose(desired(end), desired(0.0) + petric.LATERAL_END, atol=1e-12)


def test_target_shift_moves_the_end_along_the_motion():
    start = np.array([0.5, 0.0, 0.6])
    shift = np.array([0.05, -0.05, 0.02])
    for name, scenario in petric.SCENARIOS.items():
        plain = petric.trajectory(name, start)[0]
        moved = petric.trajectory(name, start, shift=shift)[0]
        np.testing.assert_allclose(moved(0.0), start, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(moved(scenario.motion / 2) - plain(scenario.motion / 2),
                                   shift / 2, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(moved(scenario.seconds) - plain(scenario.seconds), shift,
                                   atol=1e-12, err_msg=name)
    # and the sweep's keys reach the stagings
    assert set(petric._SHIFT_KEYS) <= set(petric.PARAMETERS_SWEPT)
    assert all(petric.PARAMETERS_SWEPT[k][0] == 0.0 for k in petric._SHIFT_KEYS)


def test_rise_and_onset():
    decay = np.exp(-np.linspace(0.0, 5.0, 50))
    assert petric._rise(decay) == 0.0
    assert petric._rise(np.r_[0.0, 0.5, 1.0, decay]) == 0.0  # a rise before the peak is fine
    assert petric._rise(np.r_[1.0, 0.2, 0.5, 0.1]) == pytest.approx(0.3)  # a rebound
    assert petric._onset(np.r_[0.0, 0.05, 0.2, 1.0]) == 2
    assert petric._onset(np.zeros(4)) is None


def _series(t, v, omega, heading, desired_end=(0.0, 0.3, 0.0)):
    """A hand-made run for the claims: base moving with (v, ω) from the origin, a TCP whose
    reference ends at ``desired_end`` (a leftward move by default), a 1 mm error."""
    n = len(t)
    pose = np.zeros((n, 3))
    pose[:, 0] = np.cumsum(v) * DT
    pose[:, 2] = heading
    desired = np.outer(np.linspace(0.0, 1.0, n), desired_end)
    return {"t": t, "base_velocity": np.column_stack([v, omega]), "base_pose": pose,
            "command_base": np.column_stack([v, omega]), "ee_error": np.full(n, 1e-3),
            "ee_desired": desired, "ee_position": desired, "tee": np.tile([0.5, 0.0, 0.3], (n, 1))}


def test_lateral_claim_decides_on_the_order_of_backward_motion_and_rotation():
    """The claim's criterion on hand-made runs: backward motion (≈ 3 cm) starting before the
    rotation holds; the same motions with the rotation first, or a retreat of 20 cm, fail."""
    t = np.arange(1200) * DT  # (beyond the square's and free path's motion: their holds)
    bump = lambda t0: np.exp(-0.5 * ((t - t0) / 0.3) ** 2)  # noqa: E731
    v = -0.04 * bump(3.0)
    omega = 0.6 * bump(4.0)
    heading = np.cumsum(omega) * DT

    def lateral(v, omega, heading):
        runs = {name: {"decoupled": _series(t, np.zeros_like(t), np.zeros_like(t),
                                            np.zeros_like(t))} for name in petric.SCENARIOS}
        runs["forward"]["fixed_base"] = runs["forward"]["decoupled"]
        runs["lateral"]["decoupled"] = _series(t, v, omega, heading)
        claims = petric._behaviour_claims(runs, "decoupled", "fixed_base", VelocityField(),
                                          "kinematic", 1.0)
        return next(c for c in claims if c.id == "lateral_retreat_first")

    good = lateral(v, omega, heading)
    assert good.holds and 0.01 < good.ours["backward_m"] < 0.1
    assert good.ours["t_backward_onset_s"] < good.ours["t_rotation_onset_s"]
    late = 0.6 * bump(2.0)
    assert not lateral(v, late, np.cumsum(late) * DT).holds     # rotation first
    assert not lateral(5 * v, omega, heading).holds             # not slight: ≈ 15 cm
    assert not lateral(v, -omega, -heading).holds               # turns away from the TCP


def test_rate_limits_are_read_per_tick_and_per_second():
    t = np.arange(100) * DT
    omega = np.where(t >= 1.0, 0.1, 0.0)  # one step of 0.1 rad/s: 5 rad/s² per second
    runs = {name: _series(t, np.zeros_like(t), omega, np.zeros_like(t))
            for name in petric.SCENARIOS}
    per_tick, per_second = petric._rate_claims(runs, VelocityField())
    assert per_tick.holds and per_tick.ours["domega"] == pytest.approx(0.1)
    assert not per_second.holds
    assert per_second.ours["domega_dt_max"] == pytest.approx(0.1 / DT)
    assert per_second.ours["ticks_over_domega"] == len(petric.SCENARIOS)
    assert per_second.ours["ticks"] == len(petric.SCENARIOS) * (len(t) - 1)
