"""Solver-timing study (``wbc bench``): the whole control tick, per robot, stack, scenario and
backend — its time, its accuracy and what it was solved with.

Robots: the catalogue's (``--robots``) and the user's own (``--robot FILE.toml``, see
:mod:`wbc.experiments.benchmarks.user_inputs`). Stacks: the built-in ones (``--stacks``)

* ``one_level``    — end-effector pose + weak posture, damping, position and velocity limits;
* ``two_levels``   — pose strictly above posture;
* ``three_levels`` — end-effector position, then its orientation, then posture;
* ``acceleration`` — decision = joint accelerations: a PD end-effector position task with the
  drift ``J̇v``, a PD posture, acceleration bounds;

and the user's (``--stack module:function``). Scenarios (``--scenarios``), the end effector's
target ``T(t)``:

* ``circle``      — a circle of 0.1 m in the y–z plane through the start, period 4 s (the
  limits stay inactive);
* ``far``         — a step between the start and a pose 1.1 m away (turned 90° about z) every
  2 s: the velocity (acceleration) bounds saturate after each step;
* ``unreachable`` — a pose 10 m above the start: the arm stretches into its position limits and
  stays there.

**Protocol.** A closed loop is run once from the robot's home configuration on the *referees'*
answer (quadprog ``tight`` without its worker thread, checked against clarabel ``tight``, each
answer certified by its KKT residuals; see :mod:`wbc.experiments.benchmarks.accuracy`); every
backend then replays exactly that state sequence (``--ticks`` after ``--warmup`` untimed ones),
so all solve the same problems. At every state each backend's controller ticks once, in an order
drawn at random per tick (``--seed``): machine noise and cache effects hit the backends alike.
``--repeat N`` replays N times (a new order each time) and reports the mean of the N medians
with a 95 % confidence interval (Student's t). Warm start is the backends' own (``--cold``:
every solver set up afresh every tick, the setup counted in ``solve``; the fused tick always
starts cold). The backends of :data:`DEDICATED` (daqp, the default) also replay the states
alone, one tick after the other (``dedicated``).

**Per tick** it records the wall time of ``Controller.step`` and its split into kinematics
(model stage) / assembly / solve (inside the backends; itself split into the solver libraries'
own calls, :attr:`~wbc.solvers.base.BackendBase.library_time`, and the rest: adapters and
cascade) / the rest ("python"); the path (``fused``: the whole tick one generated C function,
whose ``solve`` is that whole call, :mod:`wbc.fused`; ``jit``; ``vm``); per level the QP's size,
the iterations, the library time and the primal and dual residuals and duality gap of the
backend's answer; whether every level was solved; and the command's deviation from the
referee's. Per cell and backend: ``full_solve_rate``, ``wrong_rate`` (fully solved but further
than :data:`~wbc.experiments.benchmarks.accuracy.WRONG_THRESHOLD` plus the referee gap from the
referees' certified answer, on the ticks they can judge), ``deviation`` (median / p95 / max),
the backend's resolved ``settings`` and package ``version``, and a shifted geometric mean of the
tick (shift :data:`SHIFT_US`, a tick not fully solved charged at the control period).
``--tolerance {default,low,mid,high}`` sets the same absolute tolerance on every backend that
has one (:mod:`wbc.experiments.benchmarks.settings`); quadprog runs without its worker thread
unless ``--quadprog-thread``.

The scaling study times the ``one_level`` stack on fixed-base serial chains of 7 to 100 joints,
sizes reported as the QPs' ``(n, m)`` (``n`` variables, ``m`` rows of ``A``; the bounds ``lb <=
x <= ub`` on top). The papers' controllers: each study's own daqp timing of its tick, fast path
against ``fused=False`` (:mod:`wbc.experiments.benchmarks.study_ticks`), read from the studies'
JSONs under ``--studies`` (default ``--out``). Outputs, in ``--out``: ``solver_timing.json``
(raw tick samples [µs] of every cell; with ``--samples`` also per-level iterations, the
deviations and the scaling study's ticks), ``solver_timing.md`` (tables: time, accuracy,
settings, summary, the studies' ticks) and ``solver_timing.png`` / ``scaling.png``. ``--export
DIR`` writes every timed tick's QPs per level as ``.npz`` files qpsolvers loads, with the
referee's solution.
"""

from __future__ import annotations

import argparse
import functools
import inspect
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import wbc
import wbc.robots
from wbc.errors import WbcError
from wbc.experiments.benchmarks import accuracy, study_ticks
from wbc.experiments.benchmarks.loops import timed_turns
from wbc.experiments.benchmarks.settings import (
    TOLERANCES,
    backend_options,
    describe,
    resolve_backend,
    tolerance_options,
)
from wbc.experiments.benchmarks.user_inputs import is_acceleration, load_robot_file, load_stack
from wbc.experiments.machine import describe_machine
from wbc.experiments.progress import report_progress
from wbc.experiments.studies.study import save_figure
from wbc.fused import FusedWorkspace
from wbc.robots.fixed_base import FixedBaseRobot
from wbc.solvers import available_backends, make_backend
from wbc.tasks import Bounds, ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

STACKS = ("one_level", "two_levels", "three_levels", "acceleration")
SCENARIOS = ("circle", "far", "unreachable")
#: Backends also timed alone, in a dedicated loop over the same states (the default one).
DEDICATED = ("daqp",)
REFERENCE = accuracy.REFEREE[:2]  # (backend, profile) of the referee (options: accuracy.REFEREE)
DT = 0.01  # control period [s]
CIRCLE_RADIUS, CIRCLE_PERIOD = 0.1, 4.0  # end-effector target path [m], [s]
FAR_OFFSET, FAR_PERIOD = (0.9, -0.6, 0.3), 4.0  # far target: offset [m], step period [s]
UNREACHABLE_HEIGHT = 10.0  # [m] above the start
KP, KD = 20.0, 10.0  # acceleration-level PD gains [1/s²], [1/s]
SCALING_JOINTS = (7, 15, 30, 50, 100)
SHIFT_US = 10.0  # shift of the shifted geometric mean [µs]


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


@dataclass(frozen=True)
class StackCase:
    """A stack the bench runs: ``build(robot) -> wbc.Stack``, the ``step()`` keywords for an
    end-effector target ``T``, and whether the command is an acceleration (``None``: the
    stack's first variable block says, see :func:`~.user_inputs.is_acceleration`)."""

    name: str
    build: Callable[[Any], wbc.Stack]
    references: Callable[[np.ndarray], dict]
    acceleration: bool | None = None
    missing_limits: str = "warn"  # the Controller's option (where it has one)


@dataclass(frozen=True)
class RobotCase:
    """A robot the bench runs: its name in reports and ``load() -> robot`` (a new instance)."""

    name: str
    load: Callable[[], Any]


def builtin_case(kind: str) -> StackCase:
    """The :class:`StackCase` of a built-in stack (:data:`STACKS`)."""
    if kind not in STACKS:
        raise WbcError(f"unknown stack {kind!r}; stacks are {list(STACKS)}")
    # the acceleration stack bounds accelerations only, on purpose (a PD stack's timing)
    return StackCase(kind, lambda robot: build_stack(robot, kind),
                     lambda T: _references(kind, T), kind == "acceleration",
                     "ignore" if kind == "acceleration" else "warn")


def _case(kind) -> StackCase:
    return kind if isinstance(kind, StackCase) else builtin_case(kind)


# ----------------------------------------------------------------------------- closed loop
def _target(pose0: np.ndarray, t: float, scenario: str = "circle") -> np.ndarray:
    """End-effector target at time ``t`` [s] of a scenario (module docstring) from the start
    pose ``pose0``."""
    T = pose0.copy()
    if scenario == "circle":
        phase = 2 * np.pi * t / CIRCLE_PERIOD
        T[1, 3] += CIRCLE_RADIUS * np.sin(phase)
        T[2, 3] += CIRCLE_RADIUS * (np.cos(phase) - 1.0)
    elif scenario == "far":
        if (t % FAR_PERIOD) < FAR_PERIOD / 2:
            T[:3, 3] += FAR_OFFSET
            turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
            T[:3, :3] = turn @ T[:3, :3]
    elif scenario == "unreachable":
        T[2, 3] += UNREACHABLE_HEIGHT
    else:
        raise WbcError(f"unknown scenario {scenario!r}; scenarios are {list(SCENARIOS)}")
    return T


def _references(kind: str, T: np.ndarray) -> dict:
    """The step() keywords of stack ``kind`` for end-effector target ``T``."""
    return {"ee": T, "ee_pose": T} if kind == "three_levels" else {"ee": T}


def _controller(robot, case: StackCase, backend, options: dict | None = None,
                kinematics: str = "compiled", jit: bool | str = True, **extra) -> wbc.Controller:
    """A controller of ``case`` on ``robot``; ``backend`` a name or a user factory."""
    if _HAS_MISSING_LIMITS:
        extra = {"missing_limits": case.missing_limits, **extra}
    return wbc.Controller(robot, case.build(robot), backend=backend, dt=DT,
                          kinematics=kinematics, jit=jit, **extra, **(options or {}))


_HAS_MISSING_LIMITS = "missing_limits" in inspect.signature(wbc.Controller).parameters


def reference_run(robot, kind, ticks: int, q0: np.ndarray | None = None,
                  scenario: str = "circle", kinematics: str = "auto") -> dict:
    """Closed loop from ``q0`` (default ``robot.neutral()``) on the referees' answer
    (:mod:`~wbc.experiments.benchmarks.accuracy`: quadprog's when certified, else clarabel's);
    returns the states, targets, the reference commands, whether the tick can be judged
    (``"referee_ok"``: a referee certified it, and where both did they agree), which referee
    answered (``"referee_used"``: 0, 1, or -1 for none) and the referee gap
    (``"referee_gap"``: their distance where both certify, else ``None``)."""
    case = _case(kind)
    name, profile, options = accuracy.REFEREE
    ctrl = _controller(robot, case, name, options, kinematics, "auto", profile=profile,
                       fused=False)
    name2, profile2, options2 = accuracy.SECOND_REFEREE
    second = _controller(robot, case, name2, options2, kinematics, "auto", profile=profile2,
                         fused=False)
    acceleration = case.acceleration if case.acceleration is not None else is_acceleration(
        ctrl.stack)
    q = np.asarray(robot.neutral() if q0 is None else q0, float).copy()
    v = np.zeros(robot.nv)
    pose0 = np.array(robot.frame_pose(q, "ee"))
    states, targets, commands, ok, used, gap = [], [], [], [], [], []
    for k in range(ticks):
        T = _target(pose0, k * DT, scenario)
        cmd = ctrl.step(q, v, **case.references(T)).copy()
        check = second.step(q, v, **case.references(T)).copy()
        good = accuracy.certified(ctrl), accuracy.certified(second)
        states.append((q.copy(), v.copy()))
        targets.append(T)
        if not good[0] and good[1]:
            cmd = check  # quadprog's answer failed its KKT check: clarabel's is the reference
        commands.append(cmd)
        distance = float(np.abs(cmd - check).max()) if all(good) else None
        gap.append(distance)
        ok.append(any(good) and (distance is None or distance <= accuracy.REFEREE_AGREE))
        used.append(0 if good[0] else 1 if good[1] else -1)
        u = cmd[:robot.nv]
        v = v + u * DT if acceleration else u.copy()
        q = robot.integrate(q, v, DT)
    return {"states": states, "targets": targets, "commands": commands, "referee_ok": ok,
            "referee_used": used, "referee_gap": gap}


def replay(robot, kind, backends: list, run: dict, warmup: int,
           kinematics: str = "compiled", jit: bool = True, *, tolerance: str = "default",
           cold: bool = False, repeat: int = 1, seed: int = 0, quadprog_thread: bool = False,
           samples: bool = False, export: Path | None = None) -> dict:
    """Time every backend on the reference state sequence (module docstring). ``backends``:
    names, or ``(label, factory)`` pairs for backends of the user's own. Returns
    ``{backend: result}`` (raw samples in µs)."""
    case = _case(kind)
    labelled: list[tuple[str, Any]] = [b if isinstance(b, tuple) else (b, b)
                                       for b in backends]
    controllers: dict[str, wbc.Controller] = {}
    meta: dict[str, dict[str, Any]] = {}
    for label, spec in labelled:
        options = backend_options(spec, tolerance, quadprog_thread) if isinstance(
            spec, str) else {}
        controllers[label] = _controller(robot, case, spec, options, kinematics, jit)
        # a backend made as the controller's were, for its resolved settings
        twin = make_backend(spec, **options) if isinstance(spec, str) else spec()
        meta[label] = describe(twin, tolerance_options(spec, tolerance)
                               if isinstance(spec, str) else None)
        meta[label]["settings"]["options_given"] = _plain(options)
    names = [label for label, _ in labelled]
    keys = ("tick", "kinematics", "assembly", "solve", "python")
    times: dict[str, dict[str, list[float]]] = {b: {key: [] for key in keys} for b in names}
    # "solve" split into the solver libraries' own calls and the rest (adapters, cascade)
    split: dict[str, dict[str, list]] = {b: {"library": [], "adapter": []} for b in names}
    ok: dict[str, list[bool]] = {b: [] for b in names}
    partial: dict[str, list[bool]] = {b: [] for b in names}
    deviation: dict[str, list[float]] = {b: [] for b in names}  # on the ticks judged
    wrong: dict[str, list[bool]] = {b: [] for b in names}
    levels: dict[str, list[dict]] = {b: [] for b in names}
    medians: dict[str, list[float]] = {b: [] for b in names}
    referee = accuracy.Referee() if export is not None else None
    index: list[dict] = []
    rng = np.random.default_rng(seed)
    for r in range(repeat):
        start = {b: len(times[b]["tick"]) for b in names}
        for k, ((q, v), T) in enumerate(zip(run["states"], run["targets"], strict=True)):
            refs = case.references(T)
            for i in rng.permutation(len(names)):
                backend = names[i]
                ctrl = controllers[backend]
                if cold:
                    ctrl.workspace.cold_start()
                t0 = time.perf_counter()
                cmd = ctrl.step(q, v, **refs)
                elapsed = time.perf_counter() - t0
                if k < warmup:
                    continue
                sol, own = ctrl.last_solution, times[backend]
                assert sol is not None  # set by step()
                own["tick"].append(elapsed * 1e6)
                own["kinematics"].append(sol.timings.model * 1e6)
                own["assembly"].append(sol.timings.assembly * 1e6)
                own["solve"].append(sol.timings.solve * 1e6)
                own["python"].append((elapsed - sol.timings.total) * 1e6)
                measured = ctrl.workspace.last_library_times()
                library = [t for t in measured if t is not None]
                if library and len(library) == len(measured):  # (none after a fused tick)
                    split[backend]["library"].append(sum(library) * 1e6)
                    split[backend]["adapter"].append((sol.timings.solve - sum(library)) * 1e6)
                if r:
                    continue  # accuracy: from the first repeat (the same states and answers)
                ok[backend].append(sol.ok)
                partial[backend].append(sol.partial)
                if run["referee_ok"][k]:
                    dev = float(np.abs(cmd - run["commands"][k]).max())
                    deviation[backend].append(dev)
                    limit = accuracy.WRONG_THRESHOLD + (run["referee_gap"][k] or 0.0)
                    wrong[backend].append(bool(sol.ok and dev > limit))
                _record_levels(levels[backend], ctrl.last_qps(),
                               ctrl.workspace.last_library_times())
                if referee is not None and export is not None:
                    index += _export_tick(export / _slug(backend), ctrl.last_qps(), k,
                                          referee, backend)
        for b in names:
            medians[b].append(float(np.median(times[b]["tick"][start[b]:])))
    if export is not None:
        accuracy.write_index(export, index)
    gaps = run["referee_gap"][warmup:]
    known = [g for g in gaps if g is not None]
    out: dict[str, dict[str, Any]] = {}
    for b in names:
        devs = deviation[b]
        tick = np.asarray(times[b]["tick"])
        solved = np.asarray(ok[b] * repeat, bool)[:len(tick)]
        entry = {
            "path": _path(controllers[b]), "kinematics": controllers[b].kinematics,
            # ticks of a fused controller answered by the ordinary path (whole run)
            "fused_fallbacks": _fused_fallbacks(controllers[b].workspace),
            "samples": {key: np.round(val, 3).tolist() for key, val in times[b].items()},
            "success_rate": float(np.mean(ok[b])), "partial_rate": float(np.mean(partial[b])),
            "full_solve_rate": float(np.mean(ok[b])),
            "wrong_rate": float(np.mean(wrong[b])) if wrong[b] else None,
            "deviation": _stats(devs) if devs else {"median": None, "p95": None, "max": None},
            "max_abs_diff_vs_reference": float(max(devs)) if devs else None,
            "referee_failures": int(sum(u < 0 for u in run["referee_used"][warmup:])),
            "referee_disagreements": int(sum(g is not None and g > accuracy.REFEREE_AGREE
                                             for g in gaps)),
            "referee_gap": _stats(known) if known else None,
            "referee_switches": int(sum(u == 1 for u in run["referee_used"][warmup:])),
            "stats": {key: _stats(val) for key, val in times[b].items()},
            # over the ticks a backend solved (not fused ones); None when none was
            "solve_split": {key: _stats(val) if val else None for key, val in split[b].items()},
            "shifted_geomean": _shifted_geomean(tick, solved),
            "repeats": _repeats(medians[b]),
            "levels": [_level_summary(level, samples) for level in levels[b]],
            **meta[b]}
        if samples:
            entry["samples"]["deviation"] = devs
        out[b] = entry
    for backend in set(DEDICATED) & set(names):
        spec = dict(labelled)[backend]
        ctrl = _controller(robot, case, spec,
                           backend_options(spec, tolerance, quadprog_thread), kinematics, jit)
        out[backend]["dedicated"] = _stats(dedicated_replay(ctrl, case, run, cold)[warmup:]
                                           * 1e6)
    return out


def _record_levels(levels: list[dict], qps: list, library: list) -> None:
    """Append this tick's iterations, library time [µs] and residuals per level to ``levels``
    (one dict per level, by position)."""
    for i, (label, qp, result) in enumerate(qps):
        if i >= len(levels):
            levels.append({"label": label, "size": [int(len(qp[1])), int(np.shape(qp[2])[0])],
                           "iterations": [], "library": [], "primal": [], "dual": [],
                           "gap": []})
        level = levels[i]
        if i < len(library) and library[i] is not None:
            level["library"].append(library[i] * 1e6)
        iterations = result.iterations  # -1: unknown (the fused tick's generated daqp)
        if iterations is not None and iterations >= 0:
            level["iterations"].append(int(iterations))
        for key, value in accuracy.residuals(qp, result).items():
            level[key].append(value)


def _level_summary(level: dict, samples: bool) -> dict:
    def spread(values):
        known = [v for v in values if v is not None]
        return _stats(known) if known else None

    out = {"label": level["label"], "size": level["size"],
           "iterations": spread(level["iterations"]),
           "library_time_us": spread(level["library"]),
           "primal_residual": spread(level["primal"]), "dual_residual": spread(level["dual"]),
           "duality_gap": spread(level["gap"]),
           "multipliers": any(v is not None for v in level["dual"])}
    if samples:
        out["iterations_samples"] = level["iterations"]
    return out


def _export_tick(folder: Path, qps: list, tick: int, referee, backend: str) -> list[dict]:
    entries = []
    for i, (label, qp, result) in enumerate(qps):
        x_ref = referee.solve(qp)
        path = accuracy.export_qp(folder / f"tick{tick:05d}_level{i}.npz", qp, label,
                                  result.status.value, x_ref)
        entries.append({"file": str(path), "backend": backend, "tick": tick, "level": i,
                        "label": label, "size": [int(len(qp[1])), int(np.shape(qp[2])[0])],
                        "status": result.status.value, "referee_solved": x_ref is not None})
    return entries


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)


def dedicated_replay(controller, kind, run: dict, cold: bool = False) -> np.ndarray:
    """``controller`` alone on the reference run's states, one tick after the other (a
    dedicated control loop, its caches warm; see :mod:`wbc.experiments.benchmarks.loops`): the
    wall time of every ``step`` [s]."""
    case = _case(kind)
    states, goals = run["states"], run["targets"]

    def turn(k: int) -> float:
        (q, v), refs = states[k], case.references(goals[k])
        if cold:
            controller.workspace.cold_start()
        t0 = time.perf_counter()
        controller.step(q, v, **refs)
        return time.perf_counter() - t0

    return timed_turns({"alone": turn}, len(states), len(states))["alone"]


def _fused_fallbacks(workspace) -> int | None:
    """Ticks of a fused controller's run answered by the ordinary path (``None``: not fused)."""
    if not isinstance(workspace, FusedWorkspace):
        return None
    return workspace.fallback_solves + workspace.skipped_solves


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


def _shifted_geomean(tick_us: np.ndarray, solved: np.ndarray) -> dict:
    """``exp(mean(log(t + s))) - s`` of the ticks [µs], shift ``s`` = :data:`SHIFT_US`, a tick
    not fully solved charged at the control period."""
    charged = np.where(solved, tick_us, DT * 1e6)
    value = float(np.exp(np.mean(np.log(charged + SHIFT_US))) - SHIFT_US)
    return {"value_us": value, "shift_us": SHIFT_US, "failure_charge_us": DT * 1e6,
            "charged_ticks": int(np.sum(~solved))}


def _repeats(medians: list[float]) -> dict:
    """The per-repeat medians, their mean and its 95 % confidence interval (Student's t;
    ``None`` with one repeat)."""
    mean = float(np.mean(medians))
    if len(medians) < 2:
        return {"medians": medians, "mean": mean, "ci95": None}
    try:
        from scipy.stats import t as student

        factor = float(student.ppf(0.975, len(medians) - 1))
    except ImportError:  # the normal quantile: slightly narrow for few repeats
        factor = 1.96
    half = factor * float(np.std(medians, ddof=1)) / math.sqrt(len(medians))
    return {"medians": medians, "mean": mean, "ci95": [mean - half, mean + half]}


def _plain(value):
    from wbc.solvers.base import plain

    return plain(value)


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
def run(robots: list, stacks: list, backends: list, ticks: int, warmup: int,
        scaling_ticks: int, scaling_joints: tuple[int, ...], kinematics: str = "compiled",
        jit: bool = True, progress=None, *, scenarios: tuple[str, ...] = ("circle",),
        tolerance: str = "default", cold: bool = False, repeat: int = 1, seed: int = 0,
        quadprog_thread: bool = False, samples: bool = False,
        export: Path | None = None) -> dict:
    """The whole study; returns the JSON-able report. ``robots``: catalogue names or
    :class:`RobotCase`; ``stacks``: built-in names or :class:`StackCase`; ``backends``: names
    or ``(label, factory)``. ``progress(done, total, what)`` is called after each robot ×
    stack × scenario and each chain size."""
    options = {"tolerance": tolerance, "cold": cold, "repeat": repeat, "seed": seed,
               "quadprog_thread": quadprog_thread, "samples": samples}
    report: dict[str, Any] = {
        "machine": describe_machine(), "dt_s": DT, "ticks": ticks, "warmup": warmup,
        "kinematics": kinematics, "jit": jit, "reference": "/".join(REFERENCE) + " (no thread)",
        "second_referee": "/".join(accuracy.SECOND_REFEREE[:2]),
        "wrong_threshold": accuracy.WRONG_THRESHOLD, "scenarios": list(scenarios),
        "tolerance_abs": TOLERANCES[tolerance], **options, "results": {}, "scaling": {}}
    robot_cases = [r if isinstance(r, RobotCase) else
                   RobotCase(r, functools.partial(wbc.robots.load, r)) for r in robots]
    stack_cases = [_case(s) for s in stacks]
    combos = [(r, s, sc) for r in robot_cases for s in stack_cases for sc in scenarios]
    total = len(combos) + len(scaling_joints)
    for i, (robot_case, case, scenario) in enumerate(combos, start=1):
        robot = robot_case.load()
        ref = reference_run(robot, case, warmup + ticks, scenario=scenario)
        folder = None if export is None else \
            export / _slug(robot_case.name) / _slug(case.name) / scenario
        cell = replay(robot, case, backends, ref, warmup, kinematics, jit, export=folder,
                      tolerance=tolerance, cold=cold, repeat=repeat, seed=seed,
                      quadprog_thread=quadprog_thread, samples=samples)
        report["results"].setdefault(robot_case.name, {}).setdefault(case.name, {})[
            scenario] = cell
        if progress:
            progress(i, total, f"{robot_case.name} / {case.name} / {scenario}")
    one_level = builtin_case("one_level")
    for j, n in enumerate(scaling_joints, start=1):
        chain = serial_chain(n)
        # start bent (the straight chain is singular)
        ref = reference_run(chain, one_level, warmup + scaling_ticks, np.full(n, 0.3))
        for backend, result in replay(chain, one_level, backends, ref, warmup, kinematics,
                                      jit, tolerance=tolerance, cold=cold, repeat=repeat,
                                      seed=seed, quadprog_thread=quadprog_thread,
                                      samples=samples).items():
            entry = {key: result[key] for key in (
                "stats", "success_rate", "full_solve_rate", "wrong_rate", "deviation", "path",
                "shifted_geomean", "repeats")}
            entry["qp_sizes"] = [level["size"] for level in result["levels"]]
            if samples:
                entry["samples"] = {"tick": result["samples"]["tick"]}
            if "dedicated" in result:
                entry["dedicated"] = result["dedicated"]
            report["scaling"].setdefault(backend, {})[str(n)] = entry
        if progress:
            progress(len(combos) + j, total, f"scaling: {n}-joint chain")
    report["summary"] = summary(report)
    return report


def _cells(report: dict):
    """``(robot, stack, scenario, {backend: result})`` of every cell."""
    for robot, per_stack in report["results"].items():
        for stack, per_scenario in per_stack.items():
            for scenario, per_backend in per_scenario.items():
                yield robot, stack, scenario, per_backend


def summary(report: dict) -> dict:
    """Per backend over every cell: the shifted geometric mean of all its ticks (failures
    charged at the control period) and its ratio to the best backend's, the median of the
    cells' median ticks, the full-solve and wrong rates."""
    ticks: dict[str, list] = {}
    out: dict[str, dict] = {}
    for *_, per_backend in _cells(report):
        for backend, r in per_backend.items():
            acc = out.setdefault(backend, {"cells": 0, "medians": [], "full": [], "wrong": [],
                                           "charged": 0})
            g = r["shifted_geomean"]
            ticks.setdefault(backend, []).append((len(r["samples"]["tick"]), g["value_us"]))
            acc["cells"] += 1
            acc["medians"].append(r["stats"]["tick"]["median"])
            acc["full"].append(r["full_solve_rate"])
            if r["wrong_rate"] is not None:
                acc["wrong"].append(r["wrong_rate"])
            acc["charged"] += g["charged_ticks"]
    result = {}
    for backend, acc in out.items():
        # the geometric mean over every tick of every cell, from the cells' (count, value)
        pairs = ticks[backend]
        logs = sum(count * math.log(value + SHIFT_US) for count, value in pairs)
        count = sum(c for c, _ in pairs)
        result[backend] = {
            "shifted_geomean_us": math.exp(logs / count) - SHIFT_US, "shift_us": SHIFT_US,
            "failure_charge_us": DT * 1e6, "charged_ticks": acc["charged"],
            "cells": acc["cells"], "median_of_cell_medians_us": float(np.median(acc["medians"])),
            "full_solve_rate": float(np.mean(acc["full"])),
            "wrong_rate": float(np.mean(acc["wrong"])) if acc["wrong"] else None}
    if result:
        best = min(r["shifted_geomean_us"] for r in result.values())
        for r in result.values():
            r["relative_to_best"] = r["shifted_geomean_us"] / best
    return result


def _num(value, spec: str = ".1f", scale: float = 1.0) -> str:
    return "–" if value is None else f"{scale * value:{spec}}"


def markdown(report: dict) -> str:
    """Tables: per cell time, its split and accuracy per backend; per level iterations and
    residuals; the backends' settings and versions; the summary."""
    out = [f"Machine: {report['machine']['cpu']}, {report['machine']['cores']} cores, "
           f"Python {report['machine']['python']}. Ticks: {report['ticks']} after "
           f"{report['warmup']} warm-up, {report.get('repeat', 1)} repeat(s), order shuffled "
           f"per tick (seed {report.get('seed', 0)}); kinematics {report['kinematics']}, "
           f"jit={report['jit']}; {'cold' if report.get('cold') else 'warm'} start; tolerance "
           f"group {report.get('tolerance', 'default')}; referee {report['reference']}, "
           f"second referee {report.get('second_referee', '–')}, answers certified by their "
           "KKT residuals. Times "
           "in µs. 'full solve': every level solved; 'wrong': fully solved but more than "
           f"{report.get('wrong_threshold', accuracy.WRONG_THRESHOLD):.0e} plus the referee "
           "gap from the referee's command, on the ticks the referees judge (see below each "
           "table); 'partial': a lower level failed and the command is the levels above it. "
           "Path 'fused': the whole tick is one generated C call (its 'solve' is "
           "that call). 'solve: library / adapter': the solver libraries' own calls (setup or "
           "update, and solve) and the rest of 'solve' (adapters, cascade), medians over the "
           "ticks a backend solved (not fused ones).",
           ""]
    for robot, stack, scenario, per_backend in _cells(report):
        out += [f"### {robot} — {stack} — {scenario}", "",
                "| backend | path | tick median | p95 | max | mean of repeats (95 % CI) | "
                "alone: median / p95 | kinematics | assembly | solve | solve: library / "
                "adapter | python | shifted geo. mean | full solve | wrong | partial | "
                "deviation median / p95 / max | iterations per level (median) |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for backend, r in per_backend.items():
            s = r["stats"]
            alone = (f"{r['dedicated']['median']:.1f} / {r['dedicated']['p95']:.1f}"
                     if "dedicated" in r else "–")
            rep = r.get("repeats", {})
            ci = (f"{rep['mean']:.1f} ({rep['ci95'][0]:.1f}–{rep['ci95'][1]:.1f})"
                  if rep.get("ci95") else "–")
            d = r["deviation"]
            split = r.get("solve_split") or {}
            library = (f"{split['library']['median']:.1f} / {split['adapter']['median']:.1f}"
                       if split.get("library") else "–")
            iters = " / ".join(_num(lv["iterations"]["median"] if lv["iterations"] else None,
                                    ".0f") for lv in r.get("levels", []))
            out.append(
                f"| {backend} | {r['path']} | {s['tick']['median']:.1f} | "
                f"{s['tick']['p95']:.1f} | {s['tick']['max']:.0f} | {ci} | {alone} | "
                f"{s['kinematics']['median']:.1f} | {s['assembly']['median']:.1f} | "
                f"{s['solve']['median']:.1f} | {library} | {s['python']['median']:.1f} | "
                f"{r['shifted_geomean']['value_us']:.1f} | "
                f"{100 * r['full_solve_rate']:.1f} % | {_num(r['wrong_rate'], '.1f', 100)} % | "
                f"{100 * r['partial_rate']:.1f} % | {_num(d['median'], '.1e')} / "
                f"{_num(d['p95'], '.1e')} / {_num(d['max'], '.1e')} | {iters or '–'} |")
        out.append("")
        first = next(iter(per_backend.values()))
        failures = first.get("referee_failures", 0)
        if failures:
            out += [f"No referee certified {failures} tick(s): not judged.", ""]
        disagreements = first.get("referee_disagreements", 0)
        if disagreements:
            out += [f"The two certified referees differ by more than "
                    f"{accuracy.REFEREE_AGREE:.0e} on {disagreements} tick(s) (badly "
                    "conditioned levels): not judged.", ""]
        switches = first.get("referee_switches", 0)
        if switches:
            out += [f"quadprog's answer failed its KKT check on {switches} tick(s): clarabel's "
                    "(certified) is the reference there.", ""]
        gap = first.get("referee_gap")
        if gap:
            out += [f"Referee gap (quadprog vs clarabel, both tight and certified): median "
                    f"{gap['median']:.1e}, max {gap['max']:.1e}.", ""]
        out += ["Per level (QP size (n, m): variables, rows of A, bounds on x besides; "
                "median library time [µs] of the ticks a backend solved; residuals of the "
                "backend's answer, max over "
                "ticks; '–': no multipliers returned):", "",
                "| backend | level | (n, m) | library time | primal | dual | duality gap |",
                "|---|---|---|---|---|---|---|"]
        for backend, r in per_backend.items():
            for i, lv in enumerate(r.get("levels", [])):
                library = lv.get("library_time_us")
                out.append(
                    f"| {backend} | {i} | ({lv['size'][0]}, {lv['size'][1]}) | "
                    f"{_num(library and library['median'], '.1f')} | "
                    f"{_num(lv['primal_residual'] and lv['primal_residual']['max'], '.1e')} | "
                    f"{_num(lv['dual_residual'] and lv['dual_residual']['max'], '.1e')} | "
                    f"{_num(lv['duality_gap'] and lv['duality_gap']['max'], '.1e')} |")
        out.append("")
    backends = _settings_by_backend(report)
    if backends:
        out += ["### Backends: versions and resolved settings", "",
                "| backend | package | version | profile | tolerance | settings set by wbc |",
                "|---|---|---|---|---|---|"]
        for backend, r in backends.items():
            st = r["settings"]
            given = {k: st.get("options", {}).get(k) for k in st.get("set_by_wbc", [])} \
                if isinstance(st.get("options"), dict) else st.get("options")
            tolerance = _tolerance_words(st.get("tolerance"), report)
            out.append(f"| {backend} | {st.get('package') or '–'} | {r.get('version') or '–'} "
                       f"| {st.get('profile', '–')} | {tolerance} | `{json.dumps(given)}` |")
        out += ["", "Every resolved option (library defaults included) is in the JSON, "
                "`settings.options` of each cell.", ""]
    if report.get("summary"):
        out += ["### Summary per backend (every cell)", "",
                f"Shifted geometric mean of every tick, shift {SHIFT_US:g} µs, a tick not "
                f"fully solved charged at the control period ({DT * 1e6:.0f} µs).", "",
                "| backend | shifted geo. mean [µs] | × best | median of cell medians [µs] | "
                "full solve | wrong | charged ticks |", "|---|---|---|---|---|---|---|"]
        for backend, r in sorted(report["summary"].items(),
                                 key=lambda item: item[1]["shifted_geomean_us"]):
            out.append(f"| {backend} | {r['shifted_geomean_us']:.1f} | "
                       f"{r['relative_to_best']:.2f} | {r['median_of_cell_medians_us']:.1f} | "
                       f"{100 * r['full_solve_rate']:.2f} % | "
                       f"{_num(r['wrong_rate'], '.2f', 100)} % | {r['charged_ticks']} |")
        out.append("")
    if report["scaling"]:
        joints = sorted({int(n) for per in report["scaling"].values() for n in per})
        sizes: dict[int, list] = {}
        for per in report["scaling"].values():
            for n, entry in per.items():
                sizes.setdefault(int(n), entry.get("qp_sizes", [[None, None]])[0])
        out += ["### Scaling: median tick [µs] (p95) vs the QP's size (n, m) (one_level stack "
                "on serial chains)", "",
                "| backend | " + " | ".join(f"{n} joints ({sizes[n][0]}, {sizes[n][1]})"
                                           for n in joints) + " |",
                "|---|" + "---|" * len(joints)]
        for backend, per in report["scaling"].items():
            cells = [f"{per[str(n)]['stats']['tick']['median']:.0f} "
                     f"({per[str(n)]['stats']['tick']['p95']:.0f})" if str(n) in per else "-"
                     for n in joints]
            out.append(f"| {backend} | " + " | ".join(cells) + " |")
            if any("dedicated" in entry for entry in per.values()):
                cells = [f"{per[str(n)]['dedicated']['median']:.0f}"
                         if "dedicated" in per.get(str(n), {}) else "-" for n in joints]
                out.append(f"| {backend} alone | " + " | ".join(cells) + " |")
    if report.get("study_ticks"):
        found = report["study_ticks"]
        out += ["", *study_ticks.markdown(found["rows"], Path(found["folder"]))]
    return "\n".join(out) + "\n"


def _tolerance_words(tolerance, report: dict) -> str:
    """The tolerance column: the group's absolute tolerance, the profile's, or none."""
    if tolerance is None:
        return "none of its own (settings kept)"
    eps = report.get("tolerance_abs")
    return "the profile's" if tolerance == {} or eps is None else f"{eps:.0e} absolute"


def _settings_by_backend(report: dict) -> dict:
    found: dict[str, dict] = {}
    for *_, per_backend in _cells(report):
        for backend, r in per_backend.items():
            found.setdefault(backend, {"settings": r["settings"], "version": r["version"]})
    return found


def plots(report: dict, out: Path) -> list[Path]:
    """Per robot a panel (shared y axis): median tick per backend and stack, whiskers to the
    p95, the fused path hatched; the scaling curves against the QP's (n, m) with p95 bands.
    Legends outside the axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    written = []
    results = report["results"]
    if results:
        fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results) + 2, 4.5),
                                 squeeze=False, sharey=True)
        handles: dict[str, Any] = {}
        palette = plt.get_cmap("tab20")  # up to 20 stack × scenario cells apart
        for ax, (name, per_stack) in zip(axes[0], results.items(), strict=True):
            cells = [(kind, scenario, per_backend) for kind, per_scenario in per_stack.items()
                     for scenario, per_backend in per_scenario.items()]
            backends = list(cells[0][2])
            width = 0.8 / max(1, len(cells))
            for i, (kind, scenario, per_backend) in enumerate(cells):
                label = f"{kind} / {scenario}"
                med = np.array([per_backend[b]["stats"]["tick"]["median"] for b in backends])
                p95 = np.array([per_backend[b]["stats"]["tick"]["p95"] for b in backends])
                x = np.arange(len(backends)) + i * width
                bars = ax.bar(x, med, width, yerr=[np.zeros_like(med), p95 - med],
                              capsize=2, label=label, color=palette(i % 20))
                for bar, b in zip(bars, backends, strict=True):
                    if per_backend[b]["path"] == "fused":
                        bar.set_hatch("//")
                handles.setdefault(label, Patch(color=palette(i % 20)))  # unhatched
            ax.set_xticks(np.arange(len(backends)) + 0.4 - width / 2)
            ax.set_xticklabels([f"{b}\n(fused)" if cells[0][2][b]["path"] == "fused" else b
                                for b in backends], rotation=45, ha="right", fontsize=8)
            ax.set_yscale("log")
            ax.set_xlabel("QP backend")
            ax.set_ylabel("tick [µs]: median, whisker to p95" if ax is axes[0][0] else "tick [µs]")
            ax.set_title(f"{name}", fontsize=9)
        fig.legend(list(handles.values()), list(handles), title="stack / scenario",
                   fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
        fig.suptitle("Whole tick per backend (hatched: fused path, one generated C call)",
                     fontsize=10)
        fig.tight_layout()
        written.append(out / save_figure(fig, out / "solver_timing.png"))
    if report["scaling"]:
        fig, ax = plt.subplots(figsize=(7.5, 4))
        for backend, per in report["scaling"].items():
            n = sorted(int(k) for k in per)
            middle = [per[str(k)]["stats"]["tick"]["median"] for k in n]
            high = [per[str(k)]["stats"]["tick"]["p95"] for k in n]
            fused = any(per[str(k)].get("path") == "fused" for k in n)
            line, = ax.plot(n, middle, "o-", label=backend + (" (fused)" if fused else ""))
            ax.fill_between(n, middle, high, color=line.get_color(), alpha=0.15)
        first = next(iter(report["scaling"].values()))
        ticks = sorted(int(k) for k in first)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(ticks)
        ax.set_xticklabels([f"{k}\n{tuple(first[str(k)]['qp_sizes'][0])}"
                            if first[str(k)].get("qp_sizes") else str(k) for k in ticks],
                           fontsize=7)
        ax.minorticks_off()
        ax.set_xlabel("joints, and the QP's (n, m) [-]")
        ax.set_ylabel("tick [µs]: median, band to p95")
        ax.set_title("Scaling: one_level stack on serial chains")
        ax.legend(title="QP backend", fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
        fig.tight_layout()
        written.append(out / save_figure(fig, out / "scaling.png"))
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="wbc bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=None, metavar="ROBOT",
                        help=f"catalogue robots (default: all of {wbc.robots.names()}, "
                             "unless --robot is given)")
    parser.add_argument("--robot", action="append", default=[], metavar="FILE.toml",
                        help="a robot of your own, described in a TOML file (repeatable; "
                             "see wbc.experiments.benchmarks.user_inputs)")
    parser.add_argument("--stacks", nargs="+", default=None, metavar="STACK",
                        help=f"built-in stacks (default: all of {list(STACKS)}, unless "
                             "--stack is given)")
    parser.add_argument("--stack", action="append", default=[], metavar="MODULE:FUNCTION",
                        help="a stack of your own: function(robot) -> wbc.Stack with a frame "
                             "task named 'ee', importable from the working directory "
                             "(repeatable)")
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), metavar="SCENARIO",
                        help=f"end-effector target scenarios (default: all of "
                             f"{list(SCENARIOS)})")
    parser.add_argument("--backends", nargs="+", default=None, metavar="BACKEND",
                        help="backends (default: every available one); also "
                             "'qpsolvers:<solver>', 'casadi:<plugin>' and 'module:function' "
                             "(a factory of your own backend)")
    parser.add_argument("--ticks", type=int, default=3000, help="timed ticks (default 3000)")
    parser.add_argument("--warmup", type=int, default=50, help="untimed first ticks")
    parser.add_argument("--repeat", type=int, default=1, metavar="N",
                        help="replay every cell N times (new order each time) and report "
                             "the mean median with a 95 %% confidence interval (default 1)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the per-tick shuffled order of the backends")
    parser.add_argument("--tolerance", choices=tuple(TOLERANCES), default="default",
                        help="default: each backend's profile; low / mid / high: the same "
                             "absolute tolerance 1e-3 / 1e-6 / 1e-9 on every backend that "
                             "has one")
    parser.add_argument("--cold", action="store_true",
                        help="cold start: every backend's solver set up afresh every tick "
                             "(the setup is timed)")
    parser.add_argument("--quadprog-thread", action="store_true",
                        help="time quadprog with its worker thread (its time limit); "
                             "default: called directly")
    parser.add_argument("--samples", action="store_true",
                        help="keep raw samples of the scaling study, per-level iterations "
                             "and deviations too (the cells' tick samples are always kept)")
    parser.add_argument("--export", type=Path, default=None, metavar="DIR",
                        help="write every timed tick's QPs per level as .npz (qpsolvers' "
                             "layout, with the referee's solution) under DIR")
    parser.add_argument("--scaling-ticks", type=int, default=3000,
                        help="timed ticks per chain in the scaling study (default 3000)")
    parser.add_argument("--scaling-joints", type=int, nargs="*", default=list(SCALING_JOINTS),
                        help="chain sizes of the scaling study (none: skip it)")
    parser.add_argument("--kinematics", choices=("compiled", "numeric", "auto"),
                        default="compiled",
                        help="model stage: poses and Jacobians inside the compiled functions "
                             "(default), from pinocchio every tick, or compiled where the "
                             "robot allows (auto: for URDF robots)")
    parser.add_argument("--no-jit", action="store_true",
                        help="evaluate the level functions on CasADi's virtual machine instead "
                             "of compiled C (wbc.jit; built once per machine, then cached)")
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="output folder (default ./results)")
    parser.add_argument("--studies", type=Path, default=None, metavar="DIR",
                        help="where the paper studies wrote their JSONs (DIR/NAME/NAME.json, "
                             "as `wbc study NAME --out DIR`), whose daqp ticks (fast and "
                             "ordinary path) the report repeats (default: --out)")
    # accepted only to be refused with the reason (wbc fuzz and wbc audit take them)
    parser.add_argument("--workers", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--scheduler", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.workers is not None or args.scheduler is not None:
        parser.error("wbc bench runs in one process: a timing needs an idle core, not a "
                     "cluster (--workers and --scheduler are for wbc fuzz and wbc audit)")
    robots: list = list(args.robots or ([] if args.robot else wbc.robots.names()))
    unknown = sorted(set(robots) - set(wbc.robots.names()))
    if unknown:
        parser.error(f"unknown robot(s) {unknown}; the catalogue is {wbc.robots.names()} "
                     "(a robot of your own: --robot FILE.toml)")
    stacks: list = list(args.stacks or ([] if args.stack else STACKS))
    bad = sorted(set(stacks) - set(STACKS))
    if bad:
        parser.error(f"unknown stack(s) {bad}; stacks are {list(STACKS)} (a stack of your "
                     "own: --stack module:function)")
    bad = sorted(set(args.scenarios) - set(SCENARIOS))
    if bad:
        parser.error(f"unknown scenario(s) {bad}; scenarios are {list(SCENARIOS)}")
    backends = bench_backends(parser, args.backends)
    if args.ticks < 1 or args.warmup < 0 or args.scaling_ticks < 1 or args.repeat < 1:
        parser.error("--ticks, --scaling-ticks and --repeat must be >= 1, --warmup >= 0")
    if any(n < 2 for n in args.scaling_joints):
        parser.error("--scaling-joints sizes must be >= 2")
    # the user's files: read now, so that a bad one fails before any timing (exit code 1)
    for path in args.robot:
        robot = load_robot_file(path)
        robots.append(RobotCase(robot.name if getattr(robot, "name", None) else Path(path).stem,
                                functools.partial(load_robot_file, path)))
    for spec in args.stack:
        user = load_stack(spec)
        stacks.append(StackCase(spec, user, lambda T: {"ee": T}, None))
    report = run(robots, stacks, backends, args.ticks, args.warmup, args.scaling_ticks,
                 tuple(args.scaling_joints), args.kinematics, not args.no_jit,
                 report_progress, scenarios=tuple(args.scenarios), tolerance=args.tolerance,
                 cold=args.cold, repeat=args.repeat, seed=args.seed,
                 quadprog_thread=args.quadprog_thread, samples=args.samples,
                 export=args.export)
    studies = args.out if args.studies is None else args.studies
    report["study_ticks"] = {"folder": str(studies), "rows": study_ticks.study_ticks(studies)}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "solver_timing.json").write_text(json.dumps(report))
    table = markdown(report)
    (args.out / "solver_timing.md").write_text(table)
    written = plots(report, args.out)
    print(table)
    print("wrote", ", ".join(str(p) for p in
                             [args.out / "solver_timing.json", args.out / "solver_timing.md",
                              *written]))
    if args.export is not None:
        print(f"exported the QPs under {args.export} (index: index.json in each cell's folder)")
    return 0


def bench_backends(parser: argparse.ArgumentParser, names: list[str] | None) -> list:
    """The ``--backends`` items (each may be a comma-separated list): names any
    :func:`wbc.solvers.make_backend` accepts, kept as names, and ``module:function`` factories
    as ``(label, factory)``; a usage error naming the first refused."""
    from wbc.errors import BackendUnavailableError

    items = [b for item in (names or available_backends()) for b in item.split(",") if b]
    if not items:
        parser.error("--backends needs at least one name")
    backends: list = []
    labels: list[str] = []
    for name in items:
        try:
            resolved = resolve_backend(name)
        except BackendUnavailableError as err:
            parser.error(f"backend {name!r} not available: {err}")
        # a backend named twice is timed twice, as "name#2", ... (a check of the protocol:
        # identical controllers should time alike)
        label = name if name not in labels else f"{name}#{labels.count(name) + 1}"
        labels.append(name)
        backends.append(resolved if label == resolved else (label, resolved))
    return backends


if __name__ == "__main__":
    raise SystemExit(main())
