"""The report's robot strips without a browser (:mod:`wbc.viz.strip_offline`): every catalogue
robot is drawn, moves between panels, the traces carry the status colours, the kinematic tree's
segments are the model's link lengths, it works without viser, bad input raises the library's
errors, and ``wbc reproduce`` falls back to it where Chromium is unavailable or fails."""

from __future__ import annotations

import sys

import matplotlib.image
import numpy as np
import pytest

import wbc.robots
import wbc.viz.browser
import wbc.viz.strip
from wbc.errors import ShapeError, WbcError
from wbc.experiments import reproduce
from wbc.viz.record import Recording, save_recordings
from wbc.viz.strip_offline import (
    LINK_COLOUR,
    PANEL_PX,
    STATUS_COLOURS,
    _Drawing,
    render_strip_offline,
)

BACKGROUND = np.array([255, 255, 255])


def _recording(robot, status=None, ticks: int = 20) -> Recording:
    """The base drives 0.8 m forward while turning, the arm's joints swing, the target runs
    ahead of it (seeded)."""
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 2.0, ticks)
    q = np.tile(np.asarray(robot.neutral(), float), (ticks, 1))
    q[:, 0] = 0.4 * t
    q[:, 2] = 0.25 * t
    q[:, 3:] += 0.5 * np.outer(np.sin(1.5 * t), rng.uniform(-1, 1, q.shape[1] - 3))
    target = np.column_stack([0.4 * t + 0.6, 0.2 * np.sin(t), np.full(ticks, 0.9)])
    status = np.zeros(ticks) if status is None else status
    return Recording(t, q, status, target=target, robot=robot.name)


def _panels(path, count: int) -> list[np.ndarray]:
    image = matplotlib.image.imread(path)[..., :3]
    image = (255 * image).round().astype(int) if image.dtype != np.uint8 else image.astype(int)
    return np.array_split(image, count, axis=1)


def _near(panel: np.ndarray, colour, tolerance: int = 30) -> int:
    """Pixels of ``panel`` within ``tolerance`` of ``colour`` in every channel."""
    return int((np.abs(panel - np.asarray(colour)) <= tolerance).all(axis=-1).sum())


@pytest.mark.parametrize("name", wbc.robots.names())
def test_every_catalogue_robot_is_drawn_and_moves(name, tmp_path):
    robot = wbc.robots.load(name)
    path = render_strip_offline(_recording(robot), tmp_path / "strip.png", instants=2)
    first, last = _panels(path, 2)
    assert first.shape[0] == PANEL_PX and first.shape[1] + last.shape[1] == 2 * PANEL_PX
    for panel in (first, last):
        drawn = (np.abs(panel - BACKGROUND) > 40).any(axis=-1).mean()
        assert 0.01 < drawn < 0.5  # something is drawn, not a flood of colour
        assert _near(panel, LINK_COLOUR) > 200  # the links, thick
    # the base drove 0.8 m and the arm swung: the robot's pixels are elsewhere at the end
    width = min(first.shape[1], last.shape[1])
    moved = (np.abs(first[:, :width] - last[:, :width]) > 40).any(axis=-1).sum()
    assert moved > 1500


def test_the_end_effector_trace_is_coloured_by_status(tmp_path):
    robot = wbc.robots.load("mecanum_gen3")
    solved = render_strip_offline(_recording(robot), tmp_path / "ok.png", instants=1)
    failed = render_strip_offline(_recording(robot, status=np.full(20, 2)),
                                  tmp_path / "failed.png", instants=1)
    red = STATUS_COLOURS[2]
    assert _near(_panels(solved, 1)[0], red, 25) == 0
    assert _near(_panels(failed, 1)[0], red, 25) > 50
    assert _near(_panels(solved, 1)[0], STATUS_COLOURS[0], 25) > 50


@pytest.mark.parametrize("name", ["omni4_arm6", "panda"])
def test_the_links_are_the_models_segments(name):
    """Segment k joins consecutive joint origins: its length is the child joint's placement
    offset, whatever q (forward kinematics on robot.model)."""
    robot = wbc.robots.load_panda() if name == "panda" else wbc.robots.load(name)
    drawing = _Drawing(robot)
    rng = np.random.default_rng(3)
    model = robot.model
    arm = 0 if name == "panda" else 3  # after the planar base's (x, y, θ)
    for _ in range(5):
        q = np.asarray(robot.neutral(), float)
        q[arm:] += rng.uniform(-1, 1, len(q) - arm)
        drawing.place(q)
        segments = drawing.segments()
        lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
        # the joints after the first: parent to child, the placement's translation
        inner = [np.linalg.norm(model.jointPlacements[j].translation)
                 for j in range(drawing.first + 1, model.njoints)]
        np.testing.assert_allclose(lengths[1:1 + len(inner)], inner, atol=1e-12)
        # the last segment ends at the end effector
        ee = drawing.data.oMf[robot.frame_id("ee")].translation
        np.testing.assert_allclose(segments[-1, 1], ee, atol=1e-12)


def test_it_needs_no_viser_nor_a_browser(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "viser", None)
    monkeypatch.setitem(sys.modules, "playwright", None)
    with pytest.raises(ImportError):
        import viser  # noqa: F401
    robot = wbc.robots.load("tiago_panda")
    path = render_strip_offline(_recording(robot, ticks=8), tmp_path / "s.png", instants=3,
                                title="tiago_panda")
    assert path.exists() and all(_near(p, LINK_COLOUR) > 100
                                 for p in _panels(path, 3))


def test_bad_input_raises_the_librarys_errors(tmp_path):
    robot = wbc.robots.load("omni4_arm6")
    recording = _recording(robot, ticks=5)
    with pytest.raises(WbcError, match="instants"):
        render_strip_offline(recording, tmp_path / "a.png", instants=0)
    nameless = Recording(recording.t, recording.q, recording.status)
    with pytest.raises(WbcError, match="names no robot"):
        render_strip_offline(nameless, tmp_path / "b.png")
    other = Recording(recording.t, recording.q[:, :-1], recording.status, robot=robot.name)
    with pytest.raises(ShapeError, match="size"):
        render_strip_offline(other, tmp_path / "c.png")
    assert not any(tmp_path.iterdir())


def _study_output(tmp_path):
    """A reproduce folder where only petric recorded its main run."""
    robot = wbc.robots.load("tiago_panda")
    save_recordings(tmp_path / "petric" / "petric_replay.npz",
                    {reproduce.MAIN_RUNS["petric"]: _recording(robot, ticks=10)}, robot.name)
    return tmp_path


def test_reproduce_falls_back_when_there_is_no_chromium(tmp_path, monkeypatch):
    out = _study_output(tmp_path)
    calls = []
    monkeypatch.setattr(wbc.viz.browser, "browser_unavailable_reason",
                        lambda: "no Chromium found (test)")
    monkeypatch.setattr(wbc.viz.strip, "render_strips", lambda *a, **k: calls.append(a))
    line = reproduce.render_strips(out, quick=False)
    assert not calls  # Chromium was not tried
    assert line.startswith("Robot strips rendered for petric by matplotlib, offline (")
    assert "no Chromium found (test)" in line and "none for sorour" in line
    assert (out / "petric" / "petric_strip.png").exists()
    report = reproduce.write_report(out, [], quick=False, strips=line)
    assert line in report.read_text()


def test_reproduce_falls_back_without_viser_and_when_chromium_fails(tmp_path, monkeypatch):
    out = _study_output(tmp_path)
    monkeypatch.setitem(sys.modules, "viser", None)
    line = reproduce.render_strips(out, quick=False)
    assert "by matplotlib, offline (viser is not installed" in line
    (out / "petric" / "petric_strip.png").unlink()

    monkeypatch.setattr("wbc.viz.require_viser", lambda: None)
    monkeypatch.setattr(wbc.viz.browser, "browser_unavailable_reason", lambda: None)

    def broken(*args, **kwargs):
        raise RuntimeError("the page drew nothing")
    monkeypatch.setattr(wbc.viz.strip, "render_strips", broken)
    line = reproduce.render_strips(out, quick=False)
    assert "offline (Chromium failed: RuntimeError: the page drew nothing)" in line
    assert (out / "petric" / "petric_strip.png").exists()


def test_reproduce_never_raises(tmp_path, monkeypatch):
    """No study recorded anything, or the offline renderer itself fails: a line, no raise."""
    monkeypatch.setattr(wbc.viz.browser, "browser_unavailable_reason", lambda: "none (test)")
    assert reproduce.render_strips(tmp_path, quick=False).startswith("Robot strips: none (")
    out = _study_output(tmp_path)

    def broken(*args, **kwargs):
        raise MemoryError("out of memory")
    monkeypatch.setattr("wbc.viz.strip_offline.render_strip_offline", broken)
    line = reproduce.render_strips(out, quick=False)
    assert line.startswith("Robot strips: none (") and "MemoryError" in line
