"""The task library (``wbc.tasks``): every task turns itself into affine terms of a stack."""

from .frame import FrameTask
from .limits import ConfigurationLimit, VelocityLimit
from .linear import Bounds, LinearConstraint, LinearTask
from .posture import PostureTask

__all__ = ["Bounds", "ConfigurationLimit", "FrameTask", "LinearConstraint", "LinearTask",
           "PostureTask", "VelocityLimit"]
from .joint_acceleration import JointAccelerationLimit, joint_acceleration_bounds  # noqa: E402

__all__ += ["JointAccelerationLimit", "joint_acceleration_bounds"]
from .rpy_pose import RpyPoseTask  # noqa: E402
from .task_sharing import ArmCompensation, DexterousPosture, share_task, sharing_factor  # noqa: E402

__all__ += ["ArmCompensation", "DexterousPosture", "RpyPoseTask", "share_task", "sharing_factor"]
from .torque_distribution import DISTRIBUTIONS, FrictionUtilisation, TorqueDistribution, UtilisationBound, WheelWrench, distribution_stack  # noqa: E402, E501, I001

__all__ += ["DISTRIBUTIONS", "FrictionUtilisation", "TorqueDistribution", "UtilisationBound", "WheelWrench", "distribution_stack"]  # noqa: E501
from .velocity_field import VelocityField, smoothstep  # noqa: E402

__all__ += ["VelocityField", "smoothstep"]
