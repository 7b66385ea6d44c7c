"""The base's actuation in Xing et al.'s setting: commanded at the velocity level, with scale
errors and noise that its odometry does not see (:class:`CommandedVelocityOdometry`)."""

from __future__ import annotations

import numpy as np

from wbc.sim.actuation import Actuation

__all__ = ["CommandedVelocityOdometry"]


class CommandedVelocityOdometry(Actuation):
    """The base executes its velocity command with a scale error and multiplicative noise;
    its odometry reports the command (the arm is exact).

    Xing et al.'s robot is commanded at the velocity level (the integral of the planned
    acceleration). With ``v_cmd = v_est + q̈·dt`` the velocity asked for — computed from the
    *measured* velocity, as the planner integrates its own state — the true base velocity is
    ``(1 + scale + noise·N(0, 1)) ⊙ v_cmd`` (errors proportional to the commanded speed, as
    wheel slip and radius errors are: a base commanded to stay still does not move) and the
    measured one is ``v_cmd``. (``wbc.sim.actuation.OdometryError`` has the same scale error
    but *additive* noise, which moves a base commanded to stay still — and whether AMP keeps
    the base still is what the study measures; hence this model.)

    Args:
        scale: relative scale errors of ``(v_x, v_y, ω)`` [-].
        noise: standard deviations of the relative noise [-].
    """

    def __init__(self, scale=(0.03, -0.03, 0.03), noise=(0.02, 0.02, 0.02)) -> None:
        self.scale = np.asarray(scale, dtype=float)
        self.noise = np.asarray(noise, dtype=float)

    def reset(self, robot, dt: float) -> None:
        self._base = slice(0, int(robot.nv_base))

    def apply(self, state) -> None:
        command = state.v_est + np.asarray(state.command, dtype=float) * state.dt
        b = self._base
        draw = state.rng.standard_normal(self.scale.shape)
        state.v_true = command.copy()
        state.v_true[b] = (1.0 + self.scale + self.noise * draw) * command[b]
        state.v_measured = command.copy()
