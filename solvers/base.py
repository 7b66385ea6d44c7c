"""Machinery shared by every QP backend of :mod:`wbc.solvers`.

A backend subclasses :class:`BackendBase` and implements ``_setup``, ``_update`` and ``_solve``;
the base class checks shapes, resolves tolerance profiles, and guarantees the contract of
:mod:`wbc.qp` on the way out (a failed or non-finite solve becomes a status with ``x = 0``).
What a backend's library prints while solving never reaches the terminal: the backends that
print (qpOASES and other CasADi plugins, OSQP with polishing, qpsolvers) capture it with a
:class:`ConsoleCapture` and count its lines (:data:`CONSOLE_LINES`); the others (daqp, proxqp,
clarabel, quadprog) print nothing, even on failures, and pay nothing.
"""

from __future__ import annotations

import ctypes
import importlib
import importlib.metadata
import math
import os
import sys
import tempfile
import threading
from time import perf_counter
from types import ModuleType
from typing import TextIO

import numpy as np

from wbc.checks import all_finite
from wbc.errors import (
    BackendError,
    BackendUnavailableError,
    ShapeError,
    UnknownNameError,
    WbcError,
)
from wbc.qp import QPResult, Status

#: the clock of :attr:`BackendBase.library_time` (the backends time their library calls with it)
clock = perf_counter


def package_version(package: str) -> str | None:
    """The installed version of distribution ``package`` (``None``: not installed, or ``""``)."""
    if not package:
        return None
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def plain(value):
    """``value`` with numpy scalars and arrays as Python numbers and lists, non-finite floats as
    strings (``"inf"``, ``"-inf"``, ``"nan"``) and other objects as their ``str``: JSON-able."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else str(float(value))
    return value if value is None or isinstance(value, str) else str(value)


class ConsoleCapture:
    """What a solver library prints during a call, kept off the terminal and counted.

    ``with capture: ...`` swaps Python's ``sys.stdout`` and ``sys.stderr`` for the call: what
    goes through them is kept (CasADi forwards its plugins' C output there, qpOASES' error
    messages included; OSQP's Python module prints there too). Writes of other threads during
    the call go on to the streams they were meant for. With ``fd=True`` file descriptors 1 and
    2 are also redirected to a scratch file for the call (``dup``/``dup2``, C's ``fflush``
    before they are restored): for libraries that write from C with ``printf`` (the OSQP
    inside CasADi); whatever any thread writes to them from C meanwhile is counted too.

    Cost per call, measured around qpOASES on a 6-variable QP (a 21 µs solve; Python 3.11,
    2-core x86-64 VM): about 1 µs without ``fd``; with it about 14 µs (the file is in memory
    where the system allows), and 40 µs on a call that prints a line.

    Attributes:
        lines: lines printed during the last call (``0`` when it printed nothing).
        first: the first of them (``""`` when none).
    """

    def __init__(self, fd: bool = False):
        self.lines = 0
        self.first = ""
        self._kept: list[str] = []
        self._sinks = (_Sink(self._kept), _Sink(self._kept))
        self._file = _scratch_file() if fd else None
        self._fflush = ctypes.CDLL(None).fflush if fd else None

    def __enter__(self) -> ConsoleCapture:
        self._kept.clear()
        self._streams = sys.stdout, sys.stderr
        thread = threading.get_ident()
        for sink, stream in zip(self._sinks, self._streams, strict=True):
            sink.stream, sink.thread = stream, thread
        if self._file is not None:
            for stream in self._streams:
                if stream is not None:
                    stream.flush()
            self._saved = os.dup(1), os.dup(2)
            os.dup2(self._file.fileno(), 1)
            os.dup2(self._file.fileno(), 2)
        sys.stdout, sys.stderr = self._sinks
        return self

    def __exit__(self, *exc) -> None:
        sys.stdout, sys.stderr = self._streams
        if self._file is not None and self._fflush is not None:
            self._fflush(None)  # C's buffered output goes to the file, not to the terminal
            for target, saved in zip((1, 2), self._saved, strict=True):
                os.dup2(saved, target)
                os.close(saved)
            fileno = self._file.fileno()
            size = os.lseek(fileno, 0, os.SEEK_CUR)
            if size:
                self._kept.append(os.pread(fileno, size, 0).decode(errors="replace"))
                os.ftruncate(fileno, 0)
                os.lseek(fileno, 0, os.SEEK_SET)
        printed = "".join(self._kept).splitlines()
        self.lines = len(printed)
        self.first = " ".join(printed[0].split()) if printed else ""

    def note(self, backend: str) -> str:
        """The last call's output in words (for :attr:`wbc.qp.QPResult.message`)."""
        return (f"{backend} printed {self.lines} line{'s' if self.lines > 1 else ''} "
                f"(kept off the console; the first: {self.first!r})")


class _Sink:
    """Stands for ``sys.stdout`` or ``sys.stderr`` during a :class:`ConsoleCapture`: keeps the
    capturing thread's writes, passes other threads' on to the stream it stands for."""

    def __init__(self, kept: list[str]):
        self.kept = kept
        self.stream: TextIO | None = None
        self.thread = 0

    def write(self, text: str) -> int:
        if threading.get_ident() == self.thread:
            self.kept.append(text)
        elif self.stream is not None:
            self.stream.write(text)
        return len(text)

    def flush(self) -> None:
        if threading.get_ident() != self.thread and self.stream is not None:
            self.stream.flush()

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


def _scratch_file():
    """A file in memory where the system allows (Linux: ``memfd_create``), else a temporary
    file on disk (4 times slower to write, truncate and read back)."""
    try:
        return open(os.memfd_create("wbc-console"), "r+b", buffering=0)  # noqa: SIM115
    except (AttributeError, OSError):
        return tempfile.TemporaryFile()


def silenced() -> ConsoleCapture:
    """``with silenced(): ...`` discards what is printed through Python's streams (the qpOASES
    banner CasADi forwards when a solver is created, CasADi's plugin-loading warnings)."""
    return ConsoleCapture()


CONSOLE_LINES: dict[str, int] = {}
"""Lines of console output captured while solving, per backend name, since the process started
(see :attr:`BackendBase.console_lines`); read by the studies (``wbc study``)."""


def import_solver(module: str, backend: str) -> ModuleType:
    """Import a solver package, or raise :class:`BackendUnavailableError` naming the backend."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise BackendUnavailableError(
            f"QP backend {backend!r} needs the Python package {module!r}, which is not "
            f"importable: {exc}"
        ) from exc


def resolve_profile(
    backend: str, profiles: dict[str, dict], profile: str, overrides: dict
) -> dict:
    """Options of ``profile`` for ``backend``, updated with ``overrides`` (which win)."""
    if profile not in profiles:
        raise UnknownNameError(
            f"unknown tolerance profile {profile!r} for QP backend {backend!r}; "
            f"known profiles: {', '.join(sorted(profiles))}"
        )
    return {**profiles[profile], **overrides}


def check_option_names(backend: str, options: dict, known) -> None:
    """Raise :class:`UnknownNameError` if ``options`` has a name outside ``known``."""
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise UnknownNameError(
            f"QP backend {backend!r}: unknown options {unknown}; known: {', '.join(sorted(known))}"
        )


def backend_error(backend: str, stage: str, err: Exception) -> BackendError:
    """A solver library's own exception ``err`` (a rejected option, a crash) as a
    :class:`~wbc.BackendError` naming the backend and the stage (``"options"``, ``"setup"``,
    ``"update"``, ``"solve"``), keeping the library's words."""
    return BackendError(f"QP backend {backend!r} failed in {stage}: {type(err).__name__}: {err}")


def check_problem(H, g, A, lA, uA, lb, ub) -> tuple[int, int]:
    """Shapes ``(n, m)`` of a QP in the form of :mod:`wbc.qp`, or :class:`ShapeError`."""
    n = np.shape(g)[0] if np.ndim(g) == 1 else -1
    if n < 0 or np.shape(H) != (n, n):
        raise ShapeError(f"QP: H must be (n, n) and g (n,), got H {np.shape(H)}, g {np.shape(g)}")
    if np.ndim(A) != 2 or np.shape(A)[1] != n:
        raise ShapeError(f"QP: A must be (m, {n}), got {np.shape(A)}")
    m = np.shape(A)[0]
    for label, vector, size in (("lA", lA, m), ("uA", uA, m), ("lb", lb, n), ("ub", ub, n)):
        if np.shape(vector) != (size,):
            raise ShapeError(f"QP: {label} must be ({size},), got {np.shape(vector)}")
    return n, m


def failure(n: int, m: int, status: Status, message: str, iterations: int = -1) -> QPResult:
    """Result of a failed solve: zeros everywhere, the status and the solver's words."""
    return QPResult(
        x=np.zeros(n), status=status, y=np.zeros(m), z=np.zeros(n),
        iterations=iterations, message=message,
    )


def empty_sides(lower: np.ndarray, upper: np.ndarray) -> bool:
    """Whether some pair of sides admits nothing: ``lower > upper``, ``lower = +inf`` or
    ``upper = -inf`` (a joint outside its limits gives such bounds). Backends whose solver
    does not report these as infeasible check with this and report INFEASIBLE themselves."""
    return bool(np.any(lower > upper) or np.any(lower == np.inf) or np.any(upper == -np.inf))


def empty_failure(name: str, n: int, m: int) -> QPResult:
    """The INFEASIBLE result of a problem with :func:`empty_sides`."""
    return failure(n, m, Status.INFEASIBLE, f"{name}: a lower side above its upper one, or an "
                   "infinite side on the wrong side (lower = +inf, upper = -inf)", 0)


class BackendBase:
    """Common part of the persistent QP backends (see :class:`wbc.qp.Backend`).

    Args:
        profile: name of a tolerance profile of the backend (``"default"``, ``"tight"``).
        **options: solver settings that override the profile's.

    Subclasses define ``name``, ``PROFILES`` (profile name -> settings dict) and the three
    hooks. Data given to the hooks have been shape-checked; the hooks must copy what they keep.
    What a hook raises that is not a :class:`~wbc.WbcError` (the solver library's own
    exceptions) leaves :meth:`setup`, :meth:`update` and :meth:`solve` as a
    :class:`~wbc.BackendError` naming the backend.

    A subclass whose library prints while solving sets ``self._console`` to a
    :class:`ConsoleCapture` (``None``, the default, costs nothing): :meth:`solve` then keeps
    that output off the terminal, counts its lines in :attr:`console_lines` and
    :data:`CONSOLE_LINES`, and appends a note to the result's ``message`` (which the cascade
    passes on to ``Solution.message`` when the level fails).

    Attributes:
        console_lines: lines of console output this backend's solves printed (kept off the
            terminal) since it was made.
        library_time: seconds spent inside the solver library's own calls (its setup, data
            update and solve) since the last :meth:`setup` or :meth:`update` — the rest of a
            backend's time is its adapter's (data layout, checks, multipliers). Each timed call
            costs two clock reads (≈ 0.1 µs). Benchmarks read it (``wbc bench``).
        cascade_caveat: what was measured when this backend (with its profile) does not give
            the exact lexicographic answer on multi-level stacks, else ``None`` (set by
            :func:`wbc.solvers.make_backend` from ``CASCADE_CAVEATS``).
    """

    name: str = "base"
    #: the distribution (pip name) of the solver library, whose version :meth:`settings` reports
    package: str = ""
    cascade_caveat: str | None = None
    PROFILES: dict[str, dict] = {"default": {}, "tight": {}}  # an instance may have its own
    # n and m for the hooks: they run after setup(), which sets both, so never None there
    _n: int
    _m: int

    def __init__(self, profile: str = "default", **options):
        self.profile = profile
        self.options = resolve_profile(self.name, self.PROFILES, profile, options)
        self.n: int | None = None
        self.m: int | None = None
        self.console_lines = 0
        self.library_time = 0.0
        self._console: ConsoleCapture | None = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, profile={self.profile!r})"

    def settings(self) -> dict:
        """What this backend solves with, for reports (JSON-able): ``{"backend", "profile",
        "package", "version", "options", "set_by_wbc"}`` — ``options`` are the resolved
        settings: the library's defaults where the library exposes them, updated with the
        profile's and the caller's (``set_by_wbc`` names those); infinities as ``"inf"``."""
        return {"backend": self.name, "profile": self.profile, "package": self.package or None,
                "version": package_version(self.package),
                "options": plain({**self._library_defaults(), **self.options}),
                "set_by_wbc": sorted(self.options)}

    def _library_defaults(self) -> dict:
        """The library's own default settings (overridden by backends that can read them)."""
        return {}

    def setup(self, H, g, A, lA, uA, lb, ub) -> None:
        """Fix the structure (``n = H.shape[0]``, ``m = A.shape[0]``) and load the first data."""
        n, m = check_problem(H, g, A, lA, uA, lb, ub)
        self.library_time = 0.0
        self.n, self.m = self._n, self._m = n, m
        self._shapes = ((n, n), (n,), (m, n), (m,), (m,), (n,), (n,))
        try:
            self._setup(H, g, A, lA, uA, lb, ub)
        except WbcError:
            raise
        except Exception as err:
            raise backend_error(self.name, "setup", err) from err

    def update(self, H, g, A, lA, uA, lb, ub) -> None:
        """Load new data of the shapes given to :meth:`setup` (no re-setup)."""
        if self.n is None:
            raise WbcError(f"QP backend {self.name!r}: update() called before setup()")
        shapes = (H.shape, g.shape, A.shape, lA.shape, uA.shape, lb.shape, ub.shape)
        if shapes != self._shapes:  # one comparison: this runs every tick
            raise ShapeError(
                f"QP backend {self.name!r} was set up for (H, g, A, lA, uA, lb, ub) shapes "
                f"{self._shapes}; got {shapes}"
            )
        self.library_time = 0.0
        try:  # free in CPython >= 3.11 when nothing is raised
            self._update(H, g, A, lA, uA, lb, ub)
        except WbcError:
            raise
        except Exception as err:
            raise backend_error(self.name, "update", err) from err

    def solve(self, warm_start: np.ndarray | None = None) -> QPResult:
        """Solve the loaded problem, optionally warm-started from a primal guess of shape (n,)."""
        if self.n is None:
            raise WbcError(f"QP backend {self.name!r}: solve() called before setup()")
        console = self._console
        try:
            if console is None:
                result = self._solve(warm_start)
            else:
                with console:
                    result = self._solve(warm_start)
        except WbcError:
            raise
        except Exception as err:
            raise backend_error(self.name, "solve", err) from err
        if result.status is Status.SOLVED and not all_finite(result.x):
            result = failure(self._n, self._m, Status.NUMERICAL, "non-finite solution")
        if console is not None and console.lines:
            self.console_lines += console.lines
            CONSOLE_LINES[self.name] = CONSOLE_LINES.get(self.name, 0) + console.lines
            note = console.note(self.name)
            result.message = f"{result.message}; {note}" if result.message else note
        return result

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        raise NotImplementedError

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        raise NotImplementedError

    def _solve(self, warm_start: np.ndarray | None) -> QPResult:
        raise NotImplementedError
