"""A mobile manipulator reaches a target pose in closed loop, with an imperfect base.

Robot: ``omni4_arm6`` from the catalogue (a 4-omni-wheel octagonal base and a 6-DoF arm;
9 velocity coordinates: base (v_x, v_y, ω), then the arm joints). Stack (velocity level):
  priority 0: the end-effector pose task (gain 0.05: 5 % of the error asked for per tick),
  priority 1: a posture task keeping the arm near its neutral configuration,
  hard, at every level: joint position limits (as velocity bounds) and velocity limits.
The simulation (:mod:`wbc.sim`) moves the true robot through an actuation chain: base odometry
error (3 % scale error plus noise; the controller believes the commanded twist) and a 50 ms
first-order lag. The controller sees the *estimated* state, so its end-effector error and the
true one differ; both are plotted.

Run:  python examples/mobile_manipulator_reach.py [--seconds 6] [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no window needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import wbc  # noqa: E402
import wbc.robots  # noqa: E402
from wbc.sim import Simulation, actuation, position_error  # noqa: E402
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit  # noqa: E402

DT = 0.01  # control period [s]


def main(argv: list[str] | None = None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=6.0, help="simulated time [s]")
    parser.add_argument("--out", type=Path, default=Path("."), help="folder for the PNG")
    args = parser.parse_args(argv)

    robot = wbc.robots.load("omni4_arm6")
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.05, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, name="posture"), priority=1)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    controller = wbc.Controller(robot, stack, backend="daqp", dt=DT)

    # Target: 1.2 m ahead, 0.5 m to the left and 10 cm lower than the neutral hand pose —
    # beyond the arm's reach, so the base has to drive.
    q0 = robot.neutral()
    target = robot.frame_pose(q0, "ee").copy()
    target[:3, 3] += [1.2, 0.5, -0.1]

    sim = Simulation(robot, controller, dt=DT,
                     actuation=[actuation.OdometryError(scale=0.03, noise=0.005),
                                actuation.Lag(tau=0.05)],
                     signals={"true_error": position_error("ee", reference="ee")}, seed=0)
    run = sim.run(seconds=args.seconds, q0=q0,
                  references={"ee": target, "posture": robot.neutral()})

    # The error the controller believes: its estimated state's hand position vs the target.
    believed = np.array([np.linalg.norm(target[:3, 3] - robot.frame_pose(q, "ee")[:3, 3])
                         for q in run.q_est])
    true = np.asarray(run.signals["true_error"])
    solved = sum(status == "solved" for status in run.status)
    print(f"{len(run.t)} ticks, {solved} solved; final hand error: believed "
          f"{1e3 * believed[-1]:.1f} mm, true {1e3 * true[-1]:.1f} mm; "
          f"median tick {1e6 * np.median(run.tick_s):.0f} µs")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    top.semilogy(run.t, true, label="true (odometry error and lag)")
    top.semilogy(run.t, believed, "--", label="as the controller believes (estimate)")
    top.set_ylabel("hand position error [m]")
    top.set_title("omni4_arm6 reaching a target 1.3 m away")
    top.legend()
    nb = robot.nv_base
    speed_base = np.linalg.norm(run.v[:, :2], axis=1)
    speed_arm = np.abs(run.v[:, nb:]).max(axis=1)
    bottom.plot(run.t, speed_base, label="base linear speed [m/s]")
    bottom.plot(run.t, speed_arm, label="fastest arm joint [rad/s]")
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("speed [m/s] or [rad/s]")
    bottom.set_title("True velocities")
    bottom.legend()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "mobile_manipulator_reach.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return run


if __name__ == "__main__":
    main()
