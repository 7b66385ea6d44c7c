"""``Controller.step``'s inputs in one C call (the stage, :data:`wbc.checks.STAGE_SOURCE`): it
accepts only what Python's checks accept and writes the same bits, a refusal — NaN, inf, a wrong
shape, a wrong type, a pose that is no rotation, an unknown keyword — is raised by Python's
checks before anything is written (parameters, last command and solution, the fused call's
buffers), and a valid tick makes no Python check at all."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

import wbc
from wbc import controller as controller_module
from wbc.cbuild import compiler_available
from wbc.checks import ROTATION_TOL, check_pose, checked_array
from wbc.robots.fixed_base import load_panda
from wbc.tasks import ConfigurationLimit, FrameTask, PostureTask, VelocityLimit

pytestmark = pytest.mark.skipif(not compiler_available(), reason="needs a C compiler")

DT = 0.01
Q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])  # "ready"


@pytest.fixture(scope="module")
def robot():
    return load_panda()


def panda(robot, **options) -> wbc.Controller:
    """The Panda problem of ``wbc pink`` / ``wbc placo`` (hand pose, posture, limits)."""
    stack = wbc.Stack(wbc.Variables(v=robot.nv), damping=1e-6)
    stack.add(FrameTask(robot, "ee", gain=0.5, lm_damping=1e-3, name="ee"))
    stack.add(PostureTask(robot, gain=0.5, weight=1e-4, name="posture"))
    stack.constrain(ConfigurationLimit(robot, gain=0.5, name="position_limit"))
    stack.constrain(VelocityLimit(robot, name="velocity_limit"))
    controller = wbc.Controller(robot, stack, dt=DT, **options)
    controller.set_references(posture=Q0)
    return controller


@pytest.fixture(scope="module")
def stage():
    function = controller_module._c_stage("cc")
    assert function is not controller_module._python_path  # built and loaded here
    return function


def _python_accepts(value, shape, allow_inf, pose) -> np.ndarray | None:
    """What Python's checks make of a reference value (the array written), or ``None``."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # (the messages of huge entries)
            array = checked_array(value, shape, "x", allow_inf)
            if pose:
                check_pose(array, "x")
    except wbc.WbcError:
        return None
    return array


def _rotation_error(T: np.ndarray) -> float:
    """:func:`wbc.checks.check_pose`'s test quantity (it accepts below ``ROTATION_TOL``)."""
    a, b, c, _, d, e, f, _, g, h, i, _ = T.ravel().tolist()[:12]
    return math.hypot(math.hypot(a, d, g) - 1.0, math.hypot(b, e, h) - 1.0, a * b + d * e + g * h,
                      d * h - g * e - c, g * b - a * h - f, a * e - d * b - i)


def _pose(rng, error: float = 0.0) -> np.ndarray:
    """A random pose whose rotation block is moved by ``error`` (Frobenius) off a rotation."""
    w = rng.standard_normal(3)
    angle = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    T = np.eye(4)
    T[:3, :3] += np.sin(angle) * K + (1 - np.cos(angle)) * K @ K  # Rodrigues
    T[:3, 3] = rng.uniform(-1, 1, 3)
    E = rng.standard_normal((3, 3))
    T[:3, :3] += error * E / np.linalg.norm(E)
    return T


def _candidates(rng):
    """Reference values of the specs below: plain ones, borderline ones and bad ones."""
    for _ in range(150):  # poses around the rotation tolerance, and far from it
        yield _pose(rng, float(ROTATION_TOL * rng.choice([0.0, 0.1, 0.5, 0.9, 1.0, 1.1, 2.0])
                               * (1 + rng.uniform(-1e-3, 1e-3))))
    for _ in range(20):  # poses on either side of the tolerance, to the last bit
        seed = int(rng.integers(1 << 30))
        low, high = 0.5 * ROTATION_TOL, 2 * ROTATION_TOL
        for _ in range(80):
            middle = 0.5 * (low + high)
            T = _pose(np.random.default_rng(seed), middle)
            low, high = (middle, high) if _rotation_error(T) < ROTATION_TOL else (low, middle)
        yield _pose(np.random.default_rng(seed), low)
        yield _pose(np.random.default_rng(seed), high)
    T = _pose(rng)
    for i, j in [(0, 0), (1, 2), (2, 3), (3, 0), (3, 3)]:
        for bad in (np.nan, np.inf, -np.inf, 1e301, 1e-300, 2.0):
            spoiled = T.copy()
            spoiled[i, j] = bad
            yield spoiled
    inverse = T.copy()
    inverse[:3, :3] = T[:3, :3].T
    yield inverse
    yield np.asfortranarray(T)
    yield T.astype(np.float32)
    yield T.astype(">f8")
    yield T.tolist()
    yield np.eye(4, dtype=int)
    yield np.eye(3)
    yield T.reshape(-1)
    yield np.tile(T, (2, 2))[::2, ::2]  # strided view
    yield from (rng.standard_normal(3), rng.standard_normal((3, 1)), rng.standard_normal((1, 3)),
                np.array([1.0, np.inf, 2.0]), np.array([1.0, np.nan, 2.0]),
                np.array([1e300, -1e300, 1.0]), np.array([1e308, 1e308, 1.0]),
                np.array(2.5), np.array([[2.5]]), np.array([2.5]), 2.5, "x", None,
                rng.standard_normal((2, 3)), np.asfortranarray(rng.standard_normal((2, 3))),
                rng.standard_normal((3, 2)).T)


SPECS = {  # keyword -> (at, rows, cols, allow_inf, pose)
    "pose": (2, 4, 4, False, True),
    "column": (20, 3, 1, False, False),
    "bound": (25, 3, 1, True, False),
    "scalar": (30, 1, 1, False, False),
    "matrix": (33, 2, 3, False, False),
}


def test_the_stage_accepts_only_what_python_accepts_and_writes_the_same_bits(stage):
    """On ≈ 1200 calls: whatever the stage accepts, Python's checks accept, and it writes
    their array bit for bit, nowhere else; what it does not accept leaves ``p`` as it was.
    Every plain value (a float64 array Python accepts, its rotation error not within 1e-12 of
    the tolerance) is accepted: the fast path is the common one."""
    rng = np.random.default_rng(0)
    values = list(_candidates(rng))
    accepted = plain = 0
    for value in values:
        for key, (at, rows, cols, allow_inf, pose) in SPECS.items():
            p = rng.standard_normal(50)
            before = p.copy()
            q = rng.standard_normal(2)
            ok = stage(p, q, None, (0, 2, -1, 2), {key: value}, SPECS)
            python = _python_accepts(value, (rows, cols), allow_inf, pose)
            if not ok:
                assert p.tobytes() == before.tobytes()
            else:
                accepted += 1
                assert python is not None, (key, value)
                expected = before.copy()
                expected[at:at + rows * cols] = python.reshape(-1, order="F")
                expected[:2] = q
                assert p.tobytes() == expected.tobytes()
            if (python is not None and type(value) is np.ndarray and value.dtype == np.float64
                    and value.dtype.isnative and np.all(np.abs(value) <= 1e300)
                    and (not pose or _rotation_error(python) < ROTATION_TOL - 1e-12)):
                plain += 1
                assert ok, (key, value)
    assert accepted >= plain > 80 and len(values) * len(SPECS) > 1000


@pytest.mark.parametrize("q, v, why", [
    (np.r_[np.full(6, 0.1), np.nan], None, "NaN"),
    (np.r_[np.full(6, 0.1), np.inf], None, "inf"),
    (np.full(6, 0.1), None, "shape"),
    (np.full((7, 1), 0.1), None, "column"),
    (np.full(7, 0.1), np.r_[np.zeros(6), np.nan], "v NaN"),
    (np.full(7, 0.1, dtype=np.float32), None, "float32"),
    ([0.1] * 7, None, "list"),
])
def test_the_stage_leaves_q_and_v_it_does_not_accept_to_python(stage, q, v, why):
    p = np.zeros(20)
    assert not stage(p, q, v, (3, 7, -1, 7), {}, {}) and not p.any(), why
    assert stage(p, np.full(7, 0.1), np.ones(7), (3, 7, 10, 7), {}, {})
    assert p.tolist() == [0.0] * 3 + [0.1] * 7 + [1.0] * 7 + [0.0] * 3


def test_a_keyword_the_stage_has_no_spec_for_is_python_s(stage):
    p = np.zeros(10)
    assert not stage(p, np.zeros(2), None, (0, 2, -1, 2), {"other": np.zeros(3)},
                     {"known": (2, 3, 1, False, False)})
    assert stage(p, np.ones(2), None, (0, 2, -1, 2), {"known": np.ones(3)},
                 {"known": (2, 3, 1, False, False)})
    assert p.tolist() == [1.0] * 5 + [0.0] * 5


@pytest.fixture(scope="module")
def ticking(robot):
    """A fused Panda controller after a few ticks, and the pose it tracks."""
    controller = panda(robot)
    assert controller.fused and controller._hot.stage is not controller_module._python_path
    q = Q0 + 0.1
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += 0.05
    for _ in range(3):
        q = q + DT * controller.step(q, ee=target)
    return controller, q, target


def _spoiled(target, i, j, value):
    T = target.copy()
    T[i, j] = value
    return T


REFUSED = [  # (q, references, error, message)
    ("nan", {}, wbc.NonFiniteError, "q contains NaN"),
    ("short", {}, wbc.ShapeError, r"q must have shape \(7,\)"),
    ("column", {}, wbc.ShapeError, r"q must have shape \(7,\)"),
    ("text", {}, wbc.InvalidValueError, "q must be numbers"),
    ("ok", {"ee": "nan-translation"}, wbc.NonFiniteError, "reference 'ee'.* NaN"),
    ("ok", {"ee": "nan-rotation"}, wbc.NonFiniteError, "reference 'ee'.* NaN"),
    ("ok", {"ee": "inf"}, wbc.NonFiniteError, "reference 'ee'.* inf"),
    ("ok", {"ee": "scaled"}, wbc.InvalidValueError, "not a homogeneous transform"),
    ("ok", {"ee": "last-row"}, wbc.InvalidValueError, "not a homogeneous transform"),
    ("ok", {"ee": "3x3"}, wbc.ShapeError, r"reference 'ee'.*expects shape \(4, 4\)"),
    ("ok", {"ee": "flat"}, wbc.ShapeError, r"reference 'ee'.*expects shape \(4, 4\)"),
    ("ok", {"ee": "text"}, wbc.InvalidValueError, "reference 'ee'.*must be numbers"),
    ("ok", {"ee": "symbol"}, wbc.InvalidValueError, "CasADi SX expression"),
    ("ok", {"ee": "none"}, wbc.InvalidValueError, "reference 'ee'.*must be numbers"),
    ("ok", {"posture": "nan"}, wbc.NonFiniteError, "reference 'posture'"),
    ("ok", {"nosuch": "ok"}, wbc.UnknownNameError, "unknown reference 'nosuch'"),
    ("nan", {"ee": "nan-rotation"}, wbc.NonFiniteError, "q contains NaN"),  # q's first
]


def _values(name, q, target):
    """The named inputs of ``REFUSED``."""
    return {
        "ok": q, "nan": np.r_[q[:6], np.nan], "short": q[:6], "column": q.reshape(7, 1),
        "text": "q", "nan-translation": _spoiled(target, 1, 3, np.nan),
        "nan-rotation": _spoiled(target, 0, 1, np.nan), "inf": _spoiled(target, 2, 3, np.inf),
        "scaled": np.diag([1.01, 1.0, 1.0, 1.0]) @ target,
        "last-row": _spoiled(target, 3, 0, 1e-9), "3x3": target[:3, :3].copy(),
        "flat": target.reshape(-1).copy(), "none": None, "symbol": ca.SX.sym("T", 4, 4),
    }[name]


@pytest.mark.parametrize("q_name, references, error, message", REFUSED,
                         ids=[f"{q}-{'-'.join(f'{k}={v}' for k, v in r.items())}"
                              for q, r, *_ in REFUSED])
def test_a_refused_step_writes_nothing(ticking, q_name, references, error, message):
    """Parameters, "never set" bookkeeping, last command and solution, the fused call's
    buffers and timings: all as before a refused step, which solved nothing; the next good
    tick gives the command it would have given."""
    controller, q, target = ticking
    workspace = controller.workspace
    controller.step(q, ee=target)
    live = workspace.fused_solution
    p, x, solve_time = workspace.p.tobytes(), live.x.tobytes(), live.timings.solve
    solution, command = controller._last_solution, controller.last_command
    assert solution is live  # not copied yet: its buffers are what a refused tick must spare
    unset, fallbacks = set(workspace._unset), workspace.fallback_solves
    moved = _spoiled(target, 0, 3, target[0, 3] + 0.01)
    values = {key: moved if value == "ok" and key == "ee" else _values(value, q, target)
              for key, value in references.items()}
    good = {"ee": moved, "posture": q + 0.01}
    later = {key: value for key, value in good.items() if key not in values}
    for call in (values, {**good, **values}, {**values, **later}):  # bad alone, last, first
        with pytest.raises(error, match=message):
            controller.step(_values(q_name, q, target), **call)
        assert workspace.p.tobytes() == p and live.x.tobytes() == x
        assert live.timings.solve == solve_time and workspace.fallback_solves == fallbacks
        assert controller._last_solution is solution and controller.last_command is command
        assert workspace._unset == unset
    np.testing.assert_array_equal(controller.step(q), command)  # the old references hold


def test_a_valid_tick_makes_no_python_check(ticking, monkeypatch):
    """Once a keyword has been seen, a tick with a float64 ``q`` and pose runs no Python
    check (the stage took them); one it does not accept does."""
    controller, q, target = ticking
    calls = []
    python_path = controller._check_and_write
    monkeypatch.setattr(controller, "_check_and_write",
                        lambda *args: calls.append(args) or python_path(*args))
    controller.step(q, ee=target)
    controller.step(q + 0.01, ee=target, posture=q)
    controller.step(q)
    assert calls == []
    controller.step(list(q), ee=target)  # lists: Python converts them
    controller.step(q, ee=target.tolist())
    assert len(calls) == 2


def test_the_stage_and_python_give_the_same_bits(robot):
    """A closed loop of 300 ticks — the pose every tick but every third, a new posture now and
    then, random kicks — on the C stage and on Python's path: the same commands and
    parameters, bit for bit. A controller that compiles no C (``fused=False, jit=False``) uses
    Python's path."""
    assert panda(robot, fused=False, jit=False)._hot.stage is controller_module._python_path
    fast, slow = panda(robot), panda(robot)
    slow._hot = slow._hot._replace(stage=controller_module._python_path)
    rng = np.random.default_rng(3)
    goals = []
    for _ in range(3):
        goal = _pose(rng)
        goal[:3, 3] = robot.frame_pose(Q0, "ee")[:3, 3] + rng.uniform(-0.1, 0.1, 3)
        goals.append(goal)
    q_fast = q_slow = Q0 + 0.1
    for k in range(300):
        references = {} if k % 3 == 1 else {"ee": goals[(k // 100) % 3]}
        if k % 50 == 7:
            references["posture"] = Q0 + rng.uniform(-0.2, 0.2, robot.nq)
        kick = rng.normal(0, 0.1, robot.nq) if k % 40 == 0 else 0.0
        v_fast, v_slow = fast.step(q_fast, **references), slow.step(q_slow, **references)
        assert v_fast.tobytes() == v_slow.tobytes(), k
        assert fast.workspace.p.tobytes() == slow.workspace.p.tobytes(), k
        q_fast, q_slow = q_fast + DT * v_fast + kick, q_slow + DT * v_slow + kick
    assert fast.workspace.fallback_solves == slow.workspace.fallback_solves


def test_without_a_compiler_the_stage_is_python_s(monkeypatch):
    monkeypatch.setenv("CC", "no-such-compiler-wbc")
    assert controller_module._c_stage("no-such-compiler-wbc") is controller_module._python_path
