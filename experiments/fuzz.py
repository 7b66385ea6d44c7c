"""``wbc fuzz``: a seeded fuzz campaign over stacks, workspaces and robot controllers.

Every case is one tick (``Workspace.solve`` or ``Controller.step``) on data with an injected
defect, or on clean random data. Its outcome is classed as

* ``"error"``: a clean :class:`~wbc.WbcError` (the input was refused, with a message);
* ``"failure"``: a solution with a failure status (infeasible, max-iter, numerical);
* ``"success"``: a solved tick;

and it is a **defect** when it raises anything else, returns NaN / inf in ``x`` (any status),
leaves a hard variable bound by more than ``1e-9 · max(1, |bound|)`` on success, or takes more
than 1 s (a hang).

Case families (drawn in proportion, all seeded from ``--seed``):

* ``stack``: random stacks of 1–4 priority levels over 1–12 variables (one or two blocks),
  built once per *structure* and then updated tick after tick through the workspace. Tasks
  are :class:`~wbc.tasks.LinearTask` (random, rank-deficient, empty-in-effect (zero rows of
  ``A``), zero weight), hard constraints :class:`~wbc.tasks.Bounds` and
  :class:`~wbc.tasks.LinearConstraint` (duplicated rows, contradictory rows, infeasible
  sides). Each tick's data are scaled by ``10^U(-12, 12)`` and receive one injected defect
  (or none): NaN / ±inf in a coefficient or a target, a wrong shape, a lower side above its
  upper side, an unknown parameter name.
* ``robot``: for each catalogue robot a velocity-level controller (frame task, posture task,
  configuration and velocity limits) — on daqp it takes the fused tick (:mod:`wbc.fused`)
  when a C compiler is there, so the fused path is fuzzed as ``"daqp (fused)"`` — ticked on
  bad states and references: NaN in ``q``, ``q`` outside the limits, wrong lengths, unknown
  reference names, non-orthonormal target rotations, unreachable targets, NaN targets.

Outputs (``--out DIR``): ``DIR/fuzz.json`` with ``"cases"``, ``"outcomes"`` (counts per class
and backend), ``"defects"`` (each with a reproducer: family, backend, seeds, injected defect,
message) and ``"parameters"``; ``DIR/fuzz.md`` the same as a table. Exit code: 0 without
defects, 1 with any (2: a usage error).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

import wbc
import wbc.robots
from wbc.fused import FusedWorkspace
from wbc.solvers import available_backends
from wbc.solvers.base import silenced
from wbc.tasks import (
    Bounds,
    ConfigurationLimit,
    FrameTask,
    LinearConstraint,
    LinearTask,
    PostureTask,
    VelocityLimit,
)

from .arguments import constructible_backends

HANG_S = 1.0  # a tick longer than this is a hang [s]
BOUND_TOL = 1e-9  # allowed excursion out of a hard variable bound, relative to max(1, |b|)
TICKS = 8  # ticks per structure and draw of a stack case family (each tick is a case)
DEFECTS = ("none", "none", "nan", "inf", "shape", "crossed", "unknown", "zero_weight", "huge")
STATE_DEFECTS = ("none", "nan_q", "outside_limits", "short_q", "long_v", "unknown_reference",
                 "skewed_rotation", "unreachable", "nan_target", "inf_v")


def classify(tick) -> tuple[str, str | None, str]:
    """Run ``tick()`` (returning a :class:`~wbc.Solution` and the hard variable bounds) and class
    it: ``(class, defect or None, message)``."""
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            solution, (lower, upper) = tick()
            # a failed tick's conflict search runs when its message is first read
            # (wbc.infeasibility): read it here, so that the campaign covers it too
            solution.message  # noqa: B018
    except wbc.WbcError as exc:
        outcome, defect, message = "error", None, f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # what the campaign looks for
        return "defect", "exception", f"{type(exc).__name__}: {exc}"
    else:
        x = np.asarray(solution.x, dtype=float)
        outcome = "success" if solution.status is wbc.Status.SOLVED else "failure"
        defect, message = None, f"{solution.status.value}"
        if not np.all(np.isfinite(x)):
            defect, message = "non_finite_x", f"x = {x.tolist()}"
        elif outcome == "success":
            slack = BOUND_TOL * np.maximum(1.0, np.maximum(np.abs(np.where(
                np.isfinite(lower), lower, 0)), np.abs(np.where(np.isfinite(upper), upper, 0))))
            out = np.maximum(lower - x, x - upper) - slack
            if np.any(out > 0):
                defect, message = "out_of_bounds", f"bound excursion {float(out.max()):.3g}"
    elapsed = time.perf_counter() - start
    if elapsed > HANG_S:
        return "defect", "hang", f"tick took {elapsed:.2f} s; {message}"
    return ("defect" if defect else outcome), defect, message


# ---------------------------------------------------------------------------------------------
# stack family


def random_structure(rng: np.random.Generator) -> dict:
    """A stack structure: sizes of the blocks, the tasks per level, the hard constraints."""
    n = int(rng.integers(1, 13))
    split = int(rng.integers(0, n)) if n > 1 and rng.random() < 0.5 else 0
    levels = int(rng.integers(1, 5))
    # 0 rows: an empty task (one in thirteen)
    tasks = [(level, int(rng.integers(0, 13))) for level in range(levels)
             for _ in range(int(rng.integers(1, 3)))]
    return {"n": n, "split": split, "tasks": tasks, "bounds": bool(rng.random() < 0.8),
            "rows": int(rng.integers(0, 5)), "damping": float(rng.choice([0.0, 1e-6, 1e-3]))}


def build_stack(structure: dict):
    """The :class:`wbc.Stack` of a structure (its data are replaced every tick)."""
    n, split = structure["n"], structure["split"]
    x = wbc.Variables(a=split, b=n - split) if split else wbc.Variables(x=n)
    stack = wbc.Stack(x, damping=structure["damping"])
    for i, (level, rows) in enumerate(structure["tasks"]):
        stack.add(LinearTask(np.zeros((rows, n)), np.zeros(rows), name=f"t{i}"), priority=level)
    if structure["bounds"]:
        stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    if structure["rows"]:
        m = structure["rows"]
        stack.constrain(LinearConstraint(np.zeros((m, n)), -np.ones(m), np.ones(m), name="rows"))
    return stack


def random_values(rng: np.random.Generator, structure: dict, defect: str) -> dict:
    """One tick's parameter values for a structure, with ``defect`` injected."""
    n = structure["n"]
    scale = 10.0 ** rng.uniform(-12, 12) if defect == "huge" else 10.0 ** rng.uniform(-3, 3)
    values = {}
    for i, (_, rows) in enumerate(structure["tasks"]):
        A = rng.standard_normal((rows, n)) * scale
        if rng.random() < 0.3:  # rank-deficient: a few random directions, or none at all
            A = A[:, :1] @ rng.standard_normal((1, n)) if rng.random() < 0.7 else 0 * A
        values[f"t{i}.A"], values[f"t{i}.b"] = A, rng.standard_normal(rows) * scale
    if structure["bounds"]:
        centre, width = rng.standard_normal(n), rng.uniform(0.0, 2.0, n)
        width[rng.random(n) < 0.1] = 0.0  # equal sides: a fixed variable
        values["box.lower"], values["box.upper"] = centre - width, centre + width
        infinite = rng.random(n) < 0.2
        values["box.lower"][infinite], values["box.upper"][infinite] = -np.inf, np.inf
    if structure["rows"]:
        m = structure["rows"]
        C = rng.standard_normal((m, n))
        lower = rng.standard_normal(m) - rng.uniform(0, 2, m)
        upper = lower + rng.uniform(0, 3, m)
        if m > 1 and rng.random() < 0.4:  # duplicated (and possibly contradictory) rows
            C[1] = C[0] * rng.choice([1.0, -1.0, 2.0])
            lower[1], upper[1] = (lower[0], upper[0]) if rng.random() < 0.5 else (5.0, 6.0)
        if rng.random() < 0.1:  # infeasible: an empty interval far away
            lower[0], upper[0] = 1e3, 1e3
        values["rows.C"], values["rows.lower"], values["rows.upper"] = C, lower, upper
    inject(rng, values, defect)
    return values


def inject(rng: np.random.Generator, values: dict, defect: str) -> None:
    """Put ``defect`` into ``values`` (in place)."""
    name = list(values)[int(rng.integers(len(values)))]
    if defect in ("nan", "inf") and values[name].size:
        bad = np.nan if defect == "nan" else rng.choice([np.inf, -np.inf])
        values[name] = values[name].astype(float).copy()
        values[name].flat[int(rng.integers(values[name].size))] = bad
    elif defect == "shape":
        values[name] = np.zeros(np.add(values[name].shape, 1))
    elif defect == "crossed" and "box.lower" in values:
        values["box.lower"], values["box.upper"] = values["box.upper"] + 1.0, values["box.lower"]
    elif defect == "unknown":
        values["nonexistent.A"] = np.zeros(1)
    elif defect == "zero_weight":
        for key in values:
            if key.endswith(".A"):
                values[key] = 0.0 * values[key]


def stack_cases(backend: str, seed: int, structures: int, draws: int, fused: bool = False):
    """Yield ``(case, class, defect, message)`` of the stack family on one backend; with
    ``fused`` (daqp only) each stack runs on a :class:`~wbc.fused.FusedWorkspace` — the fused
    cascade on CasADi's virtual machine (the same function the C build compiles, without a
    compilation per random stack) — labelled ``"daqp (fused)"``."""
    label = f"{backend} (fused)" if fused else backend
    for s in range(structures):
        rng = np.random.default_rng([seed, s])
        structure = random_structure(rng)
        stack = build_stack(structure)
        ws = (FusedWorkspace(stack.compile(), compile=False) if fused
              else stack.workspace(backend))
        for d in range(draws * TICKS):
            defect = str(rng.choice(DEFECTS))
            values = random_values(rng, structure, defect)

            def tick(values=values, ws=ws):
                ws.set(**values)
                # CasADi's virtual machine prints a failed daqp node's inputs through Python
                with silenced():
                    return ws.solve(), ws.variable_bounds()

            case = {"family": "stack", "backend": label, "seed": seed, "structure": s,
                    "tick": d, "injected": defect, "structure_spec": structure}
            yield (case, *classify(tick))


# ---------------------------------------------------------------------------------------------
# robot family


def robot_controller(robot, backend: str, dt: float = 0.01):
    """The velocity-level controller fuzzed on every robot (frame, posture, both limits)."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, name="q_limits"))
    stack.constrain(VelocityLimit(robot, name="v_limits"))
    return wbc.Controller(robot, stack, dt=dt, backend=backend)


def random_state(rng, robot, defect: str):
    """``(q, v, references)`` with ``defect`` injected."""
    lo, up = robot.limits.q_lower, robot.limits.q_upper
    q = robot.neutral().copy()
    arm = np.isfinite(lo) & np.isfinite(up)
    q[arm] = rng.uniform(lo[arm], up[arm])
    v = rng.uniform(robot.limits.v_lower, robot.limits.v_upper) * 0.5
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += rng.uniform(-0.3, 0.3, 3)
    refs = {"ee": target}
    if defect == "nan_q":
        q[int(rng.integers(len(q)))] = np.nan
    elif defect == "outside_limits" and arm.any():
        j = int(rng.choice(np.flatnonzero(arm)))
        q[j] = (up[j] if rng.random() < 0.5 else lo[j]) + rng.choice([-1, 1]) * rng.uniform(0.01, 2)
    elif defect == "short_q":
        q = q[:-1]
    elif defect == "long_v":
        v = np.append(v, 0.0)
    elif defect == "unknown_reference":
        refs["elbow_typo"] = target
    elif defect == "skewed_rotation":
        target[:3, :3] = target[:3, :3] @ (np.eye(3) + rng.uniform(-0.3, 0.3, (3, 3)))
    elif defect == "unreachable":
        target[:3, 3] += rng.choice([-1, 1], 3) * 50.0
    elif defect == "nan_target":
        target[int(rng.integers(3)), 3] = np.nan
    elif defect == "inf_v":
        v[int(rng.integers(len(v)))] = np.inf
    return q, v, refs


def robot_cases(backend: str, seed: int, ticks: int):
    """Yield ``(case, class, defect, message)`` of the robot family on one backend (the
    label is ``"daqp (fused)"`` when the controller takes the fused tick)."""
    for r, name in enumerate(wbc.robots.names()):
        robot = wbc.robots.load(name)
        ctrl = robot_controller(robot, backend)
        label = f"{backend} (fused)" if getattr(ctrl, "fused", False) else backend
        rng = np.random.default_rng([seed, 1000 + r])
        for k in range(ticks):
            defect = str(rng.choice(STATE_DEFECTS))
            q, v, refs = random_state(rng, robot, defect)

            def tick(q=q, v=v, refs=refs, ctrl=ctrl):
                command = ctrl.step(q, v, **refs)
                solution = ctrl.last_solution
                return _Commanded(command, solution), ctrl.workspace.variable_bounds()

            case = {"family": "robot", "backend": label, "seed": seed, "robot": name,
                    "tick": k, "injected": defect}
            yield (case, *classify(tick))


class _Commanded:
    """What a controller tick is judged by: the command it returns (``x``), and its solution's
    status and message."""

    def __init__(self, x, solution):
        self.x, self.status, self.message = x, solution.status, solution.message


# ---------------------------------------------------------------------------------------------


def campaign(cases: int, backends: list[str], seed: int = 0, seconds: float | None = None):
    """Run about ``cases`` cases spread over ``backends`` (a sixth of them robot ticks);
    stops early after ``seconds`` [s]. Returns the JSON-ready result."""
    per_backend = -(-cases // len(backends))  # rounded up: at least ``cases`` in all
    robot_ticks = max(1, per_backend // 6 // len(wbc.robots.names()))
    stack_ticks = per_backend - robot_ticks * len(wbc.robots.names())
    draws = 2
    structures = max(1, -(-stack_ticks // (draws * TICKS)))
    outcomes: dict[str, dict[str, int]] = {}
    defects: list[dict] = []
    total, start = 0, time.perf_counter()
    for backend in backends:
        if seconds is not None and time.perf_counter() - start > seconds:
            break
        families = [stack_cases(backend, seed, structures, draws),
                    robot_cases(backend, seed, robot_ticks)]
        if backend == "daqp":  # the fused cascade too (the robots' controllers take it anyway)
            families.append(stack_cases(backend, seed, structures, draws, fused=True))
        for case, outcome, defect, message in _chain(*families):
            counts = outcomes.setdefault(case["backend"], {"error": 0, "failure": 0,
                                                           "success": 0, "defect": 0})
            counts[outcome] += 1
            total += 1
            if defect:
                defects.append({**case, "defect": defect, "message": message[:500]})
            if seconds is not None and time.perf_counter() - start > seconds:
                break
    return {"cases": total, "outcomes": outcomes, "defects": defects,
            "parameters": {"seed": seed, "backends": backends, "hang_s": HANG_S,
                           "bound_tol": BOUND_TOL, "ticks_per_draw": TICKS,
                           "wall_s": round(time.perf_counter() - start, 1)}}


def _chain(*generators):
    for generator in generators:
        yield from generator


def markdown(result: dict) -> str:
    """The outcome table (rows: backends) and the defects."""
    lines = [f"# wbc fuzz: {result['cases']} cases, {len(result['defects'])} defects", "",
             "| backend | clean error | failure status | success | defect |",
             "|---|---|---|---|---|"]
    for backend, c in result["outcomes"].items():
        lines.append(f"| {backend} | {c['error']} | {c['failure']} | {c['success']} | "
                     f"{c['defect']} |")
    for d in result["defects"]:
        lines.append(f"\n- `{d['backend']}` {d['family']} {d['injected']}: {d['defect']} — "
                     f"{d['message']}")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``wbc fuzz [--cases N] [--backends a,b] [--seconds S] [--seed K] [--out DIR]``."""
    parser = argparse.ArgumentParser(prog="wbc fuzz", description="a seeded fuzz campaign "
                                     "over stacks, workspaces and robot controllers")
    parser.add_argument("--cases", type=int, default=10_000)
    parser.add_argument("--backends", default=",".join(available_backends()))
    parser.add_argument("--seconds", type=float, default=None,
                        help="stop after this wall time [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results"))
    args = parser.parse_args(argv)
    if args.cases < 1:
        parser.error("--cases must be >= 1")
    if args.seconds is not None and not args.seconds > 0:
        parser.error("--seconds must be > 0")
    backends = constructible_backends(parser, args.backends)
    result = campaign(args.cases, backends, args.seed, args.seconds)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "fuzz.json").write_text(json.dumps(result, indent=1, default=_plain))
    (args.out / "fuzz.md").write_text(markdown(result))
    print(markdown(result))
    return 1 if result["defects"] else 0  # a CI gate: defects fail the command


def _plain(value):
    return value.tolist() if isinstance(value, np.ndarray) else str(value)
