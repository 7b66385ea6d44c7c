"""``wbc exactness``: is every backend's command the exact lexicographic answer, on every state,
limits saturating included, with no false failures? (issue #21)

Each *state* (a configuration and the task targets) is solved by an exact **referee** — the
ordinary (non-fused) cascade on quadprog and on clarabel, both with the ``"tight"`` profile — and
by every backend *variant* under test, each a :class:`wbc.Controller` built once per (robot,
stack, variant) and reused over that robot's states (warm starts kept, as in a closed loop).
A state counts (*agreed*) when both referees solve every level and their commands are within
:data:`AGREE` (1e-6, max-abs, rad/s or m/s) of each other; the reference command ``v_ref`` is
quadprog's. Per variant and state: *full success* (``solution.ok``: every level solved), *false
failure* (not solved where the referees solve), *partial* (a lower level failed, the levels above
commanded), *error* (an exception), and the deviation ``max|v − v_ref|`` of the command.

Families (each deterministic from ``seed``):

* ``random`` — every catalogue robot (:func:`wbc.robots.names`); ``q`` = ``robot.neutral()``
  plus N(0, 0.6) (rad, or m for base x, y) on each coordinate with probability 0.7, clipped into
  the position limits; targets = the current ``"ee"`` pose moved by N(0, 0.25) m per axis and
  rotated by U(0.25, 0.75) rad about a random axis. Stacks ``one`` (frame + posture with weight
  1e-2 on one level), ``two`` (frame ≻ posture), ``three`` (position ≻ orientation ≻ posture;
  the orientation task is a :class:`~wbc.tasks.FrameTask` with zero weight on its three
  position rows); gain 0.5, both limits (:class:`~wbc.tasks.ConfigurationLimit`,
  :class:`~wbc.tasks.VelocityLimit`), damping 1e-3, ``dt`` = :data:`DT`. One tick per state.
* ``saturating`` — the arms of :data:`ARMS` (example-robot-data URDFs) mounted 0.35 m above
  every distinct base of :func:`wbc.robots.base_names` (aliases of one base model run once);
  frame ≻ posture (gain 0.5), both limits, closed loops from ``neutral()`` toward four targets
  (:func:`saturating_targets`: near, 1.5 m ahead, to the side and turned, 2.6 m high —
  unreachable), ``dt`` = :data:`LOOP_DT`. Every tick is a state; the loop integrates the
  referee's command (``q ← robot.integrate(q, v_ref, dt)``), so the states are the exact
  trajectory, and every variant answers on that same state.
* ``priorities`` — every catalogue robot, position ≻ pose ≻ posture (frame gains 5, so a velocity
  bound is active on every tick), both limits, closed loops as above from a ``random``-family
  start toward targets 1–2.5 m away (random direction) turned by U(0.3, 1.0) rad.

Variants are ``<backend>[/tight][/ordinary]``: ``<backend>`` any name
:func:`wbc.solvers.make_backend` accepts, ``tight`` the tolerance profile (else ``"default"``),
``ordinary`` forces ``fused=False`` (else the controller's default: the fused tick for daqp).
The result records per variant whether the controller took the fused path (``"fused"``).

Output (``--out DIR``): ``DIR/exactness.json`` — ``{family: {variant: stats}}`` with, per
variant, ``states`` (in the family), ``agreed`` (compared), ``full_success``,
``full_success_rate`` (of agreed), ``false_failures``, ``partial``, ``errors``,
``max_deviation`` / ``p99_deviation`` (over agreed states, failed ones included),
``max_deviation_solved`` (fully solved ones only), ``over_tol`` (agreed states deviating by more
than :data:`TOL`), ``failed_unrefereed`` (states where the
referees solve but disagree, and the variant does not solve), ``median_tick_us``,
``max_tick_ms``, ``fused``, ``fused_fallbacks`` (ticks of a fused controller solved on the
ordinary path: its call failed, or was skipped after failures),
``worst`` (where the largest deviation was), ``first_false_failure``; plus ``"referee"`` (per
family: states, agreed, disagreements, referee failures, the largest referee gap, the share of
agreed states with a velocity / position-limit bound active in ``v_ref``) and ``"parameters"``;
``DIR/exactness.md`` as tables. Exit code 0 when no variant has a false failure or a
deviation above ``--tol`` on the exact variants (:data:`EXACT`), else 1.
"""

from __future__ import annotations

import argparse
import json
import math
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

import wbc
import wbc.robots
from wbc.solvers import available_backends
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

from ..arguments import constructible_backends
from ..progress import report_progress

DT = 0.01  # control period of the random states [s]
LOOP_DT = 0.05  # control period of the closed loops [s] (long enough to reach position limits)
AGREE = 1e-6  # referees agree when max|v_quadprog − v_clarabel| <= AGREE [rad/s or m/s]
TOL = 1e-5  # the deviation allowed to an exact variant by the CLI's exit code [rad/s or m/s]
ACTIVE = 1e-9  # a bound is active when v is within ACTIVE·(1 + |bound|) of it
REFEREES = ("quadprog", "clarabel")
FAMILIES = ("random", "saturating", "priorities")
STACKS = ("one", "two", "three")
#: Variants whose answer is exact (active-set solvers, or "tight" profiles): the CLI's gate.
EXACT = ("daqp", "daqp/tight", "daqp/ordinary", "daqp/tight/ordinary", "quadprog",
         "quadprog/tight", "qpoases", "clarabel/tight")
#: The default variants: every daqp path and profile, then every installed backend. Not
#: ``proxqp/tight``: its profile allows 10⁵ iterations, and one saturating tick of the
#: ``saturating`` family (ur5 on the omni base) ran for more than 10 minutes.
DEFAULT_VARIANTS = ("daqp", "daqp/tight", "daqp/ordinary", "daqp/tight/ordinary", "quadprog",
                    "clarabel", "osqp", "osqp/tight", "proxqp", "qpoases", "casadi:osqp",
                    "qpsolvers:daqp")
#: Arms of the ``saturating`` family: name -> (example-robot-data URDF, end-effector frame);
#: the Panda is :func:`wbc.robots.panda` (its URDF with the fingers locked).
ARMS = {"panda": (None, None),
        "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
        "kinova_j2s6s200": ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
        "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef")}
MOUNT_HEIGHT = 0.35  # arm root above the base frame [m]


# ---------------------------------------------------------------------------- variants
def parse_variant(spec: str) -> tuple[str, str, bool]:
    """``"<backend>[/tight][/ordinary]"`` -> ``(backend, profile, ordinary)``.

    Raises:
        ValueError: an unknown suffix.
    """
    backend, *tokens = spec.split("/")
    unknown = [t for t in tokens if t not in ("tight", "ordinary")]
    if unknown or not backend:
        raise ValueError(f"variant {spec!r}: use <backend>[/tight][/ordinary]")
    return backend, "tight" if "tight" in tokens else "default", "ordinary" in tokens


def make_controller(robot, stack: wbc.Stack, spec: str, dt: float) -> wbc.Controller:
    """The controller of variant ``spec`` (see the module docstring) with period ``dt`` [s]."""
    backend, profile, ordinary = parse_variant(spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # no C compiler: today's path, reported
        return wbc.Controller(robot, stack, backend=backend, profile=profile, dt=dt,
                              fused=False if ordinary else "auto")


def make_referee(robot, stack: wbc.Stack, backend: str, dt: float) -> wbc.Controller:
    """A referee: the ordinary cascade on ``backend`` with the ``"tight"`` profile."""
    return wbc.Controller(robot, stack, backend=backend, profile="tight", dt=dt, fused=False)


# ---------------------------------------------------------------------------- stacks
def build_stack(robot, kind: str, gain: float = 0.5) -> tuple[wbc.Stack, tuple[str, ...]]:
    """A fresh stack and the names of its frame tasks (each takes the ``"ee"`` target).

    Kinds: ``"one"`` — frame + posture (weight 1e-2) on one level; ``"two"`` — frame ≻ posture;
    ``"three"`` — position ≻ orientation ≻ posture; ``"pose3"`` — position ≻ pose ≻ posture.
    Frame tasks have ``gain`` [-], the posture gain 0.5 and weight 1e-2; hard
    :class:`~wbc.tasks.ConfigurationLimit` (gain 0.5) and :class:`~wbc.tasks.VelocityLimit`;
    damping 1e-3 on every level.
    """
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    posture = PostureTask(robot, gain=0.5, weight=1e-2, name="posture")
    if kind in ("one", "two"):
        stack.add(FrameTask(robot, "ee", gain=gain, name="ee"), priority=0)
        stack.add(posture, priority=0 if kind == "one" else 1)
        frames: tuple[str, ...] = ("ee",)
    elif kind in ("three", "pose3"):
        stack.add(FrameTask(robot, "ee", gain=gain, position_only=True, name="position"),
                  priority=0)
        name = "orientation" if kind == "three" else "pose"
        second = (FrameTask(robot, "ee", gain=gain, weight=[0, 0, 0, 1, 1, 1],
                            name=name) if kind == "three" else
                  FrameTask(robot, "ee", gain=gain, name=name))
        stack.add(second, priority=1)
        stack.add(posture, priority=2)
        frames = ("position", name)
    else:
        raise ValueError(f"unknown stack kind {kind!r}")
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack, frames


# ---------------------------------------------------------------------------- states
def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of ``angle`` [rad] about ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def random_configuration(rng: np.random.Generator, robot) -> np.ndarray:
    """``neutral()`` + N(0, 0.6) on ~70 % of the coordinates, clipped into the limits."""
    q = robot.neutral().copy()
    mask = rng.random(q.size) < 0.7
    q += mask * rng.normal(0.0, 0.6, q.size)
    return np.clip(q, robot.limits.q_lower, robot.limits.q_upper)


def moved(rng: np.random.Generator, T: np.ndarray, distance: float | None,
          angle: tuple[float, float]) -> np.ndarray:
    """``T`` moved by N(0, 0.25) m per axis (``distance=None``) or by ``distance`` [m] in a
    random direction, and turned by U(``angle``) rad about a random axis (world frame)."""
    out = T.copy()
    if distance is None:
        out[:3, 3] += rng.normal(0.0, 0.25, 3)
    else:
        direction = rng.standard_normal(3)
        out[:3, 3] += distance * direction / np.linalg.norm(direction)
    out[:3, :3] = rotation(rng.standard_normal(3), rng.uniform(*angle)) @ T[:3, :3]
    return out


def saturating_targets(robot) -> dict[str, np.ndarray]:
    """The four targets of the ``saturating`` family, from the ``"ee"`` pose at ``neutral()``:
    ``near`` (+(0.1, 0.05, −0.05) m), ``ahead`` (+1.5 m along x), ``side`` (+1.2 m along y,
    turned π/2 about z and 0.5 rad about x), ``high`` (z = 2.6 m: out of reach)."""
    T0 = robot.frame_pose(robot.neutral(), "ee").copy()
    near, ahead, side, high = (T0.copy() for _ in range(4))
    near[:3, 3] += [0.1, 0.05, -0.05]
    ahead[0, 3] += 1.5
    side[1, 3] += 1.2
    side[:3, :3] = rotation(np.array([0.0, 0, 1]), math.pi / 2) \
        @ rotation(np.array([1.0, 0, 0]), 0.5) @ T0[:3, :3]
    high[2, 3] = 2.6
    return {"near": near, "ahead": ahead, "side": side, "high": high}


def distinct_bases() -> list[str]:
    """:func:`wbc.robots.base_names` without aliases (the first name of each base model)."""
    seen, out = set(), []
    for name in wbc.robots.base_names():
        kind = type(wbc.robots.make_base(name)).__name__
        if kind not in seen:
            seen.add(kind)
            out.append(name)
    return out


def make_arm_robot(arm: str, base: str):
    """Arm ``arm`` of :data:`ARMS` on base ``base``, its root :data:`MOUNT_HEIGHT` above."""
    from wbc.robots.resources import urdf_path

    mount = np.eye(4)
    mount[2, 3] = MOUNT_HEIGHT
    path, ee = ARMS[arm]
    source = wbc.robots.panda() if path is None else urdf_path(path)
    return wbc.robots.from_urdf(source, base=base, ee_frame=ee, mount=mount,
                                name=f"{arm}@{base}")


@dataclass
class Cell:
    """One robot and stack of a family, and how its states come.

    ``states`` yields ``(label, q, target)`` for independent states; ``loops`` yields
    ``(label, q0, target, ticks)`` for closed loops (each tick a state).
    """

    family: str
    label: str
    robot: Callable[[], wbc.robots.Robot]
    kind: str
    gain: float
    dt: float
    states: Callable[[wbc.robots.Robot], Iterator] | None = None
    loops: Callable[[wbc.robots.Robot], Iterator] | None = None


def cells(states: int, seed: int) -> dict[str, list[Cell]]:
    """The cells of every family, sized for about ``states`` states per family (rounded up)."""
    robots = wbc.robots.names()
    out: dict[str, list[Cell]] = {f: [] for f in FAMILIES}

    per_cell = -(-states // (len(robots) * len(STACKS)))
    for r, name in enumerate(robots):
        for k, kind in enumerate(STACKS):
            def independent(robot, r=r, k=k):
                rng = np.random.default_rng([seed, 0, r, k])
                for i in range(per_cell):
                    q = random_configuration(rng, robot)
                    T = moved(rng, robot.frame_pose(q, "ee"), None, (0.25, 0.75))
                    yield f"#{i}", q, T
            out["random"].append(Cell("random", f"{name}/{kind}", partial(wbc.robots.load, name),
                                      kind, 0.5, DT, states=independent))

    arms = [(arm, base) for arm in ARMS for base in distinct_bases()]
    ticks = max(5, -(-states // (len(arms) * 4)))
    for arm, base in arms:
        def saturating(robot):
            for target_name, T in saturating_targets(robot).items():
                yield target_name, robot.neutral(), T, ticks
        out["saturating"].append(Cell("saturating", f"{arm}@{base}/two",
                                      partial(make_arm_robot, arm, base), "two", 0.5,
                                      LOOP_DT, loops=saturating))

    ticks3 = 25
    loops = max(1, -(-states // (len(robots) * ticks3)))
    for r, name in enumerate(robots):
        def far(robot, r=r):
            rng = np.random.default_rng([seed, 2, r])
            for i in range(loops):
                q0 = random_configuration(rng, robot)
                T = moved(rng, robot.frame_pose(q0, "ee"), rng.uniform(1.0, 2.5), (0.3, 1.0))
                yield f"loop {i}", q0, T, ticks3
        out["priorities"].append(Cell("priorities", f"{name}/pose3",
                                      partial(wbc.robots.load, name), "pose3", 5.0, LOOP_DT,
                                      loops=far))
    return out


# ---------------------------------------------------------------------------- tallies
@dataclass
class Tally:
    """What one variant did on one family's states."""

    states: int = 0
    agreed: int = 0
    full_success: int = 0
    false_failures: int = 0
    partial: int = 0
    errors: int = 0
    failed_unrefereed: int = 0
    fused_fallbacks: int = 0
    deviations: list = field(default_factory=list)
    solved_deviations: list = field(default_factory=list)
    ticks: list = field(default_factory=list)
    fused: set = field(default_factory=set)
    worst: tuple = (-1.0, "")
    first_false_failure: str = ""

    def summary(self) -> dict:
        dev = np.asarray(self.deviations)
        solved = np.asarray(self.solved_deviations)
        return {"states": self.states, "agreed": self.agreed,
                "full_success": self.full_success,
                "full_success_rate": self.full_success / self.agreed if self.agreed else None,
                "false_failures": self.false_failures, "partial": self.partial,
                "errors": self.errors, "failed_unrefereed": self.failed_unrefereed,
                "over_tol": int((dev > TOL).sum()),
                "max_deviation": float(dev.max()) if dev.size else None,
                "p99_deviation": float(np.quantile(dev, 0.99)) if dev.size else None,
                "max_deviation_solved": float(solved.max()) if solved.size else None,
                "median_tick_us": float(np.median(self.ticks) * 1e6) if self.ticks else None,
                "max_tick_ms": float(np.max(self.ticks) * 1e3) if self.ticks else None,
                "fused": sorted(self.fused) == [True] if self.fused else None,
                "fused_fallbacks": self.fused_fallbacks,
                "worst": self.worst[1], "first_false_failure": self.first_false_failure}


@dataclass
class RefereeTally:
    """The referees on one family's states."""

    states: int = 0
    agreed: int = 0
    disagree: int = 0
    failed: int = 0
    max_gap: float = 0.0
    worst_gap: str = ""
    velocity_active: int = 0
    position_active: int = 0

    def summary(self) -> dict:
        n = max(self.agreed, 1)
        return {"states": self.states, "agreed": self.agreed, "disagree": self.disagree,
                "referee_failed": self.failed, "max_referee_gap": self.max_gap,
                "worst_gap": self.worst_gap,
                "velocity_bound_active": self.velocity_active / n,
                "position_bound_active": self.position_active / n}


def active_bounds(referee: wbc.Controller, robot, v: np.ndarray) -> tuple[bool, bool]:
    """Whether ``v`` (the referee's answer) touches a velocity-limit bound, and a
    position-limit (configuration) bound, of the referee's last tick."""
    lower, upper = referee.workspace.variable_bounds()
    at_lower = np.abs(v - lower) <= ACTIVE * (1 + np.abs(lower))
    at_upper = np.abs(v - upper) <= ACTIVE * (1 + np.abs(upper))
    lim = robot.limits
    vel = (at_lower & (lower == lim.v_lower)) | (at_upper & (upper == lim.v_upper))
    pos = (at_lower & (lower != lim.v_lower)) | (at_upper & (upper != lim.v_upper))
    return bool(vel.any()), bool(pos.any())


def _last_solution(controller: wbc.Controller) -> wbc.Solution:
    """The solution of ``controller``'s last step (a step sets it)."""
    solution = controller.last_solution
    assert solution is not None
    return solution


def run_cell(cell: Cell, variants: list[str], tallies: dict[str, Tally],
             referee: RefereeTally) -> None:
    """Solve every state of ``cell`` with the referees and every variant (controllers built
    once here); add the outcomes to ``tallies`` and ``referee``."""
    robot = cell.robot()
    stacks = [build_stack(robot, cell.kind, cell.gain) for _ in range(len(variants) + 2)]
    frames = stacks[0][1]
    refs = [make_referee(robot, stacks[i][0], b, cell.dt) for i, b in enumerate(REFEREES)]
    ctrls: list[wbc.Controller | wbc.WbcError] = []
    for i, spec in enumerate(variants):
        try:
            ctrls.append(make_controller(robot, stacks[i + 2][0], spec, cell.dt))
        except wbc.WbcError as err:  # a backend that cannot even be built: every state an error
            ctrls.append(err)

    def state(label: str, q: np.ndarray, T: np.ndarray) -> np.ndarray:
        targets = {name: T for name in frames}
        answers = []
        for ref in refs:
            answers.append((ref.step(q, **targets).copy(), _last_solution(ref).ok))
        (v_ref, ok_a), (v_b, ok_b) = answers
        where = f"{cell.label} {label}"
        referee.states += 1
        gap = float(np.max(np.abs(v_ref - v_b)))
        if not (ok_a and ok_b):
            referee.failed += 1
        elif gap > AGREE:
            referee.disagree += 1
        else:
            referee.agreed += 1
        if ok_a and ok_b and gap > referee.max_gap:
            referee.max_gap, referee.worst_gap = gap, where
        agreed = ok_a and ok_b and gap <= AGREE
        if agreed:
            vel, pos = active_bounds(refs[0], robot, v_ref)
            referee.velocity_active += vel
            referee.position_active += pos
        for spec, ctrl in zip(variants, ctrls, strict=True):
            tally = tallies[spec]
            tally.states += 1
            if not agreed:
                if ok_a and ok_b and not isinstance(ctrl, Exception):  # referees disagree
                    try:
                        ctrl.step(q, **targets)
                        tally.failed_unrefereed += not _last_solution(ctrl).ok
                    except Exception:
                        tally.failed_unrefereed += 1
                continue
            tally.agreed += 1
            if isinstance(ctrl, Exception):
                tally.errors += 1
                tally.false_failures += 1
                continue
            tally.fused.add(bool(ctrl.fused))
            t0 = time.perf_counter()
            try:
                v = ctrl.step(q, **targets).copy()
            except Exception as err:  # a library error is an outcome, not the end of the run
                tally.errors += 1
                tally.false_failures += 1
                tally.first_false_failure = tally.first_false_failure or f"{where}: {err}"
                continue
            tally.ticks.append(time.perf_counter() - t0)
            solution = _last_solution(ctrl)
            dev = float(np.max(np.abs(v - v_ref)))
            tally.deviations.append(dev)
            if dev > tally.worst[0]:
                tally.worst = (dev, where)
            if solution.ok:
                tally.full_success += 1
                tally.solved_deviations.append(dev)
            else:
                tally.false_failures += 1
                tally.partial += bool(solution.partial)
                failed = [lv.label for lv in solution.levels if lv.status is not wbc.Status.SOLVED]
                tally.first_false_failure = tally.first_false_failure or (
                    f"{where}: {solution.status.value} at {failed[0] if failed else '?'}")
        return v_ref

    if cell.states is not None:
        for label, q, T in cell.states(robot):
            state(label, q, T)
    if cell.loops is not None:
        for label, q0, T, ticks in cell.loops(robot):
            q = q0.copy()
            for k in range(ticks):
                v_ref = state(f"{label} tick {k}", q, T)
                q = robot.integrate(q, v_ref, cell.dt)
    for spec, ctrl in zip(variants, ctrls, strict=True):
        ws = getattr(ctrl, "workspace", None)
        tallies[spec].fused_fallbacks += (getattr(ws, "fallback_solves", 0)
                                          + getattr(ws, "skipped_solves", 0))


# ---------------------------------------------------------------------------- campaign
def campaign(states: int = 1000, variants: list[str] | tuple[str, ...] | None = None,
             families: list[str] | tuple[str, ...] = FAMILIES, seed: int = 0,
             progress: bool = False) -> dict:
    """About ``states`` states per family (rounded up to fill every cell), each solved by the
    referees and every variant (default: :func:`default_variants`). Returns the JSON-ready
    dict of the module docstring."""
    start = time.perf_counter()
    variants = default_variants() if variants is None else list(variants)
    plan = cells(states, seed)
    todo = [c for f in families for c in plan[f]]
    result: dict = {}
    referees: dict = {}
    walls: dict = {}
    done = 0
    for family in families:
        t0 = time.perf_counter()
        tallies = {spec: Tally() for spec in variants}
        referee = RefereeTally()
        for cell in plan[family]:
            run_cell(cell, list(variants), tallies, referee)
            done += 1
            if progress:
                report_progress(done, len(todo), f"{family} {cell.label}")
        result[family] = {spec: t.summary() for spec, t in tallies.items()}
        referees[family] = referee.summary()
        walls[family] = round(time.perf_counter() - t0, 1)
    result["referee"] = referees
    result["parameters"] = {"states": states, "seed": seed, "variants": list(variants),
                            "families": list(families), "referees": list(REFEREES),
                            "agree": AGREE, "dt": DT, "loop_dt": LOOP_DT,
                            "arms": list(ARMS), "bases": distinct_bases(),
                            "robots": wbc.robots.names(), "wall_s_per_family": walls,
                            "wall_s": round(time.perf_counter() - start, 1)}
    return result


def findings(result: dict, tol: float = TOL) -> list[str]:
    """The exact variants (:data:`EXACT`) with a false failure or a deviation above ``tol``."""
    out = []
    for family in result["parameters"]["families"]:
        for spec, s in result[family].items():
            if spec not in EXACT:
                continue
            if s["false_failures"] or (s["max_deviation"] or 0.0) > tol:
                out.append(f"{family}/{spec}: {s['false_failures']} false failures, max "
                           f"deviation {s['max_deviation']:.1e}")
    return out


def _e(value) -> str:
    return "—" if value is None else f"{value:.1e}"


def markdown(result: dict) -> str:
    """One table per family (rows: variants) and the referees' table."""
    p = result["parameters"]
    lines = [f"# wbc exactness: referees {' & '.join(p['referees'])} (tight, ordinary), "
             f"agreement {p['agree']:g}; {p['wall_s']} s", ""]
    for family in p["families"]:
        r = result["referee"][family]
        lines += [f"## {family}: {r['states']} states, {r['agreed']} agreed "
                  f"({r['disagree']} referee disagreements, {r['referee_failed']} referee "
                  f"failures; velocity bound active {100 * r['velocity_bound_active']:.0f} %, "
                  f"position bound {100 * r['position_bound_active']:.0f} % of agreed)", "",
                  "| variant | path | agreed | full success | false failures | partial | "
                  "errors | dev > 1e-5 | max dev | p99 dev | median tick [µs] | failed where "
                  "referees disagree |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for spec, s in result[family].items():
            path = {True: f"fused ({s['fused_fallbacks']} fell back)", False: "ordinary",
                    None: "—"}[s["fused"]]
            rate = "—" if s["full_success_rate"] is None else \
                f"{100 * s['full_success_rate']:.2f} %"
            tick = "—" if s["median_tick_us"] is None else f"{s['median_tick_us']:.0f}"
            lines.append(f"| {spec} | {path} | {s['agreed']} | {rate} | {s['false_failures']} "
                         f"| {s['partial']} | {s['errors']} | {s['over_tol']} | "
                         f"{_e(s['max_deviation'])} | {_e(s['p99_deviation'])} | {tick} | "
                         f"{s['failed_unrefereed']} |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    """``wbc exactness [--states N] [--backends a,b/tight,c/ordinary] [--families ...]
    [--seed K] [--tol T] [--out DIR]``."""
    parser = argparse.ArgumentParser(
        prog="wbc exactness", description="every backend against an exact referee (quadprog "
        "and clarabel, tight) on random, saturating and strict-priority states")
    parser.add_argument("--states", type=int, default=1000, help="states per family (>= 1)")
    parser.add_argument("--backends", default=",".join(default_variants()),
                        help="variants <backend>[/tight][/ordinary], comma-separated")
    parser.add_argument("--families", default=",".join(FAMILIES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tol", type=float, default=TOL,
                        help="deviation allowed to the exact variants for exit code 0")
    parser.add_argument("--out", type=Path, default=Path("results"))
    args = parser.parse_args(argv)
    if args.states < 1:
        parser.error("--states must be >= 1")
    specs = [s for s in args.backends.split(",") if s]
    try:
        names = [parse_variant(s)[0] for s in specs]
    except ValueError as err:
        parser.error(str(err))
    constructible_backends(parser, ",".join(dict.fromkeys(names)))
    if not specs:
        parser.error("--backends needs at least one name")
    families = [f for f in args.families.split(",") if f]
    for family in families:
        if family not in FAMILIES:
            parser.error(f"--families: unknown family {family!r}; families: "
                         f"{', '.join(FAMILIES)}")
    result = campaign(args.states, specs, families, args.seed, progress=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "exactness.json").write_text(json.dumps(result, indent=1))
    (args.out / "exactness.md").write_text(markdown(result))
    print(markdown(result))
    return 1 if findings(result, args.tol) else 0


def default_variants() -> list[str]:
    """:data:`DEFAULT_VARIANTS` whose backend is installed (``qpsolvers:`` ones if qpsolvers
    has that solver)."""
    installed = set(available_backends())
    out = []
    for spec in DEFAULT_VARIANTS:
        backend = parse_variant(spec)[0]
        if backend in installed:
            out.append(spec)
        elif backend.startswith("qpsolvers:"):
            try:
                import qpsolvers

                if backend.partition(":")[2] in qpsolvers.available_solvers:
                    out.append(spec)
            except ImportError:
                pass
    return out
