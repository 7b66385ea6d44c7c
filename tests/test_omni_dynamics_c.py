"""The compiled sub-step loop of OmniDynamics equals the numpy loop (its referee) on random
states and commands of every servo kind, including sub-steps that hit the active set (binding
limits, unloaded wheels with limit 0, unpowered wheels)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import Constant

import wbc.robots
from wbc.cbuild import compiler_available
from wbc.papers.omni import dynamics as dynamics_module
from wbc.papers.omni import dynamics_c
from wbc.papers.omni.dynamics import OmniDynamics, coulomb_forces
from wbc.sim import Simulation

pytestmark = pytest.mark.skipif(not compiler_available(), reason="no C compiler")

CASES = 500


@pytest.fixture(scope="module")
def robot():
    return wbc.robots.load("omni4_arm6")


def counting(calls):
    """coulomb_forces that counts its calls that leave the all-stick shortcut."""
    def wrapped(A, s_free, limit, A_inv=None):
        calls[0] += 1
        calls[1] += not (np.abs(A_inv @ s_free) <= limit).all()
        return coulomb_forces(A, s_free, limit, A_inv)
    return wrapped


@pytest.mark.parametrize("servo", ["torque", "angle", "angle_target"])
def test_compiled_substeps_equal_the_numpy_loop(robot, servo, monkeypatch):
    assert dynamics_c.library() is not None
    rng = np.random.default_rng(["torque", "angle", "angle_target"].index(servo))
    calls = [0, 0]
    monkeypatch.setattr(dynamics_module, "coulomb_forces", counting(calls))
    worst, bitwise = 0.0, 0
    for _ in range(CASES):
        model = OmniDynamics(servo=servo, active=rng.random(4) > 0.2,
                             gain_error=0.05 * rng.standard_normal(4),
                             radius_error=0.01 * rng.standard_normal(4),
                             substeps=int(rng.integers(1, 12)))
        model.reset(robot, 0.01)
        v = rng.standard_normal(3) * [1.0, 1.0, 2.0] * (1.0 if servo == "torque" else 0.05)
        rates = (model._G @ v) / model._radii + 0.05 * rng.standard_normal(4)
        # limits from ample to binding; some wheels unloaded (limit 0)
        limit = rng.uniform(0.0, 150.0, 4) * 10.0 ** rng.uniform(-2, 2) * (rng.random(4) > 0.1)
        noise = 0.5 * rng.standard_normal(4) * (model._gain != 0)
        scale = 3.0 if servo == "torque" else 0.05
        command = scale * rng.standard_normal(4)
        integral = 0.02 * rng.standard_normal(4)
        model._integral = integral.copy()
        python = model._python_substeps(v.copy(), rates.copy(), command, limit, noise)
        python_integral = model._integral
        model._integral = integral.copy()
        compiled = model._compiled_substeps(v.copy(), rates.copy(), command, limit, noise)
        for ours, referee in zip((*compiled, model._integral), (*python, python_integral),
                                 strict=True):
            gap = np.abs(ours - referee).max() / max(1.0, np.abs(referee).max())
            worst = max(worst, gap)
            bitwise += np.array_equal(ours, referee)
    assert worst <= 1e-12, worst
    # both the all-stick shortcut and the active set are exercised
    assert 0.2 * calls[0] <= calls[1] <= 0.8 * calls[0], calls
    print(f"{servo}: worst relative gap {worst:.1e}, {bitwise} of {7 * CASES} signals bitwise, "
          f"{calls[1]} of {calls[0]} sub-steps in the active set")


def test_the_compiled_loop_runs_in_apply(robot, monkeypatch):
    """apply uses the compiled loop when it is built, and the numpy loop otherwise."""
    used = []
    for name in ("_python_substeps", "_compiled_substeps"):
        original = getattr(OmniDynamics, name)
        monkeypatch.setattr(OmniDynamics, name, lambda self, *a, _o=original, _n=name:
                            used.append(_n) or _o(self, *a))
    Simulation(robot, Constant(np.full(4, 2.0)), 0.01, [OmniDynamics()], command="torque",
               seed=0).run(seconds=0.03)
    assert set(used) == {"_compiled_substeps"}
    monkeypatch.setattr(dynamics_c, "library", lambda: None)
    used.clear()
    Simulation(robot, Constant(np.full(4, 2.0)), 0.01, [OmniDynamics()], command="torque",
               seed=0).run(seconds=0.03)
    assert set(used) == {"_python_substeps"}
