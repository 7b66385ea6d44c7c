"""``wbc fuzz``: a seeded fuzz campaign over stacks, workspaces and robot controllers.

Every case is one tick (``Workspace.solve`` or ``Controller.step``) on data with an injected
defect, or on clean random data. Its outcome is classed as

* ``"error"``: a clean :class:`~wbc.WbcError` (the input was refused, with a message);
* ``"failure"``: a solution with a failure status (infeasible, max-iter, numerical);
* ``"success"``: a solved tick;

and it is a **defect** when it raises anything else, returns NaN / inf in ``x`` (any status),
leaves a hard variable bound by more than ``1e-9 · max(1, |bound|)`` on success, or takes more
than 1 s (a hang).

Case families (drawn in proportion, all seeded from ``--seed``; ``--families`` picks some):

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
* ``constructors``: one call of a public constructor or stack method (``wbc.Variables``,
  ``Stack.parameter`` / ``add`` / ``constrain`` / ``set_mobility``, every task of
  ``wbc.tasks`` — built, put in a fitting stack and compiled (a hard one beside a cost) —, the
  robots' loaders ``load`` / ``make_base`` / ``from_urdf`` (an arm on a base, and a whole-robot
  URDF on each kind of root: ``"free_flyer"``, ``"planar"``, ``"fixed"``, a base) /
  ``arm_from_urdf`` / ``arm_from_model``, the collision geometry (``CollisionModel``,
  ``Obstacle.box`` / ``sphere`` / ``capsule``), and a controller's ``set_references``; the
  cases are :func:`constructor_specs`, each valid as given — tested, as is that every task of
  ``wbc.tasks`` has one) with valid arguments and then one or two of them replaced by
  a bad value: NaN, ±inf, a wrong shape, an empty array, a ``str``, ``None``, a ``dict``, a
  complex number, a negative number, a ``bool``, a CasADi symbol, a ragged list, an ``int``
  beyond float's range, zero. Rule: a call that returns is a ``"success"`` (some of these values
  are legal: ``name=None``, ``weight=0``), a :class:`~wbc.WbcError` an ``"error"``, and *any
  other exception is a defect* — the calls pass their arguments by keyword, in the right
  number, so not even a ``TypeError`` is excused. Its outcomes are the row ``"constructors"``.

Where (:mod:`~wbc.experiments.campaigns.cluster`): in this process (the default), on
``--workers N`` local processes or on the Dask cluster of ``--scheduler ADDRESS``; the
campaign is cut into pieces (:func:`plan`: a stack structure's ticks, a robot's ticks, a slice
of the constructor calls), each seeded from ``--seed`` and its place, so the JSON is the same
wherever they ran (the wall time and ``"cluster"`` aside). A piece that raises outside the
classifier, hangs past ``--time-limit`` (on a cluster) or kills its worker is a defect
(``"raised"``, ``"hang"``, ``"killed_worker"``) with its key, seed and a one-line command that
reruns it alone (``--case KEY``); an interrupted campaign leaves ``DIR/fuzz.partial.json``,
which the same command resumes.

Outputs (``--out DIR``): ``DIR/fuzz.json`` with ``"cases"``, ``"outcomes"`` (counts per class
and backend), ``"defects"`` (each with a reproducer: family, backend, seeds, injected defect,
message), ``"parameters"`` and ``"cluster"`` (``"workers"``, ``"scheduler"``, the
``"machine"`` of every worker, ``"batch_cases"``, the ``"attempts"`` of pieces run more than
once); ``DIR/fuzz.md`` the same as a table. Exit code: 0 without defects, 1 with any (2: a
usage error).
"""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

import wbc
import wbc.robots
import wbc.tasks as tasks
from wbc.fused import FusedWorkspace
from wbc.robots import arms
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
from wbc.tasks.manipulability import ManipulabilityAccelerationTask

from ..arguments import (
    add_cluster_arguments,
    cluster_options,
    constructible_backends,
    user_robots_and_stack,
)
from . import cluster

HANG_S = 1.0  # a tick longer than this is a hang [s]
CONSTRUCTOR_MIN = 64  # constructor calls per campaign at least (one per constructor, 57)
FAMILIES = ("stack", "robot", "constructors")  # the case families (module docstring)
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
    for s in range(structures):
        yield from structure_cases(backend, seed, s, draws, fused)


def structure_cases(backend: str, seed: int, s: int, draws: int, fused: bool = False):
    """Yield ``(case, class, defect, message)`` of the stack structure ``s`` (drawn from the
    seed ``[seed, s]``): ``draws * TICKS`` ticks on one workspace (see :func:`stack_cases`)."""
    label = f"{backend} (fused)" if fused else backend
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


def robot_controller(robot, backend: str, dt: float = 0.01, fused: bool | str = "auto",
                     build=None):
    """The velocity-level controller fuzzed on every robot (frame, posture, both limits), or
    the stack ``build(robot)`` of the user's (``--stack``)."""
    if build is not None:
        return wbc.Controller(robot, build(robot), dt=dt, backend=backend, fused=fused)
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"))
    stack.constrain(ConfigurationLimit(robot, name="q_limits"))
    stack.constrain(VelocityLimit(robot, name="v_limits"))
    return wbc.Controller(robot, stack, dt=dt, backend=backend, fused=fused)


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


def catalogue_robots() -> list[tuple[str, Callable]]:
    """``(name, load)`` of every catalogue robot: the robot family's default."""
    return [(name, lambda name=name: wbc.robots.load(name)) for name in wbc.robots.names()]


def robot_cases(backend: str, seed: int, ticks: int, robots: list | None = None,
                build=None):
    """Yield ``(case, class, defect, message)`` of the robot family on one backend (the
    label is ``"daqp (fused)"`` when the controller takes the fused tick). ``robots``:
    ``(name, load)`` pairs (default :func:`catalogue_robots`); ``build(robot) -> Stack``: the
    user's stack instead of the default controller's."""
    for r, (name, load) in enumerate(robots or catalogue_robots()):
        yield from one_robot_cases(backend, seed, ticks, r, name, load, build)


def one_robot_cases(backend: str, seed: int, ticks: int, r: int, name: str, load,
                    build=None):
    """Yield ``(case, class, defect, message)`` of the robot family on the ``r``-th robot
    (``name``, ``load()``; drawn from the seed ``[seed, 1000 + r]``): ``ticks`` ticks of one
    controller (see :func:`robot_cases`)."""
    robot = load()
    ctrl = robot_controller(robot, backend, build=build)
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
# constructor family

BAD_VALUES = ("nan", "inf", "shape", "empty", "str", "none", "dict", "complex", "negative",
              "bool", "symbol", "ragged", "huge", "zero")


def bad_value(rng: np.random.Generator, good, kind: str):
    """A bad value of ``kind`` (:data:`BAD_VALUES`) in place of the valid argument ``good``."""
    arr = None
    if not isinstance(good, (bool, str)):
        try:
            arr = np.asarray(good, dtype=float)
        except (TypeError, ValueError):
            arr = None
    if kind in ("nan", "inf"):
        bad = np.nan if kind == "nan" else float(rng.choice([np.inf, -np.inf]))
        if arr is None or arr.ndim == 0 or not arr.size:
            return bad
        arr = arr.copy()
        arr.flat[int(rng.integers(arr.size))] = bad
        return arr
    if kind == "shape":
        if arr is None or arr.ndim == 0 or rng.random() < 0.3:
            return np.ones((int(rng.integers(1, 5)),) * int(rng.integers(1, 4)))
        return np.ones(tuple(d + int(rng.integers(1, 3)) for d in arr.shape))
    if kind == "empty":
        return np.zeros((0,) * int(rng.integers(1, 3)))
    if kind == "complex":
        return (1.0 if arr is None else arr) * (1 + 1j)
    if kind == "negative":
        return -1.0 if arr is None else -np.abs(arr) - 1.0
    if kind == "symbol":
        return ca.SX.sym("s", int(rng.integers(1, 4)))
    return {"str": "abc", "none": None, "dict": {"a": 1.0}, "bool": True,
            "ragged": [[1.0, 2.0], [3.0]], "huge": 10 ** 400, "zero": 0}[kind]


def _in_stack(build, variables, hard: bool = False):
    """A call that builds a task, adds (or constrains) it in a stack over ``variables`` and
    compiles the stack (a hard one beside a cost over every variable: a stack without a task
    is refused before the constraint's terms are built)."""
    def call(**kwargs):
        stack = wbc.Stack(variables(), damping=1e-3)
        task = build(**kwargs)
        if hard:
            _add_rest(stack)
        (stack.constrain if hard else stack.add)(task)
        stack.compile()
    return call


def _add_rest(stack) -> None:
    """A zero-target cost over the whole decision vector, so that ``stack`` compiles."""
    n = stack.variables.n
    stack.add(LinearTask(np.eye(n), np.zeros(n), name="rest"))


def constructor_specs() -> dict:
    """``name -> (call, valid_kwargs(rng))`` of every constructor the family fuzzes."""
    robot = wbc.robots.load("omni4_arm6")
    nv, n = robot.nv, 4
    ur5 = wbc.robots.urdf_path("ur_description/urdf/ur5_robot.urdf")
    ur5_model = arms.load_urdf_model(str(ur5))
    ctrl = robot_controller(robot, "daqp", fused=False)
    target = robot.frame_pose(robot.neutral(), "ee").copy()
    # whole-robot URDFs for from_urdf(root=...): the 2-joint pendulum (the cheapest to load)
    # on the roots without wheels, the whole Tiago (two drive wheels) on the differential base
    pendulum = wbc.robots.urdf_path("double_pendulum_description/urdf/double_pendulum_simple.urdf")
    tiago = wbc.robots.urdf_path("tiago_description/robots/tiago_no_hand.urdf")
    # collision avoidance on the Panda against one sphere: no self pairs keeps it cheap
    panda = wbc.robots.load_panda()
    panda_srdf = wbc.robots.urdf_path("panda_description/srdf/panda.srdf")
    ball = wbc.robots.Obstacle.sphere("ball", 0.1, position=[0.5, 0.0, 0.5])
    collisions = wbc.robots.CollisionModel(panda, obstacles=[ball], self_collision=False)
    box_pose = np.eye(4)
    box_pose[:3, 3] = [0.55, 0.0, 0.5]

    def on(n_x=n):
        return lambda: wbc.Variables(x=n_x)

    def velocities():
        return wbc.Variables(v=nv)

    def panda_velocities():
        return wbc.Variables(v=panda.nv)

    def safe_displacement(**kwargs):
        stack = wbc.Stack(velocities(), damping=1e-3)
        stack.add(tasks.SafeDisplacement(**kwargs))
        stack.compile()

    def robot_weights(rng):
        return {"robot": robot, "weight": rng.uniform(0.0, 1.0, nv), "name": "w",
                "block": None}

    def stack_method(method):
        def call(**kwargs):
            stack = wbc.Stack(3)
            if method == "constrain":
                _add_rest(stack)
            getattr(stack, method)(**kwargs)
            if method in ("add", "constrain"):
                stack.compile()
        return call

    def wheel_jacobian(rng):
        return rng.standard_normal((4, 3))

    field = {"l0": 0.333, "l1": 0.328, "l2": 0.394, "b_d": 0.27, "k_f": 2.0, "k_r": 2.0,
             "k_omega": 1.0, "delta_f": 0.15, "delta_r": 0.15, "phi_min": 0.5, "phi_max": 0.8,
             "phi_t": 0.5, "epsilon": 0.05, "v_max": 1.0, "omega_max": 1.0, "alpha": 0.25,
             "dv_max": 1.0, "domega_max": 1.0}

    def rate_limit_level(**kwargs):
        stack = wbc.Stack(wbc.Variables(u=2))
        tasks.VelocityField().rate_limit_level(stack, **kwargs)
        stack.compile()

    def share(**kwargs):
        stack = wbc.Stack(wbc.Variables(base=3, arm=2))
        stack.add(tasks.LinearTask(np.eye(5), np.ones(5), name="t"))
        tasks.share_task(stack, **kwargs)
        stack.compile()

    return {
        "Variables": (lambda **kw: wbc.Variables(**kw), lambda rng: {"blocks": {"a": 2, "b": 3}}),
        "Stack.parameter": (stack_method("parameter"), lambda rng: {
            "name": "p", "shape": (2, 3), "default": rng.standard_normal((2, 3)),
            "allow_inf": False}),
        "Stack.add": (stack_method("add"), lambda rng: {
            "task": tasks.LinearTask(np.eye(3), rng.standard_normal(3), name="t"),
            "priority": 0, "weight": 1.0, "scaling": False}),
        "Stack.constrain": (stack_method("constrain"), lambda rng: {
            "task": tasks.Bounds(-1.0, 1.0, name="b"), "levels": None}),
        "Stack.set_mobility": (stack_method("set_mobility"), lambda rng: {
            "mobility": rng.uniform(0.1, 1.0, 3), "levels": None}),
        "LinearTask": (_in_stack(tasks.LinearTask, on()), lambda rng: {
            "A": rng.standard_normal((3, n)), "b": rng.standard_normal(3),
            "weight": 1.0, "name": "t", "block": None}),
        "LinearConstraint": (_in_stack(tasks.LinearConstraint, on(), hard=True), lambda rng: {
            "C": rng.standard_normal((2, n)), "lower": -np.ones(2), "upper": np.ones(2),
            "name": "c", "block": None}),
        "Bounds": (_in_stack(tasks.Bounds, on(), hard=True), lambda rng: {
            "lower": -np.ones(n), "upper": np.ones(n), "name": "b", "block": None}),
        "FrameTask": (_in_stack(tasks.FrameTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "gain": 0.5, "weight": np.ones(6),
            "position_only": False, "lm_damping": 0.1, "name": "ee", "block": None}),
        "PostureTask": (_in_stack(tasks.PostureTask, velocities), lambda rng: {
            "robot": robot, "gain": 0.5, "weight": 1.0, "lm_damping": 0.0, "name": "posture",
            "joints": None, "block": None}),
        "ConfigurationLimit": (_in_stack(tasks.ConfigurationLimit, velocities, hard=True),
                               lambda rng: {"robot": robot, "gain": 0.5, "name": "q_limits",
                                            "joints": None, "block": None}),
        "VelocityLimit": (_in_stack(tasks.VelocityLimit, velocities, hard=True), lambda rng: {
            "robot": robot, "scale": 1.0, "name": "v_limits", "block": None}),
        "RpyPoseTask": (_in_stack(tasks.RpyPoseTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "gain": 1.7, "name": "rpy", "block": None}),
        "JointAccelerationLimit": (_in_stack(tasks.JointAccelerationLimit, velocities,
                                             hard=True), lambda rng: {
            "robot": robot, "dt": 0.01, "method": "viable", "name": "qdd_limits", "joints": None,
            "block": None}),
        "ManipulabilityAccelerationTask": (_in_stack(ManipulabilityAccelerationTask, velocities),
                               lambda rng: {"robot": robot, "frame": "ee", "gamma1": 5.0,
                                            "gamma2": 0.5, "name": "m", "joints": None,
                                            "block": None}),
        "DexterousPosture": (_in_stack(tasks.DexterousPosture, velocities), lambda rng: {
            "robot": robot, "q_dex": rng.uniform(-1, 1, 6), "gain": 3.5, "name": "dex",
            "block": None}),
        "WheelWrench": (_in_stack(tasks.WheelWrench, lambda: wbc.Variables(tau=4), hard=True),
                        lambda rng: {"J": wheel_jacobian(rng), "name": "wrench",
                                     "block": "tau"}),
        "FrictionUtilisation": (_in_stack(tasks.FrictionUtilisation,
                                          lambda: wbc.Variables(tau=4)), lambda rng: {
            "n_wheels": 4, "mu": 0.5, "name": "friction", "parameters": "friction",
            "block": "tau"}),
        "UtilisationBound": (_in_stack(tasks.UtilisationBound,
                                       lambda: wbc.Variables(tau=4, t=1), hard=True),
                             lambda rng: {"n_wheels": 4, "mu": 0.5, "name": "u",
                                          "parameters": "friction", "block": "tau",
                                          "bound": "t"}),
        "distribution_stack": (tasks.distribution_stack, lambda rng: {
            "J": wheel_jacobian(rng), "method": "minmax", "mu": 0.5}),
        "TorqueDistribution": (tasks.TorqueDistribution, lambda rng: {
            "J": wheel_jacobian(rng), "method": "proportional", "mu": 0.5, "backend": "daqp",
            "profile": "default"}),
        "VelocityField": (tasks.VelocityField, lambda rng: dict(field)),
        "VelocityField.rate_limit_level": (rate_limit_level, lambda rng: {
            "priority": 0, "block": None, "name": "rate"}),
        "joint_acceleration_bounds": (tasks.joint_acceleration_bounds, lambda rng: {
            "q": rng.uniform(-0.5, 0.5, 3), "qd": np.zeros(3), "q_min": -1.0, "q_max": 1.0,
            "v_min": -1.0, "v_max": 1.0, "a_min": -2.0, "a_max": 2.0, "dt": 0.01,
            "method": "xing"}),
        "sharing_factor": (tasks.sharing_factor, lambda rng: {
            "error_norm": ca.SX.sym("e"), "r_fm": 0.25, "r_mm": 0.9}),
        "share_task": (share, lambda rng: {"psi": 0.5, "n_base": 3, "priority": 0}),
        "ArmCompensation": (tasks.ArmCompensation, lambda rng: {
            "n_arm": 3, "rows": 6, "backend": "daqp", "profile": "default"}),
        "ComTask": (_in_stack(tasks.ComTask, velocities), lambda rng: {
            "robot": robot, "gain": 0.5, "weight": np.ones(3), "lm_damping": 0.0,
            "name": "centre", "block": None}),
        "RelativeFrameTask": (_in_stack(tasks.RelativeFrameTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "root": "base_link", "gain": 0.5,
            "weight": np.ones(6), "lm_damping": 0.0, "name": "relative", "block": None}),
        "DampingTask": (_in_stack(tasks.DampingTask, velocities), robot_weights),
        "JointVelocityTask": (_in_stack(tasks.JointVelocityTask, velocities), robot_weights),
        "LowAccelerationTask": (_in_stack(tasks.LowAccelerationTask, velocities),
                                robot_weights),
        "JointCouplingTask": (_in_stack(tasks.JointCouplingTask, velocities), lambda rng: {
            "robot": robot, "joints": ["shoulder_lift_joint", "elbow_joint"],
            "ratios": [1.0, -0.5], "gain": 0.5, "weight": 1.0, "lm_damping": 0.0,
            "name": "coupling", "block": None}),
        "DofFreezing": (_in_stack(tasks.DofFreezing, velocities, hard=True), lambda rng: {
            "robot": robot, "dofs": ["vx", 4], "form": str(rng.choice(["bounds", "equality"])),
            "name": "frozen", "block": None}),
        "KineticEnergyRegularizationTask": (_in_stack(tasks.KineticEnergyRegularizationTask,
                                                      velocities), lambda rng: {
            "robot": robot, "weight": 1e-3, "name": "energy", "block": None}),
        "AccelerationLimit": (_in_stack(tasks.AccelerationLimit, velocities, hard=True),
                              lambda rng: {"robot": robot, "a_max": np.full(nv, 5.0),
                                           "method": "viable", "name": "a_limits",
                                           "joints": None, "block": None}),
        "PositionBarrier": (_in_stack(tasks.PositionBarrier, velocities, hard=True),
                            lambda rng: {"robot": robot, "frame": "ee",
                                         "p_min": [-2.0, -2.0, 0.0], "p_max": [2.0, 2.0, 2.0],
                                         "indices": [0, 1, 2], "gain": np.ones(3),
                                         "safe_displacement_gain": 1.0, "name": "box",
                                         "block": None}),
        "SafeDisplacement": (safe_displacement, lambda rng: {
            "barrier": tasks.PositionBarrier(robot, "ee", p_max=[2.0, 2.0, 2.0],
                                             safe_displacement_gain=1.0, name="box"),
            "name": "safe"}),
        "BodySphericalBarrier": (_in_stack(tasks.BodySphericalBarrier, velocities, hard=True),
                                 lambda rng: {"robot": robot, "frames": ("ee", "base_link"),
                                              "d_min": 0.2, "gain": 1.0,
                                              "safe_displacement_gain": 3.0, "name": "sphere",
                                              "block": None}),
        "AxisAlignTask": (_in_stack(tasks.AxisAlignTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "axis": (0.0, 0.0, 1.0), "gain": 0.5,
            "weight": np.ones(3), "lm_damping": 0.0, "name": "axis", "block": None}),
        "LookAtTask": (_in_stack(tasks.LookAtTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "axis": (1.0, 0.0, 0.0), "gain": 0.5,
            "weight": np.ones(3), "lm_damping": 1e-3, "name": "gaze", "block": None}),
        "ManipulabilityTask": (_in_stack(tasks.ManipulabilityTask, velocities), lambda rng: {
            "robot": robot, "frame": "ee", "rate": 0.1, "weight": 1.0, "lm_damping": 0.0,
            "name": "manipulability", "joints": None, "block": None}),
        "CollisionAvoidance": (_in_stack(tasks.CollisionAvoidance, panda_velocities,
                                         hard=True), lambda rng: {
            "robot": panda, "pairs": collisions, "d_min": 0.02, "gain": 0.5, "max_pairs": 2,
            "name": "collision", "block": None}),
        "robots.load": (wbc.robots.load, lambda rng: {"name": "omni4_arm6"}),
        "robots.make_base": (wbc.robots.make_base, lambda rng: {"name": "mecanum"}),
        "robots.from_urdf": (wbc.robots.from_urdf, lambda rng: {
            "urdf": ur5, "base": "omni", "ee_frame": "tool0", "mount": np.eye(4),
            "name": "r", "locked_joints": (), "v_max": np.ones(6), "a_max": np.ones(6),
            "home": np.zeros(6)}),
        "robots.from_urdf(root=free_flyer)": (wbc.robots.from_urdf, lambda rng: {
            "urdf": pendulum, "root": "free_flyer", "ee_frame": "link2", "name": "pendulum",
            "locked_joints": (), "v_max": np.ones(2), "a_max": np.ones(2),
            "home": np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.1, 0.2])}),
        "robots.from_urdf(root=planar)": (wbc.robots.from_urdf, lambda rng: {
            "urdf": pendulum, "root": "planar", "ee_frame": "link2", "name": "pendulum",
            "locked_joints": (), "v_max": np.ones(2), "a_max": np.ones(2),
            "home": np.zeros(5)}),
        "robots.from_urdf(root=fixed)": (wbc.robots.from_urdf, lambda rng: {
            "urdf": pendulum, "root": "fixed", "ee_frame": "link2", "name": "pendulum",
            "locked_joints": ("joint2",), "v_max": np.ones(1), "a_max": np.ones(1),
            "home": np.zeros(1)}),
        "robots.from_urdf(root=differential)": (wbc.robots.from_urdf, lambda rng: {
            "urdf": tiago, "root": "differential", "ee_frame": "arm_tool_link",
            "name": "tiago", "locked_joints": ("head_1_joint", "head_2_joint"),
            "v_max": np.ones(8), "a_max": np.ones(8), "home": None}),
        "robots.CollisionModel": (wbc.robots.CollisionModel, lambda rng: {
            "robot": panda, "urdf": panda.urdf_path, "srdf": panda_srdf, "pairs": None,
            "obstacles": [ball], "self_collision": bool(rng.random() < 0.5), "convex": True,
            "package_dirs": ()}),
        "robots.Obstacle.box": (wbc.robots.Obstacle.box, lambda rng: {
            "name": "wall", "size": (0.05, 1.0, 1.0), "pose": box_pose.copy()}),
        "robots.Obstacle.sphere": (wbc.robots.Obstacle.sphere, lambda rng: {
            "name": "ball", "radius": 0.1, "position": rng.uniform(-1, 1, 3), "pose": None}),
        "robots.Obstacle.capsule": (wbc.robots.Obstacle.capsule, lambda rng: {
            "name": "rod", "radius": 0.05, "length": 0.4, "pose": box_pose.copy()}),
        "arms.arm_from_urdf": (arms.arm_from_urdf, lambda rng: {
            "path": ur5, "ee_frame": "tool0", "name": "ur5", "locked_joints": (),
            "locked_values": None, "v_max": np.ones(6), "a_max": np.ones(6),
            "home": np.zeros(6)}),
        "arms.arm_from_model": (arms.arm_from_model, lambda rng: {
            "model": ur5_model, "ee_frame": "tool0", "name": "ur5", "v_max": np.ones(6),
            "a_max": np.ones(6), "home": np.zeros(6)}),
        "Controller.set_references": (ctrl.set_references, lambda rng: {
            "ee": target.copy(), "posture": robot.neutral()}),
    }


def constructor_cases(seed: int, count: int, start: int = 0, specs: dict | None = None):
    """Yield ``(case, class, defect, message)`` of the constructor family: ``count`` calls,
    round-robin over :func:`constructor_specs`, each with one or two arguments replaced by a
    bad value (one call in ten keeps its valid arguments), all drawn from the seed
    ``[seed, 2000]``. ``start``: yield the calls from the ``start``-th on only (the arguments
    of the earlier ones are still drawn, not called: the same calls as in one stream);
    ``specs``: :func:`constructor_specs` if built already."""
    specs = constructor_specs() if specs is None else specs
    names = list(specs)
    rng = np.random.default_rng([seed, 2000])
    for k in range(count):
        name = names[k % len(names)]
        call, valid = specs[name]
        kwargs = valid(rng)
        injected = {}
        if rng.random() >= 0.1:
            for argument in rng.choice(list(kwargs), size=min(len(kwargs), int(
                    rng.integers(1, 3))), replace=False):
                kind = str(rng.choice(BAD_VALUES))
                kwargs[str(argument)] = bad_value(rng, kwargs[str(argument)], kind)
                injected[str(argument)] = kind
        if k < start:
            continue
        outcome, defect, message = classify_call(call, kwargs)
        case = {"family": "constructors", "backend": "constructors", "seed": seed,
                "constructor": name, "call": k,
                "injected": ", ".join(f"{a}={v}" for a, v in injected.items()) or "none"}
        yield case, outcome, defect, message


def classify_call(call, kwargs: dict) -> tuple[str, str | None, str]:
    """Class one constructor call ``call(**kwargs)``: ``"success"``, ``"error"`` (a
    :class:`~wbc.WbcError`) or a ``"defect"`` (any other exception)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            call(**kwargs)
    except wbc.WbcError as exc:
        return "error", None, f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # what the family looks for
        return "defect", "exception", f"{type(exc).__name__}: {exc}"
    return "success", None, "built"


# ---------------------------------------------------------------------------------------------


def campaign(cases: int, backends: list[str], seed: int = 0, seconds: float | None = None,
             robots: list | None = None, build=None, families=FAMILIES, *,
             workers: int | None = None, scheduler: str | None = None,
             out: Path | None = None, time_limit: float = cluster.TIME_LIMIT_S,
             only: str | None = None, progress: bool = True, robot_files=()):
    """Run about ``cases`` cases: a twentieth of them (at least :data:`CONSTRUCTOR_MIN`, one
    per constructor) constructor calls, the rest spread over ``backends`` (a sixth of them robot
    ticks); stops early after ``seconds`` [s]. ``robots`` and ``build``: the robot family's
    robots and stack (see :func:`robot_cases`). ``families``: the case families run (a subset
    of :data:`FAMILIES`; ``("constructors",)`` alone spends every case on constructor calls).

    Where: in this process, or on Dask — ``workers`` local processes or the cluster at
    ``scheduler`` — in the pieces of :func:`plan` (:mod:`~wbc.experiments.campaigns.cluster`:
    the same result wherever they run); ``out``: the folder of ``fuzz.partial.json`` (finished
    pieces, resumed by a rerun); ``time_limit``: of one piece on a cluster [s]; ``only``: the
    key of one piece to run alone (its reproduction). A piece that raises, hangs or kills its
    workers is a defect with its seed and a reproduction command (``robot_files``: the
    ``--robot`` files the robots came from, for that command).
    Returns the JSON-ready result."""
    families = tuple(families)
    unknown = sorted(set(families) - set(FAMILIES))
    if unknown or not families:
        raise wbc.InvalidValueError(f"families must be a non-empty subset of {list(FAMILIES)}, "
                                    f"got {list(families)}")
    robots = robots or catalogue_robots()
    identity = {"cases": cases, "backends": list(backends), "seed": seed,
                "families": list(families), "robots": [name for name, _ in robots],
                "stack": getattr(build, "spec", None), "robot_files": list(robot_files)}
    start = time.perf_counter()
    pieces, finished = cluster.run_campaign(
        run_piece, plan(cases, backends, seed, families, [name for name, _ in robots]),
        name="fuzz", robots=robots, build=build, identity=identity, only=only,
        keys_hint="'stack/daqp/3', 'robot/daqp/tiago_panda', 'constructors/0'", out=out,
        workers=workers, scheduler=scheduler, time_limit=time_limit, seconds=seconds,
        progress=progress)
    failures = {failure["index"]: failure for failure in finished.failures}
    outcomes: dict[str, dict[str, int]] = {}
    defects: list[dict] = []
    families_count: dict[str, int] = {}
    total = 0
    for index, (piece, result) in enumerate(zip(pieces, finished.results, strict=True)):
        if index in failures:
            defects.append(_failure_defect(piece, failures[index], identity))
        if result is None:
            continue
        for label, counts in result["outcomes"].items():
            mine = outcomes.setdefault(label, {"error": 0, "failure": 0, "success": 0,
                                               "defect": 0})
            for outcome, n in counts.items():
                mine[outcome] += n
        for family, n in result["families"].items():
            families_count[family] = families_count.get(family, 0) + n
        total += result["cases"]
        defects.extend(result["defects"])
    return {"cases": total, "families": families_count, "outcomes": outcomes,
            "defects": defects,
            "parameters": {"seed": seed, "backends": backends, "families": list(families),
                           "hang_s": HANG_S,
                           "robots": [name for name, _ in robots],
                           "stack": getattr(build, "spec", None),
                           "bound_tol": BOUND_TOL, "ticks_per_draw": TICKS,
                           "wall_s": round(time.perf_counter() - start, 1)},
            "cluster": finished.cluster}


CONSTRUCTOR_PIECE = 128  # constructor calls per piece of a campaign (see plan)


def plan(cases: int, backends: list[str], seed: int, families=FAMILIES,
         robots: list[str] | None = None) -> list[dict]:
    """The pieces of a campaign, in the order their cases are counted — each a JSON-ready dict
    with a ``"key"`` and the ``"seed"`` its random generator is drawn from:

    * ``constructors/K``: the constructor calls ``K ..`` (at most :data:`CONSTRUCTOR_PIECE`)
      of the one stream ``[seed, 2000]``;
    * per backend, ``stack/BACKEND/S``: the ticks of stack structure ``S`` (seed ``[seed, S]``),
      ``robot/BACKEND/NAME``: a robot's ticks (seed ``[seed, 1000 + r]``), and on daqp
      ``fused/daqp/S``: structure ``S`` on the fused cascade.

    ``robots``: the robot family's robot names (default: the catalogue)."""
    robots = list(wbc.robots.names()) if robots is None else robots
    solved = [f for f in ("stack", "robot") if f in families]  # the families on a backend
    constructor_calls = 0
    if "constructors" in families:
        constructor_calls = max(CONSTRUCTOR_MIN, cases // 20) if solved else max(1, cases)
    per_backend = max(1, -(-(cases - constructor_calls) // len(backends)))  # rounded up
    robot_ticks = 0
    if "robot" in families:
        robot_ticks = max(1, per_backend // (6 if "stack" in families else 1) // len(robots))
    stack_ticks = per_backend - robot_ticks * len(robots)
    draws = 2
    structures = max(1, -(-stack_ticks // (draws * TICKS)))
    pieces: list[dict] = [
        {"key": f"constructors/{k}", "seed": [seed, 2000], "family": "constructors",
         "backend": "constructors", "start": k,
         "stop": min(constructor_calls, k + CONSTRUCTOR_PIECE)}
        for k in range(0, constructor_calls, CONSTRUCTOR_PIECE)]
    for backend in backends if solved else ():
        if "stack" in families:
            pieces += [{"key": f"stack/{backend}/{s}", "seed": [seed, s], "family": "stack",
                        "backend": backend, "structure": s, "draws": draws, "fused": False}
                       for s in range(structures)]
        if "robot" in families:
            pieces += [{"key": f"robot/{backend}/{name}", "seed": [seed, 1000 + r],
                        "family": "robot", "backend": backend, "robot": r, "ticks": robot_ticks}
                       for r, name in enumerate(robots)]
        if backend == "daqp" and "stack" in families:  # the fused cascade too
            pieces += [{"key": f"fused/{backend}/{s}", "seed": [seed, s], "family": "stack",
                        "backend": f"{backend} (fused)", "structure": s, "draws": draws,
                        "fused": True} for s in range(structures)]
    return pieces


def run_piece(context: dict, piece: dict, deadline: float | None = None) -> dict:
    """Run one piece of :func:`plan` (on whichever process): its counts per backend label and
    class, its cases per family, its defects; ``"stopped"`` when ``time.time()`` passed
    ``deadline`` before its last case."""
    robots, build = cluster.user_inputs(context)
    seed = piece["seed"][0]
    if piece["family"] == "constructors":
        specs = cluster.cached(context, "specs", constructor_specs)
        cases = constructor_cases(seed, piece["stop"], piece["start"], specs)
    elif piece["family"] == "stack":
        backend = piece["backend"].removesuffix(" (fused)")
        cases = structure_cases(backend, seed, piece["structure"], piece["draws"],
                                piece["fused"])
    else:
        name, load = robots[piece["robot"]]
        cases = one_robot_cases(piece["backend"], seed, piece["ticks"], piece["robot"], name,
                                load, build)
    outcomes: dict[str, dict[str, int]] = {}
    families: dict[str, int] = {}
    defects: list[dict] = []
    total, stopped = 0, False
    for case, outcome, defect, message in cases:
        counts = outcomes.setdefault(case["backend"], {"error": 0, "failure": 0,
                                                       "success": 0, "defect": 0})
        counts[outcome] += 1
        families[case["family"]] = families.get(case["family"], 0) + 1
        total += 1
        if defect:
            defects.append({**case, "defect": defect, "message": message[:500]})
        if deadline is not None and time.time() > deadline:
            stopped = True
            break
    return {"cases": total, "outcomes": outcomes, "families": families, "defects": defects,
            "stopped": stopped}


def reproduce_command(identity: dict, key: str) -> str:
    """The one-line command that reruns the piece ``key`` of a campaign in one process."""
    return cluster.reproduction("wbc fuzz", {
        "--cases": identity["cases"], "--backends": ",".join(identity["backends"]),
        "--families": ",".join(identity["families"]), "--seed": identity["seed"],
        "--robot": identity.get("robot_files") or None, "--stack": identity["stack"],
        "--out": "fuzz_case"}, key)


def _failure_defect(piece: dict, failure: dict, identity: dict) -> dict:
    """A defect entry for a piece that raised, hung or killed its workers."""
    return {"family": piece["family"], "backend": piece["backend"], "seed": identity["seed"],
            "case": piece["key"], "case_seed": piece["seed"], "injected": "-",
            "defect": failure["failure"], "message": failure["message"],
            "attempts": failure["attempts"],
            "reproduce": reproduce_command(identity, piece["key"])}


def markdown(result: dict) -> str:
    """The outcome table (rows: backends) and the defects."""
    families = ", ".join(f"{k} {v}" for k, v in result.get("families", {}).items())
    lines = [f"# wbc fuzz: {result['cases']} cases, {len(result['defects'])} defects", "",
             *([f"Cases per family: {families} (the row `constructors` is that family: "
                "no solver).", ""] if families else []),
             "| backend | clean error | failure status | success | defect |",
             "|---|---|---|---|---|"]
    for backend, c in result["outcomes"].items():
        lines.append(f"| {backend} | {c['error']} | {c['failure']} | {c['success']} | "
                     f"{c['defect']} |")
    for d in result["defects"]:
        lines.append(f"\n- `{d['backend']}` {d['family']} {d['injected']}: {d['defect']} — "
                     f"{d['message']}")
        if "reproduce" in d:  # a piece that raised, hung or killed its workers
            lines.append(f"  (case `{d['case']}`, seed {d['case_seed']}, "
                         f"{d['attempts']} attempt(s); rerun: `{d['reproduce']}`)")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``wbc fuzz [--cases N] [--backends a,b] [--families f,g] [--seconds S] [--seed K]
    [--out DIR] [--workers N | --scheduler ADDRESS] [--time-limit S] [--case KEY]``."""
    parser = argparse.ArgumentParser(prog="wbc fuzz", description="a seeded fuzz campaign "
                                     "over stacks, workspaces and robot controllers")
    parser.add_argument("--cases", type=int, default=10_000)
    parser.add_argument("--backends", default=",".join(available_backends()))
    parser.add_argument("--seconds", type=float, default=None,
                        help="stop after this wall time [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--families", default=",".join(FAMILIES),
                        help="the case families to run, comma-separated (default: all); "
                             "'constructors' alone spends every case on constructor calls")
    parser.add_argument("--robot", action="append", default=[], metavar="FILE.toml",
                        help="the robot family on a robot of your own (TOML description; "
                             "repeatable) instead of the catalogue")
    parser.add_argument("--stack", default=None, metavar="MODULE:FUNCTION",
                        help="the robot family's controller from a stack of your own: "
                             "function(robot) -> wbc.Stack with a frame task named 'ee'")
    parser.add_argument("--out", type=Path, default=Path("results"))
    add_cluster_arguments(parser)
    args = parser.parse_args(argv)
    where = cluster_options(parser, args)
    if args.cases < 1:
        parser.error("--cases must be >= 1")
    if args.seconds is not None and not args.seconds > 0:
        parser.error("--seconds must be > 0")
    families = tuple(f.strip() for f in args.families.split(",") if f.strip())
    if not families or set(families) - set(FAMILIES):
        parser.error(f"--families must be a comma-separated subset of {','.join(FAMILIES)}, "
                     f"got {args.families!r}")
    backends = constructible_backends(parser, args.backends)
    robot_files = [os.path.abspath(path) for path in args.robot]  # workers: any directory
    robots, build = user_robots_and_stack(robot_files, args.stack)
    result = campaign(args.cases, backends, args.seed, args.seconds, robots, build, families,
                      out=args.out, robot_files=robot_files, **where)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "fuzz.json").write_text(json.dumps(result, indent=1, default=_plain))
    (args.out / "fuzz.md").write_text(markdown(result))
    print(markdown(result))
    return 1 if result["defects"] else 0  # a CI gate: defects fail the command


def _plain(value):
    return value.tolist() if isinstance(value, np.ndarray) else str(value)
