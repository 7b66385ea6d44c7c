"""Names of the QP backends, what is installed, and the factory.

Names: the native persistent adapters ``"daqp"``, ``"proxqp"``, ``"osqp"``, ``"clarabel"``,
``"quadprog"``, ``"qpoases"`` (CasADi's qpOASES plugin); other CasADi conic plugins as
``"casadi:<plugin>"``; any solver of qpsolvers as ``"qpsolvers:<solver>"`` (stateless).
:func:`available_backends` lists the installed native ones, the tested CasADi plugins that load,
and the qpsolvers solvers that have no native adapter; :func:`make_backend` also accepts the
others explicitly (``"qpsolvers:daqp"``, ``"casadi:qpoases"``), for benchmarks.
"""

from __future__ import annotations

import functools
import importlib.util

from wbc.errors import BackendUnavailableError, WbcError

from .base import BackendBase, backend_error, silenced
from .casadi_backend import CasadiConicBackend
from .clarabel_backend import ClarabelBackend
from .daqp_backend import DaqpBackend
from .osqp_backend import OsqpBackend
from .proxqp_backend import ProxqpBackend
from .qpsolvers_backend import QpsolversBackend
from .quadprog_backend import QuadprogBackend

NATIVE: dict[str, tuple[type[BackendBase], str]] = {
    "daqp": (DaqpBackend, "daqp"),
    "proxqp": (ProxqpBackend, "proxsuite"),
    "osqp": (OsqpBackend, "osqp"),
    "clarabel": (ClarabelBackend, "clarabel"),
    "quadprog": (QuadprogBackend, "quadprog"),
}
"""Native adapter and the package it needs, per name (``"qpoases"`` is CasADi's, below)."""

CASADI_PLUGINS = ("qpoases", "osqp")
"""CasADi conic plugins that pass the backend tests; ``qpoases`` is listed as ``"qpoases"``."""


def _installed(package: str) -> bool:
    return importlib.util.find_spec(package) is not None


@functools.cache
def _has_conic(plugin: str) -> bool:
    if not _installed("casadi"):
        return False
    import casadi

    with silenced():  # CasADi warns about plugins whose libraries are missing
        return bool(casadi.has_conic(plugin))


def _casadi_plugins() -> tuple[str, ...]:
    return tuple(p for p in CASADI_PLUGINS if _has_conic(p))


@functools.cache
def _qpsolvers_solvers() -> tuple[str, ...]:
    if not _installed("qpsolvers"):
        return ()
    import qpsolvers

    return tuple(qpsolvers.available_solvers)


def _casadi_name(plugin: str) -> str:
    return "qpoases" if plugin == "qpoases" else f"casadi:{plugin}"


def available_backends() -> list[str]:
    """Names of the installed backends: native ones first, then CasADi's, then qpsolvers'."""
    names = [name for name, (_, package) in NATIVE.items() if _installed(package)]
    names += [_casadi_name(plugin) for plugin in _casadi_plugins()]
    native = set(NATIVE) | {"qpoases"}
    names += [f"qpsolvers:{s}" for s in _qpsolvers_solvers() if s not in native]
    return names


def make_backend(name: str, profile: str = "default", **options) -> BackendBase:
    """A new, not yet set up, backend.

    Args:
        name: a name of :func:`available_backends`, or ``"qpsolvers:<solver>"`` /
            ``"casadi:<plugin>"`` for any installed solver or plugin.
        profile: tolerance profile, ``"default"`` or ``"tight"`` (equivalence tests).
        **options: solver settings overriding the profile's.

    Raises:
        BackendUnavailableError: unknown name, or its package is not installed; the message
            lists the available names.
        UnknownNameError: unknown profile or option name (the message lists the known ones).
        BackendError: the solver library rejected an option.
    """
    family, _, solver = name.partition(":")
    try:  # a solver library rejecting an option raises its own exception type
        if name in NATIVE and _installed(NATIVE[name][1]):
            return NATIVE[name][0](profile, **options)
        if name == "qpoases" and _has_conic("qpoases"):
            return CasadiConicBackend("qpoases", profile, name="qpoases", **options)
        if family == "casadi" and solver and _has_conic(solver):
            return CasadiConicBackend(solver, profile, **options)
        if family == "qpsolvers" and solver in _qpsolvers_solvers():
            return QpsolversBackend(solver, profile, **options)
    except WbcError:
        raise
    except Exception as err:
        raise backend_error(name, "options", err) from err
    raise BackendUnavailableError(
        f"unknown or unavailable QP backend {name!r}; available: "
        f"{', '.join(available_backends())} (also 'qpsolvers:<solver>' for "
        f"{', '.join(_qpsolvers_solvers()) or 'none'}, and 'casadi:<conic plugin>')"
    )

