"""A strip of a recorded run drawn offline: matplotlib's 3-D axes instead of a browser.

:func:`render_strip_offline` writes the same kind of picture as :func:`wbc.viz.strip.render_strip`
— the robot at ``instants`` evenly spaced ticks of a :class:`~wbc.viz.record.Recording`, side by
side, the time above each panel — on a machine without viser, playwright or Chromium (the
README's main job installs none of them): it needs numpy, pinocchio and matplotlib only.

What a panel shows, in world coordinates [m], every panel seen by one fixed camera that frames
the whole run, the three axes at one scale:

* the links as thick segments between consecutive joint origins along the kinematic tree
  (pinocchio ``forwardKinematics`` on ``robot.model``), the last one to the end-effector frame,
  joints as dots;
* a planar base as its deck's outline (:mod:`wbc.viz.geometry`'s footprint and height, the
  top face shaded) and its wheels as circles in their rolling planes (a steerable wheel turned
  along its hip's velocity, as the viewer does);
* the target's trace (orange) and the end effector's (coloured by each tick's status: green
  solved, orange partial, red failed — the viewer's colours), and the base's path on the floor,
  all of the whole run, thin; the target at that instant as a dot.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import cast

import numpy as np

from wbc.checks import checked_integer
from wbc.errors import ShapeError, WbcError

from . import geometry
from .record import Recording

__all__ = ["render_strip_offline", "render_strips_offline"]

# the viewer's colours (wbc.viz.viewer, which needs viser to import), RGB 0-255
STATUS_COLOURS = {0: (40, 170, 60), 1: (240, 150, 20), 2: (220, 30, 30)}
TARGET_COLOUR = (240, 120, 0)
BASE_PATH_COLOUR = (90, 90, 220)
LINK_COLOUR = geometry.LINK_COLOURS[0]
JOINT_COLOUR = (40, 40, 48)
GRID_COLOUR = (215, 215, 220)
#: one panel's size [px] (the strip is ``instants`` panels wide)
PANEL_PX = 400
#: the camera: seen from the front-right, above (the viewer's direction (0.45, -0.95, 0.65))
ELEVATION_DEG = math.degrees(math.atan2(0.65, math.hypot(0.45, 0.95)))
AZIMUTH_DEG = math.degrees(math.atan2(-0.95, 0.45))
#: how far the camera zooms in on the run's bounding box (matplotlib's 3-D axes leave wide
#: margins around it at 1)
ZOOM = 1.15
#: at most this many ticks are put through forward kinematics to frame the camera
FRAMING_TICKS = 200


def _rgb(colour) -> tuple[float, float, float]:
    return tuple(c / 255 for c in colour)  # type: ignore[return-value]


class _Drawing:
    """What is drawn of one robot: its kinematic tree, deck and wheels, at any ``q``."""

    def __init__(self, robot, ee_frame: str = "ee") -> None:
        import pinocchio as pin

        self.pin = pin
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.first = geometry._first_body_joint(robot)
        self.fixed = getattr(robot, "root", "fixed") == "fixed"
        self.base_fid = geometry._base_frame(robot)
        has_ee = hasattr(robot, "has_frame") and robot.has_frame(ee_frame)
        self.ee_fid = robot.frame_id(ee_frame) if has_ee else None
        self.drawn_base = self.base_fid is not None and \
            type(robot.base).__name__ != "PlanarRoot"
        self.floor_z = geometry.deck_span(robot)[0] if self.drawn_base else 0.0
        self.wheels = geometry.wheels(robot) if self.drawn_base else []
        self.deck = self._deck() if self.drawn_base else None
        mount = getattr(robot, "mount", None)
        self.mount = None if mount is None or not self.drawn_base else \
            np.asarray(mount.translation, float)
        # the leaves of the tree end at a frame they carry: the end effector's where it is one
        parents = set(self.model.parents[j] for j in range(self.first + 1, self.model.njoints))
        self.leaf_ends: dict[int, int] = {}
        for j in range(self.first, self.model.njoints):
            if j in parents:
                continue
            carried = [i for i, f in enumerate(self.model.frames) if f.parentJoint == j
                       and np.linalg.norm(f.placement.translation) > 1e-3]
            if self.ee_fid is not None and self.model.frames[self.ee_fid].parentJoint == j:
                carried.insert(0, self.ee_fid)
            if carried:
                self.leaf_ends[j] = carried[0]

    def _deck(self) -> tuple[np.ndarray, np.ndarray]:
        """The deck's bottom and top outlines in the base frame, ``(2, n, 3)`` [m]."""
        floor, top = geometry.deck_span(self.robot)
        radius = float(getattr(self.robot.base, "radius", 0.1))
        bottom = floor + max(0.6 * radius, 0.04)  # as the viewer's deck: clear of the floor
        kind, size = geometry._footprint(self.robot.base)
        if kind == "box":
            hx, hy = np.asarray(size, float) / 2
            polygon = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        else:
            polygon = np.asarray(size, float)
        n = len(polygon)
        return (np.column_stack([polygon, np.full(n, bottom)]),
                np.column_stack([polygon, np.full(n, top)]))

    def check(self, recording: Recording) -> None:
        if recording.q.shape[1] != self.model.nq:
            raise ShapeError(f"render_strip: the recording's configurations have size "
                             f"{recording.q.shape[1]}, the robot {recording.robot!r} "
                             f"{self.model.nq}")

    def place(self, q: np.ndarray) -> None:
        self.pin.forwardKinematics(self.model, self.data, np.asarray(q, float))
        self.pin.updateFramePlacements(self.model, self.data)

    def segments(self) -> np.ndarray:
        """The links at the last :meth:`place`, ``(n, 2, 3)`` [m]."""
        oMi, oMf, model = self.data.oMi, self.data.oMf, self.model
        out = []
        for j in range(self.first, model.njoints):
            parent = model.parents[j]
            if self.mount is not None and parent < self.first:  # from the deck's top
                out.append((oMf[self.base_fid].act(self.mount), oMi[j].translation))
            elif parent > 0:  # its parent joint's origin (a planar root's: on the floor)
                out.append((oMi[parent].translation, oMi[j].translation))
            elif parent == 0 and self.fixed:  # a fixed arm: from its foot on the ground
                out.append((oMi[0].translation, oMi[j].translation))
            if j in self.leaf_ends:
                out.append((oMi[j].translation, oMf[self.leaf_ends[j]].translation))
        return np.array(out, float).reshape(-1, 2, 3)

    def joints(self) -> np.ndarray:
        return np.array([self.data.oMi[j].translation
                         for j in range(self.first, self.model.njoints)]).reshape(-1, 3)

    def ee(self) -> np.ndarray | None:
        return None if self.ee_fid is None else self.data.oMf[self.ee_fid].translation.copy()

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        M = self.data.oMf[self.base_fid]
        return np.asarray(M.rotation), np.asarray(M.translation)

    def deck_world(self) -> np.ndarray:
        R, p = self.base_pose()
        return self.deck @ R.T + p  # type: ignore[operator]

    def wheel_circles(self, hip_velocity=None, sides: int = 32) -> list[np.ndarray]:
        """Each wheel as a closed ``(sides + 1, 3)`` circle in its rolling plane [m];
        ``hip_velocity(hip)``: the hip's velocity in the base frame, for steered wheels."""
        R, p = self.base_pose()
        a = np.linspace(0, 2 * math.pi, sides + 1)
        out = []
        for wheel in self.wheels:
            heading = wheel.heading
            if wheel.steerable and hip_velocity is not None:
                v = hip_velocity(wheel.hip)
                if np.hypot(*v) > 1e-4:  # standing still: the last heading (here the default)
                    heading = math.atan2(v[1], v[0])
            e = np.array([math.cos(heading), math.sin(heading), 0.0])
            centre = np.array([*wheel.hip, wheel.z]) - wheel.offset * e
            ring = centre + wheel.radius * (np.outer(np.cos(a), e) +
                                            np.outer(np.sin(a), [0.0, 0.0, 1.0]))
            out.append(ring @ R.T + p)
        return out


def _hip_velocity(recording: Recording, k: int):
    """The function hip (base frame) -> its velocity (base frame) at tick ``k``, by central
    differences of the base's planar pose ``q[:3]`` (x, y, θ)."""
    lo, hi = max(k - 1, 0), min(k + 1, len(recording) - 1)
    dt = float(recording.t[hi] - recording.t[lo])
    if hi == lo or dt <= 0:
        return None
    x0, x1 = recording.q[lo, :3], recording.q[hi, :3]
    vx, vy = (x1[:2] - x0[:2]) / dt
    w = (x1[2] - x0[2]) / dt
    c, s = math.cos(recording.q[k, 2]), math.sin(recording.q[k, 2])
    v_base = np.array([c * vx + s * vy, -s * vx + c * vy])  # world -> base frame

    def velocity(hip):
        return v_base + w * np.array([-hip[1], hip[0]])
    return velocity


def render_strip_offline(recording: Recording, path: str | os.PathLike[str], instants: int = 4,
                        title: str = "", robot=None) -> Path:
    """Write the strip of ``recording`` to the PNG ``path`` (``instants`` panels of
    :data:`PANEL_PX` px square) and return it. ``robot``: the robot to draw (default: the
    catalogue robot ``recording.robot``, :func:`wbc.robots.load`).

    Raises:
        WbcError: the recording names no robot (and none is given), or ``instants`` < 1.
        ShapeError: the recording's configurations are not the robot's.
    """
    return render_strips_offline([(recording, path, title)], instants, robot)[0]


def render_strips_offline(jobs, instants: int = 4, robot=None) -> list[Path]:
    """:func:`render_strip_offline` for several ``(recording, path, title)`` (each catalogue
    robot loaded once)."""
    jobs = list(jobs)
    instants = checked_integer(instants, "render_strip: instants", low=1)
    for recording, _, _ in jobs:
        if robot is None and not recording.robot:
            raise WbcError("render_strip: the recording names no robot")
    drawings: dict[str, _Drawing] = {}
    paths = []
    for recording, path, title in jobs:
        key = "" if robot is not None else recording.robot
        if key not in drawings:
            drawings[key] = _Drawing(robot if robot is not None else _load(recording.robot))
        drawing = drawings[key]
        drawing.check(recording)
        paths.append(_draw(drawing, recording, Path(path), instants, title))
    return paths


def _load(name: str):
    """The catalogue robot ``name``."""
    import wbc.robots

    return wbc.robots.load(name)


def _draw(drawing: _Drawing, recording: Recording, path: Path, instants: int,
          title: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d import Axes3D
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    n = len(recording)
    ticks = np.unique(np.linspace(0, n - 1, instants).round().astype(int))
    ee = recording.ee
    if ee is None and drawing.ee_fid is not None:
        ee = np.empty((n, 3))
        for k in range(n):
            drawing.place(recording.q[k])
            ee[k] = drawing.ee()
    base_path = (np.column_stack([recording.q[:, :2], np.full(n, drawing.floor_z)])
                 if drawing.drawn_base else None)

    # the camera frames every instant of the run: the robot at up to FRAMING_TICKS ticks
    seen = []
    for k in np.unique(np.r_[np.linspace(0, n - 1, min(n, FRAMING_TICKS)).astype(int), ticks]):
        drawing.place(recording.q[k])
        seen.append(drawing.segments().reshape(-1, 3))
        if drawing.drawn_base:
            seen.append(drawing.deck_world().reshape(-1, 3))
            seen += drawing.wheel_circles()
    seen += [p for p in (ee, recording.target, base_path) if p is not None]
    points = np.vstack(seen)
    points = points[np.isfinite(points).all(axis=1)]
    low, high = points.min(axis=0), points.max(axis=0)
    # the floor: the base's, a fixed arm's foot (z = 0), else under the lowest point
    floor_z = drawing.floor_z if drawing.drawn_base or drawing.fixed else float(low[2])
    low[2] = min(low[2], floor_z)
    # at least 0.8 m of floor around the run (the viewer's smallest frame), as a sense of scale
    centre, half = (low + high) / 2, np.maximum((high - low) / 2, 0.4)
    low[:2], high[:2] = centre[:2] - half[:2], centre[:2] + half[:2]
    pad = 0.04 * max(float(np.max(high - low)), 0.5)
    low, high = low - pad, high + pad
    span = np.maximum(high - low, 1e-3)

    width = PANEL_PX * len(ticks)
    fig = plt.figure(figsize=(width / 100, PANEL_PX / 100), dpi=100)
    for i, k in enumerate(ticks):
        ax = cast(Axes3D, fig.add_axes((i / len(ticks), 0.0, 1 / len(ticks), 0.92),
                                        projection="3d"))
        ax.set_proj_type("ortho")  # equal scales read as lengths anywhere in the panel
        ax.view_init(elev=ELEVATION_DEG, azim=AZIMUTH_DEG)
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_zlim(low[2], high[2])
        ax.set_box_aspect(tuple(span), zoom=ZOOM)  # one scale on the three axes
        ax.set_axis_off()
        # drawn in layers by zorder (floor, traces, base, links, joints, markers): matplotlib's
        # depth sort is per artist, and would put a whole trace or the deck over the arm
        ax.computed_zorder = False
        _floor_grid(ax, low, high, floor_z, Line3DCollection)
        if base_path is not None:
            ax.plot(*base_path.T, color=_rgb(BASE_PATH_COLOUR), lw=0.8, alpha=0.7, zorder=1)
        if recording.target is not None:
            # wider than the end effector's, drawn under it: both show where they coincide
            ax.plot(*recording.target.T, color=_rgb(TARGET_COLOUR), lw=2.2, alpha=0.6,
                    zorder=1)
        if ee is not None and n > 1:
            colours = [_rgb(STATUS_COLOURS[int(c)]) for c in recording.status[1:]]
            ax.add_collection3d(Line3DCollection(np.stack([ee[:-1], ee[1:]], axis=1),
                                                 colors=colours, linewidths=1.0, zorder=1.5))
        drawing.place(recording.q[k])
        if drawing.drawn_base:
            bottom, top = drawing.deck_world()
            deck = _rgb(geometry.DECK_COLOUR)
            sides = [np.array([a, b, c, d]) for a, b, c, d in
                     zip(bottom, np.roll(bottom, -1, axis=0), np.roll(top, -1, axis=0), top,
                         strict=True)]
            # two collections: one of polygons of unequal sizes is padded with whatever
            # memory holds (matplotlib masks it, but its projection may warn of overflows)
            ax.add_collection3d(Poly3DCollection([top], edgecolors="none", zorder=2,
                                                 facecolors=[(*deck, 0.45)]))
            ax.add_collection3d(Poly3DCollection(sides, edgecolors="none", zorder=2,
                                                 facecolors=[(*deck, 0.15)]))
            edges = [np.array([a, b]) for ring in (bottom, top)
                     for a, b in zip(ring, np.roll(ring, -1, axis=0), strict=True)]
            if len(top) <= 8:  # a round deck's many vertical edges would only clutter it
                edges += [np.array([a, b]) for a, b in zip(bottom, top, strict=True)]
            ax.add_collection3d(Line3DCollection(edges, colors=[deck], linewidths=1.2,
                                                 zorder=2.1))
            for ring in drawing.wheel_circles(_hip_velocity(recording, int(k))):
                ax.plot(*ring.T, color=_rgb(geometry.WHEEL_COLOUR), lw=1.6, zorder=2.2)
        ax.add_collection3d(Line3DCollection(drawing.segments(), colors=[_rgb(LINK_COLOUR)],
                                             linewidths=5.0, capstyle="round", zorder=3))
        joints = drawing.joints()
        ax.scatter(joints[:, 0], joints[:, 1], joints[:, 2], s=14, color=_rgb(JOINT_COLOUR),
                   depthshade=False, zorder=4)
        if recording.target is not None:
            tx, ty, tz = recording.target[k]
            ax.scatter(tx, ty, tz, s=30, color=_rgb(TARGET_COLOUR),
                       depthshade=False, edgecolors="black", linewidths=0.5, zorder=5)
        if ee is not None:
            ex, ey, ez = ee[k]
            ax.scatter(ex, ey, ez, s=18, color=_rgb(STATUS_COLOURS[int(recording.status[k])]),
                       depthshade=False, zorder=5)
        fig.text((i + 0.5) / len(ticks), 0.97, f"t = {recording.t[k]:.1f} s", ha="center",
                 va="top", fontsize=11)
    if title:
        fig.suptitle(title, fontsize=12, y=1.0, va="bottom")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight" if title else None)
    plt.close(fig)
    return path


def _floor_grid(ax, low, high, z: float, Line3DCollection) -> None:
    """Light lines on the floor every 0.25, 0.5 or 1 m (a sense of scale and of depth)."""
    step = next(s for s in (0.25, 0.5, 1.0, 2.0, 5.0) if max(high[:2] - low[:2]) / s <= 12)
    xs = np.arange(math.ceil(low[0] / step), math.floor(high[0] / step) + 1) * step
    ys = np.arange(math.ceil(low[1] / step), math.floor(high[1] / step) + 1) * step
    lines = [np.array([[x, low[1], z], [x, high[1], z]]) for x in xs]
    lines += [np.array([[low[0], y, z], [high[0], y, z]]) for y in ys]
    if lines:
        ax.add_collection3d(Line3DCollection(lines, colors=[_rgb(GRID_COLOUR)],
                                             linewidths=0.6, zorder=0))
