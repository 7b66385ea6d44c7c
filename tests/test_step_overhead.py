"""``Controller.step``'s inputs in one C call (the stage, :data:`wbc.checks.STAGE_SOURCE`): it
accepts only what Python's checks accept and writes the same bits, a refusal — NaN, inf, a wrong
shape, a wrong type, a pose that is no rotation, an unknown keyword — is raised by Python's
checks before anything is written (parameters, last command and solution, the fused call's
buffers), and a valid tick makes no Python check at all."""

from __future__ import annotations

import math
import weakref

import casadi as ca
import numpy as np
import pytest

import wbc
from wbc import controller as controller_module
from wbc.cbuild import compiler_available
from wbc.checks import ROTATION_TOL, check_pose, checked_array
from wbc.fused import stage_extension
from wbc.robots.fixed_base import load_panda
from wbc.solution import Timings
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
def extension():
    module = stage_extension("cc")
    assert module is not None  # built and loaded here
    assert controller_module._c_stage("cc") is module.tick
    return module


@pytest.fixture(scope="module")
def stage(extension):
    return extension.stage


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
    assert controller.fused and controller._hot.tick is not controller_module._python_path
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
    p, x, times = workspace.p.tobytes(), live.x.tobytes(), live.timings
    timed = (times.model, times.solve)
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
        assert (times.model, times.solve) == timed and workspace.fallback_solves == fallbacks
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
    assert panda(robot, fused=False, jit=False)._hot.tick is controller_module._python_path
    # jit resolved once: "auto" compiles C exactly where a compiler is found
    assert panda(robot, fused=False, jit=False).jit_c is False
    assert panda(robot, fused=False, jit=True).jit_c is True
    assert panda(robot, fused=False).jit_c is compiler_available()
    fast, slow = panda(robot), panda(robot)
    slow._hot = slow._hot._replace(tick=controller_module._python_path)
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


def _states(robot, rng, count: int):
    """``count`` random ``(q, references)`` of the Panda problem: a pose near the hand every
    tick but every third, a new posture now and then, and one state in seven with joint 4
    beyond its upper limit (the position and velocity limits cross: the fused call fails,
    the ordinary path reports the infeasibility)."""
    limits = robot.limits
    for k in range(count):
        q = rng.uniform(limits.q_lower, limits.q_upper)
        if k % 7 == 3:
            q[3] = limits.q_upper[3] + 0.5
        references = {}
        if k % 3 != 1:
            goal = _pose(rng)
            goal[:3, 3] = robot.frame_pose(q, "ee")[:3, 3] + rng.uniform(-0.1, 0.1, 3)
            references["ee"] = goal
        if k % 11 == 5:
            references["posture"] = rng.uniform(limits.q_lower, limits.q_upper)
        yield q, references


def test_the_c_tick_gives_the_python_tick_s_outputs_bit_for_bit(robot):
    """On 200 random states (failed fused calls among them): the tick made in C (stage, call,
    copy) against the same controller whose fused call is made by the workspace's Python
    closure (``call=None``: the tick before the C call existed): the same commands, solutions,
    statuses, messages, conflicts and fallback counts, bit for bit; every tick timed."""
    fast, slow = panda(robot), panda(robot)
    assert fast._hot.call is fast.workspace.c_call is not None
    slow._hot = slow._hot._replace(call=None)
    answered_in_c = 0
    for k, (q, references) in enumerate(_states(robot, np.random.default_rng(5), 200)):
        before = fast.workspace.fallback_solves
        v_fast, v_slow = fast.step(q, **references), slow.step(q, **references)
        answered_in_c += fast.workspace.fallback_solves == before and k > 0 and (
            fast._last_solution is fast.workspace.fused_solution)
        assert v_fast.tobytes() == v_slow.tobytes(), k
        a, b = fast.last_solution, slow.last_solution
        assert a.x.tobytes() == b.x.tobytes() and a.status is b.status, k
        assert (a.message, a.conflict, a.fallback) == (b.message, b.conflict, b.fallback), k
        assert a.timings.model > 0 and a.timings.solve > 0, k
        assert fast.workspace.p.tobytes() == slow.workspace.p.tobytes(), k
    assert fast.workspace.fallback_solves == slow.workspace.fallback_solves > 20
    assert fast.workspace.skipped_solves == slow.workspace.skipped_solves
    assert answered_in_c > 100  # most ticks: no Python between the stage and the command


def test_what_a_tick_returns_survives_the_next_tick(robot):
    """The command (a new array, or ``out``), ``last_solution`` and its timings, read after a
    tick the C call answered, keep their values through the next ticks; the fused solution's
    timings are the tick's clock readings, copied into a plain :class:`~wbc.solution.Timings`
    by the snapshot."""
    controller = panda(robot)
    rng = np.random.default_rng(9)
    states = list(_states(robot, rng, 40))
    controller.step(states[0][0], **states[0][1])  # arms the C call
    kept = []
    for q, references in states:
        command = controller.step(q, **references)
        assert controller.last_command is command
        solution = controller.last_solution
        assert type(solution.timings) is Timings
        kept.append((command, command.copy(), solution, solution.x.copy(),
                     solution.timings.model, solution.timings.solve, solution.status))
    assert len({id(entry[0]) for entry in kept}) == len(kept)  # a new array every tick
    for command, values, solution, x, model, solve, status in kept:
        assert command.tobytes() == values.tobytes() and solution.x.tobytes() == x.tobytes()
        assert (solution.timings.model, solution.timings.solve) == (model, solve)
        assert solution.status is status and model > 0 and solve > 0
    out = np.full(2 * robot.nv, np.nan)[::2]  # a strided out: written in place
    q, references = states[0]
    expected = controller.step(q, **references)
    assert controller.step(q, out=out, **references) is out and controller.last_command is out
    assert out.tobytes() == expected.tobytes()


@pytest.mark.parametrize("out", [np.zeros(6), np.zeros(7, np.float32), np.zeros((7, 1)),
                                 [0.0] * 7], ids=["short", "float32", "column", "list"])
def test_a_bad_out_is_refused_before_anything_is_written(ticking, out):
    controller, q, target = ticking
    workspace = controller.workspace
    controller.step(q, ee=target)
    p, times = workspace.p.tobytes(), workspace.times[2:].tobytes()
    command = controller.last_command
    with pytest.raises(wbc.ShapeError, match="out must be a float numpy array"):
        controller.step(q + 0.01, out=out, ee=_spoiled(target, 0, 3, target[0, 3] + 0.01))
    assert workspace.p.tobytes() == p and workspace.times[2:].tobytes() == times
    assert controller.last_command is command


def test_a_command_someone_can_still_see_is_never_reused(robot):
    """The C tick reuses a command array only when nothing else references it: a command seen
    through a view, a weak reference, or reshaped in place by its holder keeps its values
    (and shape) through the next ticks, while each tick still returns its own command."""
    controller = panda(robot)
    states = list(_states(robot, np.random.default_rng(13), 30))
    controller.step(states[0][0], **states[0][1])
    watched = []
    for k, (q, references) in enumerate(states):
        command = controller.step(q, **references)
        expected = command.copy()
        if k % 3 == 0:
            watched.append((command[:4], expected[:4]))  # a view keeps its base
        elif k % 3 == 1:
            watched.append((weakref.ref(command), expected))
        else:
            command.shape = (1, robot.nv)  # in place: no longer what a tick returns
            watched.append((command, expected.reshape(1, -1)))
        del command
        for seen, values in watched:
            seen = seen() if isinstance(seen, weakref.ref) else seen
            assert seen is None or seen.tobytes() == values.tobytes(), k
            assert seen is None or seen.shape == values.shape, k
