"""Machinery shared by every QP backend of :mod:`wbc.solvers`.

A backend subclasses :class:`BackendBase` and implements ``_setup``, ``_update`` and ``_solve``;
the base class checks shapes, resolves tolerance profiles, and guarantees the contract of
:mod:`wbc.qp` on the way out (a failed or non-finite solve becomes a status with ``x = 0``).
"""

from __future__ import annotations

import contextlib
import importlib
import io
from types import ModuleType
from typing import ClassVar

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


@contextlib.contextmanager
def silenced():
    """Swallow what solvers print through Python's ``sys.stdout``/``sys.stderr`` (the qpOASES
    banner that CasADi forwards, OSQP's polishing notes, CasADi's plugin-loading warnings)."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        yield


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
    """

    name: str = "base"
    PROFILES: ClassVar[dict[str, dict]] = {"default": {}, "tight": {}}

    def __init__(self, profile: str = "default", **options):
        self.profile = profile
        self.options = resolve_profile(self.name, self.PROFILES, profile, options)
        self.n: int | None = None
        self.m: int | None = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, profile={self.profile!r})"

    def setup(self, H, g, A, lA, uA, lb, ub) -> None:
        """Fix the structure (``n = H.shape[0]``, ``m = A.shape[0]``) and load the first data."""
        self.n, self.m = n, m = check_problem(H, g, A, lA, uA, lb, ub)
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
        try:
            result = self._solve(warm_start)
        except WbcError:
            raise
        except Exception as err:
            raise backend_error(self.name, "solve", err) from err
        if result.status is Status.SOLVED and not all_finite(result.x):
            return failure(self.n, self.m, Status.NUMERICAL, "non-finite solution")
        return result

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        raise NotImplementedError

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        raise NotImplementedError

    def _solve(self, warm_start: np.ndarray | None) -> QPResult:
        raise NotImplementedError
