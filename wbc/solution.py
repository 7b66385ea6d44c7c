"""What one solve of a stack returns."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .infeasibility import Diagnosis
from .qp import Status
from .variables import Variables


@dataclass(slots=True)
class Timings:
    """Wall-clock split of one tick [s].

    Attributes:
        model: kinematics / parameter update (filled by a controller; 0 for ``stack.solve``).
        assembly: evaluating the compiled level functions and the cascade's frozen rows.
        solve: inside the QP backends (update + solve).
    """

    model: float = 0.0
    assembly: float = 0.0
    solve: float = 0.0

    @property
    def total(self) -> float:
        return self.model + self.assembly + self.solve


class RecordedTimings(Timings):
    """The :class:`Timings` of the fused tick's reused solution (:mod:`wbc.fused`), read when
    first asked from the float64 4-vector ``times`` — ``(started, called, model, solve)``, see
    :data:`wbc.checks.STAGE_SOURCE` — that the tick writes (``assembly`` is 0: the generated
    call assembles and solves). A tick thus writes two floats, and builds no object;
    :meth:`Solution.snapshot` copies the values into a plain :class:`Timings`."""

    __slots__ = ("_times",)

    def __init__(self, times: np.ndarray) -> None:
        self._times = times
        self.assembly = 0.0

    @property  # type: ignore[override]
    def model(self) -> float:
        return float(self._times[2])

    @model.setter
    def model(self, value: float) -> None:
        self._times[2] = value

    @property  # type: ignore[override]
    def solve(self) -> float:
        return float(self._times[3])

    @solve.setter
    def solve(self, value: float) -> None:
        self._times[3] = value


@dataclass(slots=True)
class LevelResult:
    """Outcome of one QP of the cascade.

    Attributes:
        label: e.g. ``"level 1 (tasks: ee, posture)"``.
        status: backend status.
        x: the decision vector after this QP (zeros if it failed).
        frozen_rank: rank of the earlier levels' frozen cost rows (with the variables the
            level fixes, and implicit equalities where a retry found them) whose null space it
            was solved in (``-1`` on the fused tick, which keeps every frozen row in a narrow
            band and computes no rank, see :mod:`wbc.fused`).
        iterations: backend iterations (``-1`` if unknown; ``0`` for a level the levels
            above determine completely, which no backend is asked to solve).
        message: the backend's message on failure.
        frozen_band: relative half-width of the band the frozen rows were kept in: 0 on the
            ordinary path (eliminated, exact), :data:`wbc.fused.FROZEN_BAND` on the fused tick.
        diagnosis: the :class:`~wbc.infeasibility.Diagnosis` of a failed QP whose conflict is
            looked for (the backend found it infeasible, or it is the first QP and failed);
            ``None`` otherwise.
        conflict: the names of the hard constraints that cannot hold together in this QP (an
            irreducible set, see :mod:`wbc.infeasibility`; found when first read); empty when
            not looked for or when the constraints can hold (the failure was the solver's).
    """

    label: str
    status: Status
    x: np.ndarray
    frozen_rank: int
    iterations: int = -1
    message: str = ""
    frozen_band: float = 0.0
    diagnosis: Diagnosis | None = None

    @property
    def conflict(self) -> tuple[str, ...]:
        return () if self.diagnosis is None else self.diagnosis.conflict


class TaskResiduals:
    """Every task's residual at a solution's ``x``, evaluated when first read (one call of the
    compiled stack's residual function, ≈ 10 µs; nothing on the tick).

    Args:
        compiled: the :class:`~wbc.CompiledStack` (its ``residuals`` and ``residual_rows``).
        p: the parameter vector of the tick; x: the solution's decision vector. Arrays the
            caller does not rewrite (the fused tick's live ones are copied by
            :meth:`frozen`).
    """

    __slots__ = ("_compiled", "_p", "_x", "_values")

    def __init__(self, compiled, p: np.ndarray, x: np.ndarray) -> None:
        self._compiled, self._p, self._x = compiled, p, x
        self._values: dict[str, np.ndarray] | None = None

    def frozen(self) -> TaskResiduals:
        """A copy that keeps its own ``p`` and ``x`` (or the values, once evaluated)."""
        copy = TaskResiduals(self._compiled, self._p.copy(), self._x.copy())
        copy._values = self._values
        return copy

    def values(self) -> dict[str, np.ndarray]:
        if self._values is None:
            compiled = self._compiled
            r = np.asarray(compiled.residuals(self._p, self._x), dtype=float).reshape(-1)
            self._values = {name: r[rows] for name, rows in compiled.residual_rows.items()}
        return self._values


@dataclass(slots=True)
class Solution:
    """Result of ``stack.solve`` / ``workspace.solve``.

    Attributes:
        x: the decision vector, exactly within the variable bounds (clipped: solvers meet
            them only to their tolerance). On failure: the result of the last level that
            succeeded (its higher priorities are still met), or zeros if the first level
            failed — never NaN.
        status: ``Status.SOLVED`` or the status of the first failing QP.
        levels: one :class:`LevelResult` per QP solved, in order.
        scale: task scale ``s ∈ [0, 1]`` of the first scaling level, ``None`` if none.
        scales: ``priority -> s`` for every scaling level.
        timings: :class:`Timings` [s].
        message: empty on success, else what failed and where: ``head`` (the failing QP and
            its status), the conflict's details (see ``conflict``) and ``notes`` (e.g. the
            fallback the controller applied), joined by ``"; "``.
        partial: the solve failed at a lower priority, and ``x`` is the solution of every
            level above it (hard constraints included): a usable command. ``False`` when solved
            or when the first level failed.
        fallback: set by :class:`~wbc.Controller`: ``None`` when the QP was solved, else what
            produced the command (``"partial"`` or the fallback policy).
        conflict: the failing QP's ``LevelResult.conflict``: the names of the hard constraints
            that cannot hold together there (drop any one and the rest can; ``"the levels
            above"`` when the optima of higher priorities take part); empty when solved or when
            none is found. ``message`` details which rows and bounds. Found when ``conflict`` or
            ``message`` is first read (one LP, see :mod:`wbc.infeasibility`), not on the tick.
        diagnosis: the failing QP's :class:`~wbc.infeasibility.Diagnosis` (or ``None``).
        residuals: task name -> its residual at ``x`` (see :meth:`residuals`).
    """

    x: np.ndarray
    status: Status
    levels: list[LevelResult]
    variables: Variables
    scales: dict[int, float] = field(default_factory=dict)
    timings: Timings = field(default_factory=Timings)
    head: str = ""
    partial: bool = False
    fallback: str | None = None
    diagnosis: Diagnosis | None = None
    notes: list[str] = field(default_factory=list)
    task_residuals: TaskResiduals | None = None

    def snapshot(self) -> Solution:
        """A copy that shares no array or list with this solution (the fused tick rewrites its
        solution's buffers every tick; see :attr:`wbc.Controller.last_solution`)."""
        timings = self.timings
        return replace(self, x=self.x.copy(),
                       levels=[replace(level, x=level.x.copy()) for level in self.levels],
                       scales=dict(self.scales),
                       timings=Timings(timings.model, timings.assembly, timings.solve),
                       notes=list(self.notes),
                       task_residuals=None if self.task_residuals is None
                       else self.task_residuals.frozen())

    @property
    def residuals(self) -> dict[str, np.ndarray]:
        """Task name -> what the task still asks at ``x``, unweighted, in the task's own units:
        ``expr − target`` of its costs (for a velocity-level :class:`~wbc.tasks.FrameTask`,
        ``J v − gain·e`` in m/s and rad/s: ``−gain·e`` when nothing moves towards an
        unreachable target; a scaling level's task at its unscaled target), the signed
        violation of its soft inequalities (0 when met). Read it to see a task that is not
        achieved though every QP solved; evaluated when first read. Empty when unknown."""
        return {} if self.task_residuals is None else self.task_residuals.values()

    @property
    def message(self) -> str:
        details = "" if self.diagnosis is None else self.diagnosis.details
        return "; ".join(part for part in (self.head, details, *self.notes) if part)

    @property
    def conflict(self) -> tuple[str, ...]:
        return () if self.diagnosis is None else self.diagnosis.conflict

    @property
    def ok(self) -> bool:
        return self.status is Status.SOLVED

    @property
    def scale(self) -> float | None:
        return next(iter(self.scales.values()), None)

    def __getitem__(self, block: str) -> np.ndarray:
        """The part of ``x`` of a variable block, e.g. ``solution["qd_arm"]``."""
        return self.x[self.variables.slice(block)]
