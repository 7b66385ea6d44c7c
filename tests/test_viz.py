"""`wbc.viz` without a browser: the scene of every kind of robot, show / replay updating it,
the compact replay records, the playground's loop, and the command line's errors (a busy port,
an unknown run, the missing extra: one line, exit 1 / 2; 127.0.0.1 by default)."""

from __future__ import annotations

import inspect
import math
import socket
import subprocess
import sys

import numpy as np
import pytest

import wbc.robots

pytest.importorskip("viser", reason='the [viz] extra (pip install ".[viz]") is not installed')

from wbc.experiments.viewing import play_main, view_main  # noqa: E402
from wbc.robots.resources import urdf_path  # noqa: E402
from wbc.viz.record import Recording, load_recordings, save_recordings  # noqa: E402
from wbc.viz.viewer import NEAR_LIMIT_COLOUR, PortInUseError, Viewer  # noqa: E402


@pytest.fixture(scope="module")
def viewer():
    robot = wbc.robots.load("mecanum_gen3")
    with Viewer(robot, port=0, verbose=False) as v:  # port 0: any free port
        yield v


def _robots():
    out = {name: wbc.robots.load(name) for name in wbc.robots.names()}
    out["panda"] = wbc.robots.load_panda()
    out["talos"] = wbc.robots.from_urdf(urdf_path("talos_data/robots/talos_reduced.urdf"),
                                        root="free_flyer")
    out["tiago"] = wbc.robots.from_urdf(urdf_path("tiago_description/robots/tiago.urdf"),
                                        root="planar")
    return out


#: name -> (meshes from the model's files, wheels drawn)
EXPECTED = {"mpo700_lwr4": (False, 4), "tiago_panda": (True, 2), "omni4_arm6": (True, 4),
            "mecanum_gen3": (False, 4), "panda": (True, 0), "talos": (True, 0),
            "tiago": (True, 0)}


def test_the_scene_of_every_kind_of_robot_follows_its_kinematics(viewer):
    """Catalogue robots, the fixed-base Panda, TALOS on a free flyer, Tiago on a planar root:
    meshes where the model has them, links drawn from the kinematics otherwise; each drawn
    frame sits at the robot's own frame pose at a random configuration."""
    rng = np.random.default_rng(0)
    for name, robot in _robots().items():
        viewer.set_robot(robot)
        names = [h.name for parts in viewer._parts_of_joint.values() for h, _ in parts]
        meshes, n_wheels = EXPECTED[name]
        assert any("/mesh" in n for n in names) == meshes, name
        assert any("/link" in n for n in names) == (not meshes), name
        assert len(viewer._wheels) == n_wheels, name
        q = robot.random_configuration(rng) if "rng" in inspect.signature(
            robot.random_configuration).parameters else robot.random_configuration()
        viewer.show(q)
        for fid, node in list(viewer._frame_nodes.items())[::3]:
            pose = robot.frame_pose(q, fid)
            np.testing.assert_allclose(node.position, pose[:3, 3], atol=1e-9, err_msg=name)


def test_wheels_roll_by_the_base_motion_and_steer(viewer):
    robot = wbc.robots.load("mecanum_gen3")
    viewer.set_robot(robot)
    q = robot.neutral()
    viewer.show(q)
    spin0 = viewer._spin.copy()
    q2 = q.copy()
    q2[0] += 0.1  # 10 cm forward: every wheel turns 0.1 / R
    viewer.show(q2)
    np.testing.assert_allclose(viewer._spin - spin0, 0.1 / robot.base.radius, rtol=1e-12)
    steerable = wbc.robots.load("mpo700_lwr4")
    viewer.set_robot(steerable)
    q = steerable.neutral()
    viewer.show(q)
    q2 = q.copy()
    q2[1] += 0.05  # sideways: the steerable wheels turn to +90°
    viewer.show(q2)
    assert all(abs(w.heading - math.pi / 2) < 1e-9 for w in viewer._wheels)


def test_a_joint_near_its_limit_is_coloured(viewer):
    robot = wbc.robots.load_panda()
    viewer.set_robot(robot)
    middle = (robot.limits.q_lower + robot.limits.q_upper) / 2
    q = middle.copy()
    viewer.show(q)
    assert viewer.joints_near_limits == []
    q[3] = robot.limits.q_upper[3] - 1e-3
    viewer.show(q)
    assert viewer.joints_near_limits == ["panda_joint4"]
    joint = robot.model.getJointId("panda_joint4")
    assert all(tuple(h.color) == NEAR_LIMIT_COLOUR for h, _ in viewer._parts_of_joint[joint])
    viewer.show(middle)
    assert all(tuple(h.color) == c for h, c in viewer._parts_of_joint[joint])


def test_overlays_target_and_paths(viewer):
    robot = wbc.robots.load("mecanum_gen3")
    viewer.set_robot(robot)
    T = robot.frame_pose(robot.neutral(), "ee").copy()
    viewer.set_target(T)
    np.testing.assert_allclose(viewer._targets["target"].position, T[:3, 3])
    for k in range(5):
        q = robot.neutral()
        q[0] = 0.05 * k
        viewer.show(q)
    assert len(viewer._base_path) == 5 and len(viewer._ee_path) == 5
    viewer.clear_paths()
    assert not viewer._base_path
    with pytest.raises(wbc.ShapeError):
        viewer.set_target(np.zeros(5))
    with pytest.raises(wbc.ShapeError):
        viewer.show(np.zeros(3))


def _short_run(robot, seconds=0.3):
    from wbc.sim import Simulation
    from wbc.viz.playground import readme_stack

    controller = wbc.Controller(robot, readme_stack(robot), backend="daqp", dt=0.01)
    target = robot.frame_pose(robot.neutral(), "ee").copy()
    target[0, 3] += 0.3
    return Simulation(robot, controller, 0.01).run(seconds=seconds, references={"ee": target})


def test_replay_moves_the_robot_and_shows_the_status(viewer):
    robot = wbc.robots.load("mecanum_gen3")
    viewer.set_robot(robot)
    run = _short_run(robot)
    failing = Recording(run.t, run.q, np.r_[np.zeros(len(run.t) - 1), 2], robot=robot.name)
    viewer.replay({"ok": run, "failing": failing})
    assert viewer.current == "ok" and viewer._slider.max == len(run.t) - 1
    viewer._slider.value = 20
    base = viewer._frame_nodes[viewer._base_fid]
    np.testing.assert_allclose(base.position[:2], run.q[20, :2], atol=1e-12)
    assert "solved" in viewer._status.content
    viewer._run_choice.value = "failing"
    viewer._slider.value = len(run.t) - 1
    assert "status: **failed**" in viewer._status.content
    with pytest.raises(wbc.UnknownNameError):
        viewer.replay({"ok": run}, name="nope")


def test_records_round_trip_and_keep_failed_ticks(tmp_path):
    t = np.arange(0, 2, 0.001)  # 1 kHz: thinned to 50 Hz
    q = np.column_stack([t, np.sin(t)])
    status = np.zeros(t.size)
    status[7] = 2  # a failed tick between two kept frames stays visible
    recording = Recording(t, q, status, target=np.c_[t, t, t])
    path = save_recordings(tmp_path / "s" / "s_replay.npz", {"a/b": recording}, "omni4_arm6")
    back = load_recordings(tmp_path)["s/a/b"]
    assert len(back) == 100 and back.robot == "omni4_arm6" and back.status[0] == 2
    np.testing.assert_allclose(back.q, q[::20], atol=1e-6)
    assert path.stat().st_size < 10_000
    with pytest.raises(wbc.WbcError, match="no such file"):
        load_recordings(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(wbc.UnknownNameError):
        load_recordings(tmp_path / "empty")


def test_the_playground_follows_the_target_and_swaps_backends():
    from wbc.viz.playground import MODES, Playground

    robot = wbc.robots.load("mecanum_gen3")
    with Playground(robot, "daqp", port=0, start=False, verbose=False) as play:
        error = {}
        for backend, mode in (("daqp", MODES[0]), ("quadprog", MODES[1])):
            play.set_backend(backend)
            play.set_mode(mode)
            play.reset()
            goal = play.target.copy()
            goal[:3, 3] += [0.2, 0.0, -0.1]
            play.set_target(goal)  # as a user dragging the gizmo
            for _ in range(30):  # 1.5 s of closed loop
                play.step()
            error[mode] = np.linalg.norm(robot.frame_pose(play.q, "ee")[:3, 3] - goal[:3, 3])
        # strict priorities reach the target; one weighted level leaves the posture's pull
        assert error[MODES[0]] < 1e-3 and 1e-4 < error[MODES[1]] < 0.03, error
        assert play.backend == "quadprog" and play.failures == 0
        assert "quadprog" in play.stats_markdown() and "µs" in play.stats_markdown()


def test_binds_localhost_by_default():
    assert inspect.signature(Viewer).parameters["host"].default == "127.0.0.1"
    with Viewer(wbc.robots.load_panda(), port=0, verbose=False) as v:
        assert v.server.get_host() == "127.0.0.1" and v.url.startswith("http://127.0.0.1:")


@pytest.fixture
def busy_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


def test_a_busy_port_is_one_line_and_exit_1(busy_port, capsys, tmp_path):
    with pytest.raises(PortInUseError):
        Viewer(wbc.robots.load_panda(), port=busy_port, verbose=False)
    assert play_main(["panda", "--port", str(busy_port), "--seconds", "0"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "in use" in err


def test_view_serves_seconds_and_refuses_an_unknown_run(tmp_path, capsys):
    robot = wbc.robots.load("mecanum_gen3")
    run = _short_run(robot, 0.1)
    save_recordings(tmp_path / "demo" / "demo_replay.npz",
                    {"reach/daqp": Recording.from_run(run, robot=robot.name)}, robot.name)
    assert view_main([str(tmp_path), "--run", "nope", "--port", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unknown run 'nope'" in err
    assert view_main([str(tmp_path / "nothing")]) == 2
    assert view_main([str(tmp_path), "--run", "reach/daqp", "--port", "0",
                      "--seconds", "0.2"]) == 0
    assert play_main(["nobody", "--seconds", "0"]) == 2
    assert play_main(["panda", "--backend", "nope", "--seconds", "0"]) == 2


def test_without_the_extra_one_line_and_exit_1():
    code = ("import sys; sys.modules['viser'] = None\n"
            "from wbc.experiments.viewing import play_main\n"
            "sys.exit(play_main(['panda', '--seconds', '0', '--port', '0']))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 1, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and "pip install" in out.stderr


def test_play_takes_a_robot_file():
    """ROBOT may be a robot file, as ``wbc bench --robot`` takes it (a URDF arm on a base)."""
    from pathlib import Path

    robot_file = Path(__file__).parent / "data" / "lab_arm.toml"
    if not robot_file.exists():
        pytest.skip("tests/data/lab_arm.toml is not here")
    assert play_main([str(robot_file), "--seconds", "0.3", "--port", "0"]) == 0


def test_the_run_dropdown_loads_another_studys_robot(viewer):
    """``wbc view results`` lists every study's runs: choosing one of another robot draws it."""
    mecanum, omni = wbc.robots.load("mecanum_gen3"), wbc.robots.load("omni4_arm6")
    viewer.set_robot(mecanum)
    runs = {"xing/a": Recording([0.0, 0.1], np.tile(mecanum.neutral(), (2, 1)), [0, 1],
                                robot="mecanum_gen3"),
            "omni/b": Recording([0.0, 0.1], np.tile(omni.neutral(), (2, 1)), [0, 0],
                                robot="omni4_arm6")}
    viewer.replay(runs)
    viewer._run_choice.value = "omni/b"
    assert viewer.robot.name == "omni4_arm6" and viewer.model.nq == omni.nq
    viewer._slider.value = 1
    assert "status: **solved**" in viewer._status.content
    viewer._run_choice.value = "xing/a"
    viewer._slider.value = 1
    assert viewer.robot.name == "mecanum_gen3" and "status: **partial**" in viewer._status.content
