"""`Playground`: the README's stack live in the browser — drag the target, watch the loop.

The stack is the README's (``FrameTask`` on ``"ee"`` + ``PostureTask`` + ``ConfigurationLimit``
+ ``VelocityLimit``), run in closed loop by :class:`wbc.sim.Simulation` at its control rate
(``dt``, 100 Hz by default; the loop sleeps to keep real time), a few ticks per
``Simulation.run`` call, each call continuing from the last one's final state. The page has:

* a transform gizmo on the end-effector target (the loop reads it every chunk of ticks);
* a dropdown to swap the QP backend live (each backend's controller is compiled on first use
  and kept), and a toggle between **strict priorities** (the frame task above the posture)
  and **one weighted level** (both in one level, the posture at weight 1e-2);
* live median / p95 tick time (``controller.step`` wall time, the last 500 ticks), the last
  solution's status, the failures so far and which limits are active (a joint within 1 % of
  its range of a position limit, a velocity at its bound).
"""

from __future__ import annotations

import collections
import threading
import time
import warnings

import numpy as np

import wbc
from wbc.errors import WbcError

from .viewer import Viewer, _wxyz

__all__ = ["MODES", "Playground", "readme_stack"]

#: the priority modes of the toggle
MODES = ("strict priorities", "one weighted level")
#: ticks per Simulation.run call (the gizmo is read between calls)
CHUNK = 5


def readme_stack(robot, mode: str = MODES[0]) -> wbc.Stack:
    """The README's frame + posture + limits stack over ``v``; ``mode``: one of :data:`MODES`
    (the posture one level below the frame task, or in the same level)."""
    from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

    if mode not in MODES:
        raise wbc.UnknownNameError(f"unknown mode {mode!r}; modes: {list(MODES)}")
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"),
              priority=1 if mode == MODES[0] else 0)
    stack.constrain(ConfigurationLimit(robot, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack


class Playground:
    """A live closed loop of the README's stack on ``robot`` (see the module docstring).

    Args:
        robot: a wbc robot with an ``"ee"`` frame.
        backend: the QP backend to start with.
        host, port: where to serve (:class:`~wbc.viz.viewer.Viewer`).
        dt: the control period [s].
        start: start the loop's thread now (else call :meth:`start`, or :meth:`step`).
        verbose, environment: as :class:`~wbc.viz.viewer.Viewer`'s.

    Raises:
        UnknownNameError: ``backend`` is not available, or the robot has no ``"ee"`` frame.
    """

    def __init__(self, robot, backend: str = "daqp", host: str = "127.0.0.1",
                 port: int = 8080, *, dt: float = 0.01, start: bool = True,
                 verbose: bool = True, environment: bool = True) -> None:
        from wbc.solvers import available_backends

        self.backends = list(available_backends())
        if backend not in self.backends:
            raise wbc.UnknownNameError(f"unknown or unavailable backend {backend!r}; "
                                       f"available: {self.backends}")
        if not robot.has_frame("ee"):
            raise wbc.UnknownNameError(f"robot {robot.name!r} has no 'ee' frame to drive")
        self.robot = robot
        self.dt = float(dt)
        self.backend, self.mode = backend, MODES[0]
        self._controllers: dict[tuple[str, str], object] = {}
        self._simulation = self._make(backend, self.mode)  # fail before serving
        self.viewer = Viewer(robot, host, port, verbose=verbose, environment=environment)
        self.q = np.asarray(robot.neutral(), float).copy()
        self.v = np.zeros(robot.nv)
        pose = robot.frame_pose(self.q, "ee")
        self.ticks = 0
        self.failures = 0
        self.status = ""
        self.active_limits: list[str] = []
        self.message = ""
        self._tick_s: collections.deque = collections.deque(maxlen=500)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        scene, gui = self.viewer.server.scene, self.viewer.server.gui
        # the camera takes in the robot and the room to drag the target around its hand
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        self.viewer.frame_points(np.vstack([
            [robot.frame_pose(self.q, i)[:3, 3] for i in range(len(robot.model.frames))],
            pose[:3, 3] + 0.4 * corners]))
        self.gizmo = scene.add_transform_controls("/target", scale=0.22,
                                                  position=pose[:3, 3].copy(),
                                                  wxyz=_wxyz(pose[:3, :3]))
        with gui.add_folder("Playground"):
            self._backend_gui = gui.add_dropdown("backend", self.backends, initial_value=backend)
            self._mode_gui = gui.add_dropdown("priorities", MODES, initial_value=self.mode)
            self._reset_gui = gui.add_button("reset")
            self._stats_gui = gui.add_markdown("")
        self._backend_gui.on_update(lambda _: self.set_backend(self._backend_gui.value))
        self._mode_gui.on_update(lambda _: self.set_mode(self._mode_gui.value))
        self._reset_gui.on_click(lambda _: self.reset())
        self._thread: threading.Thread | None = None
        if start:
            self.start()

    # ------------------------------------------------------------------ controls
    def _make(self, backend: str, mode: str):
        from wbc.sim import Simulation

        key = (backend, mode)
        if key not in self._controllers:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                controller = wbc.Controller(self.robot, readme_stack(self.robot, mode),
                                            backend=backend, dt=self.dt)
            self.message = str(caught[0].message).splitlines()[0] if caught else ""
            self._controllers[key] = controller
        return Simulation(self.robot, self._controllers[key], self.dt)

    def set_backend(self, backend: str) -> None:
        """Swap the QP backend (the loop continues from the same state)."""
        with self._lock:
            try:
                self._simulation = self._make(backend, self.mode)
                self.backend = backend
            except WbcError as err:
                self.message = f"{backend}: {err}"
        self._tick_s.clear()

    def set_mode(self, mode: str) -> None:
        """Switch between :data:`MODES`."""
        with self._lock:
            self._simulation = self._make(self.backend, mode)
            self.mode = mode
        self._tick_s.clear()

    def reset(self) -> None:
        """Back to the home configuration, the target on the end effector."""
        with self._lock:
            self.q = np.asarray(self.robot.neutral(), float).copy()
            self.v = np.zeros(self.robot.nv)
            pose = self.robot.frame_pose(self.q, "ee")
            self.gizmo.position = pose[:3, 3].copy()
            self.gizmo.wxyz = _wxyz(pose[:3, :3])
            self.viewer.clear_paths()

    @property
    def target(self) -> np.ndarray:
        """The gizmo's pose, ``(4, 4)`` (world)."""
        import pinocchio as pin

        w, x, y, z = (float(c) for c in self.gizmo.wxyz)
        pose = np.eye(4)
        pose[:3, :3] = pin.Quaternion(w, x, y, z).normalized().matrix()
        pose[:3, 3] = np.asarray(self.gizmo.position, float)
        return pose

    def set_target(self, pose) -> None:
        """Move the gizmo (as a user dragging it would) to ``pose``: ``(4, 4)`` or ``(3,)``."""
        pose = np.asarray(pose, float)
        if pose.shape == (3,):
            self.gizmo.position = pose.copy()
            return
        self.gizmo.position = pose[:3, 3].copy()
        self.gizmo.wxyz = _wxyz(pose[:3, :3])

    # ------------------------------------------------------------------ the loop
    def step(self, ticks: int = CHUNK) -> None:
        """Run ``ticks`` ticks of the closed loop towards the gizmo's pose and show the robot."""
        with self._lock:
            run = self._simulation.run(ticks=ticks, q0=self.q, v0=self.v,
                                       references={"ee": self.target})
            self.q, self.v = run.q_final.copy(), run.v_final.copy()
            self.ticks += ticks
            self.failures += run.failures
            self.status = run.status[-1]
            self._tick_s.extend(run.tick_s)
            self.active_limits = self._active(run)
        self.viewer.show(self.q)
        self._stats_gui.content = self.stats_markdown()

    def _active(self, run) -> list[str]:
        limits = self.robot.limits
        names = self.robot.velocity_names
        q_names = self.robot.configuration_names
        q = run.q_final
        span = limits.q_upper - limits.q_lower
        finite = np.isfinite(span)
        margin = np.where(finite, 0.01 * np.where(finite, span, 0), 0)
        near = finite & ((q - limits.q_lower < margin) | (limits.q_upper - q < margin))
        out = [f"position: {q_names[i]}" for i in np.flatnonzero(near)]
        command = run.command[-1][:self.robot.nv]
        at = (np.abs(command - limits.v_upper) < 1e-6) | (np.abs(command - limits.v_lower)
                                                          < 1e-6)
        out += [f"velocity: {names[i]}" for i in np.flatnonzero(at)]
        return out

    def stats_markdown(self) -> str:
        """The page's live numbers, as markdown."""
        ticks = np.asarray(self._tick_s, float)
        timing = (f"tick median {1e6 * np.median(ticks):.0f} µs · p95 "
                  f"{1e6 * np.percentile(ticks, 95):.0f} µs" if ticks.size else "tick —")
        limits = ", ".join(self.active_limits) or "none"
        lines = [f"**{self.backend}**, {self.mode}", timing,
                 f"status: **{self.status or '—'}** · {self.failures} failed of {self.ticks} "
                 "ticks", f"active limits: {limits}"]
        if self.message:
            lines.append(f"_{self.message[:160]}_")
        return "  \n".join(lines)

    def _loop(self) -> None:
        period = CHUNK * self.dt
        next_time = time.perf_counter()
        while not self._stop.is_set():
            try:
                self.step(CHUNK)
            except WbcError as err:  # shown on the page; the loop holds the robot
                self.message = str(err).splitlines()[0]
                self._stats_gui.content = self.stats_markdown()
            next_time += period
            delay = next_time - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:  # behind (a compilation, a slow backend): do not try to catch up
                next_time = time.perf_counter()

    def start(self) -> None:
        """Run the loop in a background thread at the control rate."""
        if self._thread is None or not self._thread.is_alive():
            self._stop.clear()
            self._thread = threading.Thread(target=self._loop, daemon=True)
            self._thread.start()

    def close(self) -> None:
        """Stop the loop and the server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.viewer.close()

    def __enter__(self) -> Playground:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
