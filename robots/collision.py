"""Collision geometry of a wbc robot: distances and normal Jacobians for collision avoidance.

A :class:`CollisionModel` holds a pinocchio ``GeometryModel`` attached to a robot's own
pinocchio model — the URDF's ``<collision>`` geometry, remapped onto the robot (fixed-base arm,
reduced model with locked fingers, or an arm appended on a mobile base) — plus static obstacles
(:class:`Obstacle`: box, sphere, capsule placed in the world), and the list of pairs whose
distance is watched. Every tick it computes all those distances at once (pinocchio's C++ loop
over coal's GJK/EPA) and hands the ``k`` closest to :class:`wbc.tasks.collision.CollisionAvoidance`
as two model quantities on the robot's :class:`~wbc.quantities.QuantityRegistry`:

=================================  ===========  ================================================
name                               shape        value (at the robot's last ``update``)
=================================  ===========  ================================================
``collision_distance[<key>]``      ``(k, 1)``   signed distances ``d_i`` [m] of the ``k``
                                                closest pairs (negative: penetration depth)
``collision_jacobian[<key>]``      ``(k, nv)``  rows ``J_i`` with ``ḋ_i = J_i v`` [m/s per unit v]
=================================  ===========  ================================================

``<key>`` is the name of the task that asked for them (:meth:`CollisionModel.register`).
Neither has a symbolic form: the controller fills them numerically on every path (ordinary and
fused), after its one kinematics update.

Geometry. Meshes are replaced by their convex hulls (``convex=True``, the default;
:func:`convex_hull`): coal's mesh–mesh distance (BVH) cost 6.9 ms per tick for the Panda's 44
self-collision pairs, the hulls ≈ 40 µs, and GJK/EPA on convex shapes gives a *signed* distance
and a well-defined normal when bodies touch or overlap (a BVH pair reports 0 and no usable
normal). The hull contains the mesh, so distances are conservative (never larger than the
mesh's). Primitive shapes of the URDF (boxes, spheres, cylinders) are kept as they are.

Pairs. By default every pair of geometry objects on different links, minus the pairs the SRDF
disables (``srdf=``, MoveIt's ``<disable_collisions>``), minus pairs rigidly attached to each
other in the robot's model (e.g. a hand and its locked fingers: their distance never changes);
without an SRDF, adjacent links (one's joint the parent of the other's) are left out too, since
their meshes touch at the joint. Every obstacle is paired with every robot geometry object.
``pairs=[("panda_hand", "panda_link0"), ("panda_hand", "wall"), ...]`` lists them explicitly,
by link name (all geometry objects of that link), geometry-object name or obstacle name.

Distance and Jacobian. For a pair ``(a, b)`` coal returns witness points ``p_a``, ``p_b`` and
the unit normal ``n`` pointing from ``a`` to ``b`` with ``d = nᵀ (p_b − p_a)``. The distance
rate is ``ḋ = nᵀ (ṗ_b − ṗ_a)`` (the witness points' sliding is tangent to the surfaces), and the
velocity of a point ``p`` carried by joint ``j`` is ``J_lin v + ω × p`` in pinocchio's WORLD
convention, so the row is ::

    J_i = [nᵀ J_lin + (p_b × n)ᵀ J_ang]·M_b − [nᵀ J_lin + (p_a × n)ᵀ J_ang]·M_a,   then · S(q)

with ``J_lin``, ``J_ang`` the rows of pinocchio's ``data.J`` (WORLD), ``M_j`` the 0/1 mask of
the columns supporting joint ``j`` (all zero for an obstacle, fixed to the world) and ``S(q)``
the robot's map from its velocity coordinates to pinocchio's ``q̇`` (identity for a fixed base;
see :mod:`wbc.robots.pinocchio_robot`). All ``k`` rows are built with a handful of numpy
products, no loop over pairs; the only per-pair Python is reading the ``k`` selected pairs'
witness points and normals.

Hot path: ``updateGeometryPlacements`` + ``computeDistances`` (C++), the distances read into an
array through proxies made once (``np.fromiter`` over ``map``: ≈ 0.14 µs a pair on this
machine), ``np.argpartition`` for the ``k`` closest, the vectorised rows above. The result is
cached on the robot's configuration: the two quantities cost one computation per tick.
Measured (Panda, daqp fused tick, a wall and the hand pushed behind it, 1460 ticks × 3, the
controllers taking turns; shared 2-core machine): 10 µs a tick without the constraint; with
it, 56 µs for the wall's 16 pairs (kinematics update 4, distances 18, selection and rows 23)
and 96 µs with the SRDF's self-collision pairs too (60 pairs: distances 54). The distances grow
with the number of pairs (TALOS, 939 pairs: ≈ 2.4 ms): list the pairs that matter.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from operator import attrgetter
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from wbc.checks import (
    as_float_array,
    check_finite,
    check_pose,
    checked_flag,
    checked_integer,
    checked_name,
    checked_number,
    checked_path,
)
from wbc.errors import InvalidValueError, ModelLoadError, ShapeError, UnknownNameError
from wbc.quantities import QuantityRegistry

from .resources import robots_dir

__all__ = ["CollisionModel", "Obstacle", "INERT_DISTANCE", "configure_requests"]

#: The distance [m] an unused row reports (fewer pairs than rows): far enough that its velocity
#: damper ``0 <= gain (d − d_min) / dt`` never binds, finite so that every backend takes it.
INERT_DISTANCE = 1e3

_MIN_DISTANCE = attrgetter("min_distance")


# ------------------------------------------------------------------------------ obstacles
@dataclass(frozen=True)
class Obstacle:
    """A static obstacle: a coal shape fixed in the world.

    Build one with :meth:`box`, :meth:`sphere` or :meth:`capsule`.

    Attributes:
        name: its name (in pairs and reports).
        kind: ``"box"``, ``"sphere"`` or ``"capsule"``.
        size: the box's full side lengths ``(x, y, z)`` [m]; the sphere's ``(radius,)``; the
            capsule's ``(radius, length)`` [m] (length of the axis segment, along the local z).
        pose: ``(4, 4)`` world pose of the shape's centre.
    """

    name: str
    kind: str
    size: tuple[float, ...]
    pose: np.ndarray

    @classmethod
    def box(cls, name: str, size, pose) -> Obstacle:
        """A box with full side lengths ``size = (x, y, z)`` [m] centred at ``pose``."""
        values = _checked_sizes(size, 3, f"size of box {name!r}")
        return cls._make(name, "box", values, pose)

    @classmethod
    def sphere(cls, name: str, radius: float, position=None, pose=None) -> Obstacle:
        """A sphere of ``radius`` [m] centred at ``position`` (3,) [m] (or at ``pose``)."""
        value = checked_number(radius, f"radius of sphere {name!r}", 0.0, strict=True)
        if position is not None:
            if pose is not None:
                raise InvalidValueError(f"sphere {name!r}: give position or pose, not both")
            point = as_float_array(position, f"position of sphere {name!r}")
            if point.shape != (3,):
                raise ShapeError(f"position of sphere {name!r} must have shape (3,), got "
                                 f"{point.shape}")
            check_finite(point, f"position of sphere {name!r}")
            pose = np.eye(4)
            pose[:3, 3] = point
        return cls._make(name, "sphere", (value,), np.eye(4) if pose is None else pose)

    @classmethod
    def capsule(cls, name: str, radius: float, length: float, pose) -> Obstacle:
        """A capsule: the points within ``radius`` [m] of a segment of ``length`` [m] along
        the local z axis of ``pose``, centred at its origin."""
        value = checked_number(radius, f"radius of capsule {name!r}", 0.0, strict=True)
        axis = checked_number(length, f"length of capsule {name!r}", 0.0)
        return cls._make(name, "capsule", (value, axis), pose)

    @classmethod
    def _make(cls, name, kind, size, pose) -> Obstacle:
        name = checked_name(name, f"name of a {kind} obstacle", optional=False)
        matrix = as_float_array(pose, f"pose of obstacle {name!r}")
        if matrix.shape != (4, 4):
            raise ShapeError(f"pose of obstacle {name!r} must have shape (4, 4), got "
                             f"{matrix.shape}")
        check_finite(matrix, f"pose of obstacle {name!r}")
        check_pose(matrix, f"pose of obstacle {name!r}")
        matrix = matrix.copy()
        matrix.setflags(write=False)
        return cls(name, kind, tuple(size), matrix)

    def geometry(self) -> coal.CollisionGeometry:
        """The coal shape."""
        if self.kind == "box":
            return coal.Box(*self.size)
        if self.kind == "sphere":
            return coal.Sphere(self.size[0])
        return coal.Capsule(self.size[0], self.size[1])


def _checked_sizes(value, count: int, what: str) -> tuple[float, ...]:
    array = as_float_array(value, what)
    if array.shape != (count,):
        raise ShapeError(f"{what} must have shape ({count},), got {array.shape}")
    check_finite(array, what)
    if (array <= 0).any():
        raise InvalidValueError(f"{what} must be > 0, got {array.tolist()}")
    return tuple(float(x) for x in array)


def _checked_paths(value, what: str) -> list[str]:
    """A list or tuple of folder paths (``str`` / ``os.PathLike``) as ``str`` s."""
    if not isinstance(value, (list, tuple)):
        raise InvalidValueError(f"{what} must be a list of folder paths, got {value!r}"[:160])
    return [checked_path(entry, f"an entry of {what}", optional=False) for entry in value]


def configure_requests(geometry_data: pin.GeometryData) -> None:
    """Set the distance requests of ``geometry_data`` as :class:`CollisionModel` uses them:
    GJK/EPA tolerances 1e-9, and *no* warm start from the previous call. pinocchio turns coal's
    cached guess on; with it, on the Panda's hulls, the distances depended on the call history:
    along a smooth path their finite-difference rates spread by up to 0.23 m/s, and 8 of 3600
    random pair-states missed the row by up to 8.5e-4 m/s; without it the rates agree with the
    rows to 2.5e-9 and the distances depend on ``q`` alone. It costs ≈ 14 µs a tick on the
    Panda's 60 pairs (30 → 44 µs, median over a path of 2000 nearby configurations)."""
    for request in geometry_data.distanceRequests:
        request.gjk_tolerance = 1e-9
        request.epa_tolerance = 1e-9
        request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
        with warnings.catch_warnings():  # coal deprecates the switch but still reads it
            warnings.simplefilter("ignore", DeprecationWarning)
            request.enable_cached_gjk_guess = False


def convex_hull(mesh: coal.BVHModelBase) -> coal.ConvexBase:
    """The convex hull of a mesh's vertices, as a coal ``Convex`` (qhull, ``"Qt"``, facets
    merged into polygons).

    Not the mesh's own ``buildConvexRepresentation``: on example-robot-data's TALOS meshes its
    hulls kept points that are no vertices, and GJK's hill-climbing support search then stopped
    on them — the same two bodies came out 0.16822 or 0.16711 m apart depending on where the
    robot stood (exact: 0.16711, a QP over the vertices). These hulls give the exact distance
    wherever the bodies are."""
    points = coal.StdVec_Vec3s()
    for vertex in mesh.vertices():
        points.append(np.array(vertex))
    return coal.ConvexBase.convexHull(points, False, "Qt")


# ------------------------------------------------------------------------------ the model
# the collision selections of a registry, {key: (CollisionModel, k)}, kept on the registry
# itself (a module-level map would keep every robot alive: its values reference the robot); a
# kind registered again replaces the previous one, so one pair of kinds serves every model
_SELECTIONS = "_collision_selections"


class CollisionModel:
    """The collision geometry of ``robot``, its watched pairs and static obstacles (see the
    module docstring).

    Args:
        robot: a wbc pinocchio robot (``model``, ``data``, ``update``, ``quantities``): a
            fixed-base arm, an arm on a planar base (rows through ``S(q)``), or a free flyer
            (rows over pinocchio's own ``v``). The quantities are registered on *this*
            instance: give the same robot to the :class:`~wbc.Controller` (a clone has a
            registry of its own).
        urdf: the URDF whose ``<collision>`` elements are read (default: ``robot.urdf_path``).
            ``None`` with no such attribute: no robot geometry (obstacles need some).
        srdf: an SRDF whose ``<disable_collisions>`` pairs are left out (optional).
        pairs: explicit pairs ``(name_a, name_b)`` of link, geometry-object or obstacle names
            (default: see the module docstring).
        obstacles: :class:`Obstacle` s fixed in the world.
        self_collision: watch pairs of robot links (default pairs only; ``False``: obstacles
            only).
        convex: replace meshes by their convex hulls (see the module docstring).
        package_dirs: folders ``package://`` URIs are resolved against (example-robot-data's
            ``share`` folder and the URDF's parent folders are always tried).

    Raises:
        ModelLoadError: the URDF cannot be read or has no collision geometry.
        UnknownNameError: a pair names no link, geometry object or obstacle; an URDF link of
            the geometry has no body frame in the robot's model.
        InvalidValueError: no pair to watch; duplicate obstacle names.
    """

    def __init__(self, robot, urdf: str | os.PathLike[str] | None = None,
                 srdf: str | os.PathLike[str] | None = None,
                 pairs: Sequence[tuple[str, str]] | None = None,
                 obstacles: Sequence[Obstacle] = (), self_collision: bool = True,
                 convex: bool = True, package_dirs: Sequence[str] = ()) -> None:
        for attribute in ("model", "data", "update", "nv", "nq"):
            if not hasattr(robot, attribute):
                raise InvalidValueError(f"CollisionModel needs a wbc pinocchio robot (with "
                                        f"{attribute!r}), got {type(robot).__name__}")
        if not isinstance(getattr(robot, "quantities", None), QuantityRegistry):
            raise InvalidValueError(f"CollisionModel: robot {type(robot).__name__} has no "
                                    "quantity registry (robot.quantities)")
        urdf = checked_path(urdf, "urdf of CollisionModel")
        srdf = checked_path(srdf, "srdf of CollisionModel")
        self_collision = checked_flag(self_collision, "self_collision of CollisionModel")
        convex = checked_flag(convex, "convex of CollisionModel")
        package_dirs = _checked_paths(package_dirs, "package_dirs of CollisionModel")
        if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, Sequence):
            raise InvalidValueError(f"obstacles of CollisionModel must be a list of "
                                    f"wbc.robots.collision.Obstacle, got {obstacles!r}"[:160])
        self.robot = robot
        model: pin.Model = robot.model
        self.model = model
        urdf = urdf if urdf is not None else getattr(robot, "urdf_path", None)
        obstacles = list(obstacles)
        for obstacle in obstacles:
            if not isinstance(obstacle, Obstacle):
                raise InvalidValueError(f"obstacles must be wbc.robots.collision.Obstacle "
                                        f"objects, got {type(obstacle).__name__}")
        names = [o.name for o in obstacles]
        if len(set(names)) != len(names):
            raise InvalidValueError(f"obstacle names must be unique, got {names}")
        self.urdf = None if urdf is None else Path(os.fspath(urdf))
        geometry = pin.GeometryModel()
        links: dict[str, list[int]] = {}  # link name -> geometry ids
        urdf_pairs: list[tuple[int, int]] = []
        if self.urdf is not None:
            urdf_pairs = self._robot_geometry(geometry, links, srdf, package_dirs, convex)
        elif srdf is not None:
            raise InvalidValueError("CollisionModel: srdf given but no URDF (pass urdf=, or "
                                    "a robot with urdf_path)")
        robot_ids = list(range(geometry.ngeoms))
        obstacle_ids = {}
        for obstacle in obstacles:
            if obstacle.name in links or geometry.existGeometryName(obstacle.name):
                raise InvalidValueError(f"obstacle name {obstacle.name!r} is also a robot "
                                        "link or geometry name")
            placement = pin.SE3(obstacle.pose[:3, :3].copy(), obstacle.pose[:3, 3].copy())
            obj = pin.GeometryObject(obstacle.name, 0, 0, placement, obstacle.geometry())
            obstacle_ids[obstacle.name] = geometry.addGeometryObject(obj)
        self.obstacles = tuple(obstacles)
        if not geometry.ngeoms:
            raise ModelLoadError(f"CollisionModel: robot {getattr(robot, 'name', '')!r} has no "
                                 "collision geometry (no URDF: pass urdf=, or obstacles=)")
        joint_of = [geometry.geometryObjects[i].parentJoint for i in range(geometry.ngeoms)]
        if pairs is not None:
            chosen = self._listed_pairs(geometry, links, obstacle_ids, pairs)
        else:
            chosen = list(urdf_pairs) if self_collision else []
            chosen += [(r, o) for o in obstacle_ids.values() for r in robot_ids]
        # rigidly attached objects keep their distance: a row of zeros, useless or infeasible
        chosen = [(a, b) for a, b in chosen if joint_of[a] != joint_of[b]]
        chosen = list(dict.fromkeys((min(a, b), max(a, b)) for a, b in chosen))
        if not chosen:
            raise InvalidValueError("CollisionModel: no pair of geometry objects to watch "
                                    "(every listed pair is rigidly attached, or none given)")
        for a, b in chosen:
            geometry.addCollisionPair(pin.CollisionPair(a, b))
        self.geometry = geometry
        self.geometry_data = pin.GeometryData(geometry)
        configure_requests(self.geometry_data)
        self.n_pairs = len(chosen)
        self._first = np.array([a for a, _ in chosen])
        self._second = np.array([b for _, b in chosen])
        # per pair: the parent joints' support masks over pinocchio's velocity coordinates
        masks = np.zeros((model.njoints, model.nv))
        for joint in range(1, model.njoints):
            for support in model.supports[joint]:
                if support > 0:
                    idx, width = model.joints[support].idx_v, model.joints[support].nv
                    masks[joint, idx:idx + width] = 1.0
        joints = np.array(joint_of)
        self._masks = np.stack((masks[joints[self._second]], masks[joints[self._first]]))
        self.pair_names = [(geometry.geometryObjects[a].name, geometry.geometryObjects[b].name)
                           for a, b in chosen]
        # proxies of the results, made once: reading them is the one loop, in C (np.fromiter)
        self._results = list(self.geometry_data.distanceResults)
        self._distances = np.empty(self.n_pairs)
        self._key = b""  # the configuration the distances are of (its bytes)
        self._selected: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._s = getattr(robot, "_s", None) if getattr(robot, "base", None) is not None else None

    # ---------------------------------------------------------------- building
    def _robot_geometry(self, geometry, links, srdf, package_dirs, convex):
        """Read the URDF's collision geometry, drop the SRDF's pairs, remap it onto the
        robot's model; returns the default self-collision pairs (geometry ids)."""
        path = self.urdf
        assert path is not None
        if not path.is_file():
            raise ModelLoadError(f"URDF file {str(path)!r} does not exist")
        dirs = [str(d) for d in package_dirs]
        try:
            dirs.append(str(robots_dir().parent.parent))  # ".../share": package://example-...
        except FileNotFoundError:
            pass
        dirs += [str(p) for p in path.resolve().parents]
        try:
            source = pin.buildModelFromUrdf(str(path))
            source_geometry = pin.buildGeomFromUrdf(source, str(path),
                                                    pin.GeometryType.COLLISION, None, dirs)
        except (ValueError, RuntimeError) as err:
            raise ModelLoadError(f"cannot read the collision geometry of {str(path)!r}: "
                                 f"{err}") from None
        if not source_geometry.ngeoms:
            raise ModelLoadError(f"URDF {str(path)!r} has no <collision> geometry")
        source_geometry.addAllCollisionPairs()
        if srdf is not None:
            srdf = os.fspath(srdf)
            if not os.path.isfile(srdf):
                raise ModelLoadError(f"SRDF file {srdf!r} does not exist")
            pin.removeCollisionPairs(source, source_geometry, srdf)
        else:  # adjacent links touch at their joint
            keep = []
            for pair in source_geometry.collisionPairs:
                ja = source_geometry.geometryObjects[pair.first].parentJoint
                jb = source_geometry.geometryObjects[pair.second].parentJoint
                if source.parents[ja] != jb and source.parents[jb] != ja:
                    keep.append((pair.first, pair.second))
            source_geometry.removeAllCollisionPairs()
            for a, b in keep:
                source_geometry.addCollisionPair(pin.CollisionPair(a, b))
        model = self.model
        for index, obj in enumerate(source_geometry.geometryObjects):
            link = source.frames[obj.parentFrame].name
            frame_id = self._body_frame(link)
            frame = model.frames[frame_id]
            # the object's placement in its link, then the link's in the robot's joint
            in_link = source.frames[obj.parentFrame].placement.actInv(obj.placement)
            shape = obj.geometry
            if convex and isinstance(shape, coal.BVHModelBase):
                shape = convex_hull(shape)
            new = pin.GeometryObject(obj.name, frame.parentJoint, frame_id,
                                     frame.placement.act(in_link), shape)
            geometry.addGeometryObject(new)  # same index as in the URDF's geometry
            links.setdefault(link, []).append(index)
        return [(p.first, p.second) for p in source_geometry.collisionPairs]

    def _body_frame(self, link: str) -> int:
        """The robot model's body frame of URDF link ``link`` (renamed ``link:<name>`` when
        ambiguous, ``arm_<name>`` on a mobile base when it clashed with the base's)."""
        model = self.model
        for name in (link, f"link:{link}", f"arm_{link}", f"arm_link:{link}"):
            for index, frame in enumerate(model.frames):
                if frame.name == name and frame.type == pin.FrameType.BODY:
                    return index
        raise UnknownNameError(f"CollisionModel: URDF link {link!r} has no body frame in the "
                               f"robot's model {model.name!r} (a different URDF?)")

    @staticmethod
    def _listed_pairs(geometry, links, obstacle_ids, pairs) -> list[tuple[int, int]]:
        if isinstance(pairs, (str, bytes)) or not isinstance(pairs, Sequence):
            raise InvalidValueError(f"pairs must be a list of (name, name) tuples, got "
                                    f"{pairs!r}"[:160])
        objects = {geometry.geometryObjects[i].name: [i] for i in range(geometry.ngeoms)}
        known = {**objects, **links, **{k: [v] for k, v in obstacle_ids.items()}}
        chosen = []
        for pair in pairs:
            if (not isinstance(pair, (tuple, list)) or len(pair) != 2
                    or not all(isinstance(n, str) for n in pair)):
                raise InvalidValueError(f"each pair must be two names, got {pair!r}"[:160])
            for name in pair:
                if name not in known:
                    raise UnknownNameError(f"collision pair {tuple(pair)}: unknown name "
                                           f"{name!r}; links: {sorted(links)}; obstacles: "
                                           f"{sorted(obstacle_ids)}")
            chosen += [(a, b) for a in known[pair[0]] for b in known[pair[1]] if a != b]
        return chosen

    # ---------------------------------------------------------------- the tick
    def compute(self) -> np.ndarray:
        """All watched distances [m] (one per pair, :attr:`pair_names` order) at the robot's
        last ``update``; computed once per configuration (the returned array is reused)."""
        robot = self.robot
        key = robot._q.tobytes()  # the configuration of the robot's last update
        if key != self._key:
            pin.updateGeometryPlacements(self.model, robot.data, self.geometry,
                                         self.geometry_data)
            pin.computeDistances(self.geometry, self.geometry_data)
            self._distances[:] = np.fromiter(map(_MIN_DISTANCE, self._results), float,
                                             self.n_pairs)
            self._key = key
            self._selected.clear()
        return self._distances

    def closest(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(d, J)`` of the ``k`` closest pairs at the robot's last update: distances
        ``(k,)`` [m] and rows ``(k, nv)`` with ``ḋ = J v`` (module docstring). Rows beyond
        :attr:`n_pairs` are inert (``d = INERT_DISTANCE``, ``J = 0``). Cached per ``k``."""
        distances = self.compute()
        hit = self._selected.get(k)
        if hit is not None:
            return hit
        n = self.n_pairs
        used = min(k, n)
        chosen = (np.argpartition(distances, used - 1)[:used] if used < n
                  else np.arange(n))
        d = np.full(k, INERT_DISTANCE)
        d[:used] = distances[chosen]
        # a point's row is [n; p × n]ᵀ J_world: the weights of the points on b, then on a,
        # in Python floats (fewer calls than numpy on a few 3-vectors)
        on_b, on_a = [], []
        for pair in chosen.tolist():  # the k selected pairs only
            result = self._results[pair]
            ax, ay, az = result.getNearestPoint1().tolist()
            bx, by, bz = result.getNearestPoint2().tolist()
            nx, ny, nz = result.normal.tolist()
            on_b.append((nx, ny, nz, by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx))
            on_a.append((nx, ny, nz, ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx))
        weights = np.array((on_b, on_a))  # (2, used, 6)
        if not math.isfinite(weights.sum()):  # coal leaves no normal for some touching shapes
            weights = np.nan_to_num(weights)
        # J_world: pinocchio's data.J, (6, nv_pin), WORLD axes, rows [linear; angular]
        sides = (weights @ self.robot.data.J) * self._masks[:, chosen]
        rows = sides[0] - sides[1]
        if self._s is not None:
            rows = rows @ self._s
        J = np.zeros((k, self.robot.nv))
        J[:used] = rows
        self._selected[k] = (d, J)
        return d, J

    # ---------------------------------------------------------------- quantities
    def register(self, key: str, k: int) -> tuple[str, str]:
        """Offer ``collision_distance[<key>]`` ``(k, 1)`` and ``collision_jacobian[<key>]``
        ``(k, nv)`` on the robot's quantity registry (module docstring); returns the two
        names. A key registered again (by any model of the same robot) replaces the earlier
        selection: one key per task, the task's name."""
        key = checked_name(key, "key of a collision selection", optional=False)
        k = checked_integer(k, "max_pairs", low=1)
        registry = self.robot.quantities
        selections = vars(registry).setdefault(_SELECTIONS, {})
        selections[key] = (self, k)
        nv = int(self.robot.nv)

        def fill_distance(argument, out) -> None:
            model, rows = selections[argument]
            out[:, 0] = model.closest(rows)[0]

        def fill_jacobian(argument, out) -> None:
            model, rows = selections[argument]
            out[...] = model.closest(rows)[1]

        keys = lambda: list(selections)  # noqa: E731
        registry.register("collision_distance", argument="task", arguments=keys,
                          shape=lambda a: (selections[a][1], 1), fill=fill_distance,
                          doc="signed distances (k, 1) [m] of the k closest collision pairs")
        registry.register("collision_jacobian", argument="task", arguments=keys,
                          shape=lambda a: (selections[a][1], nv), fill=fill_jacobian,
                          doc="distance-rate rows (k, nv): ḋ = J v [m/s per unit v]")
        return f"collision_distance[{key}]", f"collision_jacobian[{key}]"

    def distances(self, q) -> dict[tuple[str, str], float]:
        """Every watched distance [m] at ``q``, by pair of geometry names (for reports and
        tests; updates the robot's kinematics)."""
        q = np.asarray(q, dtype=float)
        self.robot.update(q)
        values = self.compute()
        return {pair: float(value) for pair, value in zip(self.pair_names, values, strict=True)}

    def min_distance(self, q) -> float:
        """The smallest watched distance [m] at ``q``."""
        return float(min(self.distances(q).values()))

    def __repr__(self) -> str:
        return (f"CollisionModel(robot={getattr(self.robot, 'name', '')!r}, "
                f"geometries={self.geometry.ngeoms}, pairs={self.n_pairs}, "
                f"obstacles={[o.name for o in self.obstacles]})")
