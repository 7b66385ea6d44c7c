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
values, no robot call on the tick (see :func:`compiled_kinematics`).

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
Write ``q``, ``v``, ``dt`` → ``robot.update`` → the quantity fillers (a loop over the few model
quantities, never over tasks) → references → ``workspace.solve()`` (one compiled evaluation
and one warm-started backend solve per priority level) → the fallback policy if the solve
failed. ``solution.timings.model`` holds the first four steps.

On the fused path (the default for a stack on daqp without task-scaling levels, with a C
compiler, see :mod:`wbc.fused`), the solve is one call of a generated C function holding the
compiled kinematics, the assembly and the daqp solves of every level (``timings.solve``), made
by the tick itself (a closure over the buffers, built once); a tick it does not solve is
solved again on the ordinary path, so statuses, partial solutions and fallbacks read the same.
The returned command and ``last_solution`` are then reused buffers.

A failed tick costs about what a solved one does: the search for the conflicting constraints
(:mod:`wbc.infeasibility`) runs when ``solution.conflict`` or ``solution.message`` is read.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings

import casadi as ca
import numpy as np

from .checks import all_finite, as_float_array, check_pose, checked_array
from .compiler import CompiledStack
from .errors import (
    InfeasibleError,
    InvalidValueError,
    NonFiniteError,
    ShapeError,
    UnknownNameError,
    WbcError,
)
from .fused import FusedWorkspace, compiler_available, why_not_fused
from .infeasibility import fixed_conflict
from .jit import jit_compiled
from .qp import Status
from .quantities import STATE_QUANTITIES, registry_of
from .solution import Solution
from .stack import Stack
from .workspace import BackendSpec, Workspace

FALLBACKS = ("hold", "last", "decelerate", "raise")
# for the tick: module globals, looked up faster than attributes
_clock, _ndarray, _FLOAT = time.perf_counter, np.ndarray, np.dtype(float)
_NAN = math.nan
_SOLVED = Status.SOLVED
DECELERATION = 0.5  # "decelerate": the previous command's share kept per failed tick


def check_frame(robot, frame: str, what: str) -> None:
    """Raise :class:`~wbc.UnknownNameError` if ``robot`` knows its frames (``has_frame`` or
    ``frame_names``) and ``frame`` is not one of them."""
    known = getattr(robot, "frame_names", None)
    has_frame = getattr(robot, "has_frame", None)
    if has_frame is not None:
        ok = has_frame(frame)
    elif known is not None:
        ok = frame in known
    else:
        return
    if not ok:
        raise UnknownNameError(f"{what}: unknown frame {frame!r}"
                               + (f"; frames are {sorted(known)}" if known else ""))


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
            from ``"q"`` (and ``"v"``), see :func:`compiled_kinematics`; the others stay
            numeric. The tick then calls no kinematics when every quantity is symbolic, and
            those parameters no longer exist in the workspace (same values to round-off, a
            ≈ 35 µs shorter tick on the catalogue robots); ``"auto"`` (default) — compiled
            when the robot offers symbolic forms, else numeric. ``self.kinematics`` holds the
            choice made.
        jit: evaluate the level functions as compiled C (needs a C compiler; each function is
            built once per machine, 0.1–0.5 s, and cached on disk, see :mod:`wbc.jit`;
            evaluation drops from ≈ 8 µs to ≈ 0.6 µs for a Panda pose + posture level).
            ``"auto"`` (default): when a C compiler is on the path (``$CC``, default ``cc``),
            else the CasADi virtual machine. ``True`` without a compiler: a warning and the
            virtual machine. Not used on the fused path (which compiles the whole tick).
        fused: the whole tick as one generated C function (compiled kinematics, assembly and
            the daqp solve, see :mod:`wbc.fused`). ``"auto"`` (default): when the backend is
            ``"daqp"``, the cascade has no task-scaling level and a C compiler is present — one
            :class:`RuntimeWarning` if only the compiler is missing, then today's path;
            ``True``: the same, but a stack that cannot be fused is a :class:`~wbc.WbcError`;
            ``False``: today's path. ``self.fused`` says which path is used and
            ``self.fused_reason`` why not.
        **options: backend options overriding the profile.

    Attributes:
        last_solution: the :class:`~wbc.Solution` of the last tick, a snapshot no later tick
            writes (on the fused path it is copied from the tick's buffers when first read).
            It also carries ``fallback``: ``None`` when the QP was solved, else the policy that
            produced the command (and its ``message`` says so).
        last_command: the array the last :meth:`step` returned (a snapshot, or the caller's
            ``out``).
        workspace: the :class:`~wbc.Workspace` (parameters, buffers, live backends).
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
                 fused: bool | str = "auto", **options) -> None:
        if fallback not in FALLBACKS:
            raise WbcError(f"unknown fallback {fallback!r}; use one of {list(FALLBACKS)}")
        for name, value in (("jit", jit), ("fused", fused)):
            if value not in (True, False, "auto"):
                raise WbcError(f"{name} must be True, False or 'auto', got {value!r}")
        self.robot = robot
        self.stack = stack
        self.fallback = fallback
        self.nq, self.nv = int(robot.nq), int(robot.nv)
        self.compiled = stack.compile()
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
        self.workspace = self._fused_workspace(fused, backend, profile, warm_start, options)
        self.fused = self.workspace is not None
        if not self.fused:
            if jit is True or (jit == "auto" and compiler_available()):
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
        # keyword -> (parameter name, view, allow_inf), cached
        self._references: dict[str, tuple] = {}  # keyword -> see _reference
        self._tick = self._tick_function()
        stack._controlled = True  # edits after this would not reach the compiled snapshot
        if type(self).step is Controller.step:  # (a subclass's own step stays in charge)
            self.step = self._tick  # type: ignore[method-assign]  # one call less per tick

    def _fused_workspace(self, fused, backend, profile, warm_start, options):
        """A :class:`~wbc.fused.FusedWorkspace` if the fused path applies (see ``fused`` in the
        class docstring), else ``None`` with ``self.fused_reason`` saying why."""
        if fused is False:
            self.fused_reason = "turned off (fused=False)"
            return None
        reason = (why_not_fused(self.compiled, options) if backend == "daqp" else
                  f"the backend is {backend!r}; the fused tick solves with daqp")
        if reason is None and not compiler_available():
            reason = "no C compiler found ($CC, default cc)"
            warnings.warn(f"wbc.Controller: {reason}; the tick runs on today's path (Python "
                          "around a persistent daqp backend), several times slower",
                          RuntimeWarning, stacklevel=3)
        if reason is None:
            try:
                workspace = FusedWorkspace(self.compiled, profile, warm_start, **options)
            except RuntimeError as err:  # the compiler failed
                reason = f"C compilation failed: {err}"
                warnings.warn(f"wbc.Controller: {reason}; the tick runs on today's path",
                              RuntimeWarning, stacklevel=3)
            else:
                self.fused_reason = None
                return workspace
        if fused is True:
            raise WbcError(f"fused=True, but the tick cannot be fused: {reason}")
        self.fused_reason = reason
        return None

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
        pose (a ``(4, 4)`` ``"<t>.target"``, e.g. a :class:`~wbc.tasks.FrameTask`'s)."""
        ref = self._references.get(key)
        if ref is None:
            params = self.compiled.parameters
            name = key if key in params else f"{key}.target"
            if name not in params or name in self.model_parameters:
                raise UnknownNameError(
                    f"unknown reference {key!r}; references are {self.reference_names}"
                    + (" (model quantities are filled by the controller; set the period "
                       "with controller.dt)" if key in self.model_parameters else ""))
            _, shape, allow_inf = params[name]
            paired = name.rpartition(".")[2] in ("lower", "upper")
            pose = shape == (4, 4) and name.endswith(".target")
            ref = self._references[key] = (name, self.workspace.view(name), shape, allow_inf,
                                           f"reference {key!r} (parameter {name!r})", paired,
                                           pose)
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

        (Each controller holds the tick as a closure over its buffers, made once by
        :meth:`_tick_function`; ``controller.step`` is that closure, this method calls it.)
        """
        return self._tick(q, v, out, **references)

    def _tick_function(self):
        """The tick as a closure over the controller's buffers and the workspace's calls (bound
        once here): local names instead of attribute lookups, and on the fused path the
        generated call made here without the workspace's method around it — ≈ 0.2 µs less
        Python per tick on the Panda problem, measured interleaved with placo."""
        ctrl, workspace, robot = self, self.workspace, self.robot
        q_view, v_view, needs_v, needs_drift = self._q, self._v, self._needs_v, self._needs_drift
        fillers, zero_v = tuple(self._fillers), self._zero_v
        q_shape, v_shape, nq, nv = self._q_shape, self._v_shape, self.nq, self.nv
        refuse, write_references, conclude = self._refuse, self._write_references, self._conclude
        refuse_out, copyto = self._refuse_out, np.copyto
        clock, ndarray, FLOAT, nan = _clock, _ndarray, _FLOAT, _NAN
        finite = all_finite
        fused = isinstance(workspace, FusedWorkspace)
        n = self.compiled.n
        if fused:
            unset, after_failure = workspace._unset, workspace.solve_after_failed_call
            solved_bookkeeping, no_qps = workspace.fused_tick_solved, workspace._no_qps
            call, done, solution, timings = workspace.call_buffers()
            x = solution.x
            self._live_solution = solution
        else:
            self._live_solution = None

        def tick(q, v=None, out=None, **references):
            # the checks' messages are built only on failure (refuse)
            t0 = clock()
            if type(q) is not ndarray or q.dtype is not FLOAT:  # else asarray would return q
                q = as_float_array(q, "q")
            if q.shape != q_shape or not finite(q):
                refuse("q", q, nq)
            if v is not None:
                if type(v) is not ndarray or v.dtype is not FLOAT:
                    v = as_float_array(v, "v")
                if v.shape != v_shape or not finite(v):
                    refuse("v", v, nv)
            if out is not None and (type(out) is not ndarray or out.shape != (n,)
                                    or out.dtype is not FLOAT):
                refuse_out(out, n)
            if references:  # before any write: a refused reference leaves the state as it was
                write_references(references)
            if q_view is not None:
                q_view[:] = q
            if needs_v:
                if v is None:
                    v = zero_v
                if v_view is not None:
                    v_view[:] = v
            if fillers:
                robot.update(q, v if needs_drift else None)
                for fill, view in fillers:
                    fill(view)
            # the fused call, unless a parameter was never set (the workspace raises) or the
            # back-off after failed calls is running
            if fused and not unset and not workspace._skip:
                done[0] = nan
                t1 = clock()
                call()
                t2 = clock()
                if done[0] == done[0]:  # not NaN: every level solved
                    if workspace._solved is not no_qps:  # the last tick took the ordinary path
                        solved_bookkeeping()
                    timings.model = t1 - t0
                    timings.solve = t2 - t1
                    ctrl._last_solution = solution
                    if out is None:
                        out = x.copy()
                    else:
                        copyto(out, x)
                    ctrl.last_command = out
                    return out
                return conclude(after_failure(), t1 - t0, out)
            t1 = clock()
            return conclude(workspace.solve(), t1 - t0, out)

        return tick

    def _conclude(self, solution: Solution, model_time: float,
                  out: np.ndarray | None = None) -> np.ndarray:
        """The command of a solved (or failed) tick: the solution's ``x``, the partial
        solution's, or the fallback's (a copy, or written into ``out``); records the tick."""
        solution.timings.model = model_time
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


def compiled_kinematics(compiled: CompiledStack, robot) -> CompiledStack:
    """A copy of ``compiled`` whose level functions compute every model quantity that has a
    symbolic form (``robot.quantities``, e.g. ``"pose[<frame>]"``, ``"J[<frame>]"``,
    ``"Jdot_v[<frame>]"``) from parameters ``"q"`` (and ``"v"`` for quantities that need it)
    inside the compiled functions. Those parameters leave the layout; ``"q"`` and ``"v"`` are
    appended if the stack needs them and had none.

    Raises:
        WbcError: no quantity of the stack has a symbolic form on this robot.
    """
    registry = registry_of(robot)
    replaced, numeric_only = {}, []  # parameter name -> Quantity; names without symbolic form
    for name in compiled.parameters:
        if name in STATE_QUANTITIES:
            continue
        quantity = (registry.get(name) if name in compiled.quantities else
                    registry.resolve(name))
        if quantity is not None:
            if quantity.symbolic is not None:
                replaced[name] = quantity
            else:
                numeric_only.append(name)
    if not replaced:
        if numeric_only:
            raise WbcError(f"kinematics='compiled' needs symbolic forms of the model quantities "
                           f"{numeric_only} (e.g. robot.symbolic_frame(frame) -> "
                           f"casadi.Function); {type(robot).__name__} offers none")
        return compiled
    params = dict(compiled.parameters)
    n_p = compiled.defaults.shape[0]
    needs_v = any(quantity.needs_v for quantity in replaced.values())
    appended: list[int] = []
    for name, size, needed in (("q", int(robot.nq), True), ("v", int(robot.nv), needs_v)):
        if needed and name not in params:
            params[name] = (n_p + sum(appended), (size, 1), False)
            appended.append(size)
    defaults = np.concatenate([compiled.defaults, np.full(sum(appended), np.nan)])
    p = ca.SX.sym("p", defaults.shape[0])

    def column(name: str) -> ca.SX:
        offset, (rows, _), _ = params[name]
        return p[offset:offset + rows]

    entries = [p[i] for i in range(n_p)]
    for name, quantity in replaced.items():
        offset, shape, _ = params.pop(name)
        build = quantity.symbolic
        assert build is not None  # replaced holds the quantities with a symbolic form only
        function = build()
        inputs = [column("q"), column("v")] if quantity.needs_v else [column("q")]
        value = function(*inputs)
        if value.shape != shape:
            raise ShapeError(f"the symbolic form of {name!r} gives shape {value.shape}, the "
                             f"stack declares {shape}")
        for c in range(shape[1]):
            for r in range(shape[0]):
                entries[offset + c * shape[0] + r] = value[r, c]
    p_in = ca.vertcat(*entries)
    blocks = []
    for block in compiled.blocks:
        fn = block.function
        outputs = fn.call([p_in])
        new = ca.Function(f"{fn.name()}_kin", [p], outputs, fn.name_in(), fn.name_out())
        names = block.hard_names
        if names is not None and names.bound_values is not None:  # a function of p too
            bounds = names.bound_values
            names = dataclasses.replace(names, bound_values=ca.Function(
                f"{bounds.name()}_kin", [p], bounds.call([p_in])))
        blocks.append(dataclasses.replace(block, function=new, hard_names=names))
    residuals = compiled.residuals
    if residuals is not None:
        x = ca.SX.sym("x", compiled.n)
        residuals = ca.Function("residuals_kin", [p, x], residuals.call([p_in, x]))
    quantities = compiled.quantities - replaced.keys()
    if appended:
        quantities = quantities | {"q"} | ({"v"} if needs_v else set())
    return dataclasses.replace(compiled, parameters=params, defaults=defaults,
                               blocks=tuple(blocks), quantities=frozenset(quantities),
                               residuals=residuals)
