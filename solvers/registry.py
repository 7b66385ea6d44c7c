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


#: ``(name, profile) -> what was measured``: backends that do not give the exact lexicographic
#: answer on multi-level stacks whose limits saturate (``wbc exactness``: 3 × ~1000 states of
#: random, saturating and strict-priority families on the catalogue robots and URDF arms on
#: every base; 2026-11-27). A workspace of more than one QP on one of these warns with it.
CASCADE_CAVEATS = {
    ("osqp", "default"): "99.6 % of ticks fully solved, commands up to 3.2 from the exact "
                         "answer (ADMM stops at 1e-5 relative, the lower levels amplify it)",
    ("osqp", "tight"): "97.9 % of ticks fully solved on saturating stacks (iteration limit at "
                       "level 0), commands up to 1.2 from the exact answer",
    ("casadi:osqp", "default"): "99.8 % of ticks fully solved, commands up to 3.2 from the "
                                "exact answer (ADMM tolerance)",
    ("proxqp", "default"): "99.9 % of ticks fully solved, commands up to 3.1 from the exact "
                           "answer (its 1e-6 tolerance at degenerate levels)",
    ("clarabel", "default"): "every tick solved, commands up to 2e-4 from the exact answer "
                             "(interior point stopped at its default tolerance)",
    ("qpoases", "default"): "every tick reported solved, but 5 of 987 saturating states up to "
                            "2.3 from the exact answer (a wrong active set reported optimal)",
}


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
    backend: BackendBase | None = None
    try:  # a solver library rejecting an option raises its own exception type
        if name in NATIVE and _installed(NATIVE[name][1]):
            backend = NATIVE[name][0](profile, **options)
        elif name == "qpoases" and _has_conic("qpoases"):
            backend = CasadiConicBackend("qpoases", profile, name="qpoases", **options)
        elif family == "casadi" and solver and _has_conic(solver):
            backend = CasadiConicBackend(solver, profile, **options)
        elif family == "qpsolvers" and solver in _qpsolvers_solvers():
            backend = QpsolversBackend(solver, profile, **options)
    except WbcError:
        raise
    except Exception as err:
        raise backend_error(name, "options", err) from err
    if backend is not None:
        backend.cascade_caveat = CASCADE_CAVEATS.get((name, profile))
        return backend
    raise BackendUnavailableError(
        f"unknown or unavailable QP backend {name!r}; available: "
        f"{', '.join(available_backends())} (also 'qpsolvers:<solver>' for "
        f"{', '.join(_qpsolvers_solvers()) or 'none'}, and 'casadi:<conic plugin>')"
    )

