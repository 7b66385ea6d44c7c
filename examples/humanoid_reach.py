"""A humanoid keeps both feet on the ground and its balance while a hand follows a moving target.

Robot: TALOS from example-robot-data (``talos_reduced.urdf``) on a free-flyer root: ``q`` is
the pelvis position and quaternion then 32 joints (nq = 39), ``v`` the pelvis twist in its own
axes then the joint rates (nv = 38). It starts in the SRDF's ``half_sitting`` posture.
Stack (velocity level), strict priorities:
  priority 0: both feet held where they are (full poses, dead-beat gain);
  priority 1: the centre of mass held over the middle of the support polygon (a ComTask weighted
              on x and y only: the height stays free, so the knees can bend);
  priority 2: the left hand's position follows a target moving on a 5 cm circle (period 8 s),
              starting 9 cm away;
  priority 3: a posture task towards half-sitting (it fixes what the tasks above leave free);
  hard, at every level: joint position limits (as velocity bounds) and velocity limits (the
  pelvis' coordinates are unbounded).
Why a CoM *target* rather than an inequality: the middle of the polygon is the point farthest
from its edges, so held there the CoM stays inside however the arm moves; a strict level above
the hand makes that exact, and the hand gets what the balance leaves. The loop runs on
:mod:`wbc.sim` (exact actuation): the true configuration moves along pinocchio's
``integrate``, the feet may only drift by the second-order terms of one tick, which the
dead-beat foot tasks take back at the next.

Run:  python examples/humanoid_reach.py [--seconds 3]
"""

from __future__ import annotations

import argparse

import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

import wbc
import wbc.robots
from wbc.robots.resources import robots_dir, urdf_path
from wbc.sim import Simulation, position_error
from wbc.tasks.com import ComTask
from wbc.tasks.frame import FrameTask
from wbc.tasks.limits import ConfigurationLimit, VelocityLimit
from wbc.tasks.posture import PostureTask

DT = 0.01  # control period [s]
FEET = ("left_sole_link", "right_sole_link")
SOLE = (0.20, 0.10)  # sole length and width [m] (TALOS' feet, rounded down: a safety margin)
RADIUS, PERIOD = 0.05, 8.0  # the hand target's circle [m] and period [s]


def support_polygon(robot, q) -> np.ndarray:
    """Corners (8, 2) [m] of the two soles' rectangles in the ground plane; their convex hull
    is the support polygon."""
    half = np.array(SOLE) / 2.0
    corners = []
    for foot in FEET:
        pose = robot.frame_pose(q, foot)
        for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
            corners.append((pose[:3, :3] @ [sx * half[0], sy * half[1], 0.0] + pose[:3, 3])[:2])
    return np.array(corners)


def inside_margin(point, corners) -> float:
    """Signed distance [m] from ``point`` (2,) to the boundary of the convex hull of ``corners``
    (positive inside)."""
    hull = ConvexHull(corners)  # facets: unit outward normal n and offset b, n·x + b <= 0 inside
    return float(-(hull.equations[:, :2] @ point + hull.equations[:, 2]).max())


def load_talos():
    """TALOS on a free-flyer root, ``"ee"`` its left gripper, at home in half-sitting (the SRDF's
    reference configuration, read with pinocchio into a model of the same layout)."""
    path = urdf_path("talos_data/robots/talos_reduced.urdf")
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    pin.loadReferenceConfigurations(model, str(robots_dir() / "talos_data/srdf/talos.srdf"),
                                    False)
    half_sitting = np.array(model.referenceConfigurations["half_sitting"])  # pelvis 1.02 m up
    return wbc.robots.from_urdf(path, root="free_flyer", ee_frame="gripper_left_base_link",
                                home=half_sitting)


def build(robot):
    """The controller, the references at time ``t`` and what to watch (see the docstring)."""
    q0 = robot.neutral()
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    for foot in FEET:
        stack.add(FrameTask(robot, foot, gain=1.0, name=foot), priority=0)
    # gains: the share of the error asked for per tick (the hand's 0.03: a time constant of
    # 0.33 s). Gentle motions keep the feet's drift small: holding a foot's twist at zero is
    # exact to first order, a tick of motion moves it by ½ J̇v dt² (≈ 4e-7 m on the first
    # tick here, when the hand sets off; the dead-beat foot tasks take it back at the next)
    stack.add(ComTask(robot, gain=0.02, weight=[1.0, 1.0, 0.0], name="balance"), priority=1)
    stack.add(FrameTask(robot, "ee", gain=0.03, position_only=True, name="hand"), priority=2)
    stack.add(PostureTask(robot, gain=0.1, weight=1e-2, name="posture"), priority=3)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    # kinematics="numeric": one pinocchio update per tick, and no C compilation (fused=False,
    # jit=False): compiling TALOS' kinematics and the fused tick into C makes faster ticks but
    # takes longer (≈ 20 s) than this short run
    controller = wbc.Controller(robot, stack, backend="daqp", dt=DT, kinematics="numeric",
                                jit=False, fused=False)

    feet = {foot: robot.frame_pose(q0, foot).copy() for foot in FEET}
    centre = support_polygon(robot, q0).mean(axis=0)  # the middle of the two soles
    com_target = np.array([centre[0], centre[1], robot.com(q0)[2]])
    hand0 = robot.frame_pose(q0, "ee")[:3, 3].copy()
    middle = hand0 + [0.06, 0.0, 0.05]  # the circle's centre, ahead of and above the hand

    def references(t: float) -> dict:
        angle = 2.0 * np.pi * t / PERIOD
        hand = np.eye(4)
        hand[:3, 3] = middle + RADIUS * np.array([0.0, np.cos(angle), np.sin(angle)])
        return {**feet, "balance.target": com_target, "hand": hand, "posture": q0}

    return controller, references, feet


def main(argv: list[str] | None = None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated time [s]")
    args = parser.parse_args(argv)

    robot = load_talos()
    controller, references, feet = build(robot)

    def feet_drift(tick) -> float:  # the worst foot's distance from where it stood [m]
        return max(float(np.linalg.norm(tick.robot.frame_pose(tick.q, foot)[:3, 3]
                                        - feet[foot][:3, 3])) for foot in FEET)

    def com_margin(tick) -> float:  # the CoM's distance inside the support polygon [m]
        com = tick.robot.com(tick.q)[:2]
        return inside_margin(com, support_polygon(tick.robot, tick.q))

    sim = Simulation(robot, controller, dt=DT,
                     signals={"feet_drift": feet_drift, "com_margin": com_margin,
                              "hand_error": position_error("ee", reference="hand")})
    run = sim.run(seconds=args.seconds, q0=robot.neutral(), references=references)

    error = run.signals["hand_error"]
    print(f"TALOS, {len(run.t)} ticks of {DT * 1e3:.0f} ms: hand error {error[0] * 100:.1f} cm "
          f"-> {error[-1] * 100:.2f} cm; feet drift <= {run.signals['feet_drift'].max():.1e} m; "
          f"CoM >= {run.signals['com_margin'].min() * 100:.1f} cm inside the support polygon; "
          f"median tick {np.median(run.tick_s) * 1e3:.2f} ms")
    return run


if __name__ == "__main__":
    main()
