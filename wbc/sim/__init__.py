"""`wbc.sim`: one closed-loop simulator for every controller, study, audit and example.

::

    from wbc.sim import Simulation, actuation, position_error
    sim = Simulation(robot, controller, dt=0.01,
                     actuation=[actuation.OdometryError(scale=0.03, noise=0.005)],
                     signals={"ee_error": position_error("ee")})
    run = sim.run(seconds=10.0, references=lambda t: {"ee": target(t)})
    run.t, run.q, run.v, run.command, run.status, run.tick_s, run.signals["ee_error"]

A tick at time ``t = k·dt``:

1. the controller sees the **measured** state ``(q_est, v_est)`` and the references of ``t``
   and returns its command (``controller.step(q_est, v_est, **references)``; any object with
   that method works — a :class:`wbc.Controller` or a class composing several pieces);
2. the command becomes the velocity asked for, ``v_command``: the command itself
   (``command="velocity"``), or ``v_est + a·dt`` for an acceleration ``a``
   (``command="acceleration"``: the actuators continue from the velocity they measure; the
   truth starts from ``v + a·dt``); any other ``command`` kind (e.g. ``"torque"``) is passed
   through raw and an actuation model must produce the motion;
3. the **actuation chain** (:mod:`wbc.sim.actuation`, in order) turns it into the velocity the
   robot really moves with, ``v_true``, and the one its encoders and odometry report,
   ``v_measured`` (both start as ``v_command``);
4. the truth integrates on the configuration manifold: ``q ← robot.integrate(q, v̄, dt)`` with
   ``v̄ = v_true`` for velocity commands and the mid-tick velocity ``(v + v_true)/2`` for the
   others (exact for constant joint accelerations); the estimate integrates ``v_measured`` the
   same way. Without actuation errors the two are identical.

Everything is seeded (``seed``): two runs of the same simulation give the same numbers.

Plants. ``Simulation(..., plant=None)`` (the default) is the kinematic plant above. A plant
object replaces steps 2–4: ``plant.reset(q0, v0, dt, command) -> (q, v)`` once per run, then each
tick ``plant.step(command) -> PlantStep`` with the true ``q``, ``v`` at the period's end, the
``v_measured`` the encoders saw (the estimate integrates it) and per-tick ``signals`` (recorded in
``run.signals``); actuation models are refused with a plant. :class:`MujocoPlant`
(:mod:`wbc.sim.mujoco_plant`, model by :mod:`wbc.sim.mjcf`; the ``[mujoco]`` extra) is real
physics: wheels with rollers on a floor with friction, servos with torque limits.
"""

from __future__ import annotations

from . import actuation
from .mujoco_plant import MujocoPlant, PlantStep  # imports mujoco only when a plant is made
from .simulation import Run, Simulation, Tick, position_error

__all__ = ["MujocoPlant", "PlantStep", "Run", "Simulation", "Tick", "actuation",
           "position_error"]
