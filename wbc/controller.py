"""`Controller`: a compiled stack closed around a robot model, one call per control tick.

Model quantities
----------------
Tasks never call the robot. They declare *model quantities* (:meth:`wbc.Stack.quantity`) and
the controller fills them every tick — ``"q"``, ``"v"`` and ``"dt"`` from its own state, every
other one from the robot's quantity registry (:mod:`wbc.quantities`; ``robot.quantities``) after
one kinematics update:

=====================  ===========  ===========================================================
name                   shape        value
=====================  ===========  ===========================================================
``"q"``                ``(nq,)``    the configuration passed to :meth:`Controller.step`
``"v"``                ``(nv,)``    the velocity passed to :meth:`Controller.step` (0 if none)
``"dt"``               ``(1,)``     the control period [s]
``"pose[<frame>]"``    ``(4, 4)``   world pose of ``<frame>`` (homogeneous transform)
``"J[<frame>]"``       ``(6, nv)``  frame Jacobian, rows ``[linear; angular]`` in world-aligned
                                    axes at the frame origin (pinocchio
                                    ``LOCAL_WORLD_ALIGNED``): the frame's twist is ``J v``
``"Jdot_v[<frame>]"``  ``(6,)``     drift ``J̇ v`` in the same axes (origin's classical
                                    acceleration at zero joint acceleration)
…                      …            whatever else the robot registers (``"com"``,
                                    ``"manipulability_gradient[ee]"``, ...)
=====================  ===========  ===========================================================

A parameter declared with ``stack.parameter`` whose name the robot's registry offers is filled
too (the names above worked that way before quantities were declared). A declared quantity the
robot does not offer is an :class:`~wbc.UnknownNameError` listing what it offers.

With ``kinematics="compiled"`` (or ``"auto"``, the default) the quantities that have a symbolic
form are computed inside the compiled level functions from ``"q"`` (and ``"v"``) instead: same
values, no robot call on the tick (see :func:`wbc.passes.compiled_kinematics`).

Every other parameter is a *reference*, set through :meth:`Controller.step`'s keywords: key
``k`` sets parameter ``k`` if it exists, else ``"k.target"`` (so ``step(q, ee=T)`` sets the
target of the task named ``"ee"``). References keep their value until set again.

Robot protocol
--------------
:class:`wbc.robots.Robot` (the core imports no robot): ``nq``, ``nv``; ``update(q, v=None)`` —
one kinematics update that the registry's fillers then read (the controller passes ``v`` only
if a quantity needs it, and skips the update when no quantity is left to fill); ``quantities``
(a :class:`~wbc.quantities.QuantityRegistry`; a robot without one is served through its
``frame_pose`` / ``frame_jacobian`` / ``frame_drift`` getters, see
:func:`wbc.quantities.registry_of`); optionally ``has_frame`` / ``frame_names`` for early errors.

The tick
--------
Check and write the references, ``q`` and ``v`` → ``robot.update`` → the quantity fillers (a
loop over the few model quantities, never over tasks) → ``workspace.solve()`` (one compiled
evaluation and one warm-started backend solve per priority level) → the fallback policy if the
solve failed. ``solution.timings.model`` holds the first three steps.

When the controller compiles C (fused, or ``jit``), the first step is one call of a small C
extension (:data:`wbc.checks.STAGE_SOURCE`, built once per machine and cached like the JIT
functions): float64 arrays it accepts are checked and written in ≈ 0.1 µs; anything else — a
list, a keyword seen for the first time, a bound pair, and every value it would refuse — takes
the same checks in Python (≈ 1.5 µs for a Panda ``q`` and a pose), with their messages. A
refused call writes nothing either way.

On the fused path (the default for a stack on daqp without task-scaling levels, with a C
compiler, see :mod:`wbc.fused`), the solve is one call of a generated C function holding the
compiled kinematics, the assembly and the daqp solves of every level (``timings.solve``).
When no numeric model quantity is filled between the stage and the solve and the last tick
was fused, the same C call that staged the inputs makes it (through the workspace's
:attr:`~wbc.fused.FusedWorkspace.c_call`), reads the clock around it and copies the command
into an array no one else holds (or ``out``): a tick it answers runs no Python after the
stage (Panda pose + posture, ``wbc placo``: ≈ 1.26× the bare generated call in a dedicated
loop, against 1.64× with the solve in Python). Every other tick makes the call through the
callable the workspace hands out once (:meth:`wbc.fused.FusedWorkspace.solver`), which also
keeps the back-off and arms the C call again. A tick the fused call does not solve is solved
again on the ordinary path, so statuses, partial solutions and fallbacks read the same. A
solved tick's solution is the workspace's reused one
(:attr:`~wbc.fused.FusedWorkspace.fused_solution`, its ``timings`` read from the tick's clock
buffer), copied when ``last_solution`` is first read.

A failed tick costs about what a solved one does: the search for the conflicting constraints
(:mod:`wbc.infeasibility`) runs when ``solution.conflict`` or ``solution.message`` is read.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from functools import cache
from typing import NamedTuple

import casadi as ca
import numpy as np

from .cbuild import compiler_available
from .checks import all_finite, as_float_array, check_pose, checked_array
from .checks import check_frame as check_frame  # re-exported: wbc.controller.check_frame
from .errors import (
    InfeasibleError,
    InvalidValueError,
    MissingLimitsWarning,
    NonFiniteError,
    ShapeError,
    UnknownNameError,
    WbcError,
)
from .fused import FusedWorkspace, build_fused, stage_extension
from .infeasibility import fixed_conflict
from .passes import compiled_kinematics, jit_compiled, why_not_fused
from .qp import Status
from .quantities import STATE_QUANTITIES, registry_of
from .solution import Solution
from .stack import Stack, _shadowing_message
from .terms import VariableBounds, as_sx_column
from .workspace import BackendSpec, Workspace

FALLBACKS = ("hold", "last", "decelerate", "raise")
MISSING_LIMITS = ("warn", "ignore", "raise")
FINITE_LIMIT = 1e10  # a robot limit beyond this [rad, m, rad/s, m/s] is "no limit" (URDF fillers)
# for the tick: module globals, looked up faster than attributes
_clock, _ndarray, _FLOAT, _copyto = time.perf_counter, np.ndarray, np.dtype(float), np.copyto
_SOLVED = Status.SOLVED
DECELERATION = 0.5  # "decelerate": the previous command's share kept per failed tick


class _HotPath(NamedTuple):
    """What :meth:`Controller.step` reads on every tick, in one attribute (see there)."""

    tick: Callable[..., object]  # C's tick (wbc.checks.STAGE_SOURCE) or _python_path
    p: np.ndarray  # the workspace's parameter vector
    layout: tuple[int, int, int, int, int]  # (q_at, nq, v_at, nv, n): "q", "v" in p (-1: absent)
    specs: dict[str, tuple]  # reference keyword -> (at, rows, cols, allow_inf, pose)
    times: np.ndarray  # (started, called, model, solve): the tick's clock readings [s]
    call: object  # FusedWorkspace.c_call when nothing runs between stage and solve, else None
    needs_v: bool
    fillers: tuple  # (fill, view) per numeric model quantity
    solve: Callable[..., Solution]  # FusedWorkspace.solver(), or _solve_ordinary
    fused_solution: Solution | None  # what solve returns when the fused call answered


def _python_path(p, q, v, layout, references, specs, out, times, call) -> None:
    """The tick when the C one cannot be built (or ``jit=False``): it reads the clock, and
    every call takes Python's path (:meth:`Controller.step`)."""
    times[0] = _clock()


@cache
def _c_stage(compiler: str) -> Callable[..., object]:
    """The ``tick`` function of :data:`wbc.checks.STAGE_SOURCE` built by ``compiler``
    (:func:`wbc.fused.stage_extension`), or :func:`_python_path` if it cannot be built or
    loaded here (no compiler, no Python headers)."""
    module = stage_extension(compiler)
    return _python_path if module is None else module.tick


class Controller:
    """A stack compiled for a robot, solved every control tick.

    Args:
        robot: an object with the robot protocol (see the module docstring).
        stack: the :class:`~wbc.Stack` (compiled here, once).
        backend: backend name (``wbc.solvers.available_backends()``) or a zero-argument
            factory returning a :class:`~wbc.Backend`.
        profile: tolerance profile of the backend, ``"default"`` or ``"tight"``.
        dt: control period [s], written into parameter ``"dt"`` every tick.
        fallback: what to command when a solve fails (the solution still says why):
            ``"hold"`` — zeros (for a velocity-level stack: stop); ``"last"`` — the previous
            command (zeros if none); ``"decelerate"`` — the previous command times
            ``DECELERATION`` (0.5), clipped into this tick's variable bounds when they are
            consistent (for velocity-level stacks: a geometric stop that respects the limits);
            ``"raise"`` — raise :class:`~wbc.InfeasibleError`. When
            only a lower priority failed (``solution.partial``), the command is the solution
            of the levels above it — every hard constraint and higher task still holds — and
            ``solution.fallback`` is ``"partial"``; only ``"raise"`` raises then too.
        warm_start: warm-start every QP from its previous solution.
        kinematics: ``"numeric"`` — model quantities come from the robot's numeric fillers
            every tick; ``"compiled"`` — those with a symbolic form (frame poses, Jacobians,
            drifts of the catalogue robots) are computed *inside* the compiled level functions
            from ``"q"`` (and ``"v"``), see :func:`wbc.passes.compiled_kinematics`; the others stay
            numeric. The tick then calls no kinematics when every quantity is symbolic, and
            those parameters no longer exist in the workspace (same values to round-off, a
            ≈ 35 µs shorter tick on the catalogue robots); ``"auto"`` (default) — compiled
            when the robot offers symbolic forms, else numeric. ``self.kinematics`` holds the
            choice made.
        jit: evaluate the level functions as compiled C (needs a C compiler; each function is
            built once per machine, 0.1–0.5 s, and cached on disk, see :mod:`wbc.cbuild`;
            evaluation drops from ≈ 8 µs to ≈ 0.6 µs for a Panda pose + posture level).
            ``"auto"`` (default): when a C compiler is on the path (``$CC``, default ``cc``),
            else the CasADi virtual machine. ``True`` without a compiler: a warning and the
            virtual machine. Not used on the fused path (which compiles the whole tick).
            ``False`` with ``fused=False``: no C at all, the input checks in Python too.
        fused: the whole tick as one generated C function (compiled kinematics, assembly and
            the daqp solve, see :mod:`wbc.fused`). ``"auto"`` (default): when the backend is
            ``"daqp"``, the cascade has no task-scaling level and a C compiler is present — one
            :class:`RuntimeWarning` if only the compiler is missing, then today's path;
            ``True``: the same, but a stack that cannot be fused is a :class:`~wbc.WbcError`;
            ``False``: today's path. ``self.fused`` says which path is used and
            ``self.fused_reason`` why not.
        missing_limits: what to do when the stack's hard constraints leave some of the robot's
            finite position or velocity limits unbounded (:func:`missing_limits_message`; pink and
            mink apply the model's limits by default, wbc only what the stack holds):
            ``"warn"`` (default) — one :class:`~wbc.errors.MissingLimitsWarning` naming the
            joints and how to bound them; ``"ignore"`` — the stack is limit-free on purpose;
            ``"raise"`` — a :class:`~wbc.WbcError`.
        **options: backend options overriding the profile.

    Attributes:
        last_solution: the :class:`~wbc.Solution` of the last tick, a snapshot no later tick
            writes (on the fused path it is copied from the tick's buffers when first read).
            It also carries ``fallback``: ``None`` when the QP was solved, else the policy that
            produced the command (and its ``message`` says so).
        last_command: the array the last :meth:`step` returned (a snapshot, or the caller's
            ``out``).
        workspace: the :class:`~wbc.Workspace` (parameters, buffers, live backends).
        jit_c: ``jit`` resolved: whether the ordinary path's level functions are compiled C
            (``True``, or ``"auto"`` with a C compiler found); set before
            :meth:`build_fused_workspace` runs.
        model_parameters: the parameter names the model stage fills.
        reference_names: the keywords :meth:`step` accepts.

    Example:
        >>> from wbc.robots.fixed_base import load_panda          # doctest: +SKIP
        >>> from wbc.tasks import FrameTask, ConfigurationLimit   # doctest: +SKIP
        >>> robot = load_panda()                                  # doctest: +SKIP
        >>> stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)  # doctest: +SKIP
        >>> stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))      # doctest: +SKIP
        >>> stack.constrain(ConfigurationLimit(robot))                  # doctest: +SKIP
        >>> ctrl = wbc.Controller(robot, stack, dt=0.01)                # doctest: +SKIP
        >>> v = ctrl.step(q, ee=T_target)                               # doctest: +SKIP
    """

    def __init__(self, robot, stack: Stack, backend: BackendSpec = "daqp",
                 profile: str = "default", dt: float = 0.01, fallback: str = "hold",
                 warm_start: bool = True, kinematics: str = "auto", jit: bool | str = "auto",
                 fused: bool | str = "auto", missing_limits: str = "warn", **options) -> None:
        if fallback not in FALLBACKS:
            raise WbcError(f"unknown fallback {fallback!r}; use one of {list(FALLBACKS)}")
        if not isinstance(missing_limits, str) or missing_limits not in MISSING_LIMITS:
            raise InvalidValueError(f"missing_limits must be one of {list(MISSING_LIMITS)}, "
                                    f"got {missing_limits!r}")
        for name, value in (("jit", jit), ("fused", fused)):
            if value not in (True, False, "auto"):
                raise WbcError(f"{name} must be True, False or 'auto', got {value!r}")
        self.robot = robot
        self.stack = stack
        self.fallback = fallback
        self.jit_c = jit is True or (jit == "auto" and compiler_available())
        self.nq, self.nv = int(robot.nq), int(robot.nv)
        self.compiled = stack.compile()
        _check_task_names(stack, robot)
        if missing_limits != "ignore":
            missing = missing_limits_message(robot, stack)
            if missing is not None and missing_limits == "raise":
                raise WbcError(f"wbc.Controller: {missing}")
            if missing is not None:
                warnings.warn(f"wbc.Controller: {missing}", MissingLimitsWarning, stacklevel=2)
        if kinematics not in ("auto", "compiled", "numeric"):
            raise WbcError(f"kinematics must be 'auto', 'compiled' or 'numeric', got "
                           f"{kinematics!r}")
        if kinematics == "compiled":
            self.compiled = compiled_kinematics(self.compiled, robot)
        elif kinematics == "auto":
            try:
                self.compiled = compiled_kinematics(self.compiled, robot)
                kinematics = "compiled"
            except WbcError:  # no symbolic forms, or joints they do not cover: the getters
                kinematics = "numeric"
        self.kinematics = kinematics
        conflict = fixed_conflict(self.compiled, self.compiled.defaults)
        if conflict is not None:
            label, _, details = conflict
            raise InfeasibleError(f"wbc.Controller: {label}: {details}, whatever the state "
                                  "(values known before the first tick: constants and "
                                  "parameter defaults)")
        fused_workspace = self.build_fused_workspace(fused, backend, profile, warm_start,
                                                     options)
        self.fused = fused_workspace is not None
        self.workspace: Workspace
        if fused_workspace is not None:
            self.workspace = fused_workspace
        else:
            if self.jit_c:
                self.compiled = jit_compiled(self.compiled)
            self.workspace = Workspace(self.compiled, backend, profile, warm_start, **options)
        self._last_solution: Solution | None = None
        self.last_command: np.ndarray | None = None
        self._q: np.ndarray | None = None  # views of "q", "v", "dt" in p (set by _plan)
        self._v: np.ndarray | None = None
        self._dt: np.ndarray | None = None
        self._needs_v = self._needs_drift = False
        self._fillers: list = []
        self.model_parameters: list[str] = []
        self._plan()
        self.dt = dt
        self._references: dict[str, tuple] = {}  # keyword -> see _reference
        self._specs: dict[str, tuple] = {}  # keyword -> its layout for the stage, see _reference
        # the solve step calls: on the fused path the callable FusedWorkspace.solver() hands
        # out, bound once, and the reused solution it answers with
        workspace = self.workspace
        solve: Callable[[float], Solution]
        self._live_solution: Solution | None
        if isinstance(workspace, FusedWorkspace):
            solve, self._live_solution = workspace.solver(), workspace.fused_solution
        else:
            solve, self._live_solution = self._solve_ordinary, None
        # the C tick when this controller compiles C anyway (fused, or jit), else Python's; it
        # makes the fused call itself when no numeric model quantity is filled in between
        uses_c = self.fused or self.jit_c
        tick = _c_stage(os.environ.get("CC", "cc")) if uses_c else _python_path
        parameters = self.compiled.parameters
        layout = (parameters["q"][0] if self._q is not None else -1, self.nq,
                  parameters["v"][0] if self._v is not None else -1, self.nv, self.compiled.n)
        call = (workspace.c_call if isinstance(workspace, FusedWorkspace) and not self._fillers
                else None)
        times = workspace.times if isinstance(workspace, FusedWorkspace) else np.zeros(4)
        self._hot = _HotPath(tick, self.workspace.p, layout, self._specs, times, call,
                             self._needs_v, tuple(self._fillers), solve, self._live_solution)
        stack._controlled = True  # edits after this would not reach the compiled snapshot

    def build_fused_workspace(self, fused: bool | str, backend: BackendSpec, profile: str,
                              warm_start: bool, options: dict) -> FusedWorkspace | None:
        """The workspace of the fused path if it applies (see ``fused`` in the class
        docstring), else ``None``; sets ``self.fused_reason`` (``None``, or why not). Called once
        by ``__init__`` (``self.compiled`` is set). The hook a subclass with a generated tick of
        its own overrides (:class:`wbc.papers.xing.fast.AMPController`), deciding through
        :func:`wbc.fused.build_fused` as this one does."""
        def why_not() -> str | None:
            return (why_not_fused(self.compiled, options) if backend == "daqp" else
                    f"the backend is {backend!r}; the fused tick solves with daqp")

        def slower(why: str) -> None:  # (stacklevel: the caller of Controller(...))
            warnings.warn(f"wbc.Controller: {why}; the tick runs on today's path"
                          + (" (Python around a persistent daqp backend), several times slower"
                             if why.startswith("no C compiler") else ""),
                          RuntimeWarning, stacklevel=5)

        workspace, self.fused_reason = build_fused(
            fused, why_not, lambda: FusedWorkspace(self.compiled, profile, warm_start, **options),
            "the tick cannot be fused", slower)
        return workspace

    # ------------------------------------------------------------------ planning
    def _plan(self) -> None:
        """Map every model-quantity parameter to a writer into its view of ``p``."""
        ws, compiled = self.workspace, self.compiled
        registry = registry_of(self.robot)
        state_shapes = {"q": (self.nq, 1), "v": (self.nv, 1), "dt": (1, 1)}
        for name, (_, shape, _) in compiled.parameters.items():
            if name in STATE_QUANTITIES:
                expected = state_shapes[name]
                view = ws.view(name).reshape(-1)
                if name == "q":
                    self._q = view
                elif name == "v":
                    self._v, self._needs_v = view, True
                else:
                    self._dt = view
            else:
                # a declared quantity must be offered; a plain parameter the robot happens to
                # offer is filled too (names before quantities)
                quantity = (registry.get(name) if name in compiled.quantities else
                            registry.resolve(name))
                if quantity is None:
                    continue
                expected = quantity.shape
                view = ws.view(name)
                if quantity.needs_v:
                    self._needs_v = self._needs_drift = True
                self._fillers.append((quantity.fill, view))
            if shape != expected:
                raise ShapeError(f"model quantity {name!r} is declared with shape {shape}, "
                                 f"but the robot gives {expected}")
            self.model_parameters.append(name)
        self._zero_v = np.zeros(self.nv)
        self._q_shape, self._v_shape = (self.nq,), (self.nv,)
        self._x_shape = (compiled.n,)

    @property
    def reference_names(self) -> list[str]:
        """Keywords :meth:`step` accepts: every non-model parameter, and the task names of the
        ``"<task>.target"`` parameters."""
        names = []
        for name in self.compiled.parameters:
            if name in self.model_parameters:
                continue
            names.append(name)
            if name.endswith(".target"):
                names.append(name[: -len(".target")])
        return sorted(names)

    def last_qps(self) -> list[tuple]:
        """The QPs of the last tick, to inspect or re-solve elsewhere: per QP of the cascade,
        ``(label, (H, g, A, lA, uA, lb, ub), result)`` — the arrays in the form of
        :mod:`wbc.qp` (``min ½x'Hx + g'x``, ``lA <= Ax <= uA``, ``lb <= x <= ub``) exactly as
        the backend saw them (in a level that eliminates the levels above, the reduced QP in
        null-space coordinates) and its :class:`~wbc.qp.QPResult` (``x``, status, multipliers
        ``y``, ``z``, iterations). Levels the tick did not reach are absent. After a fused tick
        (:mod:`wbc.fused`) the QPs the generated daqp solved are evaluated again (slower: for
        diagnostics, not for the control loop). The arrays are live buffers the next tick
        overwrites: copy what you keep. ``wbc bench --export DIR`` writes them as files
        qpsolvers loads."""
        return self.workspace.last_qps()

    @property
    def dt(self) -> float:
        """Control period [s]."""
        return self._dt_value

    @dt.setter
    def dt(self, value: float) -> None:
        value = float(value)
        if not np.isfinite(value) or value <= 0:
            raise InvalidValueError(f"dt must be a finite number > 0, got {value!r}")
        self._dt_value = value
        if self._dt is not None:
            self._dt[0] = value

    # ------------------------------------------------------------------ references
    def _reference(self, key: str) -> tuple:
        """``(name, view, shape, allow_inf, what, paired, pose)`` of reference keyword ``key``
        (cached): its parameter, the view to write, how to check it, its name in errors,
        whether it is a side of a ``"<t>.lower"``/``"<t>.upper"`` pair, and whether it is a
        pose (a ``(4, 4)`` ``"<t>.target"``, e.g. a :class:`~wbc.tasks.FrameTask`'s). A
        keyword that is not a side of a pair gets its spec for the C stage too (the pairs'
        order check stays in Python)."""
        ref = self._references.get(key)
        if ref is None:
            params = self.compiled.parameters
            name = key if key in params else f"{key}.target"
            if name not in params or name in self.model_parameters:
                raise UnknownNameError(
                    f"unknown reference {key!r}; references are {self.reference_names}"
                    + (" (model quantities are filled by the controller; set the period "
                       "with controller.dt)" if key in self.model_parameters else ""))
            at, shape, allow_inf = params[name]
            paired = name.rpartition(".")[2] in ("lower", "upper")
            pose = shape == (4, 4) and name.endswith(".target")
            ref = self._references[key] = (name, self.workspace.view(name), shape, allow_inf,
                                           f"reference {key!r} (parameter {name!r})", paired,
                                           pose)
            if not paired:
                self._specs[key] = (at, *shape, bool(allow_inf), pose)
        return ref

    def set_references(self, **references) -> None:
        """Set references by keyword without solving (checked: name, shape, type, NaN, inf;
        a pose — a ``(4, 4)`` ``"<task>.target"``, as a :class:`~wbc.tasks.FrameTask`'s — must
        be a homogeneous transform whose rotation is one, :func:`wbc.checks.check_pose`, else
        :class:`~wbc.InvalidValueError`). All-or-nothing: every value is checked before any is
        written, so a refused call leaves the controller as it was."""
        if self._last_solution is not None and self._last_solution is self._live_solution:
            self.last_solution  # noqa: B018  (the fused solution's snapshot, before p changes)
        self._write_references(references)

    def _write_references(self, references: dict) -> None:
        """:meth:`set_references` without its snapshot of the last solution (the tick's own
        use: the solution it writes next replaces that one)."""
        checked, paired = [], False
        for key, value in references.items():
            name, view, shape, allow_inf, what, pair, pose = self._reference(key)
            value = checked_array(value, shape, what, allow_inf)
            if pose:
                check_pose(value, what)
            checked.append((name, view, value))
            paired |= pair
        if paired:
            self.workspace.check_bound_pairs({name: value for name, _, value in checked})
        for _, view, value in checked:
            view[...] = value

    # ------------------------------------------------------------------ the tick
    @property
    def last_solution(self) -> Solution | None:
        solution = self._last_solution
        if solution is not None and solution is self._live_solution:
            # the fused tick's own buffers: copied once, when first read
            solution = self._last_solution = solution.snapshot()
        return solution

    @last_solution.setter
    def last_solution(self, solution: Solution | None) -> None:
        self._last_solution = solution

    def step(self, q, v=None, out=None, **references) -> np.ndarray:
        """One control tick: model stage, references, solve, fallback.

        Args:
            q: configuration ``(nq,)``.
            v: velocity ``(nv,)`` (used by ``"v"`` and the drifts; zeros if ``None``).
            out: an array of shape ``(n,)`` (the decision vector's) to write the command
                into, or ``None`` for a new array.
            **references: reference values by keyword (see the module docstring).

        Returns:
            The command: the decision vector ``x`` of the solution, or the fallback's — a new
            array that no later tick writes (``out`` itself when given), on every path and
            backend.
        """
        # One call in C (the tick, wbc.checks.STAGE_SOURCE) checks and writes q, v and the
        # references and, on the fused path when the last tick was fused, makes the fused call
        # and copies the command: then nothing else runs here. It leaves every call it does not
        # accept — a refusal, a list, a keyword seen for the first time, a bad out — to the
        # same checks in Python (_check_and_write), before anything is written either way, and
        # every other tick to _finish. The hot path reads one tuple of what _plan and __init__
        # prepared (an attribute read each would cost ≈ 1 % of a Panda tick).
        tick, p, layout, specs, times, call, _, _, _, fused_solution = self._hot
        answer = tick(p, q, v, layout, references, specs, out, times, call)
        if answer.__class__ is _ndarray:  # the fused call answered: its reused solution
            self._last_solution = fused_solution
            self.last_command = answer
            return answer  # type: ignore[return-value]
        return self._finish(q, v, out, references, answer)  # type: ignore[arg-type]

    def _finish(self, q, v, out, references: dict, staged: bool | None) -> np.ndarray:
        """:meth:`step` after the C tick (or Python's, :func:`_python_path`) returned
        ``staged``: ``None`` — nothing written, the inputs take Python's checks; ``True`` — the
        inputs are written; ``False`` — written, and the fused call made and not answered."""
        _, _, _, _, times, _, needs_v, fillers, solve, fused_solution = self._hot
        if staged is None:
            q, v = self._check_and_write(q, v, out, references)
        if needs_v and v is None:
            v = self._zero_v
            if self._v is not None:
                self._v[...] = v
        if fillers:
            self.robot.update(q, v if self._needs_drift else None)
            for fill, view in fillers:
                fill(view)
        solution = solve(times.item(0), staged is False)  # timings.model: from the tick's start
        if solution is fused_solution:  # a fused call answered: the workspace's reused buffers
            self._last_solution = solution
            if out is None:
                out = solution.x.copy()
            else:
                _copyto(out, solution.x)
            self.last_command = out
            return out
        return self._conclude(solution, out)

    def _check_and_write(self, q, v, out, references: dict) -> tuple:
        """Python's path of :meth:`step`'s inputs: check ``q``, ``v``, ``out`` and the
        references (messages built only on failure, :meth:`_refuse`), then write the
        references, ``q`` and ``v`` (all-or-nothing); ``(q, v)`` as float arrays."""
        if type(q) is not _ndarray or q.dtype is not _FLOAT:  # else asarray would return q
            q = as_float_array(q, "q")
        if q.shape != self._q_shape or not all_finite(q):
            self._refuse("q", q, self.nq)
        if v is not None:
            if type(v) is not _ndarray or v.dtype is not _FLOAT:
                v = as_float_array(v, "v")
            if v.shape != self._v_shape or not all_finite(v):
                self._refuse("v", v, self.nv)
        if out is not None and (type(out) is not _ndarray or out.shape != self._x_shape
                                or out.dtype is not _FLOAT):
            self._refuse_out(out, self.compiled.n)
        if references:  # before any write: a refused reference leaves the state as it was
            self._write_references(references)
        if self._q is not None:
            self._q[...] = q  # (≈ 0.1 µs less than self._q[:] = q)
        if v is not None and self._v is not None:
            self._v[...] = v
        return q, v

    def _solve_ordinary(self, started: float, tried: bool = False) -> Solution:
        """``workspace.solve()`` with ``timings.model`` the time from ``started`` to it (the
        callable :meth:`step` calls when the tick is not fused; see
        :meth:`wbc.fused.FusedWorkspace.solver`; ``tried`` is always ``False`` here)."""
        t1 = _clock()
        solution = self.workspace.solve()
        solution.timings.model = t1 - started
        return solution

    def _conclude(self, solution: Solution, out: np.ndarray | None = None) -> np.ndarray:
        """The command of a tick no fused call answered (the ordinary path's solution, solved
        or not): its ``x``, the partial solution's, or the fallback's (a copy, or written into
        ``out``); records the tick."""
        if solution.status is _SOLVED:
            command = solution.x
        elif solution.partial and self.fallback != "raise":
            solution.fallback = "partial"
            solution.notes.append("command from the levels above (partial)")
            command = solution.x
        else:
            command = self._fall_back(solution)
        if out is None:
            out = command.copy()  # the solution keeps its own x
        else:
            out[:] = command
        self.last_solution = solution
        self.last_command = out
        return out

    @staticmethod
    def _refuse(name: str, value: np.ndarray, size: int) -> None:
        """Raise the error of a bad ``q`` or ``v``."""
        if value.shape != (size,):
            raise ShapeError(f"{name} must have shape ({size},), got {value.shape}")
        raise NonFiniteError(f"{name} contains NaN or inf")

    @staticmethod
    def _refuse_out(out, size: int) -> None:
        """Raise the error of a bad ``out``."""
        raise ShapeError(f"out must be a float numpy array of shape ({size},), got "
                         f"{type(out).__name__} of shape {np.shape(out)}, dtype "
                         f"{getattr(out, 'dtype', None)}")

    def _fall_back(self, solution: Solution) -> np.ndarray:
        policy = self.fallback
        if policy == "raise":
            solution.fallback = "raise"
            self.last_solution = solution
            raise InfeasibleError(f"controller: {solution.message or solution.status.value}")
        if policy == "last" and self.last_command is not None:
            command = self.last_command.copy()
            what = "previous command repeated"
        elif policy == "decelerate" and self.last_command is not None:
            command = DECELERATION * self.last_command
            lower, upper = self.workspace.variable_bounds()
            if np.all(lower <= upper):
                np.clip(command, lower, upper, out=command)
            what = f"previous command × {DECELERATION}, within the bounds"
        else:
            command = np.zeros(self.compiled.n)
            what = "zero command (hold)"
        solution.fallback = policy
        solution.notes.append(f"fallback {policy!r}: {what}")
        return command

    def __repr__(self) -> str:
        return (f"Controller(robot={self.robot!r}, backend={self.workspace.backend_name!r}, "
                f"dt={self.dt}, fallback={self.fallback!r})")


# ---------------------------------------------------------------------- checks when built
def _check_task_names(stack: Stack, robot) -> None:
    """Refuse a task whose name is a parameter the controller fills from this robot (a plain
    ``stack.parameter`` the robot's registry offers, e.g. ``"com"``): ``step(q, com=...)``
    would name the quantity, not the task's target. :meth:`wbc.Stack.add` refuses the clashes
    it can see (the state names, declared quantities); this one needs the robot."""
    registry = registry_of(robot)
    for name in stack.task_names:
        parameter = stack.parameters.get(name)
        if parameter is None or parameter.quantity:
            continue
        if name in registry:
            raise WbcError(f"wbc.Controller: {_shadowing_message(name, name)}")


def _finite(values) -> np.ndarray:
    return np.abs(np.asarray(values, dtype=float).reshape(-1)) < FINITE_LIMIT


def _arm_joints(robot, nq: int, nv: int) -> int | None:
    """The number of trailing arm joints (whose ``q`` and ``v`` entries correspond one to one),
    as :func:`wbc.tasks.posture.arm_size` decides without arguments; ``None`` if unknown."""
    if getattr(robot, "n_arm", None) is not None:
        return int(robot.n_arm)
    if getattr(getattr(robot, "base", None), "nv", None) is not None:
        return nv - int(robot.base.nv)
    return nv if nq == nv else None


def _bounded_coordinates(stack: Stack, start: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """``(by_position, by_velocity)``: boolean masks over the ``nv`` joint coordinates
    ``x[start:start + nv]`` — some hard :class:`~wbc.VariableBounds` of every level puts a side
    on it that depends on ``"q"`` (a position limit: ``ConfigurationLimit``,
    ``JointAccelerationLimit``), or one that does not depend on ``"q"`` or depends on ``"v"``
    (a velocity limit: ``VelocityLimit``, numeric ``Bounds``, ``JointAccelerationLimit``).
    A side is open where it evaluates to ±inf with the parameters' defaults (a side that
    cannot be evaluated, e.g. of the state, counts as closed). One CasADi evaluation and one
    dependency query for all the bounds (≈ 2 ms for a catalogue robot's stack)."""
    lowers: list = []
    uppers: list = []
    columns: list = []
    for entry in stack.constraints:
        term = entry.term
        if not isinstance(term, VariableBounds) or entry.levels is not None:
            continue
        block = stack.variables.slice(term.block)
        size = block.stop - block.start
        lowers.append(as_sx_column(term.lower, size, "bounds", allow_inf=True))
        uppers.append(as_sx_column(term.upper, size, "bounds", allow_inf=True))
        columns.extend(range(block.start - start, block.stop - start))
    by_position, by_velocity = np.zeros(nv, bool), np.zeros(nv, bool)
    if not columns:
        return by_position, by_velocity
    lower, upper = ca.vertcat(*lowers), ca.vertcat(*uppers)
    params = list(stack.parameters.values())
    symbols = ca.vertcat(*[ca.vec(p.symbol) for p in params]) if params else ca.SX(0, 1)
    values = np.concatenate([
        (p.default.reshape(-1, order="F") if p.default is not None else np.full(p.size, np.nan))
        for p in params]) if params else np.zeros(0)
    low, up = (np.asarray(v, dtype=float).reshape(-1) for v in
               ca.Function("sides", [symbols], [lower, upper])(values))
    closed = (low != -np.inf) | (up != np.inf)  # NaN (not evaluable) counts as closed

    def depends(name: str) -> np.ndarray:
        parameter = stack.parameters.get(name)
        if parameter is None:
            return np.zeros(len(columns), bool)
        symbol = ca.vec(parameter.symbol)
        return np.array(ca.which_depends(lower, symbol, 1, True), bool) | np.array(
            ca.which_depends(upper, symbol, 1, True), bool)

    uses_q, uses_v = depends("q"), depends("v")
    for row, joint in enumerate(columns):
        if closed[row] and 0 <= joint < nv:
            by_position[joint] |= uses_q[row]
            by_velocity[joint] |= uses_v[row] or not uses_q[row]
    return by_position, by_velocity


def missing_limits_message(robot, stack: Stack) -> str | None:
    """What of the robot's finite limits no hard constraint of ``stack`` bounds, as a sentence
    naming the joints and how to bound them — or ``None`` when every finite limit is bounded or
    the question cannot be asked (a robot without ``limits``; a decision vector without a block
    of the robot's ``nv`` joint coordinates, e.g. wheel torques).

    The joint coordinates are the whole decision vector when it has ``nv`` entries, else its
    one block of ``nv`` entries. Position limits count on the arm joints (the trailing
    ``n_arm`` coordinates, as :class:`~wbc.tasks.ConfigurationLimit` bounds them); velocity
    limits on every coordinate. Only constraints of every level count (``stack.constrain(task)``
    without ``levels``)."""
    limits = getattr(robot, "limits", None)
    nq, nv = int(robot.nq), int(robot.nv)
    if limits is None:
        return None
    variables = stack.variables
    if variables.n == nv:
        start = 0
    else:
        blocks = [name for name in variables.names if variables.size(name) == nv]
        if len(blocks) != 1:
            return None
        start = variables.slice(blocks[0]).start
    try:
        q_finite = _finite(limits.q_lower) | _finite(limits.q_upper)
        v_finite = _finite(limits.v_lower) | _finite(limits.v_upper)
    except (AttributeError, TypeError, ValueError):
        return None
    arm = _arm_joints(robot, nq, nv)
    position = np.zeros(nv, bool)
    if arm is not None and q_finite.shape == (nq,) and 0 < arm <= min(nq, nv):
        position[nv - arm:] = q_finite[nq - arm:]
    velocity = v_finite if v_finite.shape == (nv,) else np.zeros(nv, bool)
    by_position, by_velocity = _bounded_coordinates(stack, start, nv)
    names = list(getattr(robot, "velocity_names", None) or [f"v[{i}]" for i in range(nv)])
    if len(names) != nv:
        names = [f"v[{i}]" for i in range(nv)]
    parts, remedies = [], []
    for label, need, have, remedy in (
            ("position", position, by_position, "stack.constrain(ConfigurationLimit(robot))"),
            ("velocity", velocity, by_velocity, "stack.constrain(VelocityLimit(robot))")):
        missing = [names[i] for i in np.flatnonzero(need & ~have)]
        if missing:
            listed = ", ".join(missing[:6]) + (", ..." if len(missing) > 6 else "")
            parts.append(f"the {label} limits of {len(missing)} coordinate"
                         f"{'s' if len(missing) > 1 else ''} ({listed})")
            remedies.append(remedy)
    if not parts:
        return None
    return (f"no hard constraint of the stack bounds {' nor '.join(parts)}, which the robot "
            "has: nothing keeps the commands within them (pink and mink apply the model's "
            f"limits by default, wbc only what the stack holds). Add {' and '.join(remedies)} "
            "(wbc.tasks) before building the controller, or pass "
            "missing_limits='ignore' if the stack is limit-free on purpose")
