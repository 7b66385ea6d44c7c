"""Every argument checked (issue #21, part 4): a constructor, stack method, robot loader or
reference given a bad argument raises a :class:`wbc.WbcError` subclass that names the argument,
when it is called — never numpy's, CasADi's or pinocchio's own exception, never at the first
tick."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import wbc
import wbc.robots as robots
import wbc.tasks as tasks
from wbc.checks import check_pose
from wbc.robots import arms
from wbc.tasks.manipulability import ManipulabilityAccelerationTask

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

ROBOT = robots.load("omni4_arm6")
UR5 = robots.urdf_path("ur_description/urdf/ur5_robot.urdf")
E = wbc.errors


def in_stack(build, variables, hard=False):
    """Build a task, add (or constrain) it in a fresh stack over ``variables``, compile."""
    def call(**kwargs):
        stack = wbc.Stack(variables)
        task = build(**kwargs)
        (stack.constrain if hard else stack.add)(task)
        stack.compile()
    return call


def velocities():
    return wbc.Variables(v=ROBOT.nv)


def stack_call(method, **fixed):
    def call(**kwargs):
        getattr(wbc.Stack(3), method)(**fixed, **kwargs)
    return call


LINEAR = dict(A=np.ones((2, 4)), b=np.zeros(2))
CASES = [
    # (id, call, bad kwargs, error class, text the message must hold)
    ("bounds_lengths", tasks.Bounds, dict(lower=-np.ones(3), upper=np.ones(4)), E.ShapeError,
     "lower has 3 entries but upper has 4"),
    ("bounds_str", tasks.Bounds, dict(lower="a", upper=1.0), E.InvalidValueError, "lower"),
    ("bounds_empty", tasks.Bounds, dict(lower=np.zeros(0), upper=1.0), E.ShapeError, "lower"),
    ("bounds_block_size", in_stack(tasks.Bounds, wbc.Variables(x=4), hard=True),
     dict(lower=-np.ones(3), upper=np.ones(3), name="b"), E.ShapeError, "lower of bounds 'b'"),
    ("linear_width", in_stack(tasks.LinearTask, wbc.Variables(x=3)),
     dict(**LINEAR, name="t"), E.ShapeError, "A of task 't' has 4 columns"),
    ("linear_b_nan", tasks.LinearTask, dict(A=np.ones((2, 4)), b=[0.0, np.nan]),
     E.NonFiniteError, "b of task"),
    ("linear_complex", tasks.LinearTask, dict(A=np.ones((2, 4)) * 1j, b=np.zeros(2)),
     E.InvalidValueError, "A of task"),
    ("linear_ragged", tasks.LinearTask, dict(A=[[1.0, 2.0], [3.0]], b=np.zeros(2)),
     E.ShapeError, "A of task"),
    ("linear_weight_negative", tasks.LinearTask, dict(**LINEAR, weight=-1.0),
     E.InvalidValueError, "weight of task"),
    ("linear_weight_rows", tasks.LinearTask, dict(**LINEAR, weight=np.ones(3)), E.ShapeError,
     "weight of task"),
    ("linear_weight_mx", tasks.LinearTask, dict(**LINEAR, weight=ca.MX.sym("w")),
     E.InvalidValueError, "weight of task"),
    ("linear_name_dict", tasks.LinearTask, dict(**LINEAR, name={"a": 1}), E.InvalidValueError,
     "name of task"),
    ("constraint_upper_shape", tasks.LinearConstraint,
     dict(C=np.ones((2, 4)), lower=-1.0, upper=np.ones(3)), E.ShapeError, "upper of constraint"),
    ("constraint_crossed", tasks.LinearConstraint,
     dict(C=np.ones((2, 4)), lower=1.0, upper=0.0), E.BoundsOrderError, "constraint"),
    ("frame_weight_str", tasks.FrameTask, dict(robot=ROBOT, frame="ee", weight="heavy"),
     E.InvalidValueError, "weight of FrameTask"),
    ("frame_gain_negative", tasks.FrameTask, dict(robot=ROBOT, frame="ee", gain=-1.0),
     E.InvalidValueError, "gain of FrameTask"),
    ("frame_gain_none", tasks.FrameTask, dict(robot=ROBOT, frame="ee", gain=None),
     E.InvalidValueError, "gain of FrameTask"),
    ("frame_lm_inf", tasks.FrameTask, dict(robot=ROBOT, frame="ee", lm_damping=np.inf),
     E.NonFiniteError, "lm_damping of FrameTask"),
    ("frame_frame_none", tasks.FrameTask, dict(robot=ROBOT, frame=None), E.InvalidValueError,
     "frame of FrameTask"),
    ("frame_robot_str", tasks.FrameTask, dict(robot="panda", frame="ee"), E.InvalidValueError,
     "robot of FrameTask"),
    ("frame_unknown", tasks.FrameTask, dict(robot=ROBOT, frame="elbow_typo"),
     E.UnknownNameError, "elbow_typo"),
    ("frame_block_size", in_stack(tasks.FrameTask, wbc.Variables(v=3)),
     dict(robot=ROBOT, frame="ee", name="ee"), E.ShapeError, "FrameTask 'ee'"),
    ("posture_weight_rows", tasks.PostureTask, dict(robot=ROBOT, weight=np.ones(2)),
     E.ShapeError, "weight of PostureTask"),
    ("posture_joints_float", tasks.PostureTask, dict(robot=ROBOT, joints=2.5),
     E.InvalidValueError, "joints"),
    ("config_gain_above_one", tasks.ConfigurationLimit, dict(robot=ROBOT, gain=1.5),
     E.InvalidValueError, "gain of ConfigurationLimit"),
    ("velocity_scale_complex", tasks.VelocityLimit, dict(robot=ROBOT, scale=1j),
     E.InvalidValueError, "scale of VelocityLimit"),
    ("rpy_gain_zero", tasks.RpyPoseTask, dict(robot=ROBOT, gain=0.0), E.InvalidValueError,
     "gain of RpyPoseTask"),
    ("accel_dt_str", tasks.JointAccelerationLimit, dict(robot=ROBOT, dt="fast"),
     E.InvalidValueError, "dt"),
    ("accel_method_list", tasks.JointAccelerationLimit, dict(robot=ROBOT, dt=0.01, method=[]),
     E.InvalidValueError, "method"),
    ("manipulability_gamma", ManipulabilityAccelerationTask, dict(robot=ROBOT, gamma1=-1.0),
     E.InvalidValueError, "gamma1"),
    ("dexterous_q_dex", tasks.DexterousPosture, dict(robot=ROBOT, q_dex=[0.0, np.nan]),
     E.NonFiniteError, "q_dex"),
    ("wrench_J_str", tasks.WheelWrench, dict(J="J"), E.InvalidValueError, "J"),
    ("friction_n_wheels", tasks.FrictionUtilisation, dict(n_wheels=4.5), E.InvalidValueError,
     "n_wheels"),
    ("friction_mu", tasks.FrictionUtilisation, dict(n_wheels=4, mu=-0.5), E.InvalidValueError,
     "mu"),
    ("distribution_method", tasks.distribution_stack, dict(J=np.ones((4, 3)), method=None),
     E.InvalidValueError, "method"),
    ("field_alpha", tasks.VelocityField, dict(alpha="0.5"), E.InvalidValueError, "alpha"),
    ("field_huge", tasks.VelocityField, dict(k_f=10 ** 400), E.NonFiniteError, "k_f"),
    ("bounds_fn_dt", tasks.joint_acceleration_bounds,
     dict(q=0.0, qd=0.0, q_min=-1, q_max=1, v_min=-1, v_max=1, a_min=-1, a_max=1, dt=None),
     E.InvalidValueError, "dt"),
    ("bounds_fn_q_str", tasks.joint_acceleration_bounds,
     dict(q="a", qd=0.0, q_min=-1, q_max=1, v_min=-1, v_max=1, a_min=-1, a_max=1, dt=0.1),
     E.InvalidValueError, "q of joint_acceleration_bounds"),
    ("sharing_radius", tasks.sharing_factor, dict(error_norm=0.1, r_fm=None),
     E.InvalidValueError, "r_fm"),
    ("arm_compensation_rows", tasks.ArmCompensation, dict(n_arm=3, rows=0),
     E.InvalidValueError, "rows"),
    ("variables_blocks", wbc.Variables, dict(blocks="abc"), E.InvalidValueError, "blocks"),
    ("variables_name", wbc.Variables, dict(blocks={5: 2}), E.InvalidValueError, "name"),
    ("parameter_shape_str", stack_call("parameter", name="p"), dict(shape="3"), E.ShapeError,
     "parameter 'p'"),
    ("parameter_shape_huge", stack_call("parameter", name="p"), dict(shape=(10 ** 4, 10 ** 4)),
     E.ShapeError, "parameter 'p'"),
    ("parameter_name", stack_call("parameter", shape=2), dict(name=None), E.InvalidValueError,
     "name of stack.parameter"),
    ("parameter_default_dict", stack_call("parameter", name="p", shape=2),
     dict(default={"a": 1}), E.InvalidValueError, "parameter 'p'"),
    ("add_weight_negative", stack_call("add", task=tasks.LinearTask(np.eye(3), np.ones(3))),
     dict(weight=-2.0), E.InvalidValueError, "weight of stack.add"),
    ("add_weight_symbol", stack_call("add", task=tasks.LinearTask(np.eye(3), np.ones(3))),
     dict(weight=ca.SX.sym("w")), E.InvalidValueError, "weight of stack.add"),
    ("add_priority", stack_call("add", task=tasks.LinearTask(np.eye(3), np.ones(3))),
     dict(priority=1.5), E.InvalidValueError, "priority of stack.add"),
    ("add_scaling", stack_call("add", task=tasks.LinearTask(np.eye(3), np.ones(3))),
     dict(scaling="yes"), E.InvalidValueError, "scaling of stack.add"),
    ("constrain_levels", stack_call("constrain", task=tasks.Bounds(-1, 1)),
     dict(levels=[np.inf]), E.WbcError, "levels"),
    ("mobility_str", stack_call("set_mobility"), dict(mobility="identity"),
     E.InvalidValueError, "mobility"),
    ("mobility_shape", stack_call("set_mobility"), dict(mobility=np.ones(4)), E.ShapeError,
     "mobility"),
    ("mobility_symbol", stack_call("set_mobility"), dict(mobility=ca.SX.sym("m", 3)),
     E.InvalidValueError, "mobility"),
    ("load_dict", robots.load, dict(name={}), E.UnknownNameError, "robot"),
    ("load_symbol", robots.load, dict(name=ca.SX.sym("r")), E.UnknownNameError, "robot"),
    ("from_urdf_no_ee", robots.from_urdf, dict(urdf=UR5), E.InvalidValueError, "ee_frame"),
    ("from_urdf_base", robots.from_urdf, dict(urdf=UR5, base=None, ee_frame="tool0"),
     E.InvalidValueError, "base"),
    ("from_urdf_mount", robots.from_urdf, dict(urdf=UR5, ee_frame="tool0", mount="up"),
     E.InvalidValueError, "mount"),
    ("from_urdf_v_max", robots.from_urdf, dict(urdf=UR5, ee_frame="tool0", v_max=-np.ones(6)),
     E.InvalidValueError, "v_max"),
    ("from_urdf_home_nan", robots.from_urdf,
     dict(urdf=UR5, ee_frame="tool0", home=[np.nan] * 6), E.NonFiniteError, "home"),
    ("from_urdf_locked", robots.from_urdf, dict(urdf=UR5, ee_frame="tool0", locked_joints=3),
     E.InvalidValueError, "locked_joints"),
    ("arm_from_urdf_path", arms.arm_from_urdf, dict(path=None, ee_frame="tool0"),
     E.InvalidValueError, "path"),
    ("arm_from_model_model", arms.arm_from_model, dict(model="ur5", ee_frame="tool0"),
     E.InvalidValueError, "model"),
]


@pytest.mark.parametrize("call, kwargs, error, text", [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_a_bad_argument_is_a_wbc_error_naming_it(call, kwargs, error, text):
    with pytest.raises(error) as info:
        call(**kwargs)
    assert isinstance(info.value, wbc.WbcError)
    assert text in str(info.value)


# ---------------------------------------------------------------------------- symbolic weights
def test_a_symbolic_weight_of_a_builtin_task_is_a_weight_set_every_tick():
    stack = wbc.Stack(wbc.Variables(v=ROBOT.nv), damping=1e-3)
    w = stack.parameter("w", 1, 1.0)
    stack.add(tasks.FrameTask(ROBOT, "ee", gain=0.5, weight=w, lm_damping=0.1, name="ee"))
    stack.add(tasks.PostureTask(ROBOT, weight=w, name="posture"), priority=1)
    ctrl = wbc.Controller(ROBOT, stack, dt=0.01, fused=False, jit=False)
    q = ROBOT.neutral()
    target = ROBOT.frame_pose(q, "ee").copy()
    target[0, 3] += 0.05
    moving = ctrl.step(q, ee=target).copy()
    assert np.abs(moving).max() > 1e-3
    ctrl.set_references(w=0.0)  # no weight: the levels ask for nothing, the damping keeps 0
    np.testing.assert_allclose(ctrl.step(q, ee=target), 0.0, atol=1e-9)


def test_a_symbolic_weight_of_another_stack_is_refused_when_added():
    other = wbc.Stack(3).parameter("w", 1)
    stack = wbc.Stack(3)
    with pytest.raises(wbc.WbcError, match="stack.parameter"):
        stack.add(tasks.LinearTask(np.eye(3), np.ones(3), weight=other, name="t"))


# ---------------------------------------------------------------------------- ambiguous frames
@pytest.fixture(scope="module")
def ambiguous_urdf(tmp_path_factory):
    """The UR5 with its fixed joint to ``tool0`` renamed ``tool0``: a link and a joint share
    the name."""
    text = open(UR5).read().replace('name="wrist_3_link-tool0_fixed_joint"', 'name="tool0"')
    path = tmp_path_factory.mktemp("urdf") / "ambiguous.urdf"
    path.write_text(text)
    return path


def test_an_ambiguous_frame_name_lists_the_candidates_with_their_types(ambiguous_urdf):
    with pytest.raises(wbc.UnknownNameError) as info:
        robots.from_urdf(ambiguous_urdf, base="mecanum", ee_frame="tool0")
    message = str(info.value)
    assert "ambiguous" in message
    assert "'link:tool0' (BODY)" in message and "'joint:tool0' (FIXED_JOINT)" in message


@pytest.mark.parametrize("kind", ["link", "joint"])
def test_an_ambiguous_frame_is_picked_by_its_kind(ambiguous_urdf, kind):
    robot = robots.from_urdf(ambiguous_urdf, base="mecanum", ee_frame=f"{kind}:tool0")
    plain = robots.from_urdf(UR5, base="mecanum", ee_frame="tool0")
    q = plain.neutral()  # the fixed joint puts both frames at the same place
    np.testing.assert_allclose(robot.frame_pose(q, "ee"), plain.frame_pose(q, "ee"),
                               atol=1e-12)
    assert {"link:tool0", "joint:tool0"} <= set(robot.frame_names)
    assert not robot.has_frame("tool0")
    with pytest.raises(wbc.UnknownNameError, match="tool0"):
        tasks.FrameTask(robot, "tool0")


def test_a_robot_built_on_a_model_with_shared_names_refuses_the_bare_name():
    import pinocchio as pin

    from wbc.robots.limits import Limits
    from wbc.robots.pinocchio_robot import PinocchioRobot

    arm = arms.panda()
    model = pin.Model(arm.model)
    frame = model.frames[model.getFrameId("panda_link8")]
    model.addFrame(pin.Frame("panda_link8", frame.parentJoint, frame.parentFrame,
                             frame.placement, pin.FrameType.OP_FRAME), False)
    limits = Limits(q_lower=arm.q_lower, q_upper=arm.q_upper, v_lower=-arm.v_max,
                    v_upper=arm.v_max, a_lower=-arm.a_max, a_upper=arm.a_max)
    robot = PinocchioRobot(model, name="twin", limits=limits, home=arm.home)
    with pytest.raises(wbc.UnknownNameError, match="ambiguous.*'link:panda_link8'"):
        robot.frame_id("panda_link8")
    assert robot.frame_id("frame:panda_link8") != robot.frame_id("link:panda_link8")


# ---------------------------------------------------------------------------- pose references
@pytest.fixture(scope="module")
def controller():
    stack = wbc.Stack(wbc.Variables(v=ROBOT.nv), damping=1e-3)
    stack.add(tasks.FrameTask(ROBOT, "ee", gain=0.5, name="ee"))
    stack.add(tasks.PostureTask(ROBOT, gain=0.5, weight=1e-2, name="posture"), priority=1)
    return wbc.Controller(ROBOT, stack, dt=0.01)


def _pose():
    T = ROBOT.frame_pose(ROBOT.neutral(), "ee").copy()
    T[:3, 3] += 0.05
    return T


def _scaled(T):
    T[:3, :3] *= 1.3
    return T


def _mirrored(T):
    T[:3, 0] *= -1.0  # orthonormal, det = -1
    return T


def _skewed(T):
    T[0, 1] += 1e-4
    return T


def _bottom(T):
    T[3, 0] = 0.1
    return T


@pytest.mark.parametrize("spoil", [_scaled, _mirrored, _skewed, _bottom])
@pytest.mark.parametrize("through", ["step", "set_references"])
def test_a_target_that_is_not_a_pose_is_refused_and_changes_nothing(controller, spoil, through):
    q = ROBOT.neutral()
    good = controller.step(q, ee=_pose()).copy()
    with pytest.raises(wbc.InvalidValueError, match="reference 'ee'.*rotation"):
        if through == "step":
            controller.step(q, ee=spoil(_pose()))
        else:
            controller.set_references(ee=spoil(_pose()))
    np.testing.assert_allclose(controller.step(q), good, atol=1e-12)  # target unchanged


@pytest.mark.parametrize("bad, error", [
    ("abc", wbc.InvalidValueError), (None, wbc.InvalidValueError), ({}, wbc.InvalidValueError),
    (np.eye(4) * (1 + 1j), wbc.InvalidValueError), (np.eye(3), wbc.ShapeError),
    (np.zeros(0), wbc.ShapeError), (np.full((4, 4), np.nan), wbc.NonFiniteError),
])
def test_a_reference_of_a_wrong_type_or_shape_is_named(controller, bad, error):
    with pytest.raises(error, match="reference 'ee'"):
        controller.set_references(ee=bad)
    if error is wbc.NonFiniteError:
        bad = np.full(ROBOT.nq, np.nan)
    with pytest.raises(error, match="reference 'posture'"):
        controller.step(ROBOT.neutral(), posture=bad)


def test_a_rotation_within_the_tolerance_is_accepted():
    rotation = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))[0]
    T = np.eye(4)
    T[:3, :3] = rotation * np.sign(np.linalg.det(rotation))
    check_pose(T, "T")
    T[:3, :3] *= 1 + 1e-8
    check_pose(T, "T")  # 1e-8 off: round-off of composed poses, accepted
