"""MuJoCo models of wbc's arms for the mink comparisons: example-robot-data URDFs loaded by MuJoCo
without their meshes (see :mod:`wbc.experiments.peers.vs_mink`, whose module docstring says why
and how they are checked against pinocchio)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

HAND = "panda_hand"
LOCKED_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")


def urdf_without_meshes(path: str, locked: tuple[str, ...] = ()) -> ET.Element:
    """The URDF ``path`` (of example-robot-data, see :func:`wbc.robots.resources.urdf_path`)
    without visual and collision elements (no meshes to find), the ``locked`` joints made
    ``fixed``: kinematics, joint ranges, velocity limits and inertias kept."""
    from wbc.robots.resources import urdf_path

    root = ET.parse(urdf_path(path)).getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    for joint in root.findall("joint"):
        if joint.get("name") in locked:  # locked at 0, as a pinocchio reduced model
            joint.set("type", "fixed")
            for tag in ("limit", "axis", "mimic", "dynamics", "safety_controller"):
                for element in joint.findall(tag):
                    joint.remove(element)
    return root


def panda_urdf_without_meshes() -> ET.Element:
    """The URDF of wbc's Panda without visual and collision elements (no meshes to find), the
    fingers fixed: kinematics, joint ranges, velocity limits and inertias kept (also the
    placo comparison's model, :mod:`wbc.experiments.peers.vs_placo`)."""
    return urdf_without_meshes("panda_description/urdf/panda.urdf", LOCKED_JOINTS)


def _for_mujoco(root: ET.Element) -> str:
    """The URDF text with MuJoCo's compiler options (see the module docstring)."""
    mujoco_block = ET.SubElement(root, "mujoco")
    ET.SubElement(mujoco_block, "compiler", discardvisual="true", fusestatic="false",
                  autolimits="true", angle="radian")
    return ET.tostring(root, encoding="unicode")


def panda_urdf_for_mujoco() -> str:
    """The URDF text of wbc's Panda, made loadable by MuJoCo without meshes (see the module
    docstring): :func:`panda_urdf_without_meshes` and MuJoCo's compiler options."""
    return _for_mujoco(panda_urdf_without_meshes())


def mujoco_panda():
    """The MuJoCo model of the Panda (7 hinge joints, ``panda_hand`` a body)."""
    import mujoco

    return mujoco.MjModel.from_xml_string(panda_urdf_for_mujoco())


def mujoco_arm(path: str, locked: tuple[str, ...] = ()):
    """The MuJoCo model of an arm of example-robot-data (``path`` under its robots folder),
    made as :func:`mujoco_panda` (e.g. the UR5 of :mod:`wbc.experiments.peers.scenarios`)."""
    import mujoco

    return mujoco.MjModel.from_xml_string(_for_mujoco(urdf_without_meshes(path, locked)))


def joint_names(robot) -> list[str]:
    """Pinocchio's joint names in velocity order (universe excluded; all joints 1-dof)."""
    return [robot.model.names[i] for i in range(1, robot.model.njoints)]
