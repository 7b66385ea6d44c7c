"""The closed loop: :class:`Simulation` runs a controller on a robot and records a :class:`Run`.

See :mod:`wbc.sim` for the tick; :mod:`wbc.sim.actuation` for the actuation models.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import all_finite
from ..errors import InvalidValueError, NonFiniteError, ShapeError, WbcError
from .actuation import Actuation, ActuationState, OdometryError

VELOCITY, ACCELERATION = "velocity", "acceleration"


@dataclass
class Tick:
    """What a signal function sees after a tick's command (see :class:`Simulation`).

    Attributes:
        t: time [s] at the start of the tick.
        q: true configuration at the start of the tick.
        q_est: the configuration the controller was given.
        v: true velocity at the start of the tick.
        command: the controller's command.
        references: the references of this tick.
        solution: the controller's ``last_solution`` (``None`` if it has none).
        robot: a probe copy of the robot (its kinematics may be updated freely).
    """

    t: float
    q: np.ndarray
    q_est: np.ndarray
    v: np.ndarray
    command: np.ndarray
    references: dict
    solution: Any
    robot: Any


@dataclass
class Run:
    """The record of one simulation, one row per tick.

    Attributes:
        t: tick start times [s], ``(N,)``.
        q: true configuration at each tick's start, ``(N, nq)``.
        q_est: the configuration the controller was given, ``(N, nq)``.
        v: true velocity the robot moved with during the tick (velocity commands) or at its
            end (other commands, and every command on a plant), ``(N, nv)``.
        v_est: the velocity the controller was given, ``(N, nv)``.
        command: the controller's commands, ``(N, n_command)``.
        status: the solution status per tick (``"solved"``, ``"infeasible"``, ...; ``""`` for a
            controller without ``last_solution``).
        partial: whether the command came from the levels above a failed one, ``(N,)``.
        fallback: the fallback policy that produced the command (``None`` when solved).
        tick_s: wall time of ``controller.step`` [s], ``(N,)``.
        model_s, assembly_s, solve_s: the solution's timing split [s] (0 without one).
        signals: ``name -> (N, ...)`` arrays: the signals asked for and those the actuation
            models record (e.g. wheel slip).
        q_final, q_est_final, v_final: the state after the last tick.
        dt: the period [s]; nv_base: the number of base velocity coordinates.
    """

    t: np.ndarray
    q: np.ndarray
    q_est: np.ndarray
    v: np.ndarray
    v_est: np.ndarray
    command: np.ndarray
    status: list[str]
    partial: np.ndarray
    fallback: list[str | None]
    tick_s: np.ndarray
    model_s: np.ndarray
    assembly_s: np.ndarray
    solve_s: np.ndarray
    signals: dict[str, np.ndarray]
    q_final: np.ndarray
    q_est_final: np.ndarray
    v_final: np.ndarray
    dt: float
    nv_base: int = 0
    failures: int = field(init=False)

    def __post_init__(self) -> None:
        self.failures = sum(s not in ("solved", "") for s in self.status)

    @property
    def base_velocity(self) -> np.ndarray:
        """True base velocity coordinates, ``(N, nv_base)``."""
        return self.v[:, :self.nv_base]

    def series(self, keys: Sequence[str] | None = None) -> dict:
        """JSON-ready series (lists): ``"t"``, ``"q"``, ``"q_est"``, ``"v"``, ``"base_velocity"``,
        ``"command"``, ``"status"``, ``"partial"``, ``"tick_s"`` and every signal by name, or
        only ``keys``."""
        every = {"t": self.t, "q": self.q, "q_est": self.q_est, "v": self.v,
                 "base_velocity": self.base_velocity, "command": self.command,
                 "status": self.status, "partial": self.partial, "tick_s": self.tick_s,
                 **self.signals}
        if keys is not None:
            missing = [k for k in keys if k not in every]
            if missing:
                raise WbcError(f"run has no series {missing}; it has {sorted(every)}")
            every = {k: every[k] for k in keys}
        return {k: (v.tolist() if isinstance(v, np.ndarray) else list(v))  # type: ignore
                for k, v in every.items()}


def position_error(frame: str = "ee", reference: str | None = None,
                   estimate: bool = False) -> Callable[[Tick], float]:
    """A signal: ``|p_target − p_frame(q)|`` [m], the distance between the target pose's
    translation (reference ``reference``, default ``frame``; a ``(4, 4)`` pose or a position)
    and the frame's position at the true configuration — or, with ``estimate=True``, at the
    configuration the controller was given (the error it believes it has). The last target
    given is kept until a new one comes."""
    key = frame if reference is None else reference
    last = {}

    def signal(tick: Tick) -> float:
        if key in tick.references:
            last["target"] = np.asarray(tick.references[key], dtype=float)
        if "target" not in last:
            raise WbcError(f"position_error: no reference {key!r} given yet")
        target = last["target"]
        goal = target[:3, 3] if target.shape == (4, 4) else target.reshape(3)
        q = tick.q_est if estimate else tick.q
        return float(np.linalg.norm(goal - tick.robot.frame_pose(q, frame)[:3, 3]))

    return signal


class Simulation:
    """A controller in closed loop with a robot whose actuation is modelled.

    Args:
        robot: the robot model (the :class:`wbc.robots.Robot` protocol: ``nq``, ``nv``,
            ``integrate``, ``neutral``; ``clone`` if signals use its kinematics).
        controller: any object with ``step(q, v, **references) -> command``; its
            ``last_solution`` (if any) gives statuses and timings.
        dt: control period [s] (also the integration step).
        actuation: actuation models applied in order (see :mod:`wbc.sim.actuation`); none
            means exact actuation.
        command: ``"velocity"``, ``"acceleration"`` or another kind passed through raw (an
            actuation model must then set the true velocity).
        command_map: optional ``command -> (nv,)`` for controllers whose decision vector holds
            more than the robot's velocities or accelerations (e.g. slacks).
        seed: seed of the random generator the actuation models draw from.
        signals: ``name -> fn(tick) -> float | array``, recorded every tick (see :class:`Tick`).
        plant: what the truth moves with: ``None`` (default) integrates it kinematically
            through the actuation chain; a plant object (``reset(q0, v0, dt, command)``,
            ``step(command)``, e.g. :class:`wbc.sim.MujocoPlant`) advances physics instead —
            the estimate then integrates what its encoders measured (or is the configuration
            the plant measured, ``step.q_measured``), its signals are recorded (with
            ``"plant_step_s"``: the wall time [s] of each ``step``), and actuation models are
            refused (the physics is the actuation).
    """

    def __init__(self, robot, controller, dt: float, actuation: Sequence[Actuation] = (),
                 command: str = VELOCITY, command_map: Callable | None = None, seed: int = 0,
                 signals: Mapping[str, Callable[[Tick], object]] | None = None,
                 plant=None) -> None:
        dt = float(dt)
        if not np.isfinite(dt) or dt <= 0:
            raise InvalidValueError(f"dt must be a finite number > 0, got {dt!r}")
        if not callable(getattr(controller, "step", None)):
            raise WbcError(f"controller must have a step(q, v, **references) method, got "
                           f"{type(controller).__name__}")
        self.actuation = list(actuation)
        if plant is not None:
            if not (callable(getattr(plant, "reset", None))
                    and callable(getattr(plant, "step", None))):
                raise WbcError(f"plant must have reset(q0, v0, dt, command) and step(command) "
                               f"methods, got {type(plant).__name__}")
            if self.actuation:
                raise WbcError("actuation models act on the kinematic plant only: with a plant, "
                               "the physics is the actuation")
        self.plant = plant
        for position, model in enumerate(self.actuation):
            if not isinstance(model, Actuation):
                raise WbcError(f"actuation models must be wbc.sim.actuation.Actuation objects, "
                               f"got {type(model).__name__}")
            if isinstance(model, OdometryError) and position > 0:
                raise WbcError("OdometryError changes what the command means on the ground: "
                               "put it first in the actuation chain (see wbc.sim.actuation)")
        self.robot = robot
        self.controller = controller
        self.dt = dt
        self.command = command
        self.command_map = command_map
        self.seed = seed
        self.signals = dict(signals or {})
        self.nq, self.nv = int(robot.nq), int(robot.nv)
        self.nv_base = int(getattr(robot, "nv_base", 0))
        self._probe = robot.clone() if hasattr(robot, "clone") else robot

    def run(self, seconds: float | None = None, ticks: int | None = None, q0=None, v0=None,
            references: Callable[[float], Mapping] | Mapping | None = None) -> Run:
        """Run ``ticks`` ticks (or ``round(seconds / dt)``) from ``(q0, v0)`` (default: the
        robot's neutral configuration at rest) and return the :class:`Run`.

        Args:
            references: ``references(t) -> dict`` of the controller's references at time ``t``
                [s], or one dict for every tick.
        """
        if (seconds is None) == (ticks is None):
            raise WbcError("give either seconds or ticks")
        n = int(round(seconds / self.dt)) if seconds is not None else int(ticks)  # type: ignore
        if n < 1:
            raise InvalidValueError(f"a run needs at least one tick, got {n}")
        q = self._state(self.robot.neutral() if q0 is None else q0, self.nq, "q0")
        v = self._state(np.zeros(self.nv) if v0 is None else v0, self.nv, "v0")
        if self.plant is not None:
            q, v = self.plant.reset(q, v, self.dt, self.command)
        q_est, v_est = q.copy(), v.copy()
        rng = np.random.default_rng(self.seed)
        for model in self.actuation:
            model.reset(self.robot, self.dt)
        if references is None:
            references = {}
        ref_fn = references if callable(references) else (lambda t, r=dict(references): r)

        columns = ("t", "q", "q_est", "v", "v_est", "command", "status", "partial", "fallback",
                   "tick_s", "model_s", "assembly_s", "solve_s")
        rows: dict[str, list] = {name: [] for name in columns}
        signals: dict[str, list] = {name: [] for name in self.signals}
        clock = time.perf_counter
        for k in range(n):
            t = k * self.dt
            refs = dict(ref_fn(t))
            t0 = clock()
            command = self.controller.step(q_est, v_est, **refs)
            tick = clock() - t0
            command = np.array(command, dtype=float).reshape(-1)
            if not all_finite(command):
                raise NonFiniteError(f"the controller commanded NaN or inf at t = {t:.6g} s")
            solution = getattr(self.controller, "last_solution", None)
            if self.plant is not None:
                q, v, q_est, v_est = self._plant_tick(rows, signals, refs, solution, tick, t,
                                                      command, q, v, q_est, v_est)
                continue
            v_command, v_true = self._velocity_command(command, v, v_est)
            state = ActuationState(self.dt, t, rng, self.robot, command, q, v, q_est, v_est,
                                   v_command)
            if v_true is not None:
                state.v_true = v_true
            for model in self.actuation:
                model.apply(state)
            if state.v_true is None:
                raise WbcError(f"command kind {self.command!r}: no actuation model set the "
                               "true velocity (state.v_true)")
            v_true = self._state(state.v_true, self.nv, "the true velocity")
            v_meas = self._state(state.v_measured, self.nv, "the measured velocity")
            self._record(rows, signals, Tick(t, q, q_est, v, command, refs, solution,
                                             self._probe), v_true, v_est, tick, state.signals)
            if self.command == VELOCITY:
                q = self.robot.integrate(q, v_true, self.dt)
                q_est = self.robot.integrate(q_est, v_meas, self.dt)
            else:
                q = self.robot.integrate(q, 0.5 * (v + v_true), self.dt)
                q_est = self.robot.integrate(q_est, 0.5 * (v_est + v_meas), self.dt)
            v, v_est = v_true, v_meas
        arrays: dict[str, Any] = {k: (np.asarray(val) if k not in ("status", "fallback") else val)
                                  for k, val in rows.items()}
        return Run(**arrays, signals={k: np.asarray(val) for k, val in signals.items()},
                   q_final=q, q_est_final=q_est, v_final=v, dt=self.dt, nv_base=self.nv_base)

    def _record(self, rows, signals, at: Tick, v_row: np.ndarray, v_est: np.ndarray,
                tick_s: float, plant_signals: Mapping[str, object]) -> None:
        """Record one tick's row: the state ``at`` its start (``v_row``: the velocity the row
        keeps, see :class:`Run`; ``v_est``: the one the controller was given), the solution,
        the signals asked for (computed on ``at``) and those the actuation models or the plant
        produced."""
        rows["t"].append(at.t)
        rows["q"].append(at.q)
        rows["q_est"].append(at.q_est)
        rows["v"].append(v_row)
        rows["v_est"].append(v_est)
        rows["command"].append(at.command)
        self._record_solution(rows, at.solution, tick_s)
        for name, fn in self.signals.items():
            signals[name].append(fn(at))
        for name, value in plant_signals.items():
            signals.setdefault(name, []).append(value)

    def _plant_tick(self, rows, signals, refs, solution, tick, t, command, q, v, q_est,
                    v_est):
        """One tick on :attr:`plant`: record the tick's row, advance the plant; return the new
        ``(q, v, q_est, v_est)`` (the estimate integrates what the encoders measured)."""
        raw = command
        if self.command in (VELOCITY, ACCELERATION):
            raw = command if self.command_map is None else np.asarray(
                self.command_map(command), dtype=float).reshape(-1)
            if raw.shape != (self.nv,):
                raise ShapeError(f"a {self.command} command must have nv = {self.nv} entries, "
                                 f"got {raw.shape[0]}; pass command_map= to select them")
        started = time.perf_counter()
        step = self.plant.step(raw)
        plant_s = time.perf_counter() - started
        q_new = self._state(step.q, self.nq, "the plant's configuration")
        v_new = self._state(step.v, self.nv, "the plant's velocity")
        v_meas = self._state(step.v_measured, self.nv, "the plant's measured velocity")
        self._record(rows, signals, Tick(t, q, q_est, v, command, refs, solution, self._probe),
                     v_new, v_est, tick, {**step.signals, "plant_step_s": plant_s})
        if getattr(step, "q_measured", None) is not None:
            q_est = self._state(step.q_measured, self.nq, "the plant's measured configuration")
        else:
            q_est = self.robot.integrate(q_est, v_meas, self.dt)
        return q_new, v_new, q_est, v_meas

    def _velocity_command(self, command: np.ndarray, v: np.ndarray, v_est: np.ndarray):
        """``(v_command, v_true)``: the velocity the actuators are asked for — the command, or
        the controller's velocity plus its acceleration over the tick, ``v_est + a·dt`` — and
        the truth's before the actuation chain (``v + a·dt``; ``None``: the same)."""
        if self.command not in (VELOCITY, ACCELERATION):
            return None, None
        mapped = command if self.command_map is None else np.asarray(
            self.command_map(command), dtype=float).reshape(-1)
        if mapped.shape != (self.nv,):
            raise ShapeError(f"a {self.command} command must have nv = {self.nv} entries, got "
                             f"{mapped.shape[0]}; pass command_map= to select them")
        if self.command == VELOCITY:
            return mapped.copy(), None
        return v_est + mapped * self.dt, v + mapped * self.dt

    @staticmethod
    def _state(value, size: int, what: str) -> np.ndarray:
        arr = np.array(value, dtype=float).reshape(-1)
        if arr.shape != (size,):
            raise ShapeError(f"{what} must have {size} entries, got {arr.shape[0]}")
        if not all_finite(arr):
            raise NonFiniteError(f"{what} contains NaN or inf")
        return arr

    @staticmethod
    def _record_solution(rows: dict, solution, tick: float) -> None:
        rows["tick_s"].append(tick)
        if solution is None:
            rows["status"].append("")
            rows["partial"].append(False)
            rows["fallback"].append(None)
            rows["model_s"].append(0.0)
            rows["assembly_s"].append(0.0)
            rows["solve_s"].append(0.0)
            return
        rows["status"].append(solution.status.value)
        rows["partial"].append(bool(solution.partial))
        rows["fallback"].append(solution.fallback)
        rows["model_s"].append(solution.timings.model)
        rows["assembly_s"].append(solution.timings.assembly)
        rows["solve_s"].append(solution.timings.solve)
