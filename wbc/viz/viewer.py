"""`Viewer`: a robot in the browser (viser), with overlays and replays of recorded runs.

::

    viewer = Viewer(robot)                      # serves http://127.0.0.1:8080, prints the URL
    viewer.show(q)                              # the robot at configuration q
    viewer.set_target(T)                        # a pose triad ((4, 4) pose or a position)
    viewer.replay(run)                          # a wbc.sim.Run (or Recordings): slider, play

What is drawn is :mod:`wbc.viz.geometry`'s (meshes where the model has them, otherwise the
kinematic model). Overlays: the end-effector frame (and any frame, :meth:`Viewer.add_frame`),
the target triad, the base's path on the floor and the end effector's path; a joint within
``near_limit`` of its range's end is coloured red (the links it moves). A replay draws the
target and end-effector traces of the whole run — the end effector's coloured by the tick's
status (green solved, orange partial, red failed) — and a time slider, play/pause and speed;
the tick's status is written beside it.

The server binds ``127.0.0.1`` unless told otherwise: the page is a control UI, not to be
exposed to the network by default. A port in use is an error (:class:`PortInUseError`), not
a silent move to the next port.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from wbc.errors import ShapeError, UnknownNameError, WbcError

from . import geometry, require_viser
from .record import STATUS_CODES, Recording

__all__ = ["PortInUseError", "Viewer"]

#: replay status colours (RGB 0-255), by status code
STATUS_COLOURS = {0: (40, 170, 60), 1: (240, 150, 20), 2: (220, 30, 30)}
NEAR_LIMIT_COLOUR = (230, 50, 40)
TARGET_COLOUR = (240, 120, 0)
BASE_PATH_COLOUR = (90, 90, 220)
EE_PATH_COLOUR = (20, 150, 150)
#: the paths keep at most this many points (older ones are dropped)
PATH_POINTS = 3000
SPEEDS = ("0.25", "0.5", "1", "2", "4")


class PortInUseError(WbcError):
    """The viewer's port is taken by another program."""


def _check_port(host: str, port: int) -> None:
    """Raise :class:`PortInUseError` when ``host:port`` cannot be bound (viser itself would
    move on to the next free port, and the printed URL would then be another's page)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        # as servers do: a closed server's connections in TIME_WAIT do not hold the port
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as err:
            raise PortInUseError(f"cannot serve on {host}:{port}: {err.strerror or err} "
                                 "(another viewer running? pick one with --port)") from None


def _wxyz(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    import pinocchio as pin

    quat = pin.Quaternion(np.asarray(rotation, float)).normalized()
    return np.array([quat.w, quat.x, quat.y, quat.z])


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _ry(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


class Viewer:
    """A viser server showing ``robot`` (see the module docstring).

    Args:
        robot: a wbc robot (catalogue, ``load_panda()``, ``from_urdf(...)`` on any root).
        host: the address to bind (default ``"127.0.0.1"``: this machine only).
        port: the TCP port (default 8080).
        ee_frame: the frame whose path and triad are drawn (skipped if the robot has none).
        near_limit: a joint closer than this fraction of its range to a limit is coloured.
        verbose: print the URL.
        environment: light the scene with viser's environment map (image-based lighting);
            ``False``: plain lights instead — the page's first picture is ready in half the
            time in software WebGL (headless tests, report strips).

    Raises:
        VizUnavailableError: viser is not installed (``pip install ".[viz]"``).
        PortInUseError: ``host:port`` is taken.
    """

    def __init__(self, robot, host: str = "127.0.0.1", port: int = 8080, *,
                 ee_frame: str = "ee", near_limit: float = 0.05, verbose: bool = True,
                 environment: bool = True) -> None:
        viser = require_viser()
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port < 65536:
            raise WbcError(f"port must be an integer in [0, 65535], got {port!r}")
        if port:
            _check_port(host, port)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        if port and self.server.get_port() != port:  # lost a race for the port
            self.server.stop()
            raise PortInUseError(f"cannot serve on {host}:{port}: in use")
        self.host, self.port = host, self.server.get_port()
        self.near_limit = float(near_limit)
        self._ee_frame = ee_frame
        self._lock = threading.RLock()
        self._replay_gui: list = []
        self._playing = False
        self._player: threading.Thread | None = None
        self._closed = False
        self.server.scene.set_up_direction("+z")
        if not environment:
            self.server.scene.configure_environment_map(None)
            self.server.scene.add_light_hemisphere("/light", intensity=1.2)
        self._targets: dict[str, object] = {}
        self.robot: Any = None
        self.set_robot(robot)
        if verbose:
            print(f"wbc viewer: {self.url}  (Ctrl-C to stop)", flush=True)

    # ------------------------------------------------------------------ the robot
    @property
    def url(self) -> str:
        """The page's address."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    def set_robot(self, robot) -> None:
        """Draw ``robot`` instead of the current one (the overlays and paths are cleared)."""
        import pinocchio as pin

        with self._lock:
            scene = self.server.scene
            if self.robot is not None:
                scene.remove_by_name("/robot")
                scene.remove_by_name("/overlays")
                self._targets = {}
            self.robot = robot
            self.model = robot.model
            self.data = robot.model.createData()
            self._pin = pin
            parts = geometry.robot_parts(robot)
            self._wheels = geometry.wheels(robot)
            drawn_base = geometry._base_frame(robot) is not None and \
                type(robot.base).__name__ != "PlanarRoot"
            floor = geometry.deck_span(robot)[0] if drawn_base else 0.0
            self.floor_z = floor
            self._last_q: np.ndarray | None = None
            self._grid = scene.add_grid("/grid", width=6.0, height=6.0,
                                        position=(0.0, 0.0, floor - 1e-3), cell_size=0.25)
            self._aim_camera(robot, floor)
            self._frame_nodes: dict[int, object] = {}
            self._parts_of_joint: dict[int, list] = {}
            for part in parts:
                if part.frame not in self._frame_nodes:
                    self._frame_nodes[part.frame] = scene.add_frame(
                        f"/robot/f{part.frame}", show_axes=False)
                handle = scene.add_mesh_simple(
                    f"/robot/f{part.frame}/{part.name}", part.vertices, part.faces,
                    color=part.color, position=part.placement[:3, 3],
                    wxyz=_wxyz(part.placement[:3, :3]))
                self._parts_of_joint.setdefault(part.joint, []).append((handle, part.color))
            self._base_fid = geometry._base_frame(robot)
            self._wheel_nodes = []
            self._spin = np.zeros(len(self._wheels))
            if self._wheels and self._base_fid is not None:
                if self._base_fid not in self._frame_nodes:
                    self._frame_nodes[self._base_fid] = scene.add_frame(
                        f"/robot/f{self._base_fid}", show_axes=False)
                for k, wheel in enumerate(self._wheels):
                    mount = scene.add_frame(f"/robot/f{self._base_fid}/wheel{k}",
                                            show_axes=False)
                    spin = scene.add_frame(f"/robot/f{self._base_fid}/wheel{k}/spin",
                                           show_axes=False)
                    scene.add_mesh_simple(f"/robot/f{self._base_fid}/wheel{k}/spin/tyre",
                                          wheel.vertices, wheel.faces,
                                          color=geometry.WHEEL_COLOUR)
                    if len(wheel.rollers):
                        scene.add_mesh_simple(
                            f"/robot/f{self._base_fid}/wheel{k}/spin/rollers", wheel.rollers,
                            wheel.roller_faces, color=geometry.ROLLER_COLOUR)
                    self._wheel_nodes.append((mount, spin))
            self._limits = self._joint_limits()
            self._near: set[int] = set()
            has_ee = hasattr(robot, "has_frame") and robot.has_frame(self._ee_frame)
            self._ee_fid = robot.frame_id(self._ee_frame) if has_ee else None
            self._overlay_frames: dict[int, object] = {}
            if self._ee_fid is not None:
                self.add_frame(self._ee_frame)
            self._base_path: list[np.ndarray] = []
            self._ee_path: list[np.ndarray] = []
            self.q = np.asarray(robot.neutral(), float).copy()
            self.show(self.q)

    def _aim_camera(self, robot, floor: float) -> None:
        """Point the page's camera at the robot at home (:meth:`frame_points`)."""
        import pinocchio as pin

        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, np.asarray(robot.neutral(), float))
        points = np.array([data.oMf[i].translation for i in range(len(robot.model.frames))])
        points = np.vstack([points, points.min(axis=0) * [1, 1, 0] + [0, 0, floor]])
        self.frame_points(points)

    def frame_points(self, points, beside_panel: bool = True) -> None:
        """Aim the camera (of the pages open now and of those opened later) at ``points``
        (``(n, 3)`` [m]) from the front-right, above, at a distance that fits them; the
        view is shifted so that they sit left of the control panel (``beside_panel``)."""
        points = np.asarray(points, float).reshape(-1, 3)
        low, high = points.min(axis=0), points.max(axis=0)
        centre = (low + high) / 2
        size = max(float(np.max(high - low)), 0.8)
        offset = size * np.array([0.45, -0.95, 0.65])
        forward = -offset / np.linalg.norm(offset)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        # the panel covers the page's right side
        look_at = centre + (0.22 * size * right if beside_panel else 0.0)
        grid = getattr(self, "_grid", None)
        if grid is not None:  # under what is shown, wherever it is
            grid.position = (round(float(centre[0])), round(float(centre[1])),
                             float(grid.position[2]))
        cameras = [self.server.initial_camera] + [c.camera for c in
                                                  self.server.get_clients().values()]
        for camera in cameras:  # a client's camera keeps its view direction when moved:
            camera.up = (0.0, 0.0, 1.0)  # position first, then what it looks at
            camera.position = tuple(look_at + offset)
            camera.look_at = tuple(look_at)

    def _joint_limits(self) -> list[tuple[int, int, float, float]]:
        """``(joint, q index, lower, upper)`` of every 1-DoF body joint with finite limits."""
        out = []
        model = self.model
        lower, upper = model.lowerPositionLimit, model.upperPositionLimit
        limits = getattr(self.robot, "limits", None)
        if limits is not None:
            lower, upper = np.asarray(limits.q_lower), np.asarray(limits.q_upper)
        for j in range(geometry._first_body_joint(self.robot), model.njoints):
            if model.joints[j].nq != 1:
                continue
            i = model.joints[j].idx_q
            lo, hi = float(lower[i]), float(upper[i])
            if math.isfinite(lo) and math.isfinite(hi) and hi > lo:
                out.append((j, i, lo, hi))
        return out

    def add_frame(self, frame: str, length: float = 0.12):
        """Draw the triad of the robot's frame ``frame`` (updated by :meth:`show`)."""
        fid = self.robot.frame_id(frame)
        handle = self.server.scene.add_frame(f"/overlays/frames/{fid}", axes_length=length,
                                             axes_radius=length / 25)
        self._overlay_frames[fid] = handle
        if self._last_q is not None:
            self.show(self._last_q)
        return handle

    def set_target(self, target, name: str = "target") -> None:
        """Draw a target triad at ``target``: a ``(4, 4)`` pose or a position ``(3,)`` [m];
        ``None`` removes it."""
        scene = self.server.scene
        if target is None:
            if name in self._targets:
                self._targets.pop(name).remove()  # type: ignore[attr-defined]
            return
        target = np.asarray(target, float)
        if target.shape == (3,):
            pose = np.eye(4)
            pose[:3, 3] = target
        elif target.shape == (4, 4):
            pose = target
        else:
            raise ShapeError(f"a target is a (4, 4) pose or a (3,) position, got {target.shape}")
        if name not in self._targets:
            self._targets[name] = scene.add_frame(f"/overlays/{name}", axes_length=0.1,
                                                  axes_radius=0.005,
                                                  origin_color=TARGET_COLOUR)
        handle = self._targets[name]
        handle.position = pose[:3, 3]  # type: ignore[attr-defined]
        handle.wxyz = _wxyz(pose[:3, :3])  # type: ignore[attr-defined]

    def clear_paths(self) -> None:
        """Forget the base and end-effector paths drawn so far."""
        self._base_path.clear()
        self._ee_path.clear()
        for name in ("base_path", "ee_path"):
            self.server.scene.remove_by_name(f"/overlays/{name}")

    def show(self, q, paths: bool = True) -> None:
        """Put the robot at configuration ``q`` (``(robot.nq,)``); with ``paths``, extend the
        base and end-effector paths. Wheels roll by the base's motion since the last call."""
        q = np.asarray(q, dtype=float).reshape(-1) if np.ndim(q) else np.asarray(q)
        if q.shape != (self.model.nq,):
            raise ShapeError(f"q must have shape ({self.model.nq},), got {np.shape(q)}")
        if not np.isfinite(q).all():
            raise WbcError("q has NaN or inf entries")
        pin = self._pin
        with self._lock:
            pin.framesForwardKinematics(self.model, self.data, q)
            with self.server.atomic():
                for fid, node in self._frame_nodes.items():
                    M = self.data.oMf[fid]
                    node.position = M.translation  # type: ignore[attr-defined]
                    node.wxyz = _wxyz(M.rotation)  # type: ignore[attr-defined]
                for fid, node in self._overlay_frames.items():
                    M = self.data.oMf[fid]
                    node.position = M.translation  # type: ignore[attr-defined]
                    node.wxyz = _wxyz(M.rotation)  # type: ignore[attr-defined]
                self._move_wheels(q)
                self._colour_limits(q)
                if paths:
                    self._extend_paths()
            self._last_q = q.copy()
            self.q = q.copy()

    def _move_wheels(self, q: np.ndarray) -> None:
        if not self._wheels:
            return
        previous = self._last_q if self._last_q is not None else q
        # the base's displacement in its own frame: each wheel rolls by its contact point's
        # displacement along its heading (and a steerable wheel turns to it)
        theta0 = previous[2]
        c, s = math.cos(theta0), math.sin(theta0)
        dx, dy = q[0] - previous[0], q[1] - previous[1]
        d = np.array([c * dx + s * dy, -s * dx + c * dy])
        dtheta = math.remainder(q[2] - theta0, 2 * math.pi)
        for k, (wheel, (mount, spin)) in enumerate(zip(self._wheels, self._wheel_nodes,
                                                      strict=True)):
            point = wheel.hip
            motion = d + dtheta * np.array([-point[1], point[0]])
            if wheel.steerable and np.linalg.norm(motion) > 1e-6:
                wheel.heading = math.atan2(motion[1], motion[0])
            heading = np.array([math.cos(wheel.heading), math.sin(wheel.heading)])
            self._spin[k] += float(motion @ heading) / wheel.radius
            centre = wheel.hip - wheel.offset * heading
            mount.position = (centre[0], centre[1], wheel.z)  # type: ignore[attr-defined]
            mount.wxyz = _wxyz(_rz(wheel.heading))  # type: ignore[attr-defined]
            spin.wxyz = _wxyz(_ry(self._spin[k]))  # type: ignore[attr-defined]

    def _colour_limits(self, q: np.ndarray) -> None:
        near = {j for j, i, lo, hi in self._limits
                if min(q[i] - lo, hi - q[i]) < self.near_limit * (hi - lo)}
        for j in near ^ self._near:
            for handle, colour in self._parts_of_joint.get(j, []):
                handle.color = NEAR_LIMIT_COLOUR if j in near else colour
        self._near = near

    @property
    def joints_near_limits(self) -> list[str]:
        """Names of the joints coloured as near a limit at the last :meth:`show`."""
        return [self.model.names[j] for j in sorted(self._near)]

    def _extend_paths(self) -> None:
        data = self.data
        if self._base_fid is not None:
            p = data.oMf[self._base_fid].translation.copy()
            p[2] = self.floor_z + 2e-3
            if self._append(self._base_path, p):
                self._draw_path("base_path", self._base_path, BASE_PATH_COLOUR)
        if self._ee_fid is not None:
            if self._append(self._ee_path, data.oMf[self._ee_fid].translation.copy()):
                self._draw_path("ee_path", self._ee_path, EE_PATH_COLOUR)

    @staticmethod
    def _append(path: list, point: np.ndarray) -> bool:
        if path and np.linalg.norm(path[-1] - point) < 5e-3:
            return False  # a point every 5 mm is enough for a picture
        path.append(point)
        del path[:-PATH_POINTS]
        return len(path) > 1

    def _draw_path(self, name: str, points, colour, colours=None) -> None:
        points = np.asarray(points, np.float32)
        if len(points) < 2:
            return
        segments = np.stack([points[:-1], points[1:]], axis=1)
        self.server.scene.add_line_segments(
            f"/overlays/{name}", segments,
            colour if colours is None else np.repeat(colours[:, None, :], 2, axis=1),
            thickness=4.0, thickness_units="screen")

    # ------------------------------------------------------------------ replays
    def replay(self, runs, name: str | None = None, target=None) -> None:
        """Replay recorded runs: a :class:`wbc.sim.Run`, a :class:`~wbc.viz.record.Recording`,
        or ``name -> either`` (a dropdown switches between them; a recording of another
        catalogue robot loads that robot). ``target``: the target trace of a single ``Run``
        (``(N, 3)`` positions or ``(N, 4, 4)`` poses).

        Adds a time slider, play/pause, a speed choice and the tick's status; draws the target
        and end-effector traces (the latter coloured by status).

        Raises:
            UnknownNameError: ``name`` is not one of the runs.
        """
        if not isinstance(runs, Mapping):
            runs = {"run": runs}
        recordings = {k: (r if isinstance(r, Recording) else
                          Recording.from_run(r, target if len(runs) == 1 else None,
                                             robot=getattr(self.robot, "name", None)))
                      for k, r in runs.items()}
        if not recordings:
            raise WbcError("replay needs at least one run")
        if name is None:
            name = next(iter(recordings))
        if name not in recordings:
            raise UnknownNameError(f"unknown run {name!r}; runs: {sorted(recordings)}")
        self.recordings = recordings
        gui = self.server.gui
        for handle in self._replay_gui:
            handle.remove()
        self._replay_gui = []
        folder = gui.add_folder("Replay")
        self._replay_gui.append(folder)
        with folder:
            self._run_choice = gui.add_dropdown("run", list(recordings), initial_value=name)
            self._slider = gui.add_slider("tick", 0, 1, 1, 0)
            self._play = gui.add_button("play / pause")
            self._speed = gui.add_dropdown("speed", SPEEDS, initial_value="1")
            self._status = gui.add_markdown("")
        self._run_choice.on_update(lambda _: self._select(self._run_choice.value))
        self._slider.on_update(lambda _: self._frame(int(self._slider.value)))
        self._play.on_click(lambda _: self.play(not self._playing))
        self._select(name)

    def _select(self, name: str) -> None:
        """Show run ``name`` (load its robot if it is another catalogue robot's)."""
        recording = self.recordings[name]
        with self._lock:
            if recording.robot and recording.robot != getattr(self.robot, "name", None):
                import wbc.robots

                self.set_robot(wbc.robots.load(recording.robot))
            if recording.q.shape[1] != self.model.nq:
                raise ShapeError(f"run {name!r} has configurations of size "
                                 f"{recording.q.shape[1]}, the robot {self.model.nq}")
            self.current = name
            self.clear_paths()
            ee = recording.ee
            if ee is None and self._ee_fid is not None:
                ee = np.array([self._position(q, self._ee_fid) for q in recording.q])
            self._trace_ee = ee
            if ee is not None:
                colours = np.array([STATUS_COLOURS[int(c)] for c in recording.status[1:]],
                                   np.uint8)
                self._draw_path("replay_ee", ee, EE_PATH_COLOUR, colours)
            if recording.target is not None:
                self._draw_path("replay_target", recording.target, TARGET_COLOUR)
            else:
                self.server.scene.remove_by_name("/overlays/replay_target")
            if self._base_fid is not None:
                base = np.column_stack([recording.q[:, :2],
                                        np.full(len(recording), self.floor_z + 2e-3)])
                self._draw_path("replay_base", base, BASE_PATH_COLOUR)
            points = [recording.q[:, :2] if self._base_fid is not None else np.zeros((1, 2))]
            seen = np.vstack([np.column_stack([points[0], np.full(len(points[0]),
                                                                  self.floor_z)])] +
                             [p for p in (ee, recording.target) if p is not None])
            self.frame_points(seen)
            self._slider.max = max(1, len(recording) - 1)
            self._last_q = None  # the wheels start afresh
            if self._slider.value != 0:
                self._slider.value = 0  # calls _frame(0)
            else:
                self._frame(0)

    def _position(self, q: np.ndarray, fid: int) -> np.ndarray:
        self._pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[fid].translation.copy()

    def _frame(self, k: int) -> None:
        """Show tick ``k`` of the current run."""
        recording = self.recordings[self.current]
        k = int(np.clip(k, 0, len(recording) - 1))
        self.show(recording.q[k], paths=False)
        if recording.target is not None:
            self.set_target(recording.target[k])
        code = int(recording.status[k])
        word = STATUS_CODES[code]
        self._status.content = (f"**{self.current}**  \nt = {recording.t[k]:.2f} s · tick "
                                f"{k + 1}/{len(recording)}  \nstatus: **{word}** · "
                                f"{recording.failures} of {len(recording)} frames not solved")
        self.frame = k

    def play(self, playing: bool = True) -> None:
        """Start (or pause) the replay at the chosen speed."""
        self._playing = bool(playing)
        if self._playing and (self._player is None or not self._player.is_alive()):
            self._player = threading.Thread(target=self._play_loop, daemon=True)
            self._player.start()

    def _play_loop(self) -> None:
        clock = time.perf_counter()
        while self._playing and not self._closed:
            time.sleep(1 / 30)
            now = time.perf_counter()
            recording = self.recordings[self.current]
            t = recording.t[int(self._slider.value)] + float(self._speed.value) * (now - clock)
            clock = now
            k = int(np.searchsorted(recording.t, t, side="right") - 1)
            if k >= len(recording) - 1:
                k = 0 if t > recording.t[-1] + 0.5 else len(recording) - 1
            self._slider.value = k

    # ------------------------------------------------------------------ life
    def sleep(self, seconds: float) -> None:
        """Serve for ``seconds`` [s] (the page stays live meanwhile)."""
        time.sleep(max(0.0, float(seconds)))

    def close(self) -> None:
        """Stop the server (idempotent)."""
        if not self._closed:
            self._closed = True
            self._playing = False
            self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
