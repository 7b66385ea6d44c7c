"""The error hierarchy of wbc. Every message names the task, parameter or shape involved."""

from __future__ import annotations


class WbcError(Exception):
    """Root of every error raised by wbc."""


class ShapeError(WbcError, ValueError):
    """An array or expression has the wrong shape."""


class NonFiniteError(WbcError, ValueError):
    """A coefficient, bound or configuration holds NaN (or inf where inf is meaningless)."""


class BoundsOrderError(WbcError, ValueError):
    """A lower bound exceeds its upper bound."""


class InvalidValueError(WbcError, ValueError):
    """A number is outside its domain: a negative weight, gain or damping, an indefinite
    metric or mobility, a non-positive period."""


class NonAffineError(WbcError, ValueError):
    """A task expression is not affine in the decision vector."""


class UnknownNameError(WbcError, KeyError):
    """A name (backend, robot, frame, parameter, variable block) is not known.

    The message lists the names that are known.
    """

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


class BackendUnavailableError(UnknownNameError):
    """The requested QP backend is unknown or its package is not installed."""


class InfeasibleError(WbcError, RuntimeError):
    """A problem has no solution; raised only where a status cannot be returned instead."""


class ModelLoadError(WbcError, ValueError):
    """A robot model file (URDF) is missing or cannot be parsed; the message names the file and
    gives the parser's reason."""


class MissingDependencyError(WbcError, ImportError):
    """An optional package a feature needs is not installed; the message says how to install
    it (e.g. ``pip install 'wbc[pink]'``)."""


class BackendError(WbcError, RuntimeError):
    """A QP backend's own library raised (a rejected option, a crash inside the solver); the
    message names the backend and keeps the library's words."""


class MissingLimitsWarning(UserWarning):
    """A :class:`~wbc.Controller` was built over a stack whose hard constraints leave some of
    the robot's finite position or velocity limits unbounded: nothing keeps the commands within
    them (pink and mink apply the model's limits by default; wbc applies what the stack says).
    The message names the joints and how to bound them; ``Controller(...,
    missing_limits="ignore")`` says the stack is limit-free on purpose."""
