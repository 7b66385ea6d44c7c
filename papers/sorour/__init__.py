"""Sorour, Cherubini & Fraisse, "Motion discontinuity-robust controller for steerable mobile
robots" (IEEE RA-L 2017): a steerable MPO700 base + KUKA LWR-IV arm, the task shared between
base and arm by a factor ψ of the position error (eqs. 9, 11), a dexterous posture in the null
space, the arm compensating the base velocity the ICR steering controller does not deliver
(eq. 14).

What lives where:

* :mod:`~wbc.papers.sorour.task_sharing` — the paper's tasks: :func:`share_task`,
  :func:`sharing_factor` (ψ, eq. 11), :class:`DexterousPosture`, :class:`ArmCompensation`;
* :mod:`~wbc.papers.sorour.steering` — the base's ICR steering controller
  (:class:`SteerableController`) and the plant driving the base through it
  (:class:`SteerableDrive`, a ``wbc.sim`` actuation);
* :mod:`~wbc.papers.sorour.steering_code` — the steering controller's tick as one CasADi
  function (:func:`steering_function`, its ICR QP in closed form), for the fast paths' generated
  C code;
* :mod:`~wbc.papers.sorour.controller` — the whole-body controller of §V in its three variants
  (:class:`SorourController`, with its fast path) and Table I (:data:`PARAMETERS`);
* :mod:`~wbc.papers.sorour.closed_form` — the closed forms (eqs. 9, 11, 14), test oracles of
  the QP forms (also in :mod:`wbc.solvers.reference`).

The study (scenarios, metrics, claims, figures): :mod:`wbc.experiments.studies.sorour`.
"""

from .closed_form import (
    arm_compensation,
    sharing_mobility,
    task_sharing_factor,
    task_sharing_velocity,
)
from .controller import (
    LIMIT_GAIN,
    N_BASE,
    PARAMETERS,
    Q_DEX,
    VARIANTS,
    SorourController,
    arm_rate_bounds,
    steering_controller,
)
from .steering import (
    MPO700_STEER_LIMITS,
    SteerableController,
    SteerableDrive,
    SteerStep,
    drive_rates,
    icr_of_twist,
    scale_into,
    steering_of_icr,
)
from .steering_code import fast_path_allowed, steering_function
from .task_sharing import (
    ArmCompensation,
    DexterousPosture,
    share_task,
    sharing_factor,
)

__all__ = [
    "ArmCompensation",
    "DexterousPosture",
    "LIMIT_GAIN",
    "MPO700_STEER_LIMITS",
    "N_BASE",
    "PARAMETERS",
    "Q_DEX",
    "SorourController",
    "SteerStep",
    "SteerableController",
    "SteerableDrive",
    "VARIANTS",
    "arm_compensation",
    "arm_rate_bounds",
    "drive_rates",
    "fast_path_allowed",
    "icr_of_twist",
    "scale_into",
    "share_task",
    "sharing_factor",
    "sharing_mobility",
    "steering_controller",
    "steering_function",
    "steering_of_icr",
    "task_sharing_factor",
    "task_sharing_velocity",
]
