"""QP backends (persistent adapters) and closed-form reference solvers."""

from .base import BackendBase
from .casadi_backend import CasadiConicBackend
from .clarabel_backend import ClarabelBackend
from .daqp_backend import DaqpBackend
from .osqp_backend import OsqpBackend
from .proxqp_backend import ProxqpBackend
from .qpsolvers_backend import QpsolversBackend
from .quadprog_backend import QuadprogBackend
from .registry import available_backends, make_backend

__all__ = [
    "BackendBase",
    "CasadiConicBackend",
    "ClarabelBackend",
    "DaqpBackend",
    "OsqpBackend",
    "ProxqpBackend",
    "QpsolversBackend",
    "QuadprogBackend",
    "available_backends",
    "make_backend",
]
