"""The omnidirectional platform paper: four omni wheels under an octagonal platform with a 6-DoF
arm, the wheel torques' redundancy used to spread the demanded wrench by the wheels' friction
capacity (eqs. 7–13), against position control through the wheel Jacobian (eq. 3).

What lives where:

* :mod:`~wbc.papers.omni.distribution_tasks` — the distributions as QP stacks
  (:class:`TorqueDistribution`, :func:`distribution_stack`, their tasks);
* :mod:`~wbc.papers.omni.control` — the platform's two controllers (:class:`OmniPositionControl`,
  :class:`OmniForceControl`) and the controller's load-transfer model (:func:`load_transfer`);
* :mod:`~wbc.papers.omni.dynamics` — the plant: the platform's planar rigid-body dynamics with
  Coulomb wheel friction and servos (:class:`OmniDynamics`, a ``wbc.sim`` actuation), whose
  sub-step loop :mod:`~wbc.papers.omni.dynamics_c` runs as compiled C (numpy's operation order;
  the Python loop where no compiler is found);
* :mod:`~wbc.papers.omni.closed_form` — the distributions in closed form (also in
  :mod:`wbc.solvers.reference`), with both readings of eq. 12's lost criterion H
  (:data:`H_CRITERIA`).

The base's kinematics, masses and normal forces stay generic in :mod:`wbc.robots.omni`. The
study (scenarios, metrics, claims, figures): :mod:`wbc.experiments.studies.omni`.
"""

from .closed_form import (
    DISTRIBUTION_METHODS,
    H_CRITERIA,
    equal_ratios,
    friction_utilisation,
    torque_distribution,
    torque_null_space,
)
from .control import (
    LIFTED_LOAD,
    OmniForceControl,
    OmniPositionControl,
    load_transfer,
    platform_error,
)
from .distribution_tasks import (
    DISTRIBUTIONS,
    FUSED_METHODS,
    FrictionUtilisation,
    TorqueDistribution,
    UtilisationBound,
    WheelWrench,
    distribution_stack,
)
from .dynamics import (
    OmniDynamics,
    coulomb_forces,
)

__all__ = [
    "DISTRIBUTIONS",
    "DISTRIBUTION_METHODS",
    "FUSED_METHODS",
    "FrictionUtilisation",
    "H_CRITERIA",
    "LIFTED_LOAD",
    "OmniDynamics",
    "OmniForceControl",
    "OmniPositionControl",
    "TorqueDistribution",
    "UtilisationBound",
    "WheelWrench",
    "coulomb_forces",
    "distribution_stack",
    "equal_ratios",
    "friction_utilisation",
    "load_transfer",
    "platform_error",
    "torque_distribution",
    "torque_null_space",
]
