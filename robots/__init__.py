"""Robot models on pinocchio: the catalogue's mobile manipulators and fixed-base arms.

Quick start::

    import wbc.robots as robots
    robots.names()            # ['mpo700_lwr4', 'tiago_panda', 'omni4_arm6', 'mecanum_gen3']
    robot = robots.load("mecanum_gen3")
    q = robot.neutral()       # [x, y, θ, arm joints]
    robot.frame_pose(q, "ee")  # (4, 4) in the world
    robot.frame_jacobian(q, "ee")  # (6, nv), rows [linear; angular], LOCAL_WORLD_ALIGNED
    robot.quantities.offered()     # ['pose[<frame>]', 'J[<frame>]', ..., 'com', ...]

Layout, one concern a module:

* :mod:`~wbc.robots.protocol` — :class:`Robot`, what the controller, tasks and simulator use;
* :mod:`~wbc.robots.pinocchio_robot` — :class:`PinocchioRobot`, the one implementation of the
  protocol (coordinates, Jacobian conventions, the one-update-per-tick pattern, clones sharing
  the immutable model); :mod:`~wbc.robots.manipulator` (:class:`MobileManipulator`) and
  :mod:`~wbc.robots.fixed_base` (:class:`FixedBaseRobot`, :func:`load_panda`) specialise it;
* :mod:`~wbc.robots.model_assembly` — the whole-body pinocchio model from base + arm + mount;
* :mod:`~wbc.robots.floating_base` — :class:`FloatingBaseRobot`, a robot on a free-flyer root
  (humanoids, quadrupeds); :mod:`~wbc.robots.whole_body` — whole-robot URDFs on any root
  (``from_urdf(path, root="free_flyer" | "planar" | "fixed" | <base>)``, wheels recognised);
* :mod:`~wbc.robots.collision` — :class:`CollisionModel` (the URDF's collision geometry, SRDF
  pairs, static :class:`Obstacle` s; distances and normal Jacobians with coal);
* :mod:`~wbc.robots.symbolic` — the hand-written CasADi kinematics (why, and which joints);
* :mod:`~wbc.robots.model_quantities` — the quantity registry every robot offers;
* :mod:`~wbc.robots.manipulability` — ``det(J Jᵀ)`` and its analytic gradient;
* :mod:`~wbc.robots.catalogue` — the named robots and their mounts, :func:`from_urdf`;
* the bases (:mod:`~wbc.robots.planar_base`, :mod:`~wbc.robots.steerable`,
  :mod:`~wbc.robots.differential`, :mod:`~wbc.robots.omni`, :mod:`~wbc.robots.mecanum`) for the
  wheel kinematics, and the arms (:mod:`~wbc.robots.arms`, :mod:`~wbc.robots.kuka_lwr4`,
  :mod:`~wbc.robots.kinova_gen3`).
"""

from wbc.aliases import moved_names

from .arms import Arm, arm_from_model, arm_from_urdf, panda, ur5, ur10
from .catalogue import base_names, from_urdf, load, make_base, names
from .collision import CollisionModel, Obstacle
from .differential import DifferentialDriveBase, tiago_base
from .fixed_base import FixedBaseRobot, load_panda
from .floating_base import FloatingBaseRobot
from .kinova_gen3 import kinova_gen3
from .kuka_lwr4 import kuka_lwr4
from .limits import Limits
from .manipulator import MobileManipulator
from .mecanum import MecanumBase, mecanum_base
from .omni import OmniBase, omni4_octagon
from .pinocchio_robot import PinocchioRobot
from .planar_base import PlanarBase, PlanarRoot
from .protocol import Robot, SymbolicRobot
from .reduced import ReducedPanda
from .resources import robots_dir, urdf_path
from .steerable import SteerableBase, SteerableRates, mpo700
from .views import column_major_view

__all__ = [
    "Arm",
    "CollisionModel",
    "DifferentialDriveBase",
    "FixedBaseRobot",
    "FloatingBaseRobot",
    "Limits",
    "MecanumBase",
    "MobileManipulator",
    "Obstacle",
    "OmniBase",
    "PinocchioRobot",
    "PlanarBase",
    "PlanarRoot",
    "ReducedPanda",
    "Robot",
    "SteerableBase",
    "SteerableRates",
    "SymbolicRobot",
    "arm_from_model",
    "arm_from_urdf",
    "base_names",
    "column_major_view",
    "from_urdf",
    "kinova_gen3",
    "kuka_lwr4",
    "load",
    "load_panda",
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
from .omni import ARM_MASS, PLATFORM_MASS, normal_forces, system_com  # noqa: E402

__all__ += ["ARM_MASS", "PLATFORM_MASS", "normal_forces", "system_com"]

#: The papers' controllers and plants, kept here under their old names for compatibility: each
#: is imported from its paper's package (``wbc.papers.<paper>``) on first access (PEP 562), so
#: that ``import wbc.robots`` loads no paper, controller, backend or simulator — robot models
#: import only the core.
_MOVED = {
    **dict.fromkeys(["SteerableController", "SteerableDrive"], "wbc.papers.sorour.steering"),
    **dict.fromkeys(["OmniForceControl", "OmniPositionControl", "platform_error"],
                    "wbc.papers.omni.control"),
    **dict.fromkeys(["OmniDynamics", "coulomb_forces"], "wbc.papers.omni.dynamics"),
}
__all__ += list(_MOVED)
#: the modules that moved to the papers (aliases kept in this folder), as attributes
_MOVED_MODULES = ('steerable_control', 'omni_control', 'omni_dynamics')


__getattr__, __dir__ = moved_names(__name__, _MOVED, _MOVED_MODULES)
