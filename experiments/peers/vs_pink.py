"""Head-to-head with pink (stephane-caron/pink) on the same differential-IK problem.

Problem (identical in both): the Panda of example-robot-data (fingers locked, 7 joints), a
frame task on ``panda_hand`` (position and orientation cost 1, gain ``FRAME_GAIN``), a posture
task (cost ``POSTURE_COST``, gain ``POSTURE_GAIN``, target the initial configuration),
configuration limits (gain ``LIMIT_GAIN``) and velocity limits, Tikhonov damping ``DAMPING``,
period ``DT``. Pink costs ``c`` are wbc weights ``c²`` and pink's damping ``d`` is wbc's
``ρ² = d`` (see :mod:`wbc.tasks.frame`): the two QPs have the same minimiser.

Closed loop: a fixed sequence of target poses (:func:`targets`), each held for an equal share
of the ticks; both controllers integrate their own configuration ``q ← q + v·dt`` (all joints
revolute). The two loops run in the same process, tick by tick, alternating which goes first,
so machine noise hits both alike. A tick is, for pink, ``configuration.update(q)`` +
``frame_task.set_target(T)`` + ``solve_ik(...)``; for wbc, ``controller.step(q, ee=T)`` (model
stage, compiled evaluation, persistent backend). Integration is outside the timed region.
Then both loops run again from ``Q0``, fresh, timed in blocks of 100 ticks
(:func:`dedicated_loops`, :mod:`wbc.experiments.benchmarks.loops`): each side as a dedicated control
loop, with the caches it warmed itself (``dedicated`` in the JSON). Tick by tick, each side
finds the caches as the other left them; the two figures bracket what a controller costs.

Agreement. Besides the two timed loops, every tick runs (untimed) pink on the same backend and
pink with quadprog — an exact active-set solution of pink's QP — at wbc's state, so commands are
compared at the same state:

* ``command_diff_*``: ``|v_wbc − v_pink|∞`` [rad/s] at the same state, same backend;
* ``wbc_error_vs_exact_max`` / ``pink_error_vs_exact_max``: each side against the exact
  solution, which tells which side a disagreement comes from;
* ``final_*_diff``: hand poses at the end of the two independent closed loops.

``agree`` holds when the final poses agree within ``POSE_TOL`` = 1e-4 [m, rad], no wbc solve
failed, and either ``max |v_wbc − v_pink| ≤ COMMAND_TOL`` = 1e-6 rad/s (met by the exact
solvers, daqp and quadprog: both sides then solve the same QP to round-off), or — for the
iterative solvers (proxqp, osqp, clarabel), whose default stopping criteria leave errors far
above 1e-6 on this ill-conditioned QP (Hessian eigenvalues from ≈1e-4, the posture weight, to
≈3) — wbc's commands are at least as close to the exact solution as pink's own are
(``wbc_error_vs_exact_max ≤ pink_error_vs_exact_max + COMMAND_TOL``). Pink's QP is written in
``Δq = v·dt``, so its solvers' absolute tolerances are amplified by ``1/dt`` in ``v``.

More loops. After the backends, the rival's ``scenarios(ticks)`` (when it has one, and
quadprog is installed on both sides) runs the loops of :mod:`wbc.experiments.peers.scenarios`:
against pink the UR5 with its configuration and velocity limits binding and the mobile base
with a relative-frame and a centre-of-mass task; against mink the UR5. Each records
``wbc_median_s``, ``<rival>_median_s``, ``ratio`` (wbc / rival, both ticked at the same states,
interleaved in this process) and ``command_diff_max``.

Run: ``python -m wbc.experiments.peers.vs_pink --ticks 3000 --out results/vs_pink`` (or
``wbc pink``).
Writes ``vs_pink.json`` (per backend ``wbc_median_s``, ``pink_median_s``, ``ratio``, p95s,
agreement figures; ``scenarios``: the loops above by name; the machine) and prints markdown
tables.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import json
import time
import warnings
from pathlib import Path
from typing import Protocol

import numpy as np

from ..arguments import installed_backends
from ..benchmarks.loops import (
    DEDICATED_BLOCK,
    call_turn,
    closed_loop_turn,
    goal_schedule,
    median_ratio,
    timed_turns,
    wbc_tick,
)

BACKENDS = ("daqp", "quadprog", "proxqp", "osqp", "clarabel")
DT = 0.01  # [s]
FRAME_GAIN = 0.5
LM_DAMPING = 1.0  # pink's Levenberg-Marquardt damping of the frame task (as in its examples)
POSTURE_GAIN = 0.5
POSTURE_COST = 1e-2  # pink cost [cost/rad]; wbc weight = cost²
LIMIT_GAIN = 0.5
DAMPING = 1e-12  # pink's default Tikhonov damping; wbc ρ = √DAMPING
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
COMMAND_TOL = 1e-6  # [rad/s], per tick, at the same state
POSE_TOL = 1e-4  # [m] and [rad], final hand poses of the two loops
INSTALL_HINT = "pip install 'wbc[pink]'"


def targets(T0: np.ndarray) -> list[np.ndarray]:
    """The target poses (world, (4, 4)): offsets of the initial hand pose ``T0``."""
    import pinocchio as pin

    offsets = [  # translation [m] (world), rotation vector [rad] (hand frame)
        ((0.10, 0.15, -0.05), (0.2, 0.0, 0.0)),
        ((-0.05, -0.20, 0.10), (0.0, 0.3, 0.0)),
        ((0.15, 0.00, 0.15), (0.0, 0.0, 0.5)),
        ((0.00, 0.25, -0.10), (0.3, -0.2, 0.1)),
        ((0.00, 0.00, 0.00), (0.0, 0.0, 0.0)),
    ]
    out = []
    for dp, dr in offsets:
        T = T0.copy()
        T[:3, 3] += dp
        T[:3, :3] = T0[:3, :3] @ pin.exp3(np.array(dr))
        out.append(T)
    return out


def build_wbc(robot, backend: str, jit: bool = True, kinematics: str = "compiled"):
    """The wbc controller of the benchmark problem."""
    import wbc
    from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=np.sqrt(DAMPING))
    stack.add(FrameTask(robot, "ee", gain=FRAME_GAIN, weight=1.0, lm_damping=LM_DAMPING,
                        name="ee"))
    stack.add(PostureTask(robot, gain=POSTURE_GAIN, weight=POSTURE_COST ** 2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=LIMIT_GAIN, name="position_limit"))
    stack.constrain(VelocityLimit(robot, name="velocity_limit"))
    controller = wbc.Controller(robot, stack, backend=backend, dt=DT, jit=jit,
                                kinematics=kinematics)
    controller.set_references(posture=Q0)
    return controller


class RivalLoop(Protocol):
    """What the study code needs of a rival library's loop class (see :class:`PinkLoop`)."""

    name: str
    requirement: str
    install_hint: str

    def __init__(self, robot, solver: str) -> None: ...

    def tick(self, q: np.ndarray, target=None) -> np.ndarray: ...

    @staticmethod
    def problem_notes() -> dict: ...

    @staticmethod
    def target(T: np.ndarray): ...


class PinkLoop:
    """Pink's side: configuration, tasks, limits; :meth:`tick` is what is timed.

    The study code (:func:`run_backend`, :func:`markdown_table`, :func:`main`) takes the rival
    library's loop class as a parameter: ``name`` keys its results, ``requirement`` is the module
    whose absence stops the study with ``install_hint``, :meth:`target` converts a ``(4, 4)``
    pose into the rival's target type (untimed), and :meth:`problem_notes` adds to the JSON's
    ``problem``."""

    name = "pink"
    requirement = "pink"
    install_hint = INSTALL_HINT

    def __init__(self, robot, solver: str) -> None:
        import pink
        from pink.limits import ConfigurationLimit, VelocityLimit
        from pink.tasks import FrameTask, PostureTask

        self.pink, self.solver = pink, solver
        model = robot.model
        self.configuration = pink.Configuration(model, model.createData(), Q0.copy())
        self.frame_task = FrameTask("panda_hand", position_cost=1.0, orientation_cost=1.0,
                                    gain=FRAME_GAIN, lm_damping=LM_DAMPING)
        posture = PostureTask(cost=POSTURE_COST, gain=POSTURE_GAIN)
        posture.set_target(Q0.copy())
        self.tasks = [self.frame_task, posture]
        self.limits = [ConfigurationLimit(model, LIMIT_GAIN), VelocityLimit(model)]

    def tick(self, q: np.ndarray, target=None) -> np.ndarray:
        self.configuration.update(q)
        if target is not None:
            self.frame_task.set_target(target)
        return self.pink.solve_ik(self.configuration, self.tasks, DT, solver=self.solver,
                                  damping=DAMPING, limits=self.limits)

    @staticmethod
    def problem_notes() -> dict:
        """What the JSON's ``problem`` adds about the rival's model: nothing, pink uses wbc's
        pinocchio model itself."""
        return {}

    @staticmethod
    def target(T: np.ndarray):
        """``T`` (world, (4, 4)) as pink's target type."""
        import pinocchio as pin

        return pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())

    @staticmethod
    def scenarios(ticks: int) -> dict:
        """The report's other loops (:mod:`wbc.experiments.peers.scenarios`): the UR5 with
        both limits binding and the mobile base with a relative-frame and a CoM task."""
        from .scenarios import pink_scenarios

        return pink_scenarios(ticks)


def _rotation_distance(Ra: np.ndarray, Rb: np.ndarray) -> float:
    cos = (np.trace(Ra.T @ Rb) - 1) / 2
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


def run_backend(backend: str, ticks: int, jit: bool = True,
                rival: type[RivalLoop] | None = None) -> dict:
    """The closed loops on one backend, interleaved tick by tick (rotating their order), plus
    untimed agreement checks at wbc's state (see the module docstring). ``rival`` is the other
    library's loop class (default :class:`PinkLoop`)."""
    from wbc.robots.fixed_base import load_panda

    rival = PinkLoop if rival is None else rival
    other = rival.name
    robot = load_panda()
    controller = build_wbc(robot, backend, jit, "compiled")
    numeric = build_wbc(robot, backend, jit, "numeric")  # the pinocchio-getter model stage
    rival_loop = rival(robot, backend)
    rival_same = rival(robot, backend)  # untimed: the rival at wbc's state
    rival_exact = rival(robot, "quadprog")  # untimed: the rival's QP solved exactly
    goals = targets(robot.frame_pose(Q0, "ee").copy())
    goals_rival = [rival.target(T) for T in goals]
    per_goal = max(1, ticks // len(goals))
    q = {"wbc": Q0.copy(), "numeric": Q0.copy(), other: Q0.copy()}
    v = {}
    times = {name: np.empty(ticks) for name in q}
    diff, err_wbc, err_rival = np.empty(ticks), np.empty(ticks), np.empty(ticks)
    split = np.empty((ticks, 3))  # wbc's own model / assembly / solve timings
    failures = 0
    clock = time.perf_counter

    def run(name: str, goal: int | None) -> None:
        if name == other:
            v[name] = rival_loop.tick(q[name], None if goal is None else goals_rival[goal])
        else:
            ctrl = controller if name == "wbc" else numeric
            if goal is None:
                v[name] = ctrl.step(q[name])
            else:
                v[name] = ctrl.step(q[name], ee=goals[goal])

    order = list(q)
    gc.collect()
    gc.disable()
    try:
        for k in range(ticks):
            g = min(k // per_goal, len(goals) - 1)
            new_goal = g if k == 0 or g != min((k - 1) // per_goal, len(goals) - 1) else None
            for i in range(len(order)):
                name = order[(k + i) % len(order)]
                t0 = clock()
                run(name, new_goal)
                times[name][k] = clock() - t0
            solution = controller.last_solution
            failures += (not solution.ok) + (not numeric.last_solution.ok)
            split[k] = solution.timings.model, solution.timings.assembly, solution.timings.solve
            v_same = rival_same.tick(q["wbc"], goals_rival[g])
            v_exact = rival_exact.tick(q["wbc"], goals_rival[g])
            diff[k] = np.abs(v["wbc"] - v_same).max()
            err_wbc[k] = np.abs(v["wbc"] - v_exact).max()
            err_rival[k] = np.abs(v_same - v_exact).max()
            for name in q:
                q[name] = q[name] + DT * v[name]
    finally:
        gc.enable()
    q_w, q_p = q["wbc"], q[other]
    t_wbc, t_rival = times["wbc"], times[other]
    T_w = robot.frame_pose(q_w, "ee").copy()
    T_p = robot.frame_pose(q_p, "ee").copy()
    goal = goals[min((ticks - 1) // per_goal, len(goals) - 1)]
    pos_diff = float(np.linalg.norm(T_w[:3, 3] - T_p[:3, 3]))
    rot_diff = _rotation_distance(T_w[:3, :3], T_p[:3, :3])
    commands_agree = bool(diff.max() <= COMMAND_TOL
                          or err_wbc.max() <= err_rival.max() + COMMAND_TOL)
    wbc_med, rival_med = float(np.median(t_wbc)), float(np.median(t_rival))
    split_median = np.median(split, axis=0)
    return {
        "wbc_median_s": wbc_med,
        f"{other}_median_s": rival_med,
        "ratio": wbc_med / rival_med,
        "wbc_numeric_median_s": float(np.median(times["numeric"])),
        "wbc_numeric_ratio": float(np.median(times["numeric"])) / rival_med,
        "numeric_vs_compiled_final_diff": float(np.abs(q["numeric"] - q_w).max()),
        "wbc_p95_s": float(np.percentile(t_wbc, 95)),
        f"{other}_p95_s": float(np.percentile(t_rival, 95)),
        "wbc_split_median_s": {"model": float(split_median[0]),
                               "assembly": float(split_median[1]),
                               "solve": float(split_median[2]),
                               "other": wbc_med - float(split_median.sum())},
        "ticks": ticks,
        "jit": jit,
        "wbc_failures": failures,
        "command_diff_max": float(diff.max()),
        "command_diff_p99": float(np.percentile(diff, 99)),
        "command_diff_median": float(np.median(diff)),
        "command_tol": COMMAND_TOL,
        "wbc_error_vs_exact_max": float(err_wbc.max()),
        f"{other}_error_vs_exact_max": float(err_rival.max()),
        "final_position_diff_m": pos_diff,
        "final_rotation_diff_rad": rot_diff,
        "pose_tol": POSE_TOL,
        "final_position_error_wbc_m": float(np.linalg.norm(T_w[:3, 3] - goal[:3, 3])),
        f"final_position_error_{other}_m": float(np.linalg.norm(T_p[:3, 3] - goal[:3, 3])),
        "commands_agree": commands_agree,
        "agree": bool(commands_agree and pos_diff <= POSE_TOL and rot_diff <= POSE_TOL
                      and failures == 0),
        "dedicated": dedicated_loops(build_wbc(robot, backend, jit, "compiled"),
                                     rival(robot, backend), goals, ticks),
    }


def dedicated_loops(controller, rival_loop, goals: list[np.ndarray], ticks: int) -> dict:
    """wbc's and the rival's closed loops again (fresh, from ``Q0``, the same goals), timed in
    blocks of :data:`~wbc.experiments.benchmarks.loops.DEDICATED_BLOCK` ticks
    (:mod:`~wbc.experiments.benchmarks.loops`: each side as a dedicated control loop, its caches
    warm): medians, p95s, ratio, block; on the fused path also the bare generated call, in
    blocks of its own, and ``step_over_bare``."""
    schedule = goal_schedule(goals, ticks)
    rival_schedule = [None if T is None else rival_loop.target(T) for T in schedule]
    turns = {"wbc": closed_loop_turn(wbc_tick(controller), schedule, Q0, DT),
             rival_loop.name: closed_loop_turn(rival_loop.tick, rival_schedule, Q0, DT)}
    if controller.fused:  # its block: the parameters of the last wbc tick before it
        turns["bare"] = call_turn(controller.workspace.bare_call)
    times = timed_turns(turns, ticks, DEDICATED_BLOCK)
    result = {**median_ratio(times, "wbc", rival_loop.name), "block": DEDICATED_BLOCK}
    if controller.fused:
        result["bare_median_s"] = bare = float(np.median(times["bare"]))
        result["step_over_bare"] = result["wbc_median_s"] / bare
    return result


def markdown_table(results: dict, rival: str = "pink") -> str:
    rows = [f"| backend | wbc median [µs] | {rival} median [µs] | wbc / {rival} | dedicated "
            f"loops: wbc / {rival} [µs] (ratio) | wbc numeric-kinematics [µs] (ratio) | Δv p99 "
            f"/ max [rad/s] | error vs exact wbc / {rival} [rad/s] | final Δpose [m, rad] | "
            "agree |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|:---:|"]
    for name, r in results.items():
        d = r["dedicated"]
        rows.append(
            f"| {name} | {r['wbc_median_s'] * 1e6:.1f} | {r[f'{rival}_median_s'] * 1e6:.1f} | "
            f"{r['ratio']:.3f} | {d['wbc_median_s'] * 1e6:.1f} / "
            f"{d[f'{rival}_median_s'] * 1e6:.1f} ({d['ratio']:.3f}) | "
            f"{r['wbc_numeric_median_s'] * 1e6:.1f} "
            f"({r['wbc_numeric_ratio']:.3f}) | "
            f"{r['command_diff_p99']:.0e} / {r['command_diff_max']:.0e} | "
            f"{r['wbc_error_vs_exact_max']:.0e} / {r[f'{rival}_error_vs_exact_max']:.0e} | "
            f"{max(r['final_position_diff_m'], r['final_rotation_diff_rad']):.1e} | "
            f"{'yes' if r['agree'] else 'NO'} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None, rival: type[RivalLoop] | None = None) -> int:
    """The study against ``rival`` (a loop class like :class:`PinkLoop`, the default)."""
    rival = PinkLoop if rival is None else rival
    other = rival.name
    parser = argparse.ArgumentParser(
        prog=f"wbc {other}",
        description=f"wbc vs {other} on the Panda: median tick per backend, ratio, agreement.")
    parser.add_argument("--ticks", type=int, default=3000, help="ticks per backend")
    parser.add_argument("--backends", nargs="+", default=list(BACKENDS),
                        help="backends to compare (those both sides support are run)")
    parser.add_argument("--out", type=Path, default=Path(f"results/vs_{other}"),
                        help=f"output folder for vs_{other}.json")
    parser.add_argument("--no-jit", dest="jit", action="store_false",
                        help="evaluate wbc's compiled stack on CasADi's VM instead of JIT C")
    args = parser.parse_args(argv)
    if args.ticks < 1:
        parser.error("--ticks must be >= 1")
    backends = installed_backends(parser, args.backends)
    try:
        importlib.import_module(rival.requirement)
        import qpsolvers
    except ImportError as err:
        from wbc.errors import MissingDependencyError

        raise MissingDependencyError(f"wbc {other} needs {rival.requirement!r}, which is not "
                                     f"installed ({err}): {rival.install_hint}") from None
    from wbc.experiments.machine import describe_machine
    from wbc.experiments.progress import report_progress

    # every name is an installed wbc backend (installed_backends); pink and mink reach their
    # QP through qpsolvers, so a backend it lacks is skipped
    theirs = set(qpsolvers.available_solvers)
    skipped = [b for b in backends if b not in theirs]
    results, errors = {}, {}
    runs = [b for b in backends if b not in skipped]
    for done, backend in enumerate(runs, start=1):
        try:
            with warnings.catch_warnings():  # pink/mink pass dense matrices to sparse solvers
                warnings.simplefilter("ignore", qpsolvers.warnings.SparseConversionWarning)
                results[backend] = run_backend(backend, args.ticks, args.jit, rival)
        except Exception as err:  # one broken backend must not hide the others' results
            errors[backend] = f"{type(err).__name__}: {err}"
        report_progress(done, len(runs), backend)
    scenarios = {}
    run_scenarios = getattr(rival, "scenarios", None)
    if run_scenarios is not None and "quadprog" in theirs:
        from wbc.solvers import available_backends

        if "quadprog" in available_backends():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", qpsolvers.warnings.SparseConversionWarning)
                scenarios = run_scenarios(args.ticks)
    machine = describe_machine()
    report = {"problem": {"robot": "panda (example-robot-data, fingers locked)", "dt": DT,
                          "frame_gain": FRAME_GAIN, "posture_gain": POSTURE_GAIN,
                          "posture_cost": POSTURE_COST, "limit_gain": LIMIT_GAIN,
                          "damping": DAMPING, "q0": Q0.tolist(), **rival.problem_notes()},
              "backends": results, "skipped": skipped, "errors": errors,
              "scenarios": scenarios, "machine": machine}
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"vs_{other}.json"
    path.write_text(json.dumps(report, indent=2))
    print(markdown_table(results, other))
    print(f"\nagree: final hand poses within {POSE_TOL:g} m and rad, no wbc failure, and the "
          f"commands within {COMMAND_TOL:g} rad/s at the same state — or, where they differ "
          f"more (iterative solvers), wbc's command at least as close to the exact QP answer "
          f"as {other}'s (the difference is {other}'s solver tolerance)")
    if scenarios:
        from .scenarios import markdown

        print(f"\nmore loops (wbc.experiments.peers.scenarios; ratio = wbc tick / {other} "
              "tick, both ticked at the same states, alternating which goes first):\n")
        print(markdown(scenarios, other))
    print(f"\nmachine: {machine['cpu']}, {machine['cores']} cores, {machine['platform']}, "
          f"python {machine['python']}; jit={args.jit}; {args.ticks} ticks per backend")
    if skipped:
        print(f"skipped (not available on both sides): {', '.join(skipped)}")
    for backend, message in errors.items():
        print(f"failed: {backend}: {message}")
    print(f"wrote {path}")
    return 0 if results else 1  # nothing compared: the job did not run


if __name__ == "__main__":
    raise SystemExit(main())
