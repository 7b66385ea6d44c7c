"""The task library (``wbc.tasks``): every task turns itself into affine terms of a stack."""

from wbc.aliases import moved_names

from .acceleration_limit import AccelerationLimit
from .axis_align import AxisAlignTask
from .body_spherical_barrier import BodySphericalBarrier
from .collision import CollisionAvoidance
from .com import ComTask
from .damping import DampingTask
from .dof_freezing import DofFreezing
from .frame import FrameTask
from .joint_acceleration import JointAccelerationLimit, joint_acceleration_bounds
from .joint_coupling import JointCouplingTask
from .joint_velocity import JointVelocityTask
from .kinetic_energy import KineticEnergyRegularizationTask
from .limits import ConfigurationLimit, VelocityLimit
from .linear import Bounds, LinearConstraint, LinearTask
from .look_at import LookAtTask
from .low_acceleration import LowAccelerationTask
from .manipulability import ManipulabilityAccelerationTask, ManipulabilityTask
from .position_barrier import PositionBarrier, SafeDisplacement
from .posture import PostureTask
from .relative_frame import RelativeFrameTask
from .rpy_pose import RpyPoseTask

__all__ = ["AccelerationLimit", "AxisAlignTask", "BodySphericalBarrier", "Bounds",
           "CollisionAvoidance", "ComTask", "ConfigurationLimit", "DampingTask", "DofFreezing",
           "FrameTask", "JointAccelerationLimit", "JointCouplingTask", "JointVelocityTask",
           "KineticEnergyRegularizationTask", "LinearConstraint", "LinearTask", "LookAtTask",
           "LowAccelerationTask", "ManipulabilityAccelerationTask", "ManipulabilityTask",
           "PositionBarrier", "PostureTask", "RelativeFrameTask", "RpyPoseTask",
           "SafeDisplacement", "VelocityLimit", "joint_acceleration_bounds"]

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
