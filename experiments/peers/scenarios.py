"""Two more closed loops against pink and mink, beside the Panda study of :mod:`.vs_pink`.

**UR5, both limits binding** (:func:`ur5_loop`; pink and mink). The UR5 of example-robot-data
(6 revolute joints; the elbow limited to ±π, the others to ±2π; velocity limits 3.15 / 3.2
rad/s), a frame task on ``ee_link`` (position and orientation cost 1, gain ``UR5_GAIN`` = 1: the
dead-beat gain, so the first ticks ask for tens of rad/s), a posture task (cost
``UR5_POSTURE_COST``), configuration limits (gain 0.5, pink's default) and velocity limits, pink's
default Tikhonov damping 1e-12. The target is the pose of ``UR5_GOAL``, whose elbow (3.6 rad)
lies past its limit, seen from ``UR5_Q0``: the loop saturates the velocity limits first, then
runs the elbow into its position limit and holds it there (``velocity_bound_ticks``,
``position_bound_ticks`` count the ticks on which a bound is active in wbc's answer). Pink is
given no ``limits=``: it applies the model's configuration and velocity limits by default,
which wbc needs written out (and warns about when they are not, see
:class:`wbc.errors.MissingLimitsWarning`). Mink gets the same limits explicitly, on a MuJoCo
model of the same URDF (:func:`wbc.experiments.peers.mujoco_models.mujoco_arm`).

**Mobile base, relative frame + centre of mass** (:func:`mobile_loop`; pink). The catalogue's
``mecanum_gen3`` (a holonomic base ``x, y, θ`` and a Kinova Gen3), a relative-frame task (the
hand ``"ee"`` in the base frame ``"base"``, costs 1, gain 0.5) towards the hand's pose moved by
``HAND_OFFSET`` in the base frame, a centre-of-mass task (gain 0.5, costs ``COM_COST``: 1 on
the world ``x`` and ``y``, 0 on the height, which the arm cannot give the hand and the centre
of mass both) towards a point 5 cm sideways, configuration limits (gain 0.5), damping
``MOBILE_DAMPING``. Pink's model limits that mean "none" (±1e10 on the base, ±1.8e308 on the
Gen3's continuous joints) are made ±inf for pink, so that it leaves those coordinates out as
wbc's ``ConfigurationLimit`` does (rows of 5e11 rad/s cost quadprog digits). Pink runs on the
robot's own pinocchio model, whose base joints are world ``x``, ``y`` (prismatic) and ``θ``
(revolute): pink's ``Δq / dt`` is ``q̇ = S v`` with ``S = blockdiag(Rz(θ), I)`` (wbc's ``v``
is the base's body twist), so pink's command is compared as ``Sᵀ q̇`` (``S`` is orthogonal:
the damping ``||Δq||²`` is ``||v||² dt²`` too, and the two QPs have the same minimiser).
Velocity limits are left out on both sides: wbc's base limits are on the body twist, pink's
model limits on the world rates — not the same set — and the model gives the arm none (wbc's
stack says so with ``missing_limits="ignore"``). Mink is not run here: the Gen3 of this robot
is built in code (:mod:`wbc.robots.kinova_gen3`) and has no URDF for MuJoCo to read.

Both loops: wbc's command drives the state (``q ← integrate(q, v, dt)``); at every state both
libraries are ticked, in one process, alternating which goes first, each tick timed
(``wbc_median_s``, ``<peer>_median_s``, ``ratio`` = wbc / peer); ``command_diff_max`` is
``max |v_wbc − v_peer|∞`` over the ticks [rad/s, m/s]. Both sides on quadprog, an exact
active-set solver: the two QPs then agree to round-off.

Measured (2026-11-27, this 2-core machine, shared; ``python -c "from wbc.experiments.peers import
scenarios as s; print(s.ur5_loop('pink', 150))"`` and alike): the UR5 against pink
``command_diff_max`` 9.5e-11 rad/s (median 6e-14; the maximum on the tick where the elbow leaves
its limit), 130 ticks with a velocity bound active, 51 with a position bound; against mink
2.8e-7 (median 3e-12) — mink's own: on the ticks where the hand arrives (errors below 1e-9 m)
mink's command differs from pink's by the same 3e-8 to 3e-7 rad/s while pink's and wbc's agree
to 1e-13 (mink's SE(3) logarithm's small-angle branch, by our reading). The mobile base against
pink: 8.5e-10 m/s (median 6e-15). Tick ratios wbc / peer: 0.66 to 0.80 in three runs, 1.10
and 1.24 in one run while other jobs loaded the machine (wbc on quadprog, the ordinary path
with JIT-compiled levels, not the fused daqp tick; ``wbc pink`` prints them per run).
"""

from __future__ import annotations

import gc
import time

import numpy as np

UR5_URDF = "ur_description/urdf/ur5_robot.urdf"
UR5_FRAME = "ee_link"
UR5_Q0 = np.array([0.0, -np.pi / 2, 2.2, -np.pi / 2, -np.pi / 2, 0.0])
UR5_GOAL = np.array([0.9, -1.3, 3.6, -1.0, -1.2, 0.6])  # elbow past its limit (π)
UR5_GAIN = 1.0
UR5_POSTURE_COST = 1e-3
LIMIT_GAIN = 0.5
DT = 0.01  # [s]
DAMPING = 1e-12  # pink's default; wbc ρ = √DAMPING
BOUND_TOL = 1e-9  # a bound is active when the command is within this of it [rad/s]

MOBILE_ROBOT = "mecanum_gen3"
MOBILE_GAIN = 0.5
MOBILE_DAMPING = 1e-6  # pink's damping d; wbc ρ = √d
HAND_OFFSET = (0.10, 0.05, -0.05)  # [m], in the base frame
COM_OFFSET = (0.0, 0.05, 0.0)  # [m], world
COM_COST = (1.0, 1.0, 0.0)  # pink's cost per world axis: the height is left to the hand


# ----------------------------------------------------------------------------- the UR5
def load_ur5():
    """The UR5 of example-robot-data as a wbc fixed-base robot, ``"ee"`` = ``ee_link``."""
    import pinocchio as pin

    from wbc.robots.fixed_base import FixedBaseRobot
    from wbc.robots.resources import urdf_path

    model = pin.buildModelFromUrdf(str(urdf_path(UR5_URDF)))
    return FixedBaseRobot(model, {"ee": UR5_FRAME}, name="ur5")


def ur5_controller(robot, backend: str = "quadprog"):
    """wbc's UR5 controller: frame ≻ nothing, one weighted level (see the module docstring)."""
    import wbc
    from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(DAMPING))
    stack.add(FrameTask(robot, "ee", gain=UR5_GAIN, weight=1.0, name="ee"))
    stack.add(PostureTask(robot, gain=1.0, weight=UR5_POSTURE_COST ** 2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=LIMIT_GAIN, name="position_limit"))
    stack.constrain(VelocityLimit(robot, name="velocity_limit"))
    controller = wbc.Controller(robot, stack, backend=backend, dt=DT)
    controller.set_references(posture=UR5_Q0)
    return controller


class PinkUr5:
    """Pink's UR5: the model's limits by default (``limits`` not given)."""

    name = "pink"

    def __init__(self, robot, solver: str = "quadprog") -> None:
        import pink
        from pink.tasks import FrameTask, PostureTask

        self.pink, self.solver = pink, solver
        model = robot.model
        self.configuration = pink.Configuration(model, model.createData(), UR5_Q0.copy())
        self.frame_task = FrameTask(UR5_FRAME, position_cost=1.0, orientation_cost=1.0,
                                    gain=UR5_GAIN)
        posture = PostureTask(cost=UR5_POSTURE_COST, gain=1.0)
        posture.set_target(UR5_Q0.copy())
        self.tasks = [self.frame_task, posture]

    def set_target(self, T: np.ndarray) -> None:
        import pinocchio as pin

        self.frame_task.set_target(pin.SE3(T[:3, :3].copy(), T[:3, 3].copy()))

    def tick(self, q: np.ndarray) -> np.ndarray:
        self.configuration.update(q)
        return self.pink.solve_ik(self.configuration, self.tasks, DT, solver=self.solver,
                                  damping=DAMPING)


class MinkUr5:
    """Mink's UR5 on a MuJoCo model of the same URDF, the limits given explicitly."""

    name = "mink"

    def __init__(self, robot, solver: str = "quadprog") -> None:
        import mink

        from .mujoco_models import joint_names, mujoco_arm

        self.mink, self.solver = mink, solver
        model = mujoco_arm(UR5_URDF)
        if [model.joint(i).name for i in range(model.njnt)] != joint_names(robot):
            raise RuntimeError("MuJoCo and pinocchio joint orders differ")
        self.configuration = mink.Configuration(model, UR5_Q0.copy())
        self.frame_task = mink.FrameTask(UR5_FRAME, "body", position_cost=1.0,
                                         orientation_cost=1.0, gain=UR5_GAIN)
        posture = mink.PostureTask(model, cost=UR5_POSTURE_COST, gain=1.0)
        posture.set_target(UR5_Q0.copy())
        self.tasks = [self.frame_task, posture]
        velocities = dict(zip(joint_names(robot), robot.model.velocityLimit, strict=True))
        self.limits = [mink.ConfigurationLimit(model, gain=LIMIT_GAIN),
                       mink.VelocityLimit(model, velocities)]

    def set_target(self, T: np.ndarray) -> None:
        self.frame_task.set_target(self.mink.SE3.from_matrix(np.asarray(T, dtype=float)))

    def tick(self, q: np.ndarray) -> np.ndarray:
        self.configuration.update(q)
        return self.mink.solve_ik(self.configuration, self.tasks, DT, solver=self.solver,
                                  damping=DAMPING, limits=self.limits)


def _interleaved(ticks: int, step_wbc, step_peer, advance) -> dict:
    """Tick both sides at the same states (wbc's command drives them), alternating which goes
    first; returns the per-tick times and commands."""
    clock = time.perf_counter
    t_wbc, t_peer, diff = np.empty(ticks), np.empty(ticks), np.empty(ticks)
    commands = []
    gc.collect()
    gc.disable()
    try:
        for k in range(ticks):
            if k % 2 == 0:
                t0 = clock()
                v_wbc = step_wbc()
                t1 = clock()
                v_peer = step_peer()
                t2 = clock()
                t_wbc[k], t_peer[k] = t1 - t0, t2 - t1
            else:
                t0 = clock()
                v_peer = step_peer()
                t1 = clock()
                v_wbc = step_wbc()
                t2 = clock()
                t_peer[k], t_wbc[k] = t1 - t0, t2 - t1
            diff[k] = float(np.abs(v_wbc - v_peer).max())
            commands.append(v_wbc)
            advance(v_wbc)
    finally:
        gc.enable()
    return {"t_wbc": t_wbc, "t_peer": t_peer, "diff": diff, "commands": commands}


def _summary(peer: str, run: dict) -> dict:
    wbc_med, peer_med = float(np.median(run["t_wbc"])), float(np.median(run["t_peer"]))
    return {"wbc_median_s": wbc_med, f"{peer}_median_s": peer_med, "ratio": wbc_med / peer_med,
            "command_diff_max": float(run["diff"].max()),
            "command_diff_median": float(np.median(run["diff"]))}


def ur5_loop(peer: str = "pink", ticks: int = 300, backend: str = "quadprog") -> dict:
    """The UR5 loop against ``peer`` (``"pink"`` or ``"mink"``), see the module docstring."""
    robot = load_ur5()
    controller = ur5_controller(robot, backend)
    rival = (PinkUr5 if peer == "pink" else MinkUr5)(robot, backend)
    goal = robot.frame_pose(UR5_GOAL, "ee").copy()
    rival.set_target(goal)
    controller.set_references(ee=goal)
    state = {"q": UR5_Q0.copy()}
    lower, upper = robot.limits.q_lower, robot.limits.q_upper
    v_max = robot.limits.v_upper
    counts = {"velocity": 0, "position": 0}

    def step_wbc():
        return controller.step(state["q"])

    def step_peer():
        return rival.tick(state["q"])

    def advance(v):
        q = state["q"]
        bound_up = LIMIT_GAIN * (upper - q) / DT
        bound_lo = LIMIT_GAIN * (lower - q) / DT
        counts["velocity"] += bool(np.any(np.abs(v) >= v_max - BOUND_TOL))
        counts["position"] += bool(np.any((v >= bound_up - BOUND_TOL)
                                          | (v <= bound_lo + BOUND_TOL)))
        state["q"] = q + DT * v

    run = _interleaved(ticks, step_wbc, step_peer, advance)
    q = state["q"]
    return {**_summary(peer, run), "ticks": ticks, "backend": backend,
            "velocity_bound_ticks": counts["velocity"],
            "position_bound_ticks": counts["position"],
            "elbow_final_rad": float(q[2]), "elbow_limit_rad": float(upper[2]),
            "wbc_failures": 0 if controller.last_solution.ok else 1}


# ------------------------------------------------------------------------ the mobile base
def mobile_controller(robot, backend: str = "quadprog"):
    """wbc's mobile-base controller: relative frame + centre of mass, one level."""
    import wbc
    from wbc.tasks import ConfigurationLimit
    from wbc.tasks.com import ComTask
    from wbc.tasks.relative_frame import RelativeFrameTask

    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(MOBILE_DAMPING))
    stack.add(RelativeFrameTask(robot, "ee", "base", gain=MOBILE_GAIN, weight=1.0,
                                name="hand"))
    stack.add(ComTask(robot, gain=MOBILE_GAIN, weight=np.square(COM_COST),
                      name="centre_of_mass"))
    stack.constrain(ConfigurationLimit(robot, gain=LIMIT_GAIN, name="position_limit"))
    # velocity limits left out on purpose (see the module docstring)
    return wbc.Controller(robot, stack, backend=backend, dt=DT, missing_limits="ignore")


class PinkMobile:
    """Pink's mobile base: the robot's pinocchio model, its configuration limits."""

    name = "pink"

    def __init__(self, robot, q0: np.ndarray, solver: str = "quadprog") -> None:
        import pink
        import pinocchio as pin
        from pink.limits import ConfigurationLimit
        from pink.tasks import ComTask, RelativeFrameTask

        self.pink, self.solver, self.robot = pink, solver, robot
        # the model's "no limit" is ±1e10 (base) or ±1.8e308 (continuous joints): as +-inf,
        # pink leaves those coordinates out, as wbc's ConfigurationLimit does (rows of 5e11
        # rad/s would cost quadprog digits, not change the answer)
        model = pin.Model(robot.model)
        for side in ("lowerPositionLimit", "upperPositionLimit"):
            limit = getattr(model, side).copy()
            limit[np.abs(limit) >= 1e10] = np.inf * np.sign(limit[np.abs(limit) >= 1e10])
            setattr(model, side, limit)
        self.configuration = pink.Configuration(model, model.createData(), q0.copy())
        self.hand = RelativeFrameTask(model.frames[robot.frame_id("ee")].name, "base",
                                      position_cost=1.0, orientation_cost=1.0,
                                      gain=MOBILE_GAIN)
        self.com = ComTask(cost=list(COM_COST), gain=MOBILE_GAIN)
        self.tasks = [self.hand, self.com]
        self.limits = [ConfigurationLimit(model, LIMIT_GAIN)]

    def set_targets(self, hand: np.ndarray, com: np.ndarray) -> None:
        import pinocchio as pin

        self.hand.set_target(pin.SE3(hand[:3, :3].copy(), hand[:3, 3].copy()))
        self.com.set_target(np.asarray(com, dtype=float).reshape(3))

    def tick(self, q: np.ndarray) -> np.ndarray:
        """Pink's command in wbc's coordinates: ``Sᵀ q̇`` (see the module docstring)."""
        self.configuration.update(q)
        qdot = self.pink.solve_ik(self.configuration, self.tasks, DT, solver=self.solver,
                                  damping=MOBILE_DAMPING, limits=self.limits)
        return self.robot.velocity_map(q).T @ qdot


def mobile_loop(ticks: int = 200, backend: str = "quadprog") -> dict:
    """The mobile-base loop against pink, see the module docstring."""
    import wbc.robots

    robot = wbc.robots.load(MOBILE_ROBOT)
    twin = robot.clone()  # pink's velocity map, without touching wbc's robot's caches
    controller = mobile_controller(robot, backend)
    q0 = robot.neutral()
    base, hand = robot.frame_pose(q0, "base").copy(), robot.frame_pose(q0, "ee").copy()
    hand_target = np.linalg.inv(base) @ hand
    hand_target[:3, 3] += HAND_OFFSET
    com_target = robot.com(q0).reshape(3) + COM_OFFSET
    rival = PinkMobile(twin, q0, backend)
    rival.set_targets(hand_target, com_target)
    controller.set_references(hand=hand_target, centre_of_mass=com_target)
    state = {"q": q0.copy()}

    def advance(v):
        state["q"] = robot.integrate(state["q"], v, DT)

    run = _interleaved(ticks, lambda: controller.step(state["q"]),
                       lambda: rival.tick(state["q"]), advance)
    q = state["q"]
    P = np.linalg.inv(robot.frame_pose(q, "base").copy()) @ robot.frame_pose(q, "ee").copy()
    return {**_summary("pink", run), "ticks": ticks, "backend": backend,
            "final_hand_error_m": float(np.linalg.norm(P[:3, 3] - hand_target[:3, 3])),
            "final_com_error_m": float(np.linalg.norm(robot.com(q).reshape(3) - com_target)),
            "wbc_failures": 0 if controller.last_solution.ok else 1}


# ----------------------------------------------------------------------------- reports
UR5_TICKS = 150  # the elbow meets its limit at tick ≈ 30 and leaves it at ≈ 80; done by ≈ 140
MOBILE_TICKS = 200
TITLES = {"ur5_limits": "UR5, configuration and velocity limits binding",
          "mobile_relative_com": "mobile base (mecanum_gen3), relative frame + centre of mass"}


def _guarded(loop, *args) -> dict:
    """``loop(*args)``, or ``{"error": ...}``: one broken loop must not hide the others."""
    try:
        return loop(*args)
    except Exception as err:  # noqa: BLE001 (reported in the JSON and the table)
        return {"error": f"{type(err).__name__}: {err}"}


def pink_scenarios(ticks: int) -> dict:
    """Both loops against pink (at most ``ticks`` ticks each), for ``wbc pink``'s report."""
    return {"ur5_limits": _guarded(ur5_loop, "pink", min(ticks, UR5_TICKS)),
            "mobile_relative_com": _guarded(mobile_loop, min(ticks, MOBILE_TICKS))}


def mink_scenarios(ticks: int) -> dict:
    """The UR5 loop against mink (the mobile base has no MuJoCo model, see the module
    docstring), for ``wbc mink``'s report."""
    return {"ur5_limits": _guarded(ur5_loop, "mink", min(ticks, UR5_TICKS))}


def markdown(scenarios: dict, peer: str) -> str:
    """The loops' table: tick medians, the ratio, the largest command difference."""
    rows = [f"| loop (quadprog, same states, interleaved) | ticks | wbc median [µs] | {peer} "
            f"median [µs] | wbc / {peer} | max \\|Δv\\| [rad/s] | limits binding [ticks] |",
            "|---|---:|---:|---:|---:|---:|---|"]
    for key, r in scenarios.items():
        title = TITLES.get(key, key)
        if "error" in r:
            rows.append(f"| {title} | — | — | — | — | — | failed: {r['error']} |")
            continue
        binding = (f"velocity {r['velocity_bound_ticks']}, position {r['position_bound_ticks']}"
                   if "velocity_bound_ticks" in r else "—")
        rows.append(f"| {title} | {r['ticks']} | {r['wbc_median_s'] * 1e6:.1f} | "
                    f"{r[f'{peer}_median_s'] * 1e6:.1f} | {r['ratio']:.3f} | "
                    f"{r['command_diff_max']:.1e} | {binding} |")
    return "\n".join(rows)
