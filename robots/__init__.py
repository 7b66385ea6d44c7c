"""Mobile manipulator models on pinocchio.

Quick start::

    import wbc.robots as robots
    robots.names()            # ['mpo700_lwr4', 'tiago_panda', 'omni4_arm6', 'mecanum_gen3']
    robot = robots.load("mecanum_gen3")
    q = robot.neutral()       # [x, y, θ, arm joints]
    robot.frame_pose(q, "ee")  # (4, 4) in the world
    robot.frame_jacobian(q, "ee")  # (6, nv), rows [linear; angular], LOCAL_WORLD_ALIGNED

See :mod:`wbc.robots.manipulator` for the coordinates, the Jacobian conventions and the
one-update-per-tick pattern, :mod:`wbc.robots.catalogue` for the robots and their mounts, and
the base modules (:mod:`~wbc.robots.steerable`, :mod:`~wbc.robots.differential`,
:mod:`~wbc.robots.omni`, :mod:`~wbc.robots.mecanum`) for the wheel kinematics.
"""

from .arms import Arm, arm_from_model, arm_from_urdf, panda, ur5, ur10
from .catalogue import base_names, from_urdf, load, make_base, names
from .differential import DifferentialDriveBase, tiago_base
from .kinova_gen3 import kinova_gen3
from .kuka_lwr4 import kuka_lwr4
from .limits import Limits
from .manipulator import MobileManipulator
from .mecanum import MecanumBase, mecanum_base
from .omni import OmniBase, omni4_octagon
from .planar_base import PlanarBase
from .reduced import ReducedPanda
from .resources import robots_dir, urdf_path
from .steerable import SteerableBase, SteerableRates, mpo700
from .views import column_major_view

__all__ = [
    "Arm",
    "DifferentialDriveBase",
    "Limits",
    "MecanumBase",
    "MobileManipulator",
    "OmniBase",
    "PlanarBase",
    "ReducedPanda",
    "SteerableBase",
    "SteerableRates",
    "arm_from_model",
    "arm_from_urdf",
    "base_names",
    "column_major_view",
    "from_urdf",
    "kinova_gen3",
    "kuka_lwr4",
    "load",
    "make_base",
    "mecanum_base",
    "mpo700",
    "names",
    "omni4_octagon",
    "panda",
    "robots_dir",
    "tiago_base",
    "ur10",
    "ur5",
    "urdf_path",
]
