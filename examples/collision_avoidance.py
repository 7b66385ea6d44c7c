"""Collision avoidance: a wall in front of the Panda, and what the constraint costs a tick.

The hand is asked, again and again, to reach 20 cm behind a wall whose face is 0.5 m in front
of the robot. The stack (hand pose, posture, joint position and velocity limits) gets one more
hard constraint, :class:`wbc.tasks.collision.CollisionAvoidance`: each tick the ``max_pairs``
closest pairs among the robot's collision bodies (the URDF's meshes as convex hulls), the wall
and — with ``--self`` — the robot's own links (pairs from its SRDF) must not close faster than
the velocity damper allows, ``ḋ >= −gain (d − d_min) / dt``.

The same loop runs without the constraint (the hand goes through the wall) and with it (it
stops ``d_min`` short), each for ``--seconds`` at 100 Hz on daqp (the fused tick). Then both
controllers are timed at the states of the constrained run, taking turns tick by tick, and the
median ticks are printed: the difference is what the distance computation, the selection of
the closest pairs and their rows (and the robot's kinematics update, which the fused tick
otherwise skips) cost.

Run:  python examples/collision_avoidance.py [--seconds 12] [--self] [--max-pairs 4]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import wbc
import wbc.robots
from wbc.robots.collision import CollisionModel, Obstacle
from wbc.robots.resources import urdf_path
from wbc.sim import Simulation
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit
from wbc.tasks.collision import CollisionAvoidance

DT = 0.01  # control period [s]
D_MIN = 0.02  # the smallest distance allowed [m]
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
WALL_POSE = np.array([[1.0, 0, 0, 0.525], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]])


def build(robot, collision: CollisionModel | None, max_pairs: int) -> wbc.Controller:
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.2, name="ee"))
    stack.add(PostureTask(robot, gain=0.1, weight=1e-3, name="posture"))
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    if collision is not None:  # hard: every row holds at every tick (or the tick fails)
        stack.constrain(CollisionAvoidance(robot, collision, d_min=D_MIN, gain=0.3,
                                           max_pairs=max_pairs, name="collision"))
    return wbc.Controller(robot, stack, dt=DT)  # daqp, the fused tick


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=12.0, help="length of each run [s]")
    parser.add_argument("--self", action="store_true", help="watch self-collisions too")
    parser.add_argument("--max-pairs", type=int, default=4, help="rows of the constraint")
    args = parser.parse_args(argv)

    robot = wbc.robots.load_panda()
    wall = Obstacle.box("wall", (0.05, 1.0, 1.0), WALL_POSE)  # 5 cm thick, face at x = 0.5 m
    collision = CollisionModel(
        robot, urdf=urdf_path("panda_description/urdf/panda.urdf"),
        srdf=urdf_path("panda_description/srdf/panda.srdf"),  # its disabled pairs are left out
        obstacles=[wall], self_collision=args.self)
    hand = robot.frame_pose(Q0, "ee")

    def references(t: float) -> dict:
        # behind the wall, sweeping sideways and up and down (period 4 s)
        target = hand.copy()
        target[:3, 3] = (0.7, 0.25 * np.sin(2 * np.pi * t / 4), 0.5 + 0.1 * np.cos(np.pi * t / 4))
        return {"ee": target}

    result: dict = {"pairs": collision.n_pairs}
    controllers, runs = {}, {}
    for label, model in (("without", None), ("with", collision)):
        controllers[label] = controller = build(robot, model, args.max_pairs)
        runs[label] = run = Simulation(robot, controller, dt=DT).run(
            seconds=args.seconds, q0=Q0, references=references)
        closest = min(collision.min_distance(q) for q in run.q)
        result[label] = {"min_distance_m": closest,
                         "failed": sum(s != "solved" for s in run.status)}
        print(f"{label:>7} the constraint: closest distance {closest * 1e3:7.2f} mm")
    # the tick cost: both controllers at the same states (those of the constrained run),
    # taking turns tick by tick so that the machine's other load hits both alike
    ticks: dict[str, list[float]] = {"without": [], "with": []}
    for k, (t, q) in enumerate(zip(runs["with"].t, runs["with"].q, strict=True)):
        refs = references(t)
        for label in (("without", "with") if k % 2 else ("with", "without")):
            started = time.perf_counter()
            controllers[label].step(q, **refs)
            ticks[label].append(time.perf_counter() - started)
    for label, times in ticks.items():
        median = 1e6 * float(np.median(times[20:]))  # the first ticks warm the caches up
        result[label].update(median_tick_us=median, ticks=len(times) - 20)
        print(f"{label:>7} the constraint: median tick {median:6.1f} µs over "
              f"{len(times) - 20} ticks ({'fused' if controllers[label].fused else 'ordinary'})")
    print(f"{collision.n_pairs} pairs watched, {args.max_pairs} rows; d_min = {D_MIN * 1e3} mm")
    return result


if __name__ == "__main__":
    main()
