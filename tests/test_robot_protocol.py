"""The robot protocol's conformance suite: every catalogue robot, the fixed-base Panda (with
and without its prismatic fingers) and two whole-robot URDFs of example-robot-data — Solo-12 on
a free-flyer root and Tiago on its differential base (wheels recognised) — against finite
differences along ``integrate``, their own getters with and without ``out=``, their symbolic
forms and their quantity registry."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import wbc
import wbc.robots
from wbc.quantities import QuantityRegistry
from wbc.robots import FixedBaseRobot, Robot, SymbolicRobot, load_panda
from wbc.robots.resources import urdf_path
from wbc.robots.views import column_major_view

# stacks here leave the robot's limits out on purpose (they test other things)
pytestmark = pytest.mark.filterwarnings("ignore::wbc.errors.MissingLimitsWarning")

SEED = 20240917
H = 1e-5  # central-difference step [s] along integrate
ROBOTS = [*wbc.robots.names(), "panda", "panda_fingers", "solo12", "tiago_urdf"]
REQUIRED_QUANTITIES = ("pose[ee]", "J[ee]", "Jdot_v[ee]", "J_base[ee]", "com", "J_com",
                       "manipulability[ee]", "manipulability_gradient[ee]")


def _load(name: str):
    if name == "panda":
        return load_panda()
    if name == "panda_fingers":  # prismatic finger joints too
        return load_panda(fingers=True)
    if name == "solo12":  # a quadruped on a free-flyer root
        return wbc.robots.from_urdf(urdf_path("solo_description/robots/solo12.urdf"),
                                    root="free_flyer", ee_frame="FL_FOOT")
    if name == "tiago_urdf":  # the whole Tiago URDF, its two wheels the differential base's
        return wbc.robots.from_urdf(urdf_path("tiago_description/robots/tiago_no_hand.urdf"),
                                    root="differential", ee_frame="arm_tool_link")
    return wbc.robots.load(name)


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return _load(request.param)


def mobile(robot) -> bool:
    return getattr(robot, "base", None) is not None


def floating(robot) -> bool:
    return getattr(robot, "root", None) == "free_flyer"


def unit_quaternion(rng: np.random.Generator) -> np.ndarray:
    quaternion = rng.normal(size=4)
    return quaternion / np.linalg.norm(quaternion)


def states(robot, rng: np.random.Generator, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random ``(q, v)``: for mobile bases headings beyond ±π [rad] (1 to 4 whole turns) and
    base velocities up to 6 m/s and 5 rad/s (beyond the robots' limits: the kinematics do not
    care); joint rates up to 3 rad/s; the joints uniform within their position limits
    (``[−π, π]`` where unbounded); a free flyer anywhere in a 10 m box with any orientation,
    its body twist up to 3 m/s and 3 rad/s."""
    lower = np.where(np.isfinite(robot.limits.q_lower), robot.limits.q_lower, -math.pi)
    upper = np.where(np.isfinite(robot.limits.q_upper), robot.limits.q_upper, math.pi)
    out = []
    for _ in range(count):
        q = rng.uniform(lower, upper)
        v = rng.uniform(-3.0, 3.0, robot.nv)
        if mobile(robot):
            q[:2] = rng.uniform(-5.0, 5.0, 2)
            turns = rng.integers(1, 5) * rng.choice([-1, 1])  # whole turns, never zero
            q[2] = rng.uniform(-math.pi, math.pi) + 2.0 * math.pi * turns
            nb = robot.nv_base
            v[: nb - 1] = rng.uniform(-6.0, 6.0, nb - 1)  # v_x (v_y) [m/s]
            v[nb - 1] = rng.uniform(-5.0, 5.0)  # ω [rad/s]
        if floating(robot):
            q[:3] = rng.uniform(-5.0, 5.0, 3)
            q[3:7] = unit_quaternion(rng)
        out.append((q, v))
    if mobile(robot):
        assert any(abs(q[2]) > math.pi for q, _ in out)
    return out


def scaled_error(value: np.ndarray, reference: np.ndarray) -> float:
    """``max |value − reference|`` relative to ``max(1, max |reference|)``: drifts grow as
    ``|v|²`` (centripetal terms of large base velocities)."""
    value, reference = np.asarray(value), np.asarray(reference)
    return float(np.abs(value - reference).max()) / max(1.0, float(np.abs(reference).max()))


def axes(robot, q: np.ndarray, frame: str, reference: str) -> np.ndarray:
    """Rotation (3 × 3) whose transpose takes world axes to the ``reference`` axes, derived from
    the documented conventions: the base frame is ``Rz(θ)`` (the world for a fixed base, the
    root body's rotation — its quaternion ``q[3:7]`` — for a free flyer)."""
    if reference == "base" and floating(robot):
        x, y, z, w = q[3:7]
        return pin.Quaternion(w, x, y, z).toRotationMatrix()
    if reference == "world" or (reference == "base" and not mobile(robot)):
        return np.eye(3)
    if reference == "base":
        return pin.utils.rpyToMatrix(0.0, 0.0, q[2])
    return robot.frame_pose(q, frame)[:3, :3].copy()


def in_axes(rotation: np.ndarray, twist: np.ndarray) -> np.ndarray:
    return np.concatenate([rotation.T @ twist[:3], rotation.T @ twist[3:]])


def frames_to_check(robot) -> list[str]:
    """``"ee"``, a frame in the middle of the chain and, for a mobile base, ``"base"``."""
    model = robot.model
    middle = model.frames[robot.frame_id("ee")].parentJoint // 2 + 1
    body = next(f.name for f in model.frames if f.parentJoint == middle)
    return ["ee", body, *(["base"] if mobile(robot) or floating(robot) else [])]


# ------------------------------------------------------------------------ protocol and sizes
def test_satisfies_the_protocol(robot):
    assert isinstance(robot, Robot) and isinstance(robot, SymbolicRobot)
    assert isinstance(robot.quantities, QuantityRegistry)
    assert "ee" in robot.frame_names and robot.has_frame("ee") and not robot.has_frame("nope")
    assert all(robot.has_frame(frame) for frame in robot.frame_names)
    assert "universe" not in robot.frame_names and not robot.has_frame("universe")
    assert not isinstance(object(), Robot)


def test_limits_have_the_sizes_of_q_and_v(robot):
    limits = robot.limits
    assert (limits.nq, limits.nv) == (robot.nq, robot.nv)
    assert limits.q_lower.shape == limits.q_upper.shape == (robot.nq,)
    for array in (limits.v_lower, limits.v_upper, limits.a_lower, limits.a_upper):
        assert array.shape == (robot.nv,)


def test_neutral_and_random_configurations_are_within_the_limits(robot):
    q = robot.neutral()
    assert q.shape == (robot.nq,)
    assert np.all(q >= robot.limits.q_lower) and np.all(q <= robot.limits.q_upper)
    q[0] += 1.0  # a copy: the robot's home is not changed
    assert not np.array_equal(q, robot.neutral())
    rng = np.random.default_rng(SEED)
    samples = np.array([robot.random_configuration(rng) for _ in range(200)])
    assert samples.shape == (200, robot.nq)
    assert np.all(samples >= robot.limits.q_lower) and np.all(samples <= robot.limits.q_upper)
    # bounded coordinates are spread over their range, unbounded ones over [−π, π] (the
    # documented range; [−2, 2] m for a base position)
    finite = np.isfinite(robot.limits.q_lower) & np.isfinite(robot.limits.q_upper)
    span = np.where(finite, robot.limits.q_upper - robot.limits.q_lower, 2.0 * math.pi)
    if mobile(robot):
        span[:2] = 4.0
    if floating(robot):  # a box of ±2 m, unit quaternions
        span[:3] = 4.0
        span[3:7] = 1.0
        np.testing.assert_allclose(np.linalg.norm(samples[:, 3:7], axis=1), 1.0, atol=1e-15)
    assert np.all(np.ptp(samples, axis=0) > 0.8 * span)
    assert np.all(np.abs(samples[:, ~finite]) <= math.pi)


def test_integrate_is_a_flow(robot):
    """``integrate`` moves along the motion of a constant ``v``: zero time is the identity,
    durations add, the joints move linearly (the base along an arc)."""
    for q, v in states(robot, np.random.default_rng(SEED + 1), 3):
        np.testing.assert_array_equal(robot.integrate(q, v, 0.0), q)
        np.testing.assert_array_equal(robot.integrate(q, np.zeros(robot.nv), 0.3), q)
        once = robot.integrate(q, v, 0.5)
        twice = robot.integrate(robot.integrate(q, v, 0.2), v, 0.3)
        np.testing.assert_allclose(twice, once, rtol=0, atol=1e-12)
        nq_base, nv_base = robot.nq_base, robot.nv_base
        np.testing.assert_allclose(once[nq_base:], q[nq_base:] + 0.5 * v[nv_base:], rtol=0,
                                   atol=1e-15)


# ------------------------------------------------------------------------ finite differences
def test_jacobians_are_the_derivative_of_the_pose_along_integrate(robot):
    """``J v`` = central difference of the frame pose along ``integrate(q, v, ±h)``: origin
    velocity and angular velocity (log of the relative rotation), in each reference's axes."""
    for q, v in states(robot, np.random.default_rng(SEED + 2), 3):
        for frame in frames_to_check(robot):
            ahead = robot.frame_pose(robot.integrate(q, v, H), frame).copy()
            behind = robot.frame_pose(robot.integrate(q, v, -H), frame).copy()
            twist = np.concatenate([(ahead[:3, 3] - behind[:3, 3]) / (2.0 * H),
                                    pin.log3(ahead[:3, :3] @ behind[:3, :3].T) / (2.0 * H)])
            for reference in ("world", "base", "local"):
                J = robot.frame_jacobian(q, frame, reference)
                expected = in_axes(axes(robot, q, frame, reference), twist)
                assert scaled_error(J @ v, expected) < 1e-7, (frame, reference)


def test_drift_is_the_derivative_of_the_twist_along_integrate(robot):
    """``J̇ v`` = ``(J(q(t+h)) v − J(q(t−h)) v) / 2h`` with ``q(t)`` the motion at constant ``v``
    (``integrate``: exact arcs for mobile bases), for the Jacobian of each reference; the
    symbolic drift (world axes) too."""
    for q, v in states(robot, np.random.default_rng(SEED + 3), 4):
        ahead_q, behind_q = robot.integrate(q, v, H), robot.integrate(q, v, -H)
        for frame in frames_to_check(robot):
            for reference in ("world", "base", "local"):
                ahead = robot.frame_jacobian(ahead_q, frame, reference) @ v
                behind = robot.frame_jacobian(behind_q, frame, reference) @ v
                difference = (ahead - behind) / (2.0 * H)
                drift = robot.frame_drift(q, v, frame, reference)
                # truncation ~ h² |d³(Jv)/dt³| / 6 and round-off ~ eps |J v| / h: below 1e-7
                error = scaled_error(difference, drift)
                assert error < 1e-6, (frame, reference, error)
                if reference == "world":
                    symbolic = np.array(robot.symbolic_drift(frame)(q, v)).ravel()
                    assert scaled_error(difference, symbolic) < 1e-6, frame


def test_centre_of_mass_jacobian_along_integrate(robot):
    for q, v in states(robot, np.random.default_rng(SEED + 4), 2):
        difference = (robot.com(robot.integrate(q, v, H)) -
                      robot.com(robot.integrate(q, v, -H))) / (2.0 * H)
        assert scaled_error(robot.com_jacobian(q) @ v, difference) < 1e-7
    assert robot.mass == pytest.approx(robot.data.mass[0], rel=1e-14)  # the bodies of com


def test_manipulability_gradient_against_finite_differences(robot):
    q = states(robot, np.random.default_rng(SEED + 5), 1)[0][0]
    first = robot.nq - robot.n_arm
    gradient = robot.manipulability_gradient(q).copy()
    expected = []
    for k in range(robot.n_arm):
        dq = np.zeros(robot.nq)
        dq[first + k] = 1e-6
        expected.append((robot.manipulability(q + dq) - robot.manipulability(q - dq)) / 2e-6)
    assert scaled_error(gradient, expected) < 1e-5


# ------------------------------------------------------------------------ getters and out=
def test_getters_with_and_without_out_are_equal(robot):
    """After one update, the getters give the same numbers returned, written into a C-ordered
    array, into a Fortran-ordered array and into a column-major view of a parameter vector, and
    the same as when called with ``(q, v)``."""
    q, v = states(robot, np.random.default_rng(SEED + 6), 1)[0]
    nv = robot.nv
    for reference in ("world", "base", "local"):
        expected = {"pose": robot.frame_pose(q, "ee").copy(),
                    "J": robot.frame_jacobian(q, "ee", reference).copy(),
                    "drift": robot.frame_drift(q, v, "ee", reference).copy()}
        robot.update(q, v)
        getters = {"pose": lambda out: robot.frame_pose(None, "ee", out),
                   "J": lambda out, r=reference: robot.frame_jacobian(None, "ee", r, out),
                   "drift": lambda out, r=reference: robot.frame_drift(None, None, "ee", r, out)}
        shapes = {"pose": (4, 4), "J": (6, nv), "drift": (6,)}
        buffer = np.full(3 + 16 + 6 * nv + 6, np.nan)
        offsets = {"pose": 3, "J": 19, "drift": 19 + 6 * nv}
        for key, getter in getters.items():
            np.testing.assert_array_equal(getter(None), expected[key], err_msg=key)
            for order in ("C", "F"):
                out = np.full(shapes[key], np.nan, order=order)
                assert getter(out) is out
                np.testing.assert_array_equal(out, expected[key], err_msg=f"{key} {order}")
            view = column_major_view(buffer, offsets[key], shapes[key])
            getter(view)
            np.testing.assert_array_equal(view, expected[key], err_msg=f"{key} view")
        assert np.all(np.isnan(buffer[:3]))  # nothing written outside the views
        np.testing.assert_array_equal(
            buffer[3:], np.concatenate([expected[k].ravel(order="F") for k in offsets]))


def test_getters_read_the_last_update(robot):
    (q1, v1), (q2, _) = states(robot, np.random.default_rng(SEED + 7), 2)
    pose1 = robot.frame_pose(q1, "ee").copy()
    robot.update(q2)
    assert not np.allclose(robot.frame_pose(None, "ee"), pose1)
    robot.update(q1, v1)
    np.testing.assert_array_equal(robot.frame_pose(None, "ee"), pose1)
    np.testing.assert_array_equal(robot.frame_drift(None, None, "ee"),
                                  robot.frame_drift(q1, v1, "ee"))


# ------------------------------------------------------------------------ symbolic forms
def test_symbolic_forms_equal_the_numeric_getters(robot):
    frame_fn, drift_fn = robot.symbolic_frame("ee"), robot.symbolic_drift("ee")
    assert frame_fn.size_in(0) == (robot.nq, 1)
    assert frame_fn.size_out(0) == (4, 4) and frame_fn.size_out(1) == (6, robot.nv)
    assert drift_fn.size_in(0) == (robot.nq, 1) and drift_fn.size_in(1) == (robot.nv, 1)
    assert drift_fn.size_out(0) == (6, 1)
    for q, v in states(robot, np.random.default_rng(SEED + 8), 8):
        pose, J = (np.array(x) for x in frame_fn(q))
        assert scaled_error(pose, robot.frame_pose(q, "ee")) < 1e-12
        assert scaled_error(J, robot.frame_jacobian(q, "ee")) < 1e-12
        drift = np.array(drift_fn(q, v)).ravel()
        assert scaled_error(drift, robot.frame_drift(q, v, "ee")) < 1e-12


def test_symbolic_forms_of_every_frame(robot):
    # URDF frame names need not be CasADi identifiers (omni4_arm6: "base_link-base_fixed_joint")
    q, v = states(robot, np.random.default_rng(SEED + 9), 1)[0]
    for frame in robot.frame_names:
        pose, J = (np.array(x) for x in robot.symbolic_frame(frame)(q))
        assert scaled_error(pose, robot.frame_pose(q, frame)) < 1e-12, frame
        assert scaled_error(J, robot.frame_jacobian(q, frame)) < 1e-12, frame
        drift = np.array(robot.symbolic_drift(frame)(q, v)).ravel()
        assert scaled_error(drift, robot.frame_drift(q, v, frame)) < 1e-12, frame


def test_symbolic_forms_are_cached_and_shared_by_clones(robot):
    frame_fn, drift_fn = robot.symbolic_frame("ee"), robot.symbolic_drift("ee")
    assert robot.symbolic_frame("ee") is frame_fn and robot.symbolic_drift() is drift_fn
    assert robot.symbolic_drift(robot.frame_id("ee")) is drift_fn  # by index too
    other = robot.clone()
    assert other.symbolic_frame("ee") is frame_fn and other.symbolic_drift("ee") is drift_fn
    assert other.quantities.get("J[ee]").symbolic() is robot.quantities.get("J[ee]").symbolic()


def test_unknown_frame_raises_as_the_getters_do(robot):
    for bad in ("no_such_frame", len(robot.model.frames) + 5):
        for call in (lambda f: robot.frame_pose(robot.neutral(), f), robot.symbolic_frame,
                     robot.symbolic_drift):
            with pytest.raises(wbc.UnknownNameError) as error:
                call(bad)
            assert error.type is wbc.UnknownNameError


# ------------------------------------------------------------------------ clones
def test_clone_is_independent(robot):
    (q1, v1), (q2, v2) = states(robot, np.random.default_rng(SEED + 10), 2)
    other = robot.clone()
    assert other.model is robot.model and other.data is not robot.data
    assert other.quantities is not robot.quantities
    robot.update(q1, v1)
    other.update(q2, v2)
    np.testing.assert_array_equal(robot.frame_pose(None, "ee"), robot.frame_pose(q1, "ee"))
    assert not np.allclose(robot.frame_pose(None, "ee"), other.frame_pose(None, "ee"))
    # each registry fills from its own robot's last update
    mine, theirs = np.empty((6, robot.nv)), np.empty((6, robot.nv))
    robot.quantities.get("J[ee]").fill(mine)
    other.quantities.get("J[ee]").fill(theirs)
    np.testing.assert_array_equal(mine, robot.frame_jacobian(q1, "ee"))
    np.testing.assert_array_equal(theirs, other.frame_jacobian(q2, "ee"))


# ------------------------------------------------------------------------ quantities
def test_registry_offers_the_required_quantities_with_their_shapes(robot):
    nv = robot.nv
    shapes = {"pose[ee]": (4, 4), "J[ee]": (6, nv), "Jdot_v[ee]": (6, 1), "J_base[ee]": (6, nv),
              "com": (3, 1), "J_com": (3, nv), "manipulability[ee]": (1, 1),
              "manipulability_gradient[ee]": (robot.n_arm, 1)}
    for name, shape in shapes.items():
        quantity = robot.quantities.get(name)
        assert quantity.shape == shape, name
        assert quantity.needs_v == (name == "Jdot_v[ee]"), name
    with pytest.raises(wbc.UnknownNameError, match="pose"):
        robot.quantities.get("pose[no_such_frame]")
    with pytest.raises(wbc.UnknownNameError, match="offers"):
        robot.quantities.get("wheel_torques")


def test_every_quantity_fills_its_getter_and_equals_its_symbolic_form(robot):
    """Each quantity, filled into a column-major view of a parameter buffer after one update,
    equals the robot's getter and — where it has one — its symbolic form (to 1e-12)."""
    q, v = states(robot, np.random.default_rng(SEED + 11), 1)[0]
    getters = {
        "pose[ee]": lambda: robot.frame_pose(q, "ee"),
        "J[ee]": lambda: robot.frame_jacobian(q, "ee"),
        "Jdot_v[ee]": lambda: robot.frame_drift(q, v, "ee")[:, None],
        "J_base[ee]": lambda: robot.frame_jacobian(q, "ee", "base"),
        "com": lambda: robot.com(q)[:, None],
        "J_com": lambda: robot.com_jacobian(q),
        "manipulability[ee]": lambda: np.array([[robot.manipulability(q)]]),
        "manipulability_gradient[ee]": lambda: robot.manipulability_gradient(q)[:, None],
    }
    symbolic = set()
    for name in REQUIRED_QUANTITIES:
        quantity = robot.quantities.get(name)
        expected = getters[name]().copy()
        size = int(np.prod(quantity.shape))
        buffer = np.full(size + 2, np.nan)
        view = column_major_view(buffer, 1, quantity.shape)
        robot.update(q, v)
        quantity.fill(view)
        np.testing.assert_array_equal(view, expected, err_msg=name)
        assert np.isnan(buffer[0]) and np.isnan(buffer[-1]), name
        if quantity.symbolic is not None:
            function = quantity.symbolic()
            assert function.n_out() == 1, name
            value = np.array(function(q, v) if quantity.needs_v else function(q))
            assert scaled_error(value, expected) < 1e-12, name
            symbolic.add(name)
    assert symbolic >= {"pose[ee]", "J[ee]", "Jdot_v[ee]", "J_base[ee]", "com", "J_com"}


# ------------------------------------------------------------------------ unsupported joints
def odd_model(joint) -> pin.Model:
    """A yaw joint carrying ``joint`` (named ``"odd"``) and a frame ``"tip"``."""
    model = pin.Model()
    parent = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "yaw")
    odd = model.addJoint(parent, joint, pin.SE3.Identity(), "odd")
    model.appendBodyToJoint(odd, pin.Inertia.FromBox(1.0, 0.1, 0.1, 0.1), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", odd, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    return model


@pytest.mark.parametrize("joint", [pin.JointModelSphericalZYX(), pin.JointModelTranslation(),
                                   pin.JointModelHZ(0.1)])
def test_an_unsupported_joint_is_an_error_at_load_time(joint):
    model = odd_model(joint)
    assert model.nq == model.nv  # passes the size check: the joint type is what is refused
    with pytest.raises(wbc.WbcError, match=r"odd \(JointModel"):
        FixedBaseRobot(model, name="odd_arm")


def test_an_unsupported_joint_in_a_mobile_robots_arm_is_an_error_at_load_time():
    model = odd_model(pin.JointModelHZ(0.1))  # helical: 1-DoF, so the arm accepts it
    with pytest.raises(wbc.WbcError, match=r"odd \(JointModelHZ"):
        wbc.robots.MobileManipulator(wbc.robots.mecanum_base(), model, ee_frame="tip")


# ------------------------------------------------------------------------ in a controller
class CentreOfMassTask(wbc.Task):
    """``J_com v = gain (target − com)`` plus a small step along the manipulability gradient
    of the arm joints: model quantities of every kind (symbolic forms and numeric only)."""

    name = "com_task"  # not "com": a task may not shadow the model quantity

    def __init__(self, n_arm: int) -> None:
        self.n_arm = n_arm

    def terms(self, stack):
        v, n_arm = stack.variables["v"], self.n_arm
        com, J_com = stack.quantity("com", (3, 1)), stack.quantity("J_com", (3, v.shape[0]))
        gradient = stack.quantity("manipulability_gradient[ee]", (n_arm, 1))
        target = stack.parameter("com_task.target", (3, 1))
        return [wbc.Cost(J_com @ v - 0.5 * (target - com), name="com_task"),
                wbc.Cost(v[v.shape[0] - n_arm:] - gradient, weight=1e-3, name="manipulability")]


@pytest.mark.parametrize("name", ["tiago_panda", "panda"])
def test_a_controller_plans_from_the_registry_numeric_and_compiled_alike(name):
    robot = _load(name)
    twin = robot.clone()

    def stack():
        s = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-3)
        return s.add(CentreOfMassTask(robot.n_arm))

    numeric = wbc.Controller(robot, stack(), backend="daqp", dt=0.01, kinematics="numeric")
    compiled = wbc.Controller(twin, stack(), backend="daqp", dt=0.01, kinematics="compiled")
    assert {"com", "J_com"} <= set(numeric.model_parameters)
    assert not {"com", "J_com"} & set(compiled.model_parameters)  # inlined
    assert "manipulability_gradient[ee]" in compiled.model_parameters  # numeric only
    q = states(robot, np.random.default_rng(SEED + 12), 1)[0][0]
    target = robot.com(q)[:, None] + [[0.05], [-0.02], [0.03]]
    for _ in range(5):
        v = numeric.step(q, **{"com_task.target": target})
        assert numeric.last_solution.ok
        np.testing.assert_allclose(compiled.step(q, **{"com_task.target": target}), v, rtol=0,
                                   atol=1e-9)
        q = robot.integrate(q, v, 0.01)
