"""wbc — optimization-based whole-body control of mobile manipulators.

A controller is a :class:`Stack` of tasks (costs, equalities, inequalities, bounds) over an
explicit decision vector (:class:`Variables`), written with CasADi, compiled once into one
function per priority level, and solved every tick by a swappable, persistent QP backend
(:mod:`wbc.solvers`).

:class:`Controller` is imported on first use (``wbc.Controller``, ``from wbc import
Controller``): it brings the fused tick and its C compilation (``wbc.fused``, ``wbc.jit``),
which the task library (``import wbc.tasks``) and the simulator do not need.
"""

from typing import TYPE_CHECKING

from .compiler import CompiledStack
from .errors import (
    BackendError,
    BackendUnavailableError,
    BoundsOrderError,
    InfeasibleError,
    InvalidValueError,
    MissingDependencyError,
    ModelLoadError,
    NonAffineError,
    NonFiniteError,
    ShapeError,
    UnknownNameError,
    WbcError,
)
from .qp import Backend, QPResult, Status
from .solution import LevelResult, Solution, Timings
from .stack import Parameter, Stack
from .terms import Cost, Equality, Inequality, Task, Term, VariableBounds
from .variables import Variables
from .workspace import Workspace

if TYPE_CHECKING:
    from .controller import Controller

__version__ = "0.1.0"

__all__ = [
    "Backend", "BackendError", "BackendUnavailableError", "BoundsOrderError", "CompiledStack",
    "Controller", "Cost", "Equality", "InfeasibleError", "Inequality", "InvalidValueError",
    "LevelResult", "MissingDependencyError", "ModelLoadError", "NonAffineError",
    "NonFiniteError", "Parameter", "QPResult", "ShapeError", "Solution",
    "Stack", "Status",
    "Task", "Term", "Timings", "UnknownNameError", "VariableBounds", "Variables", "WbcError",
    "Workspace",
]


def __getattr__(name: str):
    """``wbc.Controller``, imported on first use (see the module docstring)."""
    if name == "Controller":
        from .controller import Controller

        return Controller
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), "Controller"})
