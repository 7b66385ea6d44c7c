"""The compile passes (:mod:`wbc.passes`): one module holds them, their former homes re-export
the same objects, and each pass returns a new compiled stack and leaves its input as it was."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from wbc import cbuild, fused, jit, passes
from wbc.tasks import Bounds, LinearTask

FUSED_NAMES = ("CASCADE_PRIMAL_TOL", "CERTIFICATE_TOL", "DAQP_PRIMAL_TOL", "DAQP_SETTINGS",
               "FROZEN_BAND", "FUSED_KINDS", "daqp_link_arguments", "fused_function",
               "fused_qps", "fused_settings", "initialise_success", "why_not_fused")


def test_the_former_homes_re_export_the_passes():
    import wbc.controller

    assert wbc.controller.compiled_kinematics is passes.compiled_kinematics
    assert jit.jit_compiled is passes.jit_compiled
    for name in FUSED_NAMES:
        assert getattr(fused, name) is getattr(passes, name), name
        assert name in fused.__all__ and name in passes.__all__
    for name in ("DEFAULT_FLAGS", "cache_dir", "compiled_c"):  # the C build and its cache
        assert getattr(jit, name) is getattr(cbuild, name), name
    assert fused.compiler_available is cbuild.compiler_available
    for module in (cbuild, fused, jit, passes):
        for name in module.__all__:
            assert hasattr(module, name), (module.__name__, name)


def test_jit_compiled_returns_a_new_stack_and_leaves_its_input():
    if not cbuild.compiler_available():
        pytest.skip("no C compiler")
    stack = wbc.Stack(wbc.Variables(x=3), damping=0.1)
    stack.add(LinearTask(np.eye(3), np.ones(3), name="t"))
    stack.constrain(Bounds(-0.5, 0.5, name="box"))
    compiled = stack.compile()
    functions = [block.function for block in compiled.blocks]
    fast = passes.jit_compiled(compiled)
    assert fast is not compiled
    assert [block.function for block in compiled.blocks] == functions  # the input's, untouched
    np.testing.assert_allclose(wbc.Workspace(fast, "daqp", "tight").solve().x,
                               wbc.Workspace(compiled, "daqp", "tight").solve().x, atol=1e-12)


def test_compiled_kinematics_returns_a_new_stack_and_leaves_its_input():
    from wbc.robots.fixed_base import load_panda
    from wbc.tasks import FrameTask

    robot = load_panda()
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=0.5, name="ee"))
    compiled = stack.compile()
    parameters = dict(compiled.parameters)
    inlined = passes.compiled_kinematics(compiled, robot)
    assert inlined is not compiled and compiled.parameters == parameters
    assert {"pose[ee]", "J[ee]"} <= set(parameters)  # the robot fills them every tick
    assert set(inlined.parameters) == set(parameters) - {"pose[ee]", "J[ee]"} | {"q"}
