"""Backends for ``wbc bench``: names or user factories, equal-tolerance groups, what each
solves with.

Tolerance groups (``--tolerance``), qpbenchmark's convention: ``default`` keeps every backend's
wbc profile; ``low``, ``mid`` and ``high`` set the same *absolute* tolerance — 1e-3, 1e-6, 1e-9
(:data:`TOLERANCES`) — on every backend that has one, by the options of
:data:`TOLERANCE_OPTIONS` (relative tolerances 0 where the solver has them, so that the
absolute one decides). The active-set solvers without such a tolerance (quadprog; qpOASES,
whose ``terminationTolerance`` is a relative one on its homotopy) keep their settings, and the
report says ``"tolerance": null`` for them.

A backend is named as :func:`wbc.solvers.make_backend` accepts it (also
``"qpsolvers:<solver>"`` and ``"casadi:<plugin>"``), or ``"module:function"`` for a backend of
the user's own: ``function()`` returns a new object with wbc's backend interface
(:class:`wbc.qp.Backend`, e.g. a subclass of :class:`wbc.solvers.base.BackendBase`), imported
from the working directory. A user's factory takes no options: tolerance groups and quadprog's
``time_limit`` do not reach it.
"""

from __future__ import annotations

from collections.abc import Callable

from wbc.errors import BackendUnavailableError, UnknownNameError, WbcError

from .user_inputs import import_from_working_directory

#: absolute tolerance of each group (``default``: each backend's wbc profile)
TOLERANCES = {"default": None, "low": 1e-3, "mid": 1e-6, "high": 1e-9}

#: backend (or qpsolvers' solver) -> the options that set an absolute tolerance ``eps``
TOLERANCE_OPTIONS: dict[str, Callable[[float], dict]] = {
    "daqp": lambda eps: {"primal_tol": eps, "dual_tol": eps},
    "osqp": lambda eps: {"eps_abs": eps, "eps_rel": 0.0},
    "proxqp": lambda eps: {"eps_abs": eps, "eps_rel": 0.0},
    "clarabel": lambda eps: {"tol_gap_abs": eps, "tol_gap_rel": 0.0, "tol_feas": eps},
    "piqp": lambda eps: {"eps_abs": eps, "eps_rel": 0.0},
}
#: CasADi plugins: the plugin's options dict inside ``casadi.conic``'s options
_CASADI_TOLERANCE = {"osqp": lambda eps: {"eps_abs": eps, "eps_rel": 0.0}}

_WITHOUT = frozenset({"quadprog", "qpoases", "casadi:qpoases", "qpsolvers:quadprog"})


def tolerance_options(backend: str, group: str) -> dict | None:
    """The options that put ``backend`` in tolerance ``group``; ``{}`` for ``"default"``;
    ``None`` when the backend has no absolute tolerance (it keeps its settings)."""
    if group not in TOLERANCES:
        raise UnknownNameError(f"unknown tolerance group {group!r}; groups: {list(TOLERANCES)}")
    eps = TOLERANCES[group]
    if eps is None:
        return {}
    if backend in _WITHOUT:
        return None
    family, _, solver = backend.partition(":")
    if family == "casadi" and solver in _CASADI_TOLERANCE:
        from wbc.solvers.casadi_backend import PLUGIN_PROFILES

        base = PLUGIN_PROFILES.get(solver, {}).get("default", {}).get(solver, {})
        return {solver: {**base, **_CASADI_TOLERANCE[solver](eps)}}
    key = solver if family == "qpsolvers" else backend
    make = TOLERANCE_OPTIONS.get(key)
    return None if make is None else make(eps)


def backend_options(backend: str, group: str, quadprog_thread: bool = False) -> dict:
    """Options of ``backend`` in a timing run: its tolerance group's, and for quadprog
    ``time_limit=None`` (no worker thread) unless ``quadprog_thread``."""
    options = tolerance_options(backend, group) or {}
    if backend == "quadprog" and not quadprog_thread:
        options = {**options, "time_limit": None}
    return options


def resolve_backend(spec: str):
    """A name :func:`wbc.solvers.make_backend` accepts (returned as is, checked), or the
    factory named by ``"module:function"`` (see the module docstring).

    Raises:
        BackendUnavailableError: neither.
    """
    from wbc.solvers import make_backend

    family, sep, rest = spec.partition(":")
    if sep and family not in ("qpsolvers", "casadi"):
        return _factory(spec, family, rest)
    make_backend(spec)  # raises BackendUnavailableError with the installed names
    return spec


def _factory(spec: str, module_name: str, attribute: str):
    try:
        module = import_from_working_directory(module_name)
    except Exception as err:  # the user's module: whatever it raises on import
        raise BackendUnavailableError(f"backend {spec!r}: cannot import {module_name!r}: "
                                      f"{type(err).__name__}: {err}") from None
    factory = getattr(module, attribute, None)
    if not callable(factory):
        raise BackendUnavailableError(f"backend {spec!r}: {module_name!r} has no callable "
                                      f"{attribute!r}")
    return factory


def describe(backend_object, tolerance: dict | None) -> dict:
    """``settings`` and ``version`` of a live backend object, for the report: its
    :meth:`~wbc.solvers.base.BackendBase.settings` when it has one, else its type."""
    settings_of = getattr(backend_object, "settings", None)
    if callable(settings_of):
        try:
            settings = settings_of()
        except WbcError:
            settings = {}
    else:
        settings = {"backend": type(backend_object).__name__,
                    "options": "unknown (the object has no settings())"}
    settings = {**settings, "tolerance": tolerance}
    return {"settings": settings, "version": settings.get("version")}
