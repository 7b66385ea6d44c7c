"""Petrič & Žlajpah, a velocity field for the base of a mobile manipulator that keeps the arm's
end point in a comfortable zone, with eq. 22's damped least-squares arm controller: Tiago
(differential drive) + Franka Panda.

What lives where:

* :mod:`~wbc.papers.petric.velocity_field` — the base's velocity field
  (:class:`VelocityField`, with its rate-limit stage as a QP level) and :func:`smoothstep`;
* :mod:`~wbc.papers.petric.stacks` — eq. 22 as a stack (:func:`arm_stack`) and the whole-body
  QP beyond the paper (:func:`whole_body_stack`), the gains (:data:`KP`, :data:`K_POSTURE`) and
  control period (:data:`DT`);
* :mod:`~wbc.papers.petric.controllers` — :class:`DecoupledController` (the paper's: arm and
  base independent) and :class:`WholeBodyController`, on a fast path by default (the arm's
  fused QPs, the TEE point and the field as generated C; ``fused=False`` turns it off);
* :mod:`~wbc.papers.petric.fast` — the whole-body QP's fast tick
  (:class:`WholeBodyQPController`: two generated daqp calls where the field's twist is
  reachable, the ordinary path elsewhere);
* :mod:`~wbc.papers.petric.closed_form` (the base's rate limits) and
  :mod:`~wbc.papers.petric.closed_form_arm` (eq. 22, eq. 26's damped projector) — the closed
  forms (also in :mod:`wbc.solvers.reference`);
* :mod:`~wbc.papers.petric.invariance` — §II-A.2's retreat-region invariance in closed loop,
  many placements of a TEE held fixed in the world integrated side by side.

The study (scenarios, metrics, claims, figures): :mod:`wbc.experiments.studies.petric`.
"""

from .closed_form import (
    rate_limit_interval,
    rate_limited_twist,
)
from .closed_form_arm import (
    PETRIC_LAMBDA,
    damped_projector,
    dls_arm_velocity,
    projector_leak,
)
from .controllers import (
    DecoupledController,
    FieldDriver,
    WholeBodyController,
)
from .fast import (
    WholeBodyFastWorkspace,
    WholeBodyQPController,
    certified,
    fast_qps,
    reachable_tick,
    why_not_fast,
)
from .invariance import (
    held_point_depths,
    placements,
    touch_height,
)
from .stacks import (
    DT,
    K_POSTURE,
    KP,
    arm_stack,
    posture_target,
    whole_body_stack,
)
from .velocity_field import (
    VelocityField,
    smoothstep,
)

__all__ = [
    "DT",
    "DecoupledController",
    "FieldDriver",
    "KP",
    "K_POSTURE",
    "PETRIC_LAMBDA",
    "VelocityField",
    "WholeBodyController",
    "WholeBodyFastWorkspace",
    "WholeBodyQPController",
    "arm_stack",
    "certified",
    "damped_projector",
    "dls_arm_velocity",
    "fast_qps",
    "held_point_depths",
    "placements",
    "posture_target",
    "projector_leak",
    "reachable_tick",
    "rate_limit_interval",
    "rate_limited_twist",
    "smoothstep",
    "touch_height",
    "why_not_fast",
    "whole_body_stack",
]
