"""The placo comparison: its model is wbc's Panda, the mirror of placo's QP is what placo
solves, and the study runs end to end where placo is installed (no timing is asserted)."""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from wbc.errors import MissingDependencyError
from wbc.experiments.peers import vs_placo


def test_the_model_placo_loads_is_wbcs_panda(tmp_path):
    """The URDF written for placo (no meshes, fingers fixed) has wbc's kinematics: loaded by
    pinocchio, the hand pose and Jacobian equal ``load_panda``'s."""
    import pinocchio as pin

    from wbc.robots.fixed_base import load_panda

    path = tmp_path / "panda.urdf"
    path.write_text(ET.tostring(vs_placo.panda_urdf_without_meshes(), encoding="unicode"))
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    robot = load_panda()
    assert model.nq == robot.nq == 7
    hand = model.getFrameId(vs_placo.HAND)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = rng.uniform(robot.limits.q_lower, robot.limits.q_upper)
        pin.framesForwardKinematics(model, data, q)
        J = pin.computeFrameJacobian(model, data, q, hand, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(data.oMf[hand].homogeneous, robot.frame_pose(q, "ee"),
                                   atol=1e-12)
        np.testing.assert_allclose(J, robot.frame_jacobian(q, "ee"), atol=1e-12)
    np.testing.assert_allclose(model.velocityLimit, robot.limits.v_upper)


def test_the_mirror_is_placos_qp_unconstrained():
    """Away from every bound, the mirror's answer is the normal equations of placo's cost
    ``Σ w‖A Δq − e‖² + 10⁻⁸‖Δq‖²`` in ``v = Δq / dt``."""
    from wbc.robots.fixed_base import load_panda

    robot = load_panda()
    q = vs_placo.Q0 + 0.05
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += [1e-4, -2e-4, 1e-4]  # a small step: no bound is active
    values = vs_placo.mirror_values(robot, q, target)
    solution = vs_placo.mirror_stack(robot).workspace("daqp", "tight").set(**values).solve()
    assert solution.ok
    A, e = values["frame.A"], values["frame.b"] * vs_placo.DT
    w = vs_placo.POSTURE_COST ** 2
    H = A.T @ A + w * np.eye(7) + vs_placo.PLACO_REGULARIZATION * np.eye(7)
    dq = np.linalg.solve(H, A.T @ e + w * (vs_placo.Q0 - q))
    np.testing.assert_allclose(solution.x, dq / vs_placo.DT, atol=1e-9)


def test_vs_placo_without_placo_is_an_error_with_the_install_hint(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "placo", None)  # import placo -> ImportError
    with pytest.raises(MissingDependencyError, match=r"pip install 'wbc\[placo\]'"):
        vs_placo.main(["--ticks", "5", "--out", str(tmp_path)])
    assert not (tmp_path / "vs_placo.json").exists()


def test_vs_placo_writes_its_json(tmp_path, capsys):
    pytest.importorskip("placo")
    assert vs_placo.main(["--ticks", "40", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "vs_placo.json").read_text())
    result = report["backends"]["daqp"]
    assert result["fused"] and result["wbc_failures"] == 0
    assert result["mirror_agrees"], result["mirror_diff_max"]  # placo's QP, understood
    assert result["wbc_median_s"] > 0 and result["placo_median_s"] > 0
    assert result["bare_median_s"] > 0 and result["raw_daqp_median_s"] > 0
    dedicated = result["dedicated"]
    assert dedicated["wbc_median_s"] > 0 and dedicated["placo_median_s"] > 0
    assert dedicated["step_over_bare"] > 0
    assert "| daqp (fused) |" in capsys.readouterr().out
