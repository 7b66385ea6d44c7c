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


def __getattr__(name: str):
    """A paper's task under its old name (see :data:`_MOVED`), imported on first access."""
    if name in _MOVED:
        import importlib

        value = getattr(importlib.import_module(_MOVED[name]), name)
        globals()[name] = value  # later accesses skip this function
        return value
    if name in _MOVED_MODULES:  # ``wbc.<package>.<old module>`` without importing it first
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_MOVED))
