"""The QP every backend solves, and the contract a backend fulfils.

Every priority level of a stack becomes one dense QP of fixed structure::

    minimise    1/2 x' H x + g' x
    subject to  lA <= A x <= uA        (rows with lA == uA are equalities)
                lb <=   x <= ub

Infinite entries (``±numpy.inf``) in ``lA, uA, lb, ub`` mean "no bound"; a row of ``A`` with both
sides infinite is inert (the cascade pads its frozen rows with such rows so that the shapes stay
fixed from tick to tick). ``H`` is symmetric positive *semi*-definite: undamped levels and the
scaling LP have singular or zero Hessians, and every backend must cope (natively or by proximal
iterations in its adapter).

Sign convention of the multipliers (that of proxqp and osqp): with ``y`` the multipliers of the
rows of ``A`` and ``z`` those of the bounds, the KKT conditions read::

    H x + g + A' y + z = 0,
    y_i >= 0 if row i is at its upper side, y_i <= 0 at its lower side, 0 if inactive,
    likewise z_j for the bounds of x_j.

The core knows this contract only; implementations live in :mod:`wbc.solvers`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


class Status(enum.Enum):
    """Outcome of one solve. Failure is a status, never a silent ``None`` or NaN."""

    SOLVED = "solved"
    INFEASIBLE = "infeasible"
    MAX_ITER = "max_iter"
    NUMERICAL = "numerical_error"

    @property
    def ok(self) -> bool:
        return self is Status.SOLVED


@dataclass(slots=True)
class QPResult:
    """Result of one backend solve.

    Attributes:
        x: primal solution, shape ``(n,)``; all zeros (never NaN) when ``status`` is not SOLVED.
        status: the outcome.
        y: multipliers of the rows of ``A``, shape ``(m,)`` (zeros if the backend gives none).
        z: multipliers of the bounds, shape ``(n,)``.
        iterations: iterations reported by the backend (``-1`` if unknown).
        message: the backend's own words on a failure (or a note on a solved QP, e.g. that
            daqp solved it on its retry). When the solver library printed during the solve
            (qpOASES' "ERROR: Division by zero ..." on a call its retry then solved, say),
            the output was kept off the terminal and the message ends with
            ``"<backend> printed <k> lines (kept off the console; the first: '<line>')"``.
    """

    x: np.ndarray
    status: Status
    y: np.ndarray
    z: np.ndarray
    iterations: int = -1
    message: str = ""


@runtime_checkable
class Backend(Protocol):
    """A persistent QP solver: set up once with the problem's structure, then updated and
    re-solved (warm-started where the solver can) every control tick.

    Arrays passed to ``setup``/``update`` are owned by the caller and rewritten in place every
    tick; a backend that keeps references must copy what it needs. ``H`` and ``A`` may be
    Fortran-ordered (CasADi writes column-major).
    """

    name: str
    profile: str

    def setup(self, H, g, A, lA, uA, lb, ub) -> None:
        """Fix the structure (``n = H.shape[0]``, ``m = A.shape[0]``) and load the first data."""

    def update(self, H, g, A, lA, uA, lb, ub) -> None:
        """Load new data of the same shapes (no re-setup)."""

    def solve(self, warm_start: np.ndarray | None = None) -> QPResult:
        """Solve the loaded problem, optionally warm-started from a primal guess of shape (n,)."""
