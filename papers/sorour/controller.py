"""Sorour, Cherubini & Fraisse's whole-body controller (eqs. 8, 9, 11, 14) with the MPO700's
steering controller in the loop: :class:`SorourController`, and the paper's parameters
(Table I, :data:`PARAMETERS`).

Three variants of the redundancy resolution, ``step(q, v, ee=target)`` each:

* ``pinv`` — the whole-body damped pseudo-inverse of eq. 8 (one level, ``ρ``, no mobility);
* ``proposed`` — eq. 9: the ψ-shared task (per-tick mobility on the task's level) and the
  dexterous posture in the null space (exact weighted QP form, docs/DESIGN.md, math note 3);
* ``compensated`` — eq. 9 plus eq. 14: the arm makes up for the base velocity the steering
  controller (:class:`~wbc.papers.sorour.steering.SteerableController`) will not deliver,
  predicted by its own copy of that controller (the paper's "next sample" prediction).
"""

from __future__ import annotations

import math
import time

import numpy as np

import wbc
from wbc.tasks import RpyPoseTask
from wbc.tasks.rpy_pose import pose_error, rpy_jacobian

from .closed_form import task_sharing_factor
from .steering import MPO700_STEER_LIMITS, SteerableController, scale_into
from .task_sharing import ArmCompensation, DexterousPosture, share_task, sharing_factor

__all__ = ["N_BASE", "PARAMETERS", "Q_DEX", "SorourController", "VARIANTS",
           "steering_controller"]

#: Table I (``ts`` the control period [s]; lengths [m]; gains [1/s]).
PARAMETERS = {"lambda_p": 1.7, "lambda_dex": 3.5, "rho": 0.001, "ts": 0.025, "Kp": 2.0,
              "r_w": 0.09, "d": 0.045, "h_x": 0.24, "h_y": 0.19, "r_fm": 0.25, "r_mm": 0.9,
              "steer_rate_max": MPO700_STEER_LIMITS[0],
              "steer_acceleration_max": MPO700_STEER_LIMITS[1], "icr_gain": 10.0}
#: the dexterous arm configuration (Table II) [rad]
Q_DEX = np.array([math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0])
#: the three redundancy resolutions of :class:`SorourController`
VARIANTS = ("pinv", "proposed", "compensated")
#: the base's velocity coordinates ``(v_x, v_y, ω)``
N_BASE = 3


class SorourController:
    """One of the three variants (see the module docstring) as a ``step(q, v, ee=target)``.

    Attributes:
        last_solution: the eq. 8/9 stack's solution of the last tick.
        psi: ψ of the last tick (eq. 11; ``nan`` for ``pinv``, which shares nothing).
        tick_parts: wall times [s] of the last tick: ``"stack"``, ``"icr_qp"``,
            ``"compensation"``.
    """

    def __init__(self, robot, variant: str, backend: str = "daqp") -> None:
        if variant not in VARIANTS:
            raise wbc.UnknownNameError(f"unknown variant {variant!r}; variants are {VARIANTS}")
        p = PARAMETERS
        self.robot, self.variant = robot, variant
        stack = wbc.Stack(wbc.Variables(qd=robot.nv), damping={0: p["rho"]}, min_norm=False)
        pose = RpyPoseTask(robot, "ee", p["lambda_p"], name="ee")
        stack.add(pose, priority=0)
        if variant != "pinv":
            share_task(stack, sharing_factor(pose.position_error_norm, p["r_fm"], p["r_mm"]),
                       N_BASE, priority=0)
            stack.add(DexterousPosture(robot, Q_DEX, p["lambda_dex"], name="dex"), priority=1)
        # the paper's eqs. 7-13 hold no joint limits: reproduced as printed, on purpose
        self.controller = wbc.Controller(robot, stack, backend=backend, dt=p["ts"],
                                         missing_limits="ignore")
        self.steering = steering_controller(robot, backend)
        self.compensation = (ArmCompensation(robot.nv - N_BASE, backend=backend)
                             if variant == "compensated" else None)
        self.last_solution: wbc.Solution | None = None
        self.psi = math.nan
        self.tick_parts: dict[str, float] = {}

    def step(self, q, v=None, ee=None) -> np.ndarray:
        clock = time.perf_counter
        t0 = clock()
        command = self.controller.step(q, ee=ee).copy()
        self.last_solution = self.controller.last_solution
        # the base's reference within its twist limits (direction kept), see the summary
        command[:N_BASE] = scale_into(command[:N_BASE], self.robot.base.v_max)
        t1 = clock()
        predicted = self.steering.step(command[:N_BASE])  # the base's next-sample twist
        t2 = clock()
        pose = self.robot.frame_pose(q, "ee")
        if self.variant != "pinv":
            self.psi = task_sharing_factor(float(np.linalg.norm(pose_error(pose, ee)[:3])),
                                           PARAMETERS["r_fm"], PARAMETERS["r_mm"])
        if self.compensation is not None:
            J = rpy_jacobian(self.robot.frame_jacobian(q, "ee"), pose[:3, :3], q[2])
            command[N_BASE:] += self.compensation(J[:, N_BASE:], J[:, :N_BASE],
                                                  command[:N_BASE], predicted.twist)
        self.tick_parts = {"stack": t1 - t0, "icr_qp": predicted.qp_s,
                           "compensation": clock() - t2}
        return command


def steering_controller(robot, backend: str) -> SteerableController:
    """The MPO700's steering controller with Table I's parameters (period, steer limits, ICR
    and drive gains)."""
    p = PARAMETERS
    return SteerableController(robot.base, dt=p["ts"], steer_rate=p["steer_rate_max"],
                               steer_acceleration=p["steer_acceleration_max"],
                               icr_gain=p["icr_gain"], drive_gain=p["Kp"], backend=backend)
