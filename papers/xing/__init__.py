"""Xing et al.'s adaptive motion planning (AMP) for a mecanum base + Kinova Gen3 at the
acceleration level: the arm tracks the task under joint bounds (SNS, task scaling), the base
joins when the arm's manipulability falls below a threshold, a manipulability objective in
the null space.

What lives where:

* :mod:`~wbc.papers.xing.stacks` — AMP as a QP cascade: :func:`amp_stack`,
  :func:`add_amp_levels`, :func:`amp_controller`, the planner's parameters (:class:`Setup`,
  :data:`POSITION`, :data:`POSE`);
* :mod:`~wbc.papers.xing.fast` — the controller's fast path: where the task is not saturated,
  the cascade's answer as one strictly convex QP in generated C (:class:`AMPController`,
  :class:`AMPFastWorkspace`, :func:`unsaturated_tick`, the zonotope test
  :func:`zonotope_interior`); the ordinary path answers the other ticks;
* :mod:`~wbc.papers.xing.planner` — the paper's planners in closed form, in closed loop
  (:class:`ClosedFormPlanner`);
* :mod:`~wbc.papers.xing.plant` — the base's velocity-level actuation with odometry error
  (:class:`CommandedVelocityOdometry`, a ``wbc.sim`` actuation);
* :mod:`~wbc.papers.xing.closed_form` — AMP and the traditional planner in closed form (also in
  :mod:`wbc.solvers.reference`).

The generic pieces it builds on stay in the task library
(:class:`wbc.tasks.JointAccelerationLimit`, :mod:`wbc.tasks.manipulability`). The study
(scenarios, metrics, claims, figures): :mod:`wbc.experiments.studies.xing`.
"""

from .closed_form import (
    AMPInfo,
    amp,
    auxiliary_projector,
    base_transition,
    manipulability_acceleration,
    manipulability_gradient,
    manipulability_hessian,
    manipulability_hessian_product,
    scaling_factor,
    traditional,
)
from .fast import (
    INTERIOR_MARGIN,
    PARALLEL,
    RANK_MARGIN,
    AMPController,
    AMPFastWorkspace,
    fast_qp,
    full_rank,
    unsaturated_tick,
    why_not_fast,
    zonotope_interior,
)
from .planner import (
    ClosedFormPlanner,
)
from .plant import (
    CommandedVelocityOdometry,
)
from .stacks import (
    DT,
    POSE,
    POSITION,
    Setup,
    add_amp_levels,
    amp_controller,
    amp_stack,
    base_slice,
    base_transition_expression,
    cartesian_command,
    symbolic_quantity,
)

__all__ = [
    "AMPController",
    "AMPFastWorkspace",
    "AMPInfo",
    "ClosedFormPlanner",
    "CommandedVelocityOdometry",
    "DT",
    "INTERIOR_MARGIN",
    "PARALLEL",
    "POSE",
    "POSITION",
    "RANK_MARGIN",
    "Setup",
    "add_amp_levels",
    "amp",
    "amp_controller",
    "amp_stack",
    "auxiliary_projector",
    "base_slice",
    "base_transition",
    "base_transition_expression",
    "cartesian_command",
    "fast_qp",
    "full_rank",
    "manipulability_acceleration",
    "manipulability_gradient",
    "manipulability_hessian",
    "manipulability_hessian_product",
    "scaling_factor",
    "symbolic_quantity",
    "traditional",
    "unsaturated_tick",
    "why_not_fast",
    "zonotope_interior",
]
