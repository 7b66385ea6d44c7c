"""Watch your own stack move: a stack of yours, run in closed loop, drawn in the browser.

The stack here is one you might write for a Tiago + Panda (``tiago_panda``): the hand's
*position* follows a circle (a position-only frame task), the hand's orientation and the
posture come next, one level below, and position and velocity limits hold throughout. Any
``wbc.Stack`` works the same way: build a controller, run :class:`wbc.sim.Simulation` a few
ticks at a time, and hand each configuration to :class:`wbc.viz.Viewer` (``viewer.show(q)``;
``viewer.set_target(T)`` draws the target's triad; the base and hand paths are drawn as it
goes). Open the printed URL (http://127.0.0.1:8080 by default — the page binds this machine
only unless ``--host`` says otherwise).

Needs the viewer's extra: ``pip install ".[viz]"``.

Run:  python examples/viewer_own_stack.py [--seconds 20] [--port 8080] [--host 127.0.0.1]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import wbc
import wbc.robots
from wbc.sim import Simulation
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

DT = 0.01  # control period [s]
CHUNK = 5  # ticks simulated between two pictures (20 pictures per second)


def my_stack(robot) -> wbc.Stack:
    """Your stack: hand position first; hand orientation and posture below; limits hard."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=2.0, position_only=True, name="hand"), priority=0)
    stack.add(FrameTask(robot, "ee", gain=1.0, name="hand_pose", weight=0.1), priority=1)
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"), priority=1)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack


def circle(start: np.ndarray, t: float, radius: float = 0.25, period: float = 8.0):
    """The target pose at time ``t`` [s]: ``start`` moved along a vertical circle."""
    angle = 2 * math.pi * t / period
    pose = start.copy()
    pose[:3, 3] += radius * np.array([0.0, math.sin(angle), 1.0 - math.cos(angle)]) \
        + np.array([0.3 * t / period, 0.0, 0.0])  # and drifting forward: the base follows
    return pose


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="how long to run the loop [s] (default 20)")
    parser.add_argument("--port", type=int, default=8080)
    parser.add_argument("--host", default="127.0.0.1")
    args = parser.parse_args(argv)

    from wbc.viz import Viewer  # the [viz] extra

    robot = wbc.robots.load("tiago_panda")
    controller = wbc.Controller(robot, my_stack(robot), backend="daqp", dt=DT)
    sim = Simulation(robot, controller, DT)
    q, v = robot.neutral(), np.zeros(robot.nv)
    start = robot.frame_pose(q, "ee").copy()
    errors, frames = [], 0
    with Viewer(robot, host=args.host, port=args.port) as viewer:
        t, clock = 0.0, time.perf_counter()
        while t < args.seconds:
            target = circle(start, t)
            run = sim.run(ticks=CHUNK, q0=q, v0=v, references={"hand": target,
                                                              "hand_pose": target})
            q, v = run.q_final, run.v_final
            t += CHUNK * DT
            viewer.set_target(target)
            viewer.show(q)
            frames += 1
            errors.append(float(np.linalg.norm(robot.frame_pose(q, "ee")[:3, 3]
                                               - target[:3, 3])))
            # keep real time: the page shows the loop as it would run on the robot
            time.sleep(max(0.0, clock + t - time.perf_counter()))
    print(f"{frames} pictures; hand position error: max {1e3 * max(errors):.1f} mm, last "
          f"{1e3 * errors[-1]:.1f} mm")
    return {"errors": errors, "frames": frames, "base_path": len(viewer._base_path)}


if __name__ == "__main__":
    main()
