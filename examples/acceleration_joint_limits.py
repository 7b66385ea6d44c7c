"""An acceleration-level stack whose joint limits are bounds on the joint accelerations.

Robot: ``mecanum_gen3`` (mecanum base x, y, θ + Kinova Gen3 7-DoF; 10 coordinates, limits of
Xing et al., Table 1). The decision vector is the acceleration ``q̈`` (10 entries); each tick the
command is held for one period T and integrated (``command="acceleration"`` in :mod:`wbc.sim`).

  priority 0: hand position, ``J q̈ + J̇ q̇ = K_p e − K_d J q̇`` (a PD law in task space,
              ``K_p`` = 20 /s², ``K_d`` = 10 /s as in Xing et al.),
  priority 1: arm posture, ``q̈_arm = K_p,post (q_home − q)_arm − K_d,post q̇_arm``,
  hard:       ``JointAccelerationLimit(method="viable")``: position, velocity and acceleration
              limits become state-dependent bounds ``Q̈_min(q, q̇) <= q̈ <= Q̈_max(q, q̇)`` that
              keep every joint able to brake before its position limit.

Every model quantity (``"pose[ee]"``, ``"J[ee]"``, ``"Jdot_v[ee]"``, ``"q"``, ``"v"``) is
declared with ``stack.quantity`` and filled by the controller every tick. Joint 4 (limit
±2.2 rad) starts at 2.0 rad and the target lies where it points the hand: following it would
take joint 4 past its limit. The bounds brake it in time; the script counts the ticks with an
active bound and checks that no position, velocity or acceleration limit is violated.

Run:  python examples/acceleration_joint_limits.py [--seconds 4]
"""

from __future__ import annotations

import argparse

import numpy as np

import wbc
import wbc.robots
from wbc.sim import Simulation
from wbc.tasks import JointAccelerationLimit

DT = 0.01  # control period [s]
KP, KD = 20.0, 10.0  # task-space PD gains [1/s²], [1/s]
KP_POSTURE, KD_POSTURE = 4.0, 4.0


def build_controller(robot) -> wbc.Controller:
    nv, n_arm = robot.nv, 7
    qdd = wbc.Variables(qdd=nv)
    stack = wbc.Stack(qdd, damping=1e-3)
    x = qdd["qdd"]
    pose = stack.quantity("pose[ee]", (4, 4))
    J = stack.quantity("J[ee]", (6, nv))
    drift = stack.quantity("Jdot_v[ee]", 6)
    q, v = stack.quantity("q", robot.nq), stack.quantity("v", nv)
    target = stack.parameter("hand.target", 3)          # world position [m], set per tick
    error = target - pose[:3, 3]
    stack.add(wbc.Cost(J[:3, :] @ x + drift[:3], target=KP * error - KD * (J[:3, :] @ v),
                       name="hand"), priority=0)
    home = stack.parameter("posture.home", n_arm)
    arm = slice(nv - n_arm, nv)
    stack.add(wbc.Cost(x[arm], target=KP_POSTURE * (home - q[arm]) - KD_POSTURE * v[arm],
                       name="posture"), priority=1)
    stack.constrain(JointAccelerationLimit(robot, dt=DT, method="viable", name="joint_limits"))
    return wbc.Controller(robot, stack, backend="daqp", dt=DT)


def main(argv: list[str] | None = None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=4.0, help="simulated time [s]")
    args = parser.parse_args(argv)

    robot = wbc.robots.load("mecanum_gen3")
    controller = build_controller(robot)
    q0 = robot.neutral()
    q0[4] = 2.0  # 0.2 rad below its limit
    # A target 0.3 m along the direction joint 4 moves the hand in.
    J = robot.frame_jacobian(q0, "ee")
    direction = J[:3, 4] / np.linalg.norm(J[:3, 4])
    target = robot.frame_pose(q0, "ee")[:3, 3] + 0.3 * direction

    def active_bounds(tick) -> int:
        """How many accelerations sit on their bound this tick (live workspace buffers)."""
        lower, upper = controller.workspace.variable_bounds()
        return int(np.sum(np.isclose(tick.command, lower) | np.isclose(tick.command, upper)))

    sim = Simulation(robot, controller, dt=DT, command="acceleration",
                     signals={"active_bounds": active_bounds})
    run = sim.run(seconds=args.seconds, q0=q0,
                  references={"hand": target, "posture.home": q0[3:]})

    limits = robot.limits
    q_excess = np.maximum(run.q - limits.q_upper, limits.q_lower - run.q).max()
    v_excess = np.maximum(run.v - limits.v_upper, limits.v_lower - run.v).max()
    a_excess = np.maximum(run.command - limits.a_upper, limits.a_lower - run.command).max()
    hand_error = np.linalg.norm(robot.frame_pose(run.q_final, "ee")[:3, 3] - target)
    # A failed lower level (here the posture) leaves the command of the levels above
    # ("partial"): every hard bound still holds.
    print(f"{len(run.t)} ticks: {sum(s == 'solved' for s in run.status)} solved, "
          f"{int(np.sum(run.partial))} partial; a bound active in "
          f"{int(np.count_nonzero(run.signals['active_bounds']))} ticks")
    print(f"joint 4: from {q0[4]:.3f} rad to max {run.q[:, 4].max():.3f} rad "
          f"(limit {limits.q_upper[4]:.3f})")
    print(f"largest limit violation: position {max(q_excess, 0):.1e} rad, velocity "
          f"{max(v_excess, 0):.1e} rad/s, acceleration {max(a_excess, 0):.1e} rad/s²")
    print(f"final hand error {1e3 * hand_error:.1f} mm after {args.seconds} s (the arm stops "
          f"at the limit; the base accelerates at most {limits.a_upper[0]} m/s²)")
    return run, (q_excess, v_excess, a_excess)


if __name__ == "__main__":
    main()
