"""``wbc audit``: closed-loop limit audits on :mod:`wbc.sim`, every catalogue robot, every exact
backend, at the velocity and the acceleration level.

A *run* starts from a random state inside the limits and drives the end effector towards a
random target — reachable (the pose of a random configuration inside the limits) or
unreachable (that pose moved 5–50 m away, so the arm stretches into its limits) — for
``--ticks`` ticks of ``dt = 0.01 s`` with exact actuation. Every tick is checked on the truth:

* ``violations``: a joint position outside ``[q_lower, q_upper]`` or a velocity outside
  ``[v_lower, v_upper]`` by more than ``1e-9`` (absolute; radians, metres, per second);
* ``nans``: a non-finite command or state;
* ``failed``: ticks whose status is not solved — each must have had a fallback applied
  (``fallback_missing`` counts those that had none); ``partial``: ticks that commanded the
  levels above a failed one.

Levels (the controllers are built once per robot and backend, then reused for every run):

* ``velocity``: decision ``v``; frame task on ``"ee"`` (gain 0.5, priority 0), posture task
  (gain 0.5, weight 1e-2, priority 1), hard :class:`~wbc.tasks.ConfigurationLimit`
  (gain 0.5) and :class:`~wbc.tasks.VelocityLimit`; ``command="velocity"``.
* ``acceleration``: decision ``v̇``; one level: the end effector's position
  ``J v̇ + J̇ v = kp e − kd J v`` (kp 20 s⁻², kd 9 s⁻¹) plus joint damping ``v̇ = −5 v``
  (weight 1e-2), hard :class:`~wbc.tasks.JointAccelerationLimit` with ``method="viable"``
  (the bounds that promise no crossing; Xing's bounds as printed are known to overshoot,
  see :mod:`wbc.tasks.joint_acceleration`); ``command="acceleration"`` (``v`` integrated).
  Start velocities are drawn inside the viable set (``|v| <= sqrt(2 a_max d)``, ``d`` the
  distance to the limit the joint moves towards, and inside the velocity limits).

Exact backends: daqp (its fused tick where it applies), quadprog, qpoases — the active-set
solvers that meet bounds exactly; the first-order ones (osqp, proxqp) meet them to their
tolerance only (the workspace clips ``x`` into the variable bounds, so they are audited with
``--backends`` too if asked).

Output (``--out DIR``): ``DIR/audit.json`` with ``"runs"``, ``"ticks"``, ``"violations"``,
``"nans"``, ``"failed"``, ``"partial"``, ``"fallback_missing"``, the same per level and
backend under ``"by_level"``, ``"by_backend"`` and ``"cells"`` (level × backend × robot), the
worst excursions in ``"worst"``, ``"parameters"`` and ``"cluster"`` (where it ran: see
:mod:`~wbc.experiments.campaigns.cluster`); ``DIR/audit.md`` as a table. Each cell (level ×
backend × robot, seeded from ``--seed`` and its place) is one case of the cluster: the same
JSON in this process, on ``--workers N`` or ``--scheduler ADDRESS``; a cell that raises, hangs
past ``--time-limit`` or kills its worker is listed under ``"defects"`` (absent when there is
none) with its seed and a command rerunning it alone (``--case KEY``); an interrupted audit
leaves ``DIR/audit.partial.json``, which the same command resumes. Exit code: 0 when no run
has a violation, a NaN or a failed tick without fallback (:data:`FINDINGS`) and no cell is a
defect, 1 otherwise (2: a usage error); failed and partial ticks with their fallback are not
findings.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

import wbc
import wbc.robots
from wbc.sim import Simulation, actuation
from wbc.solvers import available_backends
from wbc.tasks import (
    ConfigurationLimit,
    FrameTask,
    JointAccelerationLimit,
    PostureTask,
    VelocityLimit,
)

from ..arguments import (
    add_cluster_arguments,
    cluster_options,
    constructible_backends,
    user_robots_and_stack,
)
from . import cluster

DT = 0.01  # control period [s]
TOL = 1e-9  # allowed excursion out of a limit (absolute)
EXACT = ("daqp", "quadprog", "qpoases")
LEVELS = ("velocity", "acceleration")
COUNTS = ("runs", "ticks", "violations", "nans", "failed", "partial", "fallback_missing")
#: The counts that make ``wbc audit`` exit 1.
FINDINGS = ("violations", "nans", "fallback_missing")


def velocity_controller(robot, backend: str):
    """The velocity-level controller audited (see the module docstring)."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"), priority=1)
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="q_limits"))
    stack.constrain(VelocityLimit(robot, name="v_limits"))
    return wbc.Controller(robot, stack, dt=DT, backend=backend)


def acceleration_controller(robot, backend: str, kp: float = 20.0, kd: float = 9.0):
    """The acceleration-level controller audited (see the module docstring)."""
    stack = wbc.Stack(wbc.Variables(a=robot.nv), damping=1e-2)
    a = stack.variables["a"]
    J = stack.quantity("J[ee]", (6, robot.nv))
    drift = stack.quantity("Jdot_v[ee]", 6)
    pose = stack.quantity("pose[ee]", (4, 4))
    v = stack.quantity("v", robot.nv)
    target = stack.parameter("ee.target", (4, 4))
    wanted = kp * (target[:3, 3] - pose[:3, 3]) - kd * (J[:3, :] @ v)
    stack.add(wbc.Cost(J[:3, :] @ a + drift[:3], wanted, name="ee"))
    stack.add(wbc.Cost(a, -5.0 * v, weight=1e-2, name="joint_damping"))
    stack.constrain(JointAccelerationLimit(robot, DT, method="viable", name="qdd_limits"))
    return wbc.Controller(robot, stack, dt=DT, backend=backend)


def random_start(rng: np.random.Generator, robot, level: str) -> tuple[np.ndarray, np.ndarray]:
    """``(q0, v0)`` inside the limits (a quarter of the starts within 1 % of a limit)."""
    lim = robot.limits
    q = robot.neutral().copy()
    arm = np.isfinite(lim.q_lower) & np.isfinite(lim.q_upper)
    span = lim.q_upper[arm] - lim.q_lower[arm]
    q[arm] = lim.q_lower[arm] + span * rng.uniform(0.0, 1.0, int(arm.sum()))
    near = rng.random(int(arm.sum())) < 0.25
    edge = np.where(rng.random(int(arm.sum())) < 0.5, 0.0, 1.0)
    q[arm] = np.where(near, lim.q_lower[arm] + span * np.abs(edge - rng.uniform(0, 0.01)),
                      q[arm])
    if level == "velocity":
        return q, np.zeros(robot.nv)
    v = rng.uniform(lim.v_lower, lim.v_upper) * 0.5
    # inside the viable set: a joint can still brake before the limit it moves towards (the
    # arm's q and v entries are the trailing ones of each, so v index = q index - (nq - nv))
    iq = np.flatnonzero(arm)
    iv = iq - (robot.nq - robot.nv)
    room = np.where(v[iv] > 0, lim.q_upper[iq] - q[iq], q[iq] - lim.q_lower[iq])
    brake = np.where(v[iv] > 0, -lim.a_lower[iv], lim.a_upper[iv])
    cap = np.sqrt(np.maximum(0.0, 2.0 * brake * room)) * 0.9
    v[iv] = np.clip(v[iv], -cap, cap)
    return q, v


def random_target(rng: np.random.Generator, robot, reachable: bool) -> np.ndarray:
    """A target pose of ``"ee"``: that of a random configuration inside the limits, moved
    5–50 m away when ``reachable`` is false."""
    q, _ = random_start(rng, robot, "velocity")
    T = robot.frame_pose(q, "ee").copy()
    if not reachable:
        direction = rng.standard_normal(3)
        T[:3, 3] += direction / np.linalg.norm(direction) * rng.uniform(5.0, 50.0)
    return T


def audit_run(robot, controller, level: str, q0, v0, target, ticks: int) -> dict:
    """One closed-loop run; its counts and worst excursions."""
    sim = Simulation(robot, controller, DT, [actuation.Exact()], command=level)
    run = sim.run(ticks=ticks, q0=q0, v0=v0, references={"ee": target})
    lim = robot.limits
    q = np.vstack([run.q, run.q_final[None, :]])
    with np.errstate(invalid="ignore"):
        q_out = np.maximum(lim.q_lower - q, q - lim.q_upper)
        v_out = np.maximum(lim.v_lower - run.v, run.v - lim.v_upper)
    q_out = np.where(np.isfinite(q_out), q_out, -np.inf)
    v_out = np.where(np.isfinite(v_out), v_out, -np.inf)
    finite = np.all(np.isfinite(q), axis=1)[:-1] & np.all(np.isfinite(run.v), axis=1) \
        & np.all(np.isfinite(run.command), axis=1)
    failed = np.array([s != "solved" for s in run.status])
    fallback = np.array([f is not None and f != "" for f in run.fallback])
    return {"runs": 1, "ticks": ticks,
            "violations": int((q_out > TOL).any(axis=1).sum() + (v_out > TOL).any(axis=1).sum()),
            "nans": int((~finite).sum()), "failed": int(failed.sum()),
            "partial": int(np.asarray(run.partial, dtype=bool).sum()),
            "fallback_missing": int((failed & ~fallback).sum()),
            "worst_q": float(q_out.max(initial=-np.inf)),
            "worst_v": float(v_out.max(initial=-np.inf))}


def audit(runs: int, backends: list[str], levels: list[str], ticks: int = 30, seed: int = 0,
          seconds: float | None = None, robots: list | None = None, build=None, *,
          workers: int | None = None, scheduler: str | None = None, out: Path | None = None,
          time_limit: float = cluster.TIME_LIMIT_S, only: str | None = None,
          progress: bool = True, robot_files=()) -> dict:
    """About ``runs`` runs spread over robots × backends × levels; stops early after
    ``seconds`` [s]. ``robots``: ``(name, load)`` pairs (default: the catalogue); ``build``:
    a stack of the user's (``build(robot) -> wbc.Stack``, see
    :mod:`wbc.experiments.benchmarks.user_inputs`) audited instead of the built-in
    controllers, at its own level (its command's kind), whatever ``levels`` says.

    Where: in this process, or on Dask — ``workers`` local processes or the cluster at
    ``scheduler`` — one cell (level × backend × robot, :func:`plan`) per case of
    :mod:`~wbc.experiments.campaigns.cluster` (the same result wherever they run); ``out``: the
    folder of ``audit.partial.json`` (finished cells, resumed by a rerun); ``time_limit``: of
    one cell on a cluster [s]; ``only``: the key of one cell to run alone (its reproduction).
    A cell that raises, hangs or kills its workers is listed under ``"defects"`` with its seed
    and a reproduction command (``robot_files``: the ``--robot`` files, for that command).
    Returns the JSON-ready result."""
    if robots is None:
        robots = [(name, lambda name=name: wbc.robots.load(name)) for name in
                  wbc.robots.names()]
    if build is not None:
        levels = [user_level(build, robots[0][1]())]
    names = [name for name, _ in robots]
    identity = {"runs": runs, "backends": list(backends), "levels": list(levels),
                "ticks": ticks, "seed": seed, "robots": names,
                "stack": getattr(build, "spec", None), "robot_files": list(robot_files)}
    start = time.perf_counter()
    _, finished = cluster.run_campaign(
        run_cell, plan(runs, backends, levels, names, seed, ticks), name="audit",
        robots=robots, build=build, identity=identity, only=only,
        keys_hint=f"'velocity/daqp/{names[0]}'", out=out, workers=workers,
        scheduler=scheduler, time_limit=time_limit, seconds=seconds, progress=progress)
    cells = {result["key"]: result["cell"] for result in finished.results
             if result is not None}
    failures = finished.failures
    parameters = {"seed": seed, "ticks_per_run": ticks, "dt": DT, "tol": TOL,
                  "backends": backends, "levels": levels, "robots": names,
                  "stack": getattr(build, "spec", None),
                  "wall_s": round(time.perf_counter() - start, 1)}
    result = summarise(cells, parameters) if cells else {
        **dict.fromkeys(COUNTS, 0), "by_level": {}, "by_backend": {}, "cells": {},
        "worst": {}, "parameters": parameters}
    if failures:  # only then: the key is absent from a clean audit's JSON, as before
        result["defects"] = [{"case": f["key"], "case_seed": f["seed"], "seed": seed,
                              "defect": f["failure"], "message": f["message"],
                              "attempts": f["attempts"],
                              "reproduce": reproduce_command(identity, f["key"])}
                             for f in failures]
    result["cluster"] = finished.cluster
    return result


def plan(runs: int, backends: list[str], levels: list[str], robots: list[str], seed: int,
         ticks: int) -> list[dict]:
    """The cells of an audit in order (level, backend, robot): each a JSON-ready dict with its
    ``"key"`` (``"LEVEL/BACKEND/ROBOT"``), the ``"seed"`` of its runs (``[seed, level,
    robot, backend]`` indices) and its number of runs."""
    per_cell = max(1, -(-runs // (len(robots) * len(backends) * len(levels))))  # rounded up
    return [{"key": f"{level}/{backend}/{name}",
             "seed": [seed, LEVELS.index(level), r, _backend_index(backend)],
             "level": level, "backend": backend, "robot": r, "runs": per_cell, "ticks": ticks}
            for level in levels for backend in backends for r, name in enumerate(robots)]


def run_cell(context: dict, cell: dict, deadline: float | None = None) -> dict:
    """Run one cell of :func:`plan` (on whichever process): ``{"key", "cell", "stopped"}``,
    the key with the backend's label (``"daqp (fused)"`` when the controller took the fused
    tick); ``"stopped"`` when ``time.time()`` passed ``deadline`` before its last run."""
    robots, build = cluster.user_inputs(context)
    level, backend = cell["level"], cell["backend"]
    name, load = robots[cell["robot"]]
    robot = load()
    if build is not None:
        controller = wbc.Controller(robot, build(robot), dt=DT, backend=backend)
    elif level == "velocity":
        controller = velocity_controller(robot, backend)
    else:
        controller = acceleration_controller(robot, backend)
    label = f"{backend} (fused)" if getattr(controller, "fused", False) else backend
    counts_total = dict.fromkeys(COUNTS, 0) | {"worst_q": -np.inf, "worst_v": -np.inf}
    rng = np.random.default_rng(cell["seed"])
    stopped = False
    for k in range(cell["runs"]):
        q0, v0 = random_start(rng, robot, level)
        target = random_target(rng, robot, reachable=bool(k % 2 == 0))
        counts = audit_run(robot, controller, level, q0, v0, target, cell["ticks"])
        for key in COUNTS:
            counts_total[key] += counts[key]
        counts_total["worst_q"] = max(counts_total["worst_q"], counts["worst_q"])
        counts_total["worst_v"] = max(counts_total["worst_v"], counts["worst_v"])
        if deadline is not None and time.time() > deadline and k + 1 < cell["runs"]:
            stopped = True
            break
    return {"key": f"{level}/{label}/{name}", "cell": counts_total, "stopped": stopped}


def reproduce_command(identity: dict, key: str) -> str:
    """The one-line command that reruns the cell ``key`` of an audit in one process."""
    return cluster.reproduction("wbc audit", {
        "--runs": identity["runs"], "--backends": ",".join(identity["backends"]),
        "--levels": ",".join(identity["levels"]), "--ticks": identity["ticks"],
        "--seed": identity["seed"], "--robot": identity.get("robot_files") or None,
        "--stack": identity["stack"], "--out": "audit_case"}, key)


def user_level(build, robot) -> str:
    """``"acceleration"`` when the user's stack commands accelerations (its first variable
    block's name, see :func:`~wbc.experiments.benchmarks.user_inputs.is_acceleration`), else
    ``"velocity"``."""
    from wbc.experiments.benchmarks.user_inputs import is_acceleration

    return "acceleration" if is_acceleration(build(robot)) else "velocity"


def _backend_index(backend: str) -> int:
    """A seed component per backend: its place among the available ones (a backend named
    otherwise, e.g. ``qpsolvers:daqp``, after them, by its name's bytes)."""
    available = available_backends()
    if backend in available:
        return available.index(backend)
    return len(available) + sum(backend.encode())


def summarise(cells: dict, parameters: dict) -> dict:
    """Totals, per level and per backend, of the cells ``"level/backend/robot"``."""
    def total(keys):
        return {key: int(sum(cells[c][key] for c in keys)) for key in COUNTS}

    levels = sorted({c.split("/")[0] for c in cells})
    backends = sorted({c.split("/")[1] for c in cells})
    out = total(cells)
    out["by_level"] = {lv: total([c for c in cells if c.split("/")[0] == lv]) for lv in levels}
    out["by_backend"] = {b: total([c for c in cells if c.split("/")[1] == b]) for b in backends}
    out["cells"] = cells
    out["worst"] = {"q_excursion": max(c["worst_q"] for c in cells.values()),
                    "v_excursion": max(c["worst_v"] for c in cells.values())}
    out["parameters"] = parameters
    return out


def markdown(result: dict) -> str:
    """One row per level and backend."""
    lines = [f"# wbc audit: {result['runs']} runs, {result['ticks']} ticks, "
             f"{result['violations']} violations, {result['nans']} NaNs", "",
             "| level / backend / robot | " + " | ".join(COUNTS) + " |",
             "|---" * (len(COUNTS) + 1) + "|"]
    for key, cell in result["cells"].items():
        lines.append(f"| {key} | " + " | ".join(str(cell[c]) for c in COUNTS) + " |")
    for d in result.get("defects", []):  # cells that raised, hung or killed their workers
        lines.append(f"\n- cell `{d['case']}` (seed {d['case_seed']}, {d['attempts']} "
                     f"attempt(s)): {d['defect']} — {d['message']}; rerun: `{d['reproduce']}`")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``wbc audit [--runs N] [--backends a,b] [--levels velocity,acceleration] [--ticks T]
    [--seconds S] [--seed K] [--out DIR]``."""
    parser = argparse.ArgumentParser(prog="wbc audit", description="closed-loop limit "
                                     "audits on wbc.sim (every robot, exact backends)")
    parser.add_argument("--runs", "--cases", dest="runs", type=int, default=10_000,
                        help="closed-loop runs in total (--cases is an alias)")
    parser.add_argument("--backends", default=",".join(
        b for b in EXACT if b in available_backends()))
    parser.add_argument("--levels", default=",".join(LEVELS))
    parser.add_argument("--ticks", type=int, default=30, help="ticks per run")
    parser.add_argument("--seconds", type=float, default=None,
                        help="stop after this wall time [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--robot", action="append", default=[], metavar="FILE.toml",
                        help="audit a robot of your own (TOML description; repeatable) "
                             "instead of the catalogue")
    parser.add_argument("--stack", default=None, metavar="MODULE:FUNCTION",
                        help="audit a stack of your own (function(robot) -> wbc.Stack with a "
                             "frame task named 'ee') at its command's level")
    parser.add_argument("--out", type=Path, default=Path("results"))
    add_cluster_arguments(parser)
    args = parser.parse_args(argv)
    where = cluster_options(parser, args)
    if args.runs < 1 or args.ticks < 1:
        parser.error("--runs and --ticks must be >= 1")
    if args.seconds is not None and not args.seconds > 0:
        parser.error("--seconds must be > 0")
    backends = constructible_backends(parser, args.backends)
    levels = [lv for lv in args.levels.split(",") if lv]
    for level in levels:
        if level not in LEVELS:
            parser.error(f"--levels: unknown level {level!r}; levels: {', '.join(LEVELS)}")
    robot_files = [os.path.abspath(path) for path in args.robot]  # workers: any directory
    robots, build = user_robots_and_stack(robot_files, args.stack)
    result = audit(args.runs, backends, levels, args.ticks, args.seed, args.seconds, robots,
                   build, out=args.out, robot_files=robot_files, **where)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "audit.json").write_text(json.dumps(result, indent=1))
    (args.out / "audit.md").write_text(markdown(result))
    print(markdown(result))
    return 1 if any(result[key] for key in FINDINGS) or result.get("defects") else 0  # CI gate
