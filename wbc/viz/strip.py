"""A strip of pictures of a recorded run: the robot at a few instants, side by side.

:func:`render_strip` draws the run's target and end-effector traces once, puts the robot at
``instants`` evenly spaced ticks, photographs each through headless Chromium
(:mod:`wbc.viz.browser`, the control panel hidden, the camera fixed on the whole run) and
writes one PNG with the time of each picture above it. ``wbc reproduce`` puts one under each
study's section of ``REPORT.md``. Where there is no Chromium or no viser,
:func:`wbc.viz.strip_offline.render_strip_offline` draws the same strip with matplotlib alone.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from wbc.errors import WbcError

from .record import Recording

__all__ = ["render_strip", "render_strips"]


def render_strip(recording: Recording, path: str | os.PathLike[str], instants: int = 4,
                 browser=None, size: tuple[int, int] = (440, 360), title: str = "") -> Path:
    """Write the strip of ``recording`` (of the catalogue robot ``recording.robot``) to the
    PNG ``path`` and return it. ``browser``: a :class:`wbc.viz.browser.Browser` to reuse
    (default: one is started and closed).

    Raises:
        WbcError: the recording names no robot, or ``instants`` < 1.
        BrowserUnavailableError: no Chromium or no playwright here.
    """
    return render_strips([(recording, path, title)], instants, browser, size)[0]


def render_strips(jobs, instants: int = 4, browser=None,
                  size: tuple[int, int] = (440, 360)) -> list[Path]:
    """:func:`render_strip` for several ``(recording, path, title)``, through one viewer and
    one page (the page's first pictures cost seconds in software WebGL; later ones 0.1 s)."""
    import wbc.robots

    from .browser import Browser
    from .viewer import Viewer

    jobs = list(jobs)
    for recording, _, _ in jobs:
        if not recording.robot:
            raise WbcError("render_strip: the recording names no robot")
    if instants < 1:
        raise WbcError(f"render_strip: instants must be >= 1, got {instants}")
    if not jobs:
        return []
    own = browser is None
    browser = browser or Browser(*size)
    paths = []
    try:
        with Viewer(wbc.robots.load(jobs[0][0].robot), port=0, verbose=False,
                    environment=False) as viewer:
            page = browser.open(viewer.url)
            browser.hide_panel(page)
            for recording, path, title in jobs:
                if recording.robot != viewer.robot.name:
                    viewer.set_robot(wbc.robots.load(recording.robot))
                    page.wait_for_timeout(2500)  # the new meshes reach the page and draw
                images, ticks = _pictures(viewer, page, recording, instants)
                paths.append(_save(images, ticks, recording, Path(path), title))
            page.close()
    finally:
        if own:
            browser.close()
    return paths


def _pictures(viewer, page, recording: Recording, instants: int):
    from .browser import image_of
    from .viewer import EE_PATH_COLOUR, STATUS_COLOURS, TARGET_COLOUR

    ticks = np.unique(np.linspace(0, len(recording) - 1, instants).round().astype(int))
    viewer.clear_paths()
    ee = recording.ee
    if ee is None and viewer._ee_fid is not None:
        ee = np.array([viewer._position(q, viewer._ee_fid) for q in recording.q])
    seen = [np.column_stack([recording.q[:, :2], np.full(len(recording), viewer.floor_z)])
            if viewer._base_fid is not None else np.zeros((1, 3))]
    seen += [p for p in (ee, recording.target) if p is not None]
    viewer.frame_points(np.vstack(seen), beside_panel=False)
    if ee is not None:
        colours = np.array([STATUS_COLOURS[int(c)] for c in recording.status[1:]], np.uint8)
        viewer._draw_path("replay_ee", ee, EE_PATH_COLOUR, colours)
    if recording.target is not None:
        viewer._draw_path("replay_target", recording.target, TARGET_COLOUR)
    else:
        viewer.set_target(None)
    viewer._last_q = None
    images = []
    for k in ticks:
        viewer.show(recording.q[k], paths=False)
        if recording.target is not None:
            viewer.set_target(recording.target[k])
        page.wait_for_timeout(400)
        images.append(image_of(page))
    return images, ticks


def _save(images, ticks, recording: Recording, path: Path, title: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(images), figsize=(2.6 * len(images), 2.3), squeeze=False)
    for ax, image, k in zip(axes[0], images, ticks, strict=True):
        ax.imshow(image)
        ax.set_axis_off()
        ax.set_title(f"t = {recording.t[k]:.1f} s", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
