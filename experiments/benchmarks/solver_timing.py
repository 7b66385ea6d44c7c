"""Solver-timing study (``wbc bench``): the whole control tick, per robot, stack and backend.

For each catalogue robot and each stack

* ``one_level``    — end-effector pose + weak posture, damping, position and velocity limits;
* ``two_levels``   — pose strictly above posture;
* ``three_levels`` — end-effector position, then its orientation, then posture;
* ``acceleration`` — decision = joint accelerations: a PD end-effector position task with the
  drift ``J̇v``, a PD posture, acceleration bounds;

a closed loop tracking a circle with the end effector is run once with the reference backend
(clarabel, tight profile). Every backend then replays exactly that state sequence (3000
ticks after a warm-up by default), so that all backends solve the same problems with realistic
warm starts; the backends take turns at every state (interleaved, in a rotating order), so
machine noise hits them alike. Per tick it records the wall time of ``Controller.step`` and its
split into kinematics (model stage) / assembly / solve / the rest ("python": checks, fallback
policy, bookkeeping), which path the controller took (``fused``: the whole tick one generated
C function, :mod:`wbc.fused` — its ``solve`` is that call; ``jit`` or ``vm``), whether it
succeeded (or only partly: a lower level failed and the command is the levels above it), and
the largest difference of its command from the reference's. Taking turns, every tick finds
the CPU caches as the other backends left them; so the backends of :data:`DEDICATED` (daqp,
the default) also replay the states alone, one tick after the other — a dedicated control
loop, caches warm — reported as ``dedicated`` beside the interleaved figures (the "alone"
column). Controllers use ``kinematics="compiled"`` by default (poses and Jacobians inside the
compiled functions; ``--kinematics numeric`` times pinocchio's getters instead) and compiled C
for the level functions (:mod:`wbc.jit`, built once per machine and cached; ``--no-jit`` times
CasADi's virtual machine).

The scaling study times the ``one_level`` stack on fixed-base serial chains of 7 to 100
joints. Outputs, in ``--out``: ``solver_timing.json`` (raw per-tick samples [µs] and the
machine), ``solver_timing.md`` (tables) and ``solver_timing.png`` / ``scaling.png``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import wbc
import wbc.robots
from wbc.experiments.arguments import installed_backends
from wbc.experiments.benchmarks.loops import timed_turns
from wbc.experiments.machine import describe_machine
from wbc.experiments.progress import report_progress
from wbc.experiments.studies.study import save_figure
from wbc.robots.fixed_base import FixedBaseRobot
from wbc.solvers import available_backends
from wbc.tasks import Bounds, ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

STACKS = ("one_level", "two_levels", "three_levels", "acceleration")
#: Backends also timed alone, in a dedicated loop over the same states (the default one).
DEDICATED = ("daqp",)
REFERENCE = ("clarabel", "tight")
DT = 0.01  # control period [s]
CIRCLE_RADIUS, CIRCLE_PERIOD = 0.1, 4.0  # end-effector target path [m], [s]
KP, KD = 20.0, 10.0  # acceleration-level PD gains [1/s²], [1/s]
SCALING_JOINTS = (7, 15, 30, 50, 100)


# ----------------------------------------------------------------------------- stacks
def build_stack(robot, kind: str) -> wbc.Stack:
    """One of :data:`STACKS` for ``robot`` (velocity level unless ``kind == "acceleration"``)."""
    if kind == "acceleration":
        return _acceleration_stack(robot)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    posture = PostureTask(robot, gain=0.5, weight=1e-2, name="posture")
    if kind == "one_level":
        stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
        stack.add(posture, priority=0)
    elif kind == "two_levels":
        stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
        stack.add(posture, priority=1)
    elif kind == "three_levels":
        stack.add(FrameTask(robot, "ee", gain=0.5, position_only=True, name="ee"), priority=0)
        stack.add(FrameTask(robot, "ee", gain=0.5, name="ee_pose"), priority=1)
        stack.add(posture, priority=2)
    else:
        raise wbc.WbcError(f"unknown stack {kind!r}; stacks are {list(STACKS)}")
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack


def _acceleration_stack(robot) -> wbc.Stack:
    """PD tracking at acceleration level: ``J a + J̇v = Kp (p* − p) − Kd J v`` (position rows)
    and ``a_arm = Kp (q*_arm − q_arm) − Kd v_arm`` (weak), within acceleration bounds."""
    nq, nv, n_arm = robot.nq, robot.nv, robot.n_arm
    a = wbc.Variables(a=nv)
    stack = wbc.Stack(a, damping=1e-3)
    J = stack.quantity("J[ee]", (6, nv))
    drift = stack.quantity("Jdot_v[ee]", 6)
    pose = stack.quantity("pose[ee]", (4, 4))
    q, v = stack.quantity("q", nq), stack.quantity("v", nv)
    target = stack.parameter("ee.target", (4, 4))
    Jp = J[:3, :]
    ee_acc = KP * (target[:3, 3] - pose[:3, 3]) - KD * (Jp @ v)
    stack.add(wbc.Cost(Jp @ a["a"] + drift[:3], target=ee_acc, name="ee"), priority=0)
    q_ref = stack.parameter("posture.target", nq, np.asarray(robot.neutral(), float))
    arm = slice(nq - n_arm, nq)
    posture_acc = KP * (q_ref[arm] - q[arm]) - KD * v[nv - n_arm:]
    stack.add(wbc.Cost(a["a"][nv - n_arm:], target=posture_acc, weight=1e-2,
                       name="posture"), priority=0)
    lower = np.where(np.isfinite(robot.limits.a_lower), robot.limits.a_lower, -50.0)
    upper = np.where(np.isfinite(robot.limits.a_upper), robot.limits.a_upper, 50.0)
    stack.constrain(Bounds(lower, upper, name="acceleration_limits"))
    return stack


# ----------------------------------------------------------------------------- closed loop
def _target(pose0: np.ndarray, t: float) -> np.ndarray:
    """End-effector target at time ``t`` [s]: a circle in the y–z plane through the start."""
    phase = 2 * np.pi * t / CIRCLE_PERIOD
    T = pose0.copy()
    T[1, 3] += CIRCLE_RADIUS * np.sin(phase)
    T[2, 3] += CIRCLE_RADIUS * (np.cos(phase) - 1.0)
    return T


def _references(kind: str, T: np.ndarray) -> dict:
    """The step() keywords of stack ``kind`` for end-effector target ``T``."""
    return {"ee": T, "ee_pose": T} if kind == "three_levels" else {"ee": T}


def reference_run(robot, kind: str, ticks: int, q0: np.ndarray | None = None) -> dict:
    """Closed loop with the reference backend from ``q0`` (default ``robot.neutral()``);
    returns the states, targets and commands."""
    ctrl = wbc.Controller(robot, build_stack(robot, kind), backend=REFERENCE[0],
                          profile=REFERENCE[1], dt=DT)
    q = np.asarray(robot.neutral() if q0 is None else q0, float).copy()
    v = np.zeros(robot.nv)
    pose0 = np.array(robot.frame_pose(q, "ee"))
    states, targets, commands = [], [], []
    for k in range(ticks):
        T = _target(pose0, k * DT)
        cmd = ctrl.step(q, v, **_references(kind, T))
        states.append((q.copy(), v.copy()))
        targets.append(T)
        commands.append(cmd.copy())
        if kind == "acceleration":
            v = v + cmd * DT
        else:
            v = cmd.copy()
        q = robot.integrate(q, v, DT)
    return {"states": states, "targets": targets, "commands": commands}


def replay(robot, kind: str, backends: list[str], run: dict, warmup: int,
           kinematics: str = "compiled", jit: bool = True) -> dict:
    """Time every backend on the reference state sequence, interleaved: at each state every
    backend's controller ticks once, in an order rotating from state to state, so that machine
    noise hits all backends alike. Returns ``{backend: result}`` with raw samples in µs.
    ``kinematics`` and ``jit`` are the :class:`wbc.Controller` options."""
    controllers = {b: wbc.Controller(robot, build_stack(robot, kind), backend=b, dt=DT,
                                     kinematics=kinematics, jit=jit) for b in backends}
    samples: dict[str, dict[str, list[float]]] = {
        b: {"tick": [], "kinematics": [], "assembly": [], "solve": [], "python": []}
        for b in backends}
    ok: dict[str, list[bool]] = {b: [] for b in backends}
    partial: dict[str, list[bool]] = {b: [] for b in backends}
    diff: dict[str, list[float]] = {b: [] for b in backends}
    for k, ((q, v), T) in enumerate(zip(run["states"], run["targets"], strict=True)):
        refs = _references(kind, T)
        for i in range(len(backends)):
            backend = backends[(k + i) % len(backends)]
            ctrl = controllers[backend]
            t0 = time.perf_counter()
            cmd = ctrl.step(q, v, **refs)
            elapsed = time.perf_counter() - t0
            if k < warmup:
                continue
            sol, own = ctrl.last_solution, samples[backend]
            assert sol is not None  # set by step()
            own["tick"].append(elapsed * 1e6)
            own["kinematics"].append(sol.timings.model * 1e6)
            own["assembly"].append(sol.timings.assembly * 1e6)
            own["solve"].append(sol.timings.solve * 1e6)
            own["python"].append((elapsed - sol.timings.total) * 1e6)
            ok[backend].append(sol.ok)
            partial[backend].append(sol.partial)
            diff[backend].append(float(np.abs(cmd - run["commands"][k]).max()))
    out = {b: {"path": _path(controllers[b]),
               "samples": {key: np.round(val, 3).tolist() for key, val in samples[b].items()},
               "success_rate": float(np.mean(ok[b])), "partial_rate": float(np.mean(partial[b])),
               "max_abs_diff_vs_reference": float(max(diff[b])),
               "stats": {key: _stats(val) for key, val in samples[b].items()}}
           for b in backends}
    for backend in set(DEDICATED) & set(backends):
        out[backend]["dedicated"] = _stats(dedicated_replay(
            wbc.Controller(robot, build_stack(robot, kind), backend=backend, dt=DT,
                           kinematics=kinematics, jit=jit), kind, run)[warmup:] * 1e6)
    return out


def dedicated_replay(controller, kind: str, run: dict) -> np.ndarray:
    """``controller`` alone on the reference run's states, one tick after the other (a
    dedicated control loop, its caches warm; see :mod:`wbc.experiments.benchmarks.loops`): the
    wall time of every ``step`` [s]."""
    states, goals = run["states"], run["targets"]

    def turn(k: int) -> float:
        (q, v), refs = states[k], _references(kind, goals[k])
        t0 = time.perf_counter()
        controller.step(q, v, **refs)
        return time.perf_counter() - t0

    return timed_turns({"alone": turn}, len(states), len(states))["alone"]


def _path(controller) -> str:
    """How a controller's tick runs: ``"fused"`` (one generated C function, :mod:`wbc.fused`),
    ``"jit"`` (compiled C level functions around Python backends) or ``"vm"`` (CasADi's
    virtual machine)."""
    if controller.fused:
        return "fused"
    jitted = all(not b.function.is_a("SXFunction") for b in controller.compiled.blocks)
    return "jit" if jitted else "vm"


def _stats(samples) -> dict:
    arr = np.asarray(samples, float)
    return {"median": float(np.median(arr)), "p95": float(np.percentile(arr, 95)),
            "max": float(arr.max())}


# ----------------------------------------------------------------------------- scaling
def serial_chain(n: int) -> FixedBaseRobot:
    """A fixed-base chain of ``n`` revolute joints (axes alternating z, y; links 0.1 m) with
    limits ±2.8 rad and ±2 rad/s, and an ``"ee"`` frame 0.1 m past the last joint."""
    model = pin.Model()
    parent = 0
    for i in range(n):
        joint = pin.JointModelRZ() if i % 2 == 0 else pin.JointModelRY()
        placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1 if i else 0.0]))
        parent = model.addJoint(parent, joint, placement, f"joint{i}")
        model.appendBodyToJoint(parent, pin.Inertia.FromBox(0.5, 0.04, 0.04, 0.1),
                                pin.SE3.Identity())
    model.addFrame(pin.Frame("ee", parent, 0, pin.SE3(np.eye(3), np.array([0, 0, 0.1])),
                             pin.FrameType.OP_FRAME))
    model.lowerPositionLimit = np.full(n, -2.8)
    model.upperPositionLimit = np.full(n, 2.8)
    model.velocityLimit = np.full(n, 2.0)
    return FixedBaseRobot(model, name=f"chain{n}")


# ----------------------------------------------------------------------------- study
def run(robots: list[str], stacks: list[str], backends: list[str], ticks: int, warmup: int,
        scaling_ticks: int, scaling_joints: tuple[int, ...], kinematics: str = "compiled",
        jit: bool = True, progress=None) -> dict:
    """The whole study; returns the JSON-able report. ``progress(done, total, what)`` is called
    after each robot × stack and each chain size."""
    report: dict[str, Any] = {
        "machine": describe_machine(), "dt_s": DT, "ticks": ticks, "warmup": warmup,
        "kinematics": kinematics, "jit": jit, "reference": "/".join(REFERENCE),
        "results": {}, "scaling": {}}
    combos = [(r, s) for r in robots for s in stacks]
    total = len(combos) + len(scaling_joints)
    for i, (name, kind) in enumerate(combos, start=1):
        robot = wbc.robots.load(name)
        ref = reference_run(robot, kind, warmup + ticks)
        report["results"].setdefault(name, {})[kind] = replay(
            robot, kind, backends, ref, warmup, kinematics, jit)
        if progress:
            progress(i, total, f"{name} / {kind}")
    for j, n in enumerate(scaling_joints, start=1):
        chain = serial_chain(n)
        # start bent (the straight chain is singular)
        ref = reference_run(chain, "one_level", warmup + scaling_ticks, np.full(n, 0.3))
        for backend, result in replay(chain, "one_level", backends, ref, warmup, kinematics,
                                      jit).items():
            report["scaling"].setdefault(backend, {})[str(n)] = {
                "stats": result["stats"], "success_rate": result["success_rate"],
                **({"dedicated": result["dedicated"]} if "dedicated" in result else {})}
        if progress:
            progress(len(combos) + j, total, f"scaling: {n}-joint chain")
    return report


def markdown(report: dict) -> str:
    """Tables: per robot and stack, median / p95 / max tick and its split, per backend."""
    out = [f"Machine: {report['machine']['cpu']}, {report['machine']['cores']} cores, "
           f"Python {report['machine']['python']}. Ticks: {report['ticks']} after "
           f"{report['warmup']} warm-up; kinematics {report['kinematics']}, "
           f"jit={report['jit']}; reference {report['reference']}. Times in µs. 'partial': "
           "ticks where a lower level failed and the command is the levels above it.", ""]
    for name, per_stack in report["results"].items():
        for kind, per_backend in per_stack.items():
            out += [f"### {name} — {kind}", "",
                    "| backend | path | tick median | p95 | max | alone: median / p95 | "
                    "kinematics | assembly | solve | python | success | partial | max abs diff "
                    "vs ref |",
                    "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
            for backend, r in per_backend.items():
                s = r["stats"]
                alone = (f"{r['dedicated']['median']:.1f} / {r['dedicated']['p95']:.1f}"
                         if "dedicated" in r else "–")
                out.append(
                    f"| {backend} | {r['path']} | {s['tick']['median']:.1f} | "
                    f"{s['tick']['p95']:.1f} | "
                    f"{s['tick']['max']:.0f} | {alone} | {s['kinematics']['median']:.1f} | "
                    f"{s['assembly']['median']:.1f} | {s['solve']['median']:.1f} | "
                    f"{s['python']['median']:.1f} | "
                    f"{100 * r['success_rate']:.1f} % | {100 * r['partial_rate']:.1f} % | "
                    f"{r['max_abs_diff_vs_reference']:.1e} |")
            out.append("")
    if report["scaling"]:
        joints = sorted({int(n) for per in report["scaling"].values() for n in per})
        out += ["### Scaling: median tick [µs] vs joints (one_level stack)", "",
                "| backend | " + " | ".join(map(str, joints)) + " |",
                "|---|" + "---|" * len(joints)]
        for backend, per in report["scaling"].items():
            cells = [f"{per[str(n)]['stats']['tick']['median']:.0f}" if str(n) in per else "-"
                     for n in joints]
            out.append(f"| {backend} | " + " | ".join(cells) + " |")
            if any("dedicated" in entry for entry in per.values()):
                cells = [f"{per[str(n)]['dedicated']['median']:.0f}"
                         if "dedicated" in per.get(str(n), {}) else "-" for n in joints]
                out.append(f"| {backend} alone | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def plots(report: dict, out: Path) -> list[Path]:
    """Median tick per backend (one panel per robot, bars per stack) and the scaling curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    results = report["results"]
    if results:
        fig, axes = plt.subplots(1, len(results), figsize=(5 * len(results), 4), squeeze=False)
        for ax, (name, per_stack) in zip(axes[0], results.items(), strict=True):
            kinds = list(per_stack)
            backends = list(next(iter(per_stack.values())))
            width = 0.8 / max(1, len(kinds))
            for i, kind in enumerate(kinds):
                med = [per_stack[kind][b]["stats"]["tick"]["median"] for b in backends]
                ax.bar(np.arange(len(backends)) + i * width, med, width, label=kind)
            ax.set_xticks(np.arange(len(backends)) + 0.4 - width / 2)
            ax.set_xticklabels(backends, rotation=45, ha="right")
            ax.set_yscale("log")
            ax.set_xlabel("QP backend")
            ax.set_ylabel("median tick [µs]")
            ax.set_title(f"{name}: median tick per stack")
            ax.legend(title="stack", fontsize=7)
        written.append(out / save_figure(fig, out / "solver_timing.png"))
    if report["scaling"]:
        fig, ax = plt.subplots(figsize=(6, 4))
        for backend, per in report["scaling"].items():
            n = sorted(int(k) for k in per)
            ax.plot(n, [per[str(k)]["stats"]["tick"]["median"] for k in n], "o-", label=backend)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("joints of the serial chain [-]")
        ax.set_ylabel("median tick [µs]")
        ax.set_title("Scaling: one_level stack on serial chains")
        ax.legend(title="QP backend", fontsize=7)
        written.append(out / save_figure(fig, out / "scaling.png"))
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="wbc bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=None, metavar="ROBOT",
                        help=f"catalogue robots (default: all of {wbc.robots.names()})")
    parser.add_argument("--stacks", nargs="+", default=list(STACKS), metavar="STACK",
                        help=f"stacks (default: all of {list(STACKS)})")
    parser.add_argument("--backends", nargs="+", default=None, metavar="BACKEND",
                        help="backends (default: every available one)")
    parser.add_argument("--ticks", type=int, default=3000, help="timed ticks (default 3000)")
    parser.add_argument("--warmup", type=int, default=50, help="untimed first ticks")
    parser.add_argument("--scaling-ticks", type=int, default=3000,
                        help="timed ticks per chain in the scaling study (default 3000)")
    parser.add_argument("--scaling-joints", type=int, nargs="*", default=list(SCALING_JOINTS),
                        help="chain sizes of the scaling study (none: skip it)")
    parser.add_argument("--kinematics", choices=("compiled", "numeric"), default="compiled",
                        help="model stage: poses and Jacobians inside the compiled functions "
                             "(default) or from pinocchio every tick")
    parser.add_argument("--no-jit", action="store_true",
                        help="evaluate the level functions on CasADi's virtual machine instead "
                             "of compiled C (wbc.jit; built once per machine, then cached)")
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="output folder (default ./results)")
    args = parser.parse_args(argv)
    robots = args.robots or wbc.robots.names()
    unknown = sorted(set(robots) - set(wbc.robots.names()))
    if unknown:
        parser.error(f"unknown robot(s) {unknown}; the catalogue is {wbc.robots.names()}")
    bad = sorted(set(args.stacks) - set(STACKS))
    if bad:
        parser.error(f"unknown stack(s) {bad}; stacks are {list(STACKS)}")
    backends = installed_backends(parser, args.backends or available_backends())
    if args.ticks < 1 or args.warmup < 0 or args.scaling_ticks < 1:
        parser.error("--ticks and --scaling-ticks must be >= 1, --warmup >= 0")
    if any(n < 2 for n in args.scaling_joints):
        parser.error("--scaling-joints sizes must be >= 2")
    report = run(robots, args.stacks, backends, args.ticks, args.warmup, args.scaling_ticks,
                 tuple(args.scaling_joints), args.kinematics, not args.no_jit,
                 report_progress)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "solver_timing.json").write_text(json.dumps(report))
    table = markdown(report)
    (args.out / "solver_timing.md").write_text(table)
    written = plots(report, args.out)
    print(table)
    print("wrote", ", ".join(str(p) for p in
                             [args.out / "solver_timing.json", args.out / "solver_timing.md",
                              *written]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
