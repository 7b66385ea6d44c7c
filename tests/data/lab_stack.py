"""A stack of one's own for ``wbc bench --stack lab_stack:two_levels`` (run from this folder, or
with it on ``sys.path``): the end-effector pose above a posture, velocity limits hard."""

import wbc
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit


def two_levels(robot):
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(FrameTask(robot, "ee", gain=1.0, name="ee"), priority=0)
    stack.add(PostureTask(robot, gain=0.5, weight=1e-2, name="posture"), priority=1)
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="position_limits"))
    stack.constrain(VelocityLimit(robot, name="velocity_limits"))
    return stack


def no_ee(robot):
    """Not usable by the bench: no frame task named 'ee'."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
    stack.add(PostureTask(robot, gain=0.5, name="posture"))
    return stack


def not_a_stack(robot):
    return 42
