"""FixedBaseRobot.integrate: the closed-loop studies step fixed-base arms with it."""

import numpy as np

from wbc.robots.fixed_base import load_panda


def test_integrate_is_euler_on_revolute_joints():
    robot = load_panda()
    rng = np.random.default_rng(0)
    q, v = robot.neutral() + 0.1 * rng.standard_normal(robot.nq), rng.standard_normal(robot.nv)
    np.testing.assert_allclose(robot.integrate(q, v, 0.01), q + 0.01 * v, atol=1e-15)
    np.testing.assert_array_equal(robot.integrate(q, np.zeros(robot.nv), 0.01), q)
