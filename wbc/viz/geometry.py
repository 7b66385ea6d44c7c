"""What the viewer draws of a robot: triangle meshes attached to the model's frames.

:func:`robot_parts` returns :class:`Part` s — a mesh in the local coordinates of one frame of
the robot's pinocchio model, moved each frame by that frame's world pose. Where the model has
visual geometry (a robot built from a URDF, ``robot.urdf_path``, or a catalogue robot whose arm
comes from example-robot-data, ``robot.arm.source``) its meshes are used, read through
pinocchio's geometry loader (assimp: ``.dae`` and ``.stl``); otherwise each link is drawn from
the kinematic model: a capsule from its joint's origin to the next joint's, and a short
cylinder along every joint axis. A planar base gets a deck (its footprint, from the floor to the
arm's mount) and its wheels (:func:`wheels`), which :class:`~wbc.viz.viewer.Viewer` rolls by the
base's motion and, on a steerable base, steers along the hip's velocity.

Units: metres. Needs numpy and pinocchio only (no viser).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Part", "Wheel", "box", "capsule", "cylinder", "robot_parts", "wheels"]

#: colour of links drawn from the kinematic model, alternating (RGB 0-255)
LINK_COLOURS = ((70, 110, 190), (225, 225, 230))
DECK_COLOUR = (60, 64, 72)
WHEEL_COLOUR = (30, 30, 30)
ROLLER_COLOUR = (200, 160, 40)
#: capsule radius of links drawn from the kinematic model [m]
LINK_RADIUS = 0.04


@dataclass
class Part:
    """A mesh attached to a frame of the robot's model.

    Attributes:
        name: unique name (a scene path component).
        frame: index of the pinocchio frame it moves with.
        joint: the pinocchio joint that frame moves with (for limit colouring).
        placement: ``(4, 4)`` pose of the mesh in the frame.
        vertices: ``(n, 3)`` float32 [m]; faces: ``(m, 3)`` uint32.
        color: RGB 0-255.
    """

    name: str
    frame: int
    joint: int
    placement: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    color: tuple[int, int, int]


@dataclass
class Wheel:
    """A base wheel: the viewer places it at ``hip`` (base frame, [m]), steered by ``heading``
    and spun about its axle by the base's motion.

    Attributes:
        hip: ``(x, y)`` of the steering axis (the wheel centre when not steerable) [m].
        offset: steering offset [m] (centre = hip − offset·e(heading)); 0 if not steerable.
        heading: the rolling direction's angle in the base frame [rad] (updated when steered).
        radius: [m]; width: [m]; z: height of the axle in the base frame [m].
        steerable: whether the viewer steers it along the hip's velocity.
        vertices / faces: the wheel mesh in its own frame (axle along y, rolling along x).
    """

    hip: np.ndarray
    offset: float
    heading: float
    radius: float
    width: float
    z: float
    steerable: bool
    vertices: np.ndarray
    faces: np.ndarray
    rollers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    roller_faces: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.uint32))


# ------------------------------------------------------------------------- primitive meshes
def box(size) -> tuple[np.ndarray, np.ndarray]:
    """A box of ``size`` = (x, y, z) [m] centred at the origin."""
    h = np.asarray(size, float) / 2
    v = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    f = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return v.astype(np.float32), np.array(f, np.uint32)


def cylinder(radius: float, length: float, sides: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder along z, centred at the origin."""
    a = np.linspace(0, 2 * math.pi, sides, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    v = np.vstack([np.column_stack([ring, np.full(sides, -length / 2)]),
                   np.column_stack([ring, np.full(sides, length / 2)]),
                   [[0, 0, -length / 2], [0, 0, length / 2]]])
    f = []
    for i in range(sides):
        j = (i + 1) % sides
        f += [[i, j, sides + j], [i, sides + j, sides + i],
              [2 * sides, j, i], [2 * sides + 1, sides + i, sides + j]]
    return v.astype(np.float32), np.array(f, np.uint32)


def capsule(a, b, radius: float, sides: int = 16, rings: int = 4) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """A capsule of ``radius`` from point ``a`` to point ``b`` (3-vectors) [m]."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    # profile along z: a hemisphere at each end, joined by the cylinder
    phis = np.concatenate([np.linspace(-math.pi / 2, 0, rings + 1),
                           np.linspace(0, math.pi / 2, rings + 1)])
    offsets = np.concatenate([np.zeros(rings + 1), np.full(rings + 1, length)])
    theta = np.linspace(0, 2 * math.pi, sides, endpoint=False)
    verts = [[radius * math.cos(p) * math.cos(t), radius * math.cos(p) * math.sin(t),
              radius * math.sin(p) + o] for p, o in zip(phis, offsets, strict=True)
             for t in theta]
    n_rings = len(phis)
    faces = []
    for r in range(n_rings - 1):
        for i in range(sides):
            j = (i + 1) % sides
            p, q = r * sides, (r + 1) * sides
            faces += [[p + i, p + j, q + j], [p + i, q + j, q + i]]
    v = np.array(verts)
    rotation = _rotation_z_to(axis / length if length > 1e-9 else np.array([0, 0, 1.0]))
    return (v @ rotation.T + a).astype(np.float32), np.array(faces, np.uint32)


def _rotation_z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation taking the z axis onto the unit vector ``direction``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, direction))
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(z, direction)
    s = np.linalg.norm(k)
    k = k / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


def _pose(rotation=None, translation=None) -> np.ndarray:
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    if translation is not None:
        T[:3, 3] = translation
    return T


# ------------------------------------------------------------------------- the robot's parts
def robot_parts(robot) -> list[Part]:
    """Every mesh of ``robot`` (a wbc robot: ``model``, ``nq_base``, ``root``), the base's
    deck included (wheels: :func:`wheels`). Meshes where the model has visual geometry,
    links drawn from the kinematic model for the joints without."""
    import pinocchio as pin

    parts = _mesh_parts(robot, pin)
    covered = {p.joint for p in parts}
    parts += _kinematic_parts(robot, pin, covered)
    parts += _deck_parts(robot)
    return parts


def visual_urdf(robot) -> str | None:
    """The URDF whose ``<visual>`` geometry draws ``robot``: ``robot.urdf_path``, or the
    example-robot-data file its arm was read from (``robot.arm.source``), or ``None``."""
    path = getattr(robot, "urdf_path", None)
    if path:
        return str(path)
    source = getattr(getattr(robot, "arm", None), "source", "") or ""
    match = re.match(r"example-robot-data (\S+\.urdf)", source)
    if match:
        from wbc.robots.resources import urdf_path

        try:
            return str(urdf_path(match.group(1)))
        except (FileNotFoundError, OSError):
            return None
    return None


def _mesh_parts(robot, pin) -> list[Part]:
    """The URDF's visual meshes, remapped onto the robot's model by link name (a link renamed
    ``link:<name>`` or ``arm_<name>`` in the model is found too)."""
    import os

    import coal

    path = visual_urdf(robot)
    if path is None or not os.path.isfile(path):
        return []
    dirs = []
    try:
        from wbc.robots.resources import robots_dir

        dirs.append(str(robots_dir().parent.parent))  # ".../share": package://example-...
    except (FileNotFoundError, OSError):
        pass
    from pathlib import Path

    dirs += [str(p) for p in Path(path).resolve().parents]
    try:
        source = pin.buildModelFromUrdf(path)
        geometry = pin.buildGeomFromUrdf(source, path, pin.GeometryType.VISUAL, None, dirs)
    except (ValueError, RuntimeError):
        return []  # unreadable visual geometry: the kinematic drawing stands in
    model = robot.model
    body = {f.name: i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY}
    parts = []
    for k, obj in enumerate(geometry.geometryObjects):
        link = source.frames[obj.parentFrame].name
        frame = next((body[n] for n in (link, f"link:{link}", f"arm_{link}",
                                        f"arm_link:{link}") if n in body), None)
        if frame is None:
            continue
        in_link = source.frames[obj.parentFrame].placement.actInv(obj.placement)
        mesh = _shape_mesh(obj.geometry, coal)
        if mesh is None:
            continue
        vertices, faces = mesh
        vertices = vertices * np.asarray(obj.meshScale, float)
        colour = np.asarray(obj.meshColor, float)[:3]
        if np.allclose(colour, 0.9):  # pinocchio's default: the file's own colour is lost
            colour = np.array(LINK_COLOURS[1]) / 255
        r, g, b = (int(round(255 * c)) for c in colour)
        parts.append(Part(f"mesh{k}", frame, int(model.frames[frame].parentJoint),
                          in_link.homogeneous, vertices.astype(np.float32), faces, (r, g, b)))
    return parts


def _shape_mesh(shape, coal) -> tuple[np.ndarray, np.ndarray] | None:
    """A coal shape as a triangle mesh (meshes, boxes, cylinders, spheres, capsules)."""
    if isinstance(shape, coal.BVHModelBase):
        if shape.num_tris == 0:
            return None
        vertices = np.array(shape.vertices(), float)
        faces = np.array([[t[0], t[1], t[2]] for t in
                          (shape.tri_indices(i) for i in range(shape.num_tris))], np.uint32)
        return vertices, faces
    if isinstance(shape, coal.Box):
        return box(2 * np.asarray(shape.halfSide))
    if isinstance(shape, coal.Cylinder):
        return cylinder(shape.radius, 2 * shape.halfLength)
    if isinstance(shape, coal.Capsule):
        return capsule([0, 0, -shape.halfLength], [0, 0, shape.halfLength], shape.radius)
    if isinstance(shape, coal.Sphere):
        return capsule([0, 0, 0], [0, 0, 1e-6], shape.radius, rings=6)
    return None


def _kinematic_parts(robot, pin, covered: set[int]) -> list[Part]:
    """Links drawn from the kinematic model for the joints ``covered`` has no mesh of: a
    capsule from each such joint to each child joint (or to the frames it carries when it
    has none), and a short cylinder along its axis."""
    model = robot.model
    first = _first_body_joint(robot)
    children: dict[int, list[np.ndarray]] = {}
    for j in range(first + 1, model.njoints):
        children.setdefault(model.parents[j], []).append(model.jointPlacements[j].translation)
    frame_of_joint = {}
    for i, f in enumerate(model.frames):
        if f.type == pin.FrameType.JOINT and f.parentJoint not in frame_of_joint:
            frame_of_joint[f.parentJoint] = i
    parts: list[Part] = []
    for j in range(first, model.njoints):
        if j in covered or j == 0 or j not in frame_of_joint:
            continue
        frame = frame_of_joint[j]
        ends = list(children.get(j, []))
        if not ends:  # the last link: to the frames it carries (the end effector's, ...)
            ends = [f.placement.translation for f in model.frames if f.parentJoint == j
                    and f.type == pin.FrameType.OP_FRAME or (f.parentJoint == j and
                                                             f.type == pin.FrameType.BODY)]
            ends = [e for e in ends if np.linalg.norm(e) > 1e-3][:1] or [np.array([0, 0, 0.08])]
        # the joint frame's own placement within the joint is the identity for URDF joints
        inverse = model.frames[frame].placement.inverse().homogeneous
        colour = LINK_COLOURS[j % 2]
        for k, end in enumerate(ends):
            if np.linalg.norm(end) < 1e-3:
                continue
            v, f = capsule(np.zeros(3), end, LINK_RADIUS)
            parts.append(Part(f"link{j}_{k}", frame, j, inverse, v, f, colour))
        axis = _joint_axis(model.joints[j])
        if axis is not None:
            v, f = cylinder(LINK_RADIUS * 1.25, LINK_RADIUS * 2.6)
            parts.append(Part(f"joint{j}", frame, j,
                              inverse @ _pose(_rotation_z_to(axis)), v, f, (40, 40, 48)))
    return parts


def _first_body_joint(robot) -> int:
    """The first pinocchio joint that is a body of the robot: 1 for a fixed base or a free
    flyer (the free flyer is the trunk), the first joint after the three planar root joints
    for a mobile base (whose body is the deck)."""
    return 1 + (3 if getattr(robot, "root", "fixed") == "planar" else 0)


def _joint_axis(joint) -> np.ndarray | None:
    """The unit axis of a revolute or prismatic joint model (``None`` for others)."""
    name = joint.shortname()
    if name.endswith(("RX", "PX")):
        return np.array([1.0, 0, 0])
    if name.endswith(("RY", "PY")):
        return np.array([0, 1.0, 0])
    if name.endswith(("RZ", "PZ")):
        return np.array([0, 0, 1.0])
    axis = getattr(getattr(joint, "extract", lambda: None)(), "axis", None)
    if axis is None and hasattr(joint, "axis"):
        axis = joint.axis
    return None if axis is None else np.asarray(axis, float) / np.linalg.norm(axis)


# ------------------------------------------------------------------------- the base
def _base_frame(robot) -> int | None:
    if getattr(robot, "root", None) != "planar" or getattr(robot, "base", None) is None:
        return None
    names = [f.name for f in robot.model.frames]
    return names.index("base") if "base" in names else None


def deck_span(robot) -> tuple[float, float]:
    """``(floor_z, top_z)`` of the deck in the base frame [m]: the top at the arm's mount, the
    floor at 0 — except a base frame on the mounting plane (the mecanum platform's, see
    :func:`wbc.robots.mecanum.mecanum_base`), whose body fills the 0.30 m below it."""
    mount = getattr(robot, "mount", None)
    top = float(np.asarray(mount.translation)[2]) if mount is not None else 0.0
    radius = float(getattr(robot.base, "radius", 0.1))
    if top < 2 * radius:
        return top - 0.30, top
    return 0.0, top


def _footprint(base) -> tuple[str, np.ndarray]:
    """``("box", (x, y))`` or ``("prism", polygon (n, 2))`` of a base's deck [m]."""
    if hasattr(base, "half_wheelbase"):  # mecanum
        return "box", np.array([2 * base.half_wheelbase + 0.14, 2 * base.half_track - 0.02])
    if hasattr(base, "angles"):  # omni: a polygon through the wheels
        n = 2 * len(base.angles)
        a = np.linspace(0, 2 * math.pi, n, endpoint=False) + math.pi / n
        r = base.distance * 1.02
        return "prism", np.column_stack([r * np.cos(a), r * np.sin(a)])
    if hasattr(base, "hips"):  # steerable
        extent = np.abs(base.hips).max(axis=0) * 2 + 2 * base.radius
        return "box", extent
    if hasattr(base, "separation"):  # differential: a round deck
        n = 24
        a = np.linspace(0, 2 * math.pi, n, endpoint=False)
        r = base.separation / 2 + 0.02
        return "prism", np.column_stack([r * np.cos(a), r * np.sin(a)])
    return "box", np.array([0.5, 0.4])


def _prism(polygon: np.ndarray, z0: float, z1: float) -> tuple[np.ndarray, np.ndarray]:
    n = len(polygon)
    v = np.vstack([np.column_stack([polygon, np.full(n, z0)]),
                   np.column_stack([polygon, np.full(n, z1)]), [[0, 0, z0], [0, 0, z1]]])
    f = []
    for i in range(n):
        j = (i + 1) % n
        f += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    return v.astype(np.float32), np.array(f, np.uint32)


def _deck_parts(robot) -> list[Part]:
    frame = _base_frame(robot)
    if frame is None or type(robot.base).__name__ == "PlanarRoot":
        return []  # a whole-robot URDF on a planar root draws its own base
    floor, top = deck_span(robot)
    radius = float(getattr(robot.base, "radius", 0.1))
    bottom = floor + max(0.6 * radius, 0.04)
    kind, size = _footprint(robot.base)
    if kind == "box":
        v, f = box([size[0], size[1], top - bottom])
        v = v + np.array([0, 0, (top + bottom) / 2], np.float32)
    else:
        v, f = _prism(size, bottom, top)
    joint = int(robot.model.frames[frame].parentJoint)
    return [Part("deck", frame, joint, np.eye(4), v, f, DECK_COLOUR)]


def wheels(robot) -> list[Wheel]:
    """The base's wheels (empty without a planar wheeled base): positions and headings from
    the base model (mecanum ``half_wheelbase``/``half_track``, omni ``angles``/``distance``,
    steerable ``hips``/``offset``, differential ``separation``), rollers hinted on omni (axis
    along the rolling direction... of the wheel's plane) and mecanum (45°) wheels."""
    base = getattr(robot, "base", None)
    if _base_frame(robot) is None or base is None or not hasattr(base, "radius") or \
            type(base).__name__ == "PlanarRoot":
        return []
    floor, _ = deck_span(robot)
    r = float(base.radius)
    z = floor + r
    out = []
    if hasattr(base, "half_wheelbase"):
        d1, d2 = base.half_wheelbase, base.half_track
        hips = [(d1, d2), (d1, -d2), (-d1, d2), (-d1, -d2)]  # FL, FR, RL, RR
        for k, hip in enumerate(hips):
            # "X" arrangement: the rollers touching the floor form an X seen from above
            angle = math.pi / 4 if k in (0, 3) else -math.pi / 4
            out.append(_wheel(hip, 0.0, 0.0, r, 0.06, z, False, roller_angle=angle))
    elif hasattr(base, "angles"):
        for alpha, (x, y) in zip(base.angles, base.wheel_positions, strict=True):
            out.append(_wheel((x, y), 0.0, alpha + math.pi / 2, r, 0.05, z, False,
                              roller_angle=math.pi / 2))
    elif hasattr(base, "hips"):
        for hip in base.hips:
            out.append(_wheel(hip, base.offset, 0.0, r, 0.05, z, True))
    elif hasattr(base, "separation"):
        for y in (base.separation / 2, -base.separation / 2):
            out.append(_wheel((0.0, y), 0.0, 0.0, r, 0.04, z, False))
    return out


def _wheel(hip, offset, heading, radius, width, z, steerable, roller_angle=None) -> Wheel:
    v, f = cylinder(radius, width, sides=24)
    v = v @ _rotation_z_to(np.array([0, 1.0, 0])).T.astype(np.float32)  # axle along y
    # a spoke: a bar across the wheel, so that rolling is visible
    sv, sf = box([radius * 1.7, width * 1.15, radius * 0.22])
    v, f = np.vstack([v, sv]), np.vstack([f, sf + len(v)])
    rv, rf = np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    if roller_angle is not None:  # rollers on the rim, their axes at roller_angle to the axle
        parts_v, parts_f, count = [], [], 0
        for a in np.linspace(0, 2 * math.pi, 8, endpoint=False):
            centre = radius * np.array([math.cos(a), 0.0, math.sin(a)])
            tangent = np.array([-math.sin(a), 0.0, math.cos(a)])
            axle = np.array([0.0, 1.0, 0.0])
            axis = math.cos(roller_angle) * axle + math.sin(roller_angle) * tangent
            half = 0.5 * width * 1.1 * axis
            cv, cf = capsule(centre - half, centre + half, radius * 0.16, sides=8, rings=2)
            parts_v.append(cv)
            parts_f.append(cf + count)
            count += len(cv)
        rv, rf = np.vstack(parts_v).astype(np.float32), np.vstack(parts_f).astype(np.uint32)
    return Wheel(np.asarray(hip, float), float(offset), float(heading), float(radius),
                 float(width), float(z), bool(steerable), v.astype(np.float32),
                 f.astype(np.uint32), rv, rf)
