"""The viewer in a real browser: headless Chromium opens the ``play`` and ``view`` pages,
waits for the scene and takes screenshots (kept in the test's temporary folder): the robot is
drawn, its pixels change when the gizmo's target is moved through the server's API and the
loop reacts, and ``view``'s slider, moved in the browser, moves the robot.

Skips (with the reason) where no Chromium or no playwright is found: ``.ci/run`` installs
Debian's ``chromium`` with apt-get first."""

from __future__ import annotations

import time

import numpy as np
import pytest

import wbc.robots

pytest.importorskip("viser", reason='the [viz] extra (pip install ".[viz]") is not installed')
from wbc.viz.browser import Browser, browser_unavailable_reason, robot_pixels  # noqa: E402

REASON = browser_unavailable_reason()
pytestmark = pytest.mark.skipif(REASON is not None, reason=f"no browser test: {REASON}")


@pytest.fixture(scope="module")
def browser():
    with Browser(width=720, height=480) as b:
        yield b


def _changed(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels that differ clearly between two screenshots."""
    return int((np.abs(a.astype(int) - b.astype(int)) > 40).any(axis=-1).sum())


def test_play_draws_the_robot_and_it_follows_the_gizmo(browser, tmp_path):
    from wbc.viz.playground import Playground

    robot = wbc.robots.load("mecanum_gen3")
    with Playground(robot, "daqp", port=0, verbose=False, environment=False) as play:
        page = browser.open(play.viewer.url)
        before = browser.screenshot(page, tmp_path / "play_before.png")
        drawn = robot_pixels(before).mean()
        assert 0.01 < drawn < 0.9, drawn  # not the empty background
        ee0 = robot.frame_pose(play.q, "ee")[:3, 3].copy()
        goal = play.target.copy()
        goal[:3, 3] += [0.35, 0.25, -0.15]
        play.set_target(goal)  # the server's API, as a drag of the gizmo ends
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            moved = np.linalg.norm(robot.frame_pose(play.q, "ee")[:3, 3] - ee0)
            if moved > 0.3:
                break
            time.sleep(0.1)
        assert moved > 0.3, moved  # the loop reacted
        page.wait_for_timeout(800)
        after = browser.screenshot(page, tmp_path / "play_after.png")
        assert _changed(before, after) > 500
        page.close()


def test_view_slider_moves_the_robot(browser, tmp_path):
    from wbc.experiments.viewing import load_robot  # noqa: F401  (the verb's loader)
    from wbc.sim import Simulation
    from wbc.viz.playground import readme_stack
    from wbc.viz.record import Recording
    from wbc.viz.viewer import Viewer

    robot = wbc.robots.load("mecanum_gen3")
    controller = wbc.Controller(robot, readme_stack(robot), backend="daqp", dt=0.02)
    target = robot.frame_pose(robot.neutral(), "ee").copy()
    target[:3, 3] += [0.6, 0.4, -0.1]
    run = Simulation(robot, controller, 0.02).run(seconds=3.0, references={"ee": target})
    with Viewer(robot, port=0, verbose=False, environment=False) as viewer:
        viewer.replay({"reach": Recording.from_run(run, robot=robot.name)})
        page = browser.open(viewer.url)
        first = browser.screenshot(page, tmp_path / "view_first.png")
        assert 0.01 < robot_pixels(first).mean() < 0.9
        slider = page.get_by_role("slider").first
        slider.focus()
        slider.press("End")  # the browser moves the slider to the last tick
        deadline = time.monotonic() + 10
        while viewer.frame != len(run.t) - 1 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert viewer.frame == len(run.t) - 1
        page.wait_for_timeout(800)
        last = browser.screenshot(page, tmp_path / "view_last.png")
        assert _changed(first, last) > 500
        page.close()


def test_a_report_strip_shows_the_run(browser, tmp_path):
    """The strip under each study's section of REPORT.md: the robot at a few instants."""
    import matplotlib.image

    from wbc.viz.record import Recording
    from wbc.viz.strip import render_strip

    robot = wbc.robots.load("mecanum_gen3")
    q = np.tile(robot.neutral(), (3, 1))
    q[:, 0] = [0.0, 0.5, 1.0]  # the base drives 1 m forward
    recording = Recording([0.0, 1.0, 2.0], q, [0, 0, 2], robot=robot.name)
    path = render_strip(recording, tmp_path / "strip.png", instants=3, browser=browser)
    image = matplotlib.image.imread(path)
    thirds = np.array_split(image[..., :3], 3, axis=1)
    assert all(robot_pixels((255 * t).astype(np.uint8)).mean() > 0.01 for t in thirds)
    assert np.abs(thirds[0][:, :thirds[2].shape[1]] - thirds[2][:, :thirds[0].shape[1]]
                  ).max() > 0.2  # the robot is elsewhere at the end
