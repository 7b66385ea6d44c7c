"""The task library (``wbc.tasks``): every task turns itself into affine terms of a stack."""

from wbc.aliases import moved_names

from .frame import FrameTask
from .limits import ConfigurationLimit, VelocityLimit
from .linear import Bounds, LinearConstraint, LinearTask
from .posture import PostureTask

__all__ = ["Bounds", "ConfigurationLimit", "FrameTask", "LinearConstraint", "LinearTask",
           "PostureTask", "VelocityLimit"]
from .joint_acceleration import JointAccelerationLimit, joint_acceleration_bounds  # noqa: E402

__all__ += ["JointAccelerationLimit", "joint_acceleration_bounds"]
from .rpy_pose import RpyPoseTask  # noqa: E402

__all__ += ["RpyPoseTask"]

#: The papers' tasks, kept here under their old names for compatibility: each is imported from
#: its paper's package (``wbc.papers.<paper>``) on first access (PEP 562), so that
#: ``import wbc.tasks`` loads no paper — the papers build on the task library, not the reverse.
_MOVED = {
    **dict.fromkeys(["ArmCompensation", "DexterousPosture", "share_task", "sharing_factor"],
                    "wbc.papers.sorour.task_sharing"),
    **dict.fromkeys(["DISTRIBUTIONS", "FrictionUtilisation", "TorqueDistribution",
                     "UtilisationBound", "WheelWrench", "distribution_stack"],
                    "wbc.papers.omni.distribution_tasks"),
    **dict.fromkeys(["VelocityField", "smoothstep"], "wbc.papers.petric.velocity_field"),
}
__all__ += list(_MOVED)
#: the modules that moved to the papers (aliases kept in this folder), as attributes
_MOVED_MODULES = ('task_sharing', 'torque_distribution', 'velocity_field')


__getattr__, __dir__ = moved_names(__name__, _MOVED, _MOVED_MODULES)
