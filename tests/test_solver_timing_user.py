"""``wbc bench`` / ``fuzz`` / ``audit`` on a user's own robot (TOML) and stack (module:function);
the bench's accuracy, settings, cold start and export (issue #24)."""

from __future__ import annotations

import importlib.metadata
import inspect
import json
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import kkt_residuals

import wbc
import wbc.robots
from wbc.errors import WbcError
from wbc.experiments.benchmarks import accuracy, solver_timing
from wbc.experiments.benchmarks.settings import tolerance_options
from wbc.experiments.benchmarks.user_inputs import is_acceleration, load_robot_file, load_stack
from wbc.experiments.campaigns import audit, fuzz
from wbc.qp import QPResult, Status
from wbc.solvers import make_backend
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

DATA = Path(__file__).resolve().parent / "data"
ROBOT = DATA / "lab_arm.toml"
URDF = DATA / "tiny_arm.urdf"


@pytest.fixture
def in_data(monkeypatch):
    """The working directory is tests/data (where lab_stack.py lives), as for a user."""
    monkeypatch.chdir(DATA)
    monkeypatch.delitem(__import__("sys").modules, "lab_stack", raising=False)


# ----------------------------------------------------------------------------- robot files
def test_robot_file_builds_the_arm_on_its_base_with_its_mount():
    robot = load_robot_file(ROBOT)
    assert robot.name == "lab_arm" and (robot.nq, robot.nv) == (7, 6)  # diff. base + 4 joints
    mount = np.eye(4)
    mount[:3, 3] = [0.05, 0.0, 0.3]
    direct = wbc.robots.from_urdf(URDF, base=robot.base, ee_frame="tool", mount=mount,
                                  v_max=[1.5, 1.5, 2.0, 2.0], a_max=[8.0, 8.0, 10.0, 10.0],
                                  home=[0.0, 0.4, 0.8, 0.4])
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = direct.neutral() + np.r_[0, 0, 0, rng.uniform(-1, 1, 4)]
        np.testing.assert_allclose(robot.frame_pose(q, "ee"), direct.frame_pose(q, "ee"),
                                   atol=1e-12)
    np.testing.assert_allclose(robot.neutral(), direct.neutral())
    np.testing.assert_allclose(robot.limits.v_upper[-4:], [1.5, 1.5, 2.0, 2.0])


def test_robot_file_rpy_mount_is_urdf_convention(tmp_path):
    """``rpy`` as in URDF (pinocchio's ``rpyToMatrix``: ``Rz(yaw) Ry(pitch) Rx(roll)``)."""
    text = ROBOT.read_text().replace("rpy = [0.0, 0.0, 0.0]", "rpy = [0.3, -0.2, 1.1]")
    (tmp_path / "tiny_arm.urdf").write_text(URDF.read_text())
    turned = load_robot_file(_write(tmp_path / "r.toml", text))
    mount = np.eye(4)
    mount[:3, :3] = _rpy(0.3, -0.2, 1.1)
    mount[:3, 3] = [0.05, 0.0, 0.3]
    direct = wbc.robots.from_urdf(URDF, base=turned.base, ee_frame="tool", mount=mount)
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = direct.neutral() + np.r_[0, 0, 0, rng.uniform(-1, 1, 4)]
        np.testing.assert_allclose(turned.frame_pose(q, "ee"), direct.frame_pose(q, "ee"),
                                   atol=1e-12)


def _rpy(roll, pitch, yaw):
    import pinocchio as pin

    return pin.rpy.rpyToMatrix(roll, pitch, yaw)


def test_robot_file_catalogue_name(tmp_path):
    robot = load_robot_file(_write(tmp_path / "gen3.toml", 'catalogue = "mecanum_gen3"'))
    assert robot.name == "mecanum_gen3"
    with pytest.raises(WbcError, match="remove \\['ee_frame'\\]"):
        load_robot_file(_write(tmp_path / "both.toml",
                               'catalogue = "mecanum_gen3"\nee_frame = "tool"'))


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("edit, words", [
    (lambda t: "colour = 'red'\n" + t, "unknown key(s) ['colour']"),
    (lambda t: t.replace('ee_frame = "tool"\n', ""), "key 'ee_frame' is missing"),
    (lambda t: t.replace('ee_frame = "tool"', 'ee_frame = "flange"'), "flange"),
    (lambda t: t.replace('urdf = "tiny_arm.urdf"', 'urdf = "gone.urdf"'), "key 'urdf'"),
    (lambda t: t.replace('kind = "differential"', 'kind = "hovercraft"'), "base.kind"),
    (lambda t: t.replace("separation = 0.4\n", ""), "separation"),
    (lambda t: t.replace("v_max = [1.5, 1.5, 2.0, 2.0]", 'v_max = "fast"'), "key 'v_max'"),
    (lambda t: t.replace("xyz = [0.05, 0.0, 0.3]", "xyz = [0.05, 0.0]"), "mount.xyz"),
    (lambda t: t.replace('name = "lab_arm"', 'name = "lab_arm"\nroot = "fixed"'),
     "'base' or 'root', not both"),
    (lambda t: t.replace("[base]", "[base"), "not valid TOML"),
])
def test_bad_robot_files_name_the_file_and_the_key(tmp_path, edit, words):
    (tmp_path / "tiny_arm.urdf").write_text(URDF.read_text())
    path = _write(tmp_path / "bad.toml", edit(ROBOT.read_text()))
    with pytest.raises(WbcError) as err:
        load_robot_file(path)
    assert str(path) in str(err.value) and words in str(err.value), str(err.value)


def test_missing_robot_file():
    with pytest.raises(WbcError, match="cannot be read"):
        load_robot_file(DATA / "no_such_robot.toml")


def test_root_key_follows_from_urdf(tmp_path):
    """``root = "fixed"``: loaded when ``wbc.robots.from_urdf`` takes ``root=``, else a
    clear error saying so."""
    (tmp_path / "tiny_arm.urdf").write_text(URDF.read_text())
    text = "\n".join(line for line in ROBOT.read_text().split("[base]")[0].splitlines()
                     if not line.startswith("mount"))
    path = _write(tmp_path / "fixed.toml", text + '\nroot = "fixed"\n')
    if "root" in inspect.signature(wbc.robots.from_urdf).parameters:
        robot = load_robot_file(path)
        assert robot.nv == 4
    else:
        with pytest.raises(WbcError, match="takes no root="):
            load_robot_file(path)


# ----------------------------------------------------------------------------- stacks
def test_user_stack_imports_from_the_working_directory(in_data):
    user = load_stack("lab_stack:two_levels")
    robot = load_robot_file(ROBOT)
    stack = user(robot)
    assert isinstance(stack, wbc.Stack) and not is_acceleration(stack)
    assert load_stack(str(DATA / "lab_stack.py") + ":two_levels")(robot).variables.n == 6


@pytest.mark.parametrize("spec, words", [
    ("lab_stack", "expected 'module:function'"),
    ("no_such_module:build", "cannot import 'no_such_module'"),
    ("lab_stack:missing", "has no function 'missing'"),
    ("lab_stack:no_ee", "no frame task named 'ee'"),
    ("lab_stack:not_a_stack", "returned int, not a wbc.Stack"),
])
def test_bad_user_stacks_are_clear_errors(in_data, spec, words):
    robot = wbc.robots.load("mecanum_gen3")
    with pytest.raises(WbcError, match=words.replace("(", r"\(").replace(")", r"\)")):
        load_stack(spec)(robot)


# ----------------------------------------------------------------------------- accuracy
def test_residuals_closed_form():
    """min ½|x|² - [1, 1]ᵀx s.t. x₀ + x₁ <= 1, x₁ <= 0.2: the KKT point x = (0.8, 0.2),
    y = 0.2, z = (0, 0.6) gives zero residuals; a shifted x its violation and stationarity
    error; no multipliers, no dual residual; a failed QP, none at all."""
    H, g = np.eye(2), np.array([-1.0, -1.0])
    A = np.array([[1.0, 1.0]])
    lA, uA = np.array([-np.inf]), np.array([1.0])
    lb, ub = np.array([-np.inf, -np.inf]), np.array([np.inf, 0.2])
    x = np.array([0.8, 0.2])
    y = np.array([1.0 - 0.8])  # from row 0: x0 - 1 + y = 0
    z = np.array([0.0, 1.0 - 0.2 - y[0]])  # row 1: x1 - 1 + y + z1 = 0
    qp = (H, g, A, lA, uA, lb, ub)
    exact = QPResult(x, Status.SOLVED, y, z)
    res = accuracy.residuals(qp, exact)
    assert res["primal"] == pytest.approx(0.0, abs=1e-15)
    assert res["dual"] == pytest.approx(0.0, abs=1e-15)
    assert res["gap"] == pytest.approx(0.0, abs=1e-15)
    helper = kkt_residuals(qp, exact)
    assert helper["stationarity"] == pytest.approx(0.0, abs=1e-15)
    moved = accuracy.residuals(qp, QPResult(x + [0.1, 0.05], Status.SOLVED, y, z))
    assert moved["primal"] == pytest.approx(0.15)  # row: 1.15 > 1; bound: 0.25 > 0.2
    assert moved["dual"] == pytest.approx(0.1)
    assert accuracy.residuals(qp, QPResult(x, Status.SOLVED, None, None))["dual"] is None
    assert accuracy.residuals(qp, QPResult(x, Status.INFEASIBLE, y, z))["primal"] is None


def test_residuals_of_random_daqp_answers_vanish():
    rng = np.random.default_rng(3)
    for _ in range(20):
        n, m = 6, 4
        M = rng.normal(size=(n, n))
        H = M @ M.T + 0.1 * np.eye(n)
        g, A = rng.normal(size=n), rng.normal(size=(m, n))
        lA, uA = -rng.uniform(0, 1, m), rng.uniform(0, 1, m)
        lb, ub = -rng.uniform(0.1, 1, n), rng.uniform(0.1, 1, n)
        qp = (H, g, A, lA, uA, lb, ub)
        backend = make_backend("daqp", "tight")
        backend.setup(*qp)
        res = accuracy.residuals(qp, backend.solve(None))
        assert max(res.values()) < 1e-8, res


# ----------------------------------------------------------------------------- settings
def test_every_backend_reports_resolved_settings_and_its_version():
    for name in ("daqp", "quadprog", "osqp", "proxqp", "clarabel", "qpsolvers:daqp"):
        settings = make_backend(name).settings()
        json.dumps(settings)  # JSON-able (infinities as strings)
        assert settings["version"] == importlib.metadata.version(settings["package"])
        assert set(settings["set_by_wbc"]) <= set(settings["options"])
    daqp = make_backend("daqp").settings()["options"]
    assert daqp["eta_prox"] == 1e-10 and daqp["primal_tol"] == 1e-6  # DAQP's own default
    assert make_backend("osqp").settings()["options"]["eps_abs"] == 1e-5


def test_tolerance_groups_set_the_same_absolute_tolerance():
    assert tolerance_options("daqp", "default") == {}
    for name, key in (("daqp", "primal_tol"), ("osqp", "eps_abs"), ("proxqp", "eps_abs"),
                      ("clarabel", "tol_gap_abs"), ("qpsolvers:proxqp", "eps_abs")):
        options = tolerance_options(name, "high")
        assert options[key] == 1e-9
        make_backend(name, **options)  # accepted by the backend
    assert tolerance_options("quadprog", "low") is None  # no tolerance: settings kept
    assert tolerance_options("casadi:osqp", "mid")["osqp"]["eps_abs"] == 1e-6


# ----------------------------------------------------------------------------- workspace
def _counting_daqp(setups: list):
    def factory():
        backend = make_backend("daqp")
        setup = backend.setup

        def counted(*qp):
            setups.append(1)
            setup(*qp)
        backend.setup = counted
        return backend
    return factory


def test_cold_start_sets_every_backend_up_again_and_last_qps_is_public():
    robot = wbc.robots.load("mecanum_gen3")
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, name="posture"), priority=1)
    stack.constrain(VelocityLimit(robot, name="v_limits"))
    stack.constrain(ConfigurationLimit(robot, name="q_limits"))
    setups: list = []
    ctrl = wbc.Controller(robot, stack, backend=_counting_daqp(setups), fused=False)
    q = robot.neutral()
    T = robot.frame_pose(q, "ee").copy()
    T[0, 3] += 0.3
    ctrl.step(q, ee=T)
    ctrl.step(q, ee=T)
    assert len(setups) == 2  # two levels, set up once
    ctrl.workspace.cold_start()
    ctrl.step(q, ee=T)
    assert len(setups) == 4
    qps = ctrl.last_qps()
    assert [label for label, _, _ in qps] == [lab for lab, _, _ in ctrl.workspace.last_qps()]
    assert len(qps) == 2 and qps[0][2].status is Status.SOLVED


# ----------------------------------------------------------------------------- the bench
def test_bench_on_a_user_robot_and_stack_reports_time_accuracy_settings(in_data, tmp_path):
    out, export = tmp_path / "out", tmp_path / "qps"
    code = solver_timing.main([
        "--robot", "lab_arm.toml", "--stack", "lab_stack:two_levels", "--scenarios", "far",
        "--backends", "daqp", "quadprog", "qpsolvers:daqp", "--ticks", "4", "--warmup", "1",
        "--repeat", "2", "--samples", "--export", str(export), "--scaling-joints", "7",
        "--scaling-ticks", "2", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "solver_timing.json").read_text())
    cell = report["results"]["lab_arm"]["lab_stack:two_levels"]["far"]
    assert set(cell) == {"daqp", "quadprog", "qpsolvers:daqp"}
    for backend, r in cell.items():
        for key in ("full_solve_rate", "wrong_rate", "deviation", "settings", "version",
                    "stats", "samples", "levels", "shifted_geomean", "repeats", "path"):
            assert key in r, (backend, key)
        assert set(r["deviation"]) == {"median", "p95", "max"}
        assert r["full_solve_rate"] == 1.0 and r["wrong_rate"] == 0.0
        assert r["deviation"]["max"] < 1e-6
        assert len(r["samples"]["tick"]) == 8  # 4 ticks × 2 repeats
        assert len(r["repeats"]["medians"]) == 2 and r["repeats"]["ci95"] is not None
        assert [lv["size"][0] for lv in r["levels"]] == [6, 6]
        for lv in r["levels"]:
            assert lv["primal_residual"]["max"] < 1e-6
    assert cell["quadprog"]["settings"]["options"]["time_limit"] is None  # no thread
    assert cell["daqp"]["version"] == importlib.metadata.version("daqp")
    assert cell["qpsolvers:daqp"]["settings"]["solver"] == "daqp"
    assert report["scaling"]["daqp"]["7"]["qp_sizes"] == [[7, 0]]
    assert len(report["scaling"]["daqp"]["7"]["samples"]["tick"]) == 4
    assert set(report["summary"]) == set(cell)
    md = (out / "solver_timing.md").read_text()
    assert "### lab_arm — lab_stack:two_levels — far" in md and "shift 10 µs" in md
    # every exported QP loads in qpsolvers and re-solves to the referee's solution
    qpsolvers = pytest.importorskip("qpsolvers")
    index = json.loads((export / "lab_arm" / "lab_stack_two_levels" / "far" /
                        "index.json").read_text())
    assert len(index) == 3 * 4 * 2  # backends × ticks × levels
    for entry in index:
        problem = qpsolvers.Problem.load(entry["file"])
        x_ref = np.load(entry["file"])["x_referee"]
        solution = qpsolvers.solve_problem(problem, solver="quadprog")
        assert solution.found
        np.testing.assert_allclose(solution.x, x_ref, atol=1e-8)


def test_bench_cold_and_tolerance_groups_are_recorded(tmp_path):
    out = tmp_path / "out"
    code = solver_timing.main([
        "--robots", "mecanum_gen3", "tiago_panda", "--stacks", "one_level", "--scenarios",
        "unreachable", "--backends", "daqp", "proxqp", "--ticks", "3", "--warmup", "1", "--cold",
        "--tolerance", "high", "--scaling-joints", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "solver_timing.json").read_text())
    assert report["cold"] is True and report["tolerance"] == "high"
    cell = report["results"]["mecanum_gen3"]["one_level"]["unreachable"]
    assert cell["proxqp"]["settings"]["options"]["eps_abs"] == 1e-9
    assert cell["proxqp"]["settings"]["tolerance"] == {"eps_abs": 1e-9, "eps_rel": 0.0}
    assert (out / "solver_timing.png").read_bytes()[:4] == b"\x89PNG"  # one panel per robot


@pytest.mark.parametrize("argv, words", [
    (["--robot", "no_such.toml"], "cannot be read"),
    (["--stack", "no_such_module:f", "--robots", "mecanum_gen3"], "cannot import"),
])
def test_bench_bad_user_files_exit_1_with_the_reason(in_data, argv, words, capsys):
    from wbc.experiments import cli

    assert cli.main(["bench", *argv, "--ticks", "1", "--scaling-joints"]) == 1
    assert words in capsys.readouterr().err


def test_bench_accepts_a_backend_wbc_does_not_list(tmp_path):
    """``qpsolvers:daqp`` (make_backend's, not in available_backends), a user factory, and a
    backend named twice (timed twice, as ``quadprog#2``)."""
    import sys
    import types

    module = types.ModuleType("my_adapter")
    module.make = lambda: make_backend("qpsolvers:quadprog")
    sys.modules["my_adapter"] = module
    try:
        code = solver_timing.main([
            "--robots", "mecanum_gen3", "--stacks", "one_level", "--scenarios", "circle",
            "--backends", "qpsolvers:daqp", "my_adapter:make", "quadprog", "quadprog",
            "--ticks", "2", "--warmup",
            "1", "--scaling-joints", "--out", str(tmp_path)])
    finally:
        del sys.modules["my_adapter"]
    assert code == 0
    cell = json.loads((tmp_path / "solver_timing.json").read_text())[
        "results"]["mecanum_gen3"]["one_level"]["circle"]
    assert cell["my_adapter:make"]["full_solve_rate"] == 1.0
    assert cell["my_adapter:make"]["settings"]["backend"] == "qpsolvers:quadprog"
    assert set(cell) == {"qpsolvers:daqp", "my_adapter:make", "quadprog", "quadprog#2"}
    assert cell["quadprog#2"]["settings"] == cell["quadprog"]["settings"]


# ----------------------------------------------------------------------------- fuzz, audit
def test_fuzz_and_audit_take_a_user_robot_and_stack(in_data, tmp_path):
    code = fuzz.main(["--cases", "40", "--backends", "daqp", "--robot", "lab_arm.toml",
                      "--stack", "lab_stack:two_levels", "--out", str(tmp_path)])
    result = json.loads((tmp_path / "fuzz.json").read_text())
    assert result["parameters"]["robots"] == ["lab_arm"]
    assert result["parameters"]["stack"] == "lab_stack:two_levels"
    assert result["families"].get("robot", 0) >= 1
    assert code == (1 if result["defects"] else 0)
    code = audit.main(["--runs", "2", "--ticks", "5", "--backends", "daqp,quadprog",
                       "--robot", "lab_arm.toml", "--stack", "lab_stack:two_levels",
                       "--out", str(tmp_path)])
    result = json.loads((tmp_path / "audit.json").read_text())
    assert result["parameters"]["robots"] == ["lab_arm"]
    assert result["parameters"]["levels"] == ["velocity"]
    assert set(result["cells"]) == {"velocity/daqp (fused)/lab_arm",
                                    "velocity/quadprog/lab_arm"}
    assert code == 0 and result["violations"] == 0


def test_referee_answers_are_certified_by_their_kkt_residuals():
    """A level QP of ``three_levels`` / ``far`` on mecanum_gen3 (tick 113) where quadprog
    (tight) returned a feasible, non-optimal point (kept in the file): the KKT check refuses
    it, and the export's referee answers with a certified solution. The QP is badly
    conditioned (cond(H) ≈ 4e6): quadprog, now re-solving such a level with its sides relaxed
    by its feasibility tolerance (solvers/quadprog_backend.py), and daqp's tight profile give
    certified answers 2e-5 apart (duality gap 2.3e-5), so they agree on the objective to 1e-4,
    not to round-off."""
    data = np.load(DATA / "quadprog_nonoptimal_level.npz")
    qp = tuple(data[k] for k in ("H", "g", "A", "lA", "uA", "lb", "ub"))
    stored = QPResult(data["x_quadprog"], Status.SOLVED, data["y"], data["z"])
    assert not accuracy.certified_qp(qp, stored)
    assert accuracy.residuals(qp, stored)["dual"] > 0.1
    daqp = make_backend("daqp", "tight")
    daqp.setup(*qp)
    exact = daqp.solve(None)
    assert accuracy.certified_qp(qp, exact)
    x = accuracy.Referee().solve(qp)
    objective = [0.5 * z @ qp[0] @ z + qp[1] @ z for z in (stored.x, exact.x, x)]
    assert objective[1] < objective[0] - 0.05  # the stored point is not optimal
    assert objective[2] == pytest.approx(objective[1], abs=1e-4)
    assert np.abs(x - exact.x).max() < 1e-4


def test_summary_statistics_closed_forms():
    g = solver_timing._shifted_geomean(np.array([10.0, 30.0]), np.array([True, False]))
    charged = np.array([10.0, solver_timing.DT * 1e6])  # the failed tick at the period
    expected = np.exp(np.mean(np.log(charged + solver_timing.SHIFT_US))) - solver_timing.SHIFT_US
    assert g["value_us"] == pytest.approx(expected) and g["charged_ticks"] == 1
    rep = solver_timing._repeats([1.0, 2.0, 3.0])
    assert rep["mean"] == 2.0
    half = 4.302652729911275 / np.sqrt(3.0)  # Student's t(0.975, 2 dof) · s / √n, s = 1
    assert rep["ci95"] == pytest.approx([2.0 - half, 2.0 + half])
    assert solver_timing._repeats([5.0])["ci95"] is None


@pytest.mark.parametrize("name", ["daqp", "quadprog", "osqp", "proxqp", "clarabel",
                                  "qpsolvers:daqp"])
def test_backends_time_their_library_calls(name):
    rng = np.random.default_rng(5)
    M = rng.normal(size=(5, 5))
    qp = (M @ M.T + np.eye(5), rng.normal(size=5), rng.normal(size=(2, 5)), -np.ones(2),
          np.ones(2), -np.ones(5), np.ones(5))
    backend = make_backend(name)
    backend.setup(*qp)
    backend.solve(None)
    assert backend.library_time > 0.0
    for _ in range(3):  # reset by update(): the library's update and solve calls of one tick
        t0 = time.perf_counter()
        backend.update(*qp)
        backend.solve(None)
        wall = time.perf_counter() - t0
        assert 0.0 < backend.library_time <= wall
