"""`wbc.viz`: see the robot — a 3-D viewer in the browser, study replays and a live playground.

Built on `viser <https://viser.studio>`_ (the optional extra ``pip install ".[viz]"``; its web
client ships in the wheel, so it works offline). Layer 3, beside :mod:`wbc.sim`: it imports the
layers below (the core, :mod:`wbc.robots`, and :mod:`wbc.tasks` / :mod:`wbc.solvers` for the
playground's stack) and :mod:`wbc.sim`, never a study.

::

    import wbc.robots
    from wbc.viz import Viewer

    robot = wbc.robots.load("mecanum_gen3")
    viewer = Viewer(robot)                # http://127.0.0.1:8080 (printed); 127.0.0.1 by default
    viewer.show(robot.neutral())          # the robot at a configuration
    viewer.replay(run)                    # a wbc.sim.Run: time slider, play/pause, speed, status

Modules:

* :mod:`wbc.viz.geometry` — what is drawn: the model's meshes where it has them
  (example-robot-data's visual geometry), otherwise links drawn from the kinematic model
  (capsules between joint frames), the base's deck and wheels (rolling; steering on a
  steerable base; rollers hinted on omni and mecanum wheels). Needs no viser.
* :mod:`wbc.viz.record` — :class:`Recording`, the compact per-tick record a replay needs
  (``t``, ``q``, status, target and end-effector traces, float32) and its ``.npz`` files, which
  the paper studies write beside their JSON. Needs no viser.
* :mod:`wbc.viz.viewer` — :class:`Viewer` (viser server, scene, overlays, replays).
* :mod:`wbc.viz.strip` / :mod:`wbc.viz.strip_offline` — the robot at a few instants of a
  recorded run, through Chromium or drawn offline with matplotlib (``wbc reproduce``'s strips).
* :mod:`wbc.viz.playground` — :class:`Playground`: the README's frame + posture + limits stack
  in closed loop on :mod:`wbc.sim` at its control rate, a gizmo on the target, the backend and
  the priority mode switchable live (``wbc play ROBOT``).

``Viewer`` and ``Playground`` are imported on first access, so ``wbc.viz.record`` and
``wbc.viz.geometry`` work without viser; without it, the first access raises
:class:`VizUnavailableError` with the install hint.
"""

from __future__ import annotations

import importlib

from wbc.errors import WbcError

__all__ = ["Playground", "Recording", "Viewer", "VizUnavailableError", "load_recordings",
           "require_viser", "save_recordings"]

#: the install hint of every message about the missing extra
INSTALL_HINT = 'pip install "wbc[viz]" (from a clone: pip install ".[viz]")'


class VizUnavailableError(WbcError):
    """viser, the viewer's optional dependency, is not installed."""


def require_viser():
    """The ``viser`` module; raises :class:`VizUnavailableError` (one line, with the install
    hint) when the ``[viz]`` extra is not installed."""
    try:
        return importlib.import_module("viser")
    except ImportError as err:
        raise VizUnavailableError(f"the viewer needs viser ({err}); install the extra: "
                                  f"{INSTALL_HINT}") from None


_LAZY = {"Viewer": "wbc.viz.viewer", "Playground": "wbc.viz.playground",
         "Recording": "wbc.viz.record", "load_recordings": "wbc.viz.record",
         "save_recordings": "wbc.viz.record"}


def __getattr__(name: str):
    if name in _LAZY:
        if name in ("Viewer", "Playground"):
            require_viser()
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'wbc.viz' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
