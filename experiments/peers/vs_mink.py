"""Head-to-head with mink (kevinzakka/mink) on the same differential-IK problem as ``vs_pink``.

Problem (identical in both, and identical to :mod:`wbc.experiments.peers.vs_pink`): the Panda of
example-robot-data (fingers locked, 7 joints), a frame task on ``panda_hand`` (position and
orientation cost 1, gain ``FRAME_GAIN``, Levenberg-Marquardt damping ``LM_DAMPING``), a posture
task (cost ``POSTURE_COST``, gain ``POSTURE_GAIN``, target the initial configuration),
configuration limits (gain ``LIMIT_GAIN``) and velocity limits, Tikhonov damping ``DAMPING``,
period ``DT``, the same target sequence (:func:`~wbc.experiments.peers.vs_pink.targets`). The wbc
controller is :func:`~wbc.experiments.peers.vs_pink.build_wbc`, unchanged.

Model. Mink works on a MuJoCo model; :func:`mujoco_panda` builds it from the very URDF that
wbc's ``load_panda`` reads, with the visual and collision elements removed (no meshes are
loaded; inertias are kept) and the two finger joints made ``fixed`` — the same as pinocchio's
``buildReducedModel`` at the neutral (closed) fingers. ``fusestatic="false"`` keeps
``panda_hand`` a body of its own, whose frame is the URDF link frame. :func:`model_discrepancy`
checks that the hand pose, mink's body Jacobian (hand axes) and MuJoCo's world-aligned Jacobian
equal pinocchio's (``robot.frame_pose`` / ``robot.frame_jacobian``) — to ~1e-15 in practice.
Joint ranges come from the URDF in both; the velocity limits are passed to mink's
``VelocityLimit`` from pinocchio's ``model.velocityLimit`` (mink does not read them from the
model).

Mapping of parameters (mink 1.3, read from its source): mink's task conventions are pink's —
frame error ``log(T_bt)`` (hand-frame twist towards the target), Jacobian ``−Jlog6(T_tb) ·
J_hand``, weighted residual ``cost · (−gain · e)``, LM term ``lm_damping · ‖cost · gain · e‖²``
on the Hessian diagonal; posture error ``q ⊖ q*`` with Jacobian ``I``; configuration limits
``gain · (q_min ⊖ q) ≤ Δq ≤ gain · (q_max ⊖ q)``; velocity limits ``|Δq| ≤ v_max · dt``;
``solve_ik``'s ``damping`` is added to the Hessian diagonal; the QP is in ``Δq = v · dt``. So,
as for pink, mink cost ``c`` ↔ wbc weight ``c²`` and mink's ``damping`` ``d`` ↔ wbc ``ρ² = d``;
gains and ``lm_damping`` carry over unchanged. The two QPs have the same minimiser.

Closed loop and timing as in ``vs_pink``: both controllers integrate their own configuration
``q ← q + v·dt``, ticks interleaved in one process with a rotating order. A mink tick is
``configuration.update(q)`` + ``frame_task.set_target(T)`` (when the target changes; the
``mink.SE3`` is built beforehand) + ``mink.solve_ik(...)`` (which includes its own
``check_limits`` and the qpsolvers call); a wbc tick is ``controller.step(q, ee=T)``.

Agreement, as in ``vs_pink``: every tick also runs (untimed) mink on the same backend and mink
with quadprog — an exact solution of mink's QP — at wbc's state. ``command_diff_*`` is
``|v_wbc − v_mink|∞`` at the same state, ``wbc_error_vs_exact_max`` /
``mink_error_vs_exact_max`` each side against the exact solution, ``final_*_diff`` the hand
poses at the end of the two independent loops. ``agree``: final poses within ``POSE_TOL``, no
wbc failure, and either ``max |Δv| ≤ COMMAND_TOL`` (exact solvers) or wbc at least as close to
the exact solution as mink's own solver is (iterative solvers).

Run: ``python -m wbc.experiments.peers.vs_mink --ticks 3000 --out results/vs_mink`` (or
``wbc mink``). Needs ``pip install 'wbc[mink]'`` (mink, mujoco); without mink it prints a skip
message and exits 0. Writes ``vs_mink.json`` (per backend ``wbc_median_s``, ``mink_median_s``,
``ratio``, p95s, agreement figures; the machine) and prints a markdown table.
"""

from __future__ import annotations

import numpy as np

from wbc.experiments.peers import vs_pink
from wbc.experiments.peers.mujoco_models import (  # noqa: F401 (their home, re-exported)
    HAND,
    LOCKED_JOINTS,
    joint_names,
    mujoco_arm,
    mujoco_panda,
    panda_urdf_for_mujoco,
    panda_urdf_without_meshes,
    urdf_without_meshes,
)
from wbc.experiments.peers.vs_pink import (
    DAMPING,
    DT,
    FRAME_GAIN,
    LIMIT_GAIN,
    LM_DAMPING,
    POSTURE_COST,
    POSTURE_GAIN,
    Q0,
)

INSTALL_HINT = "pip install 'wbc[mink]'"
MODEL_NOTE = ("example-robot-data panda.urdf loaded by MuJoCo: visual/collision elements "
              "removed, finger joints fixed (closed), fusestatic=false")


def model_discrepancy(robot, model=None, configurations: int = 20, seed: int = 0) -> dict:
    """Largest differences between MuJoCo/mink and pinocchio on the hand frame over random
    configurations within the joint limits: pose (4 × 4), mink's body Jacobian vs pinocchio's
    LOCAL one, MuJoCo's ``mj_jacBody`` vs pinocchio's LOCAL_WORLD_ALIGNED one; joint ranges."""
    import mink
    import mujoco

    model = mujoco_panda() if model is None else model
    configuration = mink.Configuration(model)
    body = model.body(HAND).id
    lower, upper = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    rng = np.random.default_rng(seed)
    qs = [Q0] + [rng.uniform(lower, upper) for _ in range(configurations - 1)]
    worst = {"pose": 0.0, "jacobian_local": 0.0, "jacobian_world": 0.0}
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for q in qs:
        configuration.update(q)
        T = configuration.get_transform_frame_to_world(HAND, "body").as_matrix()
        J_local = configuration.get_frame_jacobian(HAND, "body")
        mujoco.mj_jacBody(model, configuration.data, jp, jr, body)
        T_pin = np.array(robot.frame_pose(q, "ee"))
        J_pin_local = np.array(robot.frame_jacobian(q, "ee", "local"))
        J_pin_world = np.array(robot.frame_jacobian(q, "ee", "world"))
        worst["pose"] = max(worst["pose"], float(np.abs(T - T_pin).max()))
        worst["jacobian_local"] = max(worst["jacobian_local"],
                                      float(np.abs(J_local - J_pin_local).max()))
        worst["jacobian_world"] = max(worst["jacobian_world"],
                                      float(np.abs(np.vstack([jp, jr]) - J_pin_world).max()))
    ranges = np.array([model.jnt_range[model.joint(name).id] for name in joint_names(robot)])
    worst["joint_range"] = float(max(np.abs(ranges[:, 0] - lower).max(),
                                     np.abs(ranges[:, 1] - upper).max()))
    return {**worst, "nq": (int(model.nq), int(robot.model.nq))}


class MinkLoop:
    """Mink's side: configuration, tasks, limits; :meth:`tick` is what is timed."""

    name = "mink"
    requirement = "mink"
    install_hint = INSTALL_HINT

    @staticmethod
    def problem_notes() -> dict:
        """What the JSON's ``problem`` records about the MuJoCo model and its verification."""
        from wbc.robots.fixed_base import load_panda

        check = model_discrepancy(load_panda())
        from importlib.metadata import version

        return {"mink_version": version("mink"), "mujoco_version": version("mujoco"),
                "mink_model": MODEL_NOTE,
                "mink_model_vs_pinocchio_max_abs_diff": {
                    k: check[k] for k in ("pose", "jacobian_local", "jacobian_world",
                                          "joint_range")}}

    def __init__(self, robot, solver: str) -> None:
        import mink

        self.mink, self.solver = mink, solver
        model = mujoco_panda()
        if [model.joint(i).name for i in range(model.njnt)] != joint_names(robot):
            raise RuntimeError("MuJoCo and pinocchio joint orders differ")
        self.configuration = mink.Configuration(model, Q0.copy())
        self.frame_task = mink.FrameTask(HAND, "body", position_cost=1.0, orientation_cost=1.0,
                                         gain=FRAME_GAIN, lm_damping=LM_DAMPING)
        posture = mink.PostureTask(model, cost=POSTURE_COST, gain=POSTURE_GAIN)
        posture.set_target(Q0.copy())
        self.tasks = [self.frame_task, posture]
        velocities = dict(zip(joint_names(robot), robot.model.velocityLimit, strict=True))
        self.limits = [mink.ConfigurationLimit(model, gain=LIMIT_GAIN),
                       mink.VelocityLimit(model, velocities)]

    def tick(self, q: np.ndarray, target=None) -> np.ndarray:
        self.configuration.update(q)
        if target is not None:
            self.frame_task.set_target(target)
        return self.mink.solve_ik(self.configuration, self.tasks, DT, solver=self.solver,
                                  damping=DAMPING, limits=self.limits)

    @staticmethod
    def target(T: np.ndarray):
        """``T`` (world, (4, 4)) as mink's target type."""
        import mink

        return mink.SE3.from_matrix(np.asarray(T, dtype=float))

    @staticmethod
    def scenarios(ticks: int) -> dict:
        """The report's other loop (:mod:`wbc.experiments.peers.scenarios`): the UR5 with
        both limits binding."""
        from .scenarios import mink_scenarios

        return mink_scenarios(ticks)


def run_backend(backend: str, ticks: int, jit: bool = True) -> dict:
    """The closed loops of wbc and mink on one backend (see :func:`vs_pink.run_backend`)."""
    return vs_pink.run_backend(backend, ticks, jit, MinkLoop)


def main(argv: list[str] | None = None) -> int:
    return vs_pink.main(argv, MinkLoop)


if __name__ == "__main__":
    raise SystemExit(main())
