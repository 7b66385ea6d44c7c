"""`CollisionAvoidance`: keep collision pairs apart, as hard velocity-damper inequalities.

For each of the ``k = max_pairs`` closest pairs of a collision model (signed distance ``d_i``
[m], distance-rate row ``J_i`` with ``ḋ_i = J_i v``), the velocity damper of Faverjon & Tournassoud
bounds how fast the gap may close::

    ḋ_i >= −gain · (d_i − d_min) / dt        i.e.        −J_i v <= gain · (d_i − d_min) / dt

so that, to first order, one tick closes at most the fraction ``gain`` of what is left above
``d_min`` (``gain = 1``: the pair may reach ``d_min`` in one tick; the distance then approaches
``d_min`` geometrically, never crossing it while the linearisation holds). A pair already closer
than ``d_min`` must separate at ``gain · (d_min − d_i) / dt``. Add it with ``stack.constrain``:
it is hard at every level (``stack.add`` makes it a soft, slack-minimising inequality).

The rows come from two model quantities the collision model registers on the robot,
``"collision_distance[<name>]"`` ``(k, 1)`` and ``"collision_jacobian[<name>]"`` ``(k, nv)``
(see :mod:`wbc.robots.collision`), filled numerically every tick; the stack always has ``k``
rows, so it compiles once, and rows beyond the model's number of pairs are inert
(``d = 10³ m``, ``J = 0``).

Peers. pink's ``SelfCollisionBarrier`` (pin-pink 4.4) is the same row with a continuous-time
gain: ``−J Δq / dt <= γ (d − d_min)`` over ``Δq = v·dt``, i.e. ``γ = gain / dt`` [1/s], on the
same pinocchio/coal distances — robot-versus-obstacle pairs too, when the obstacles are in its
geometry model. Differences: it adds by default a "safe displacement" cost
``r / (2‖J‖²) ‖Δq‖²`` (r = 1) that this task does not; it zeroes a row whose witness points
coincide to ``np.allclose`` (≈ 5 µm), and keeps its rows while ``q`` stays ``np.allclose``
(rtol 1e-5) to the last one it saw, so near rest it can use an earlier tick's rows; and its
normal ``(p_a − p_b)/‖p_a − p_b‖`` reverses when the bodies overlap, so its row is then ``−ḋ``
and the barrier pushes deeper (checked against this row on penetrating Panda states), where
coal's signed normal (used here) keeps ``J_i v = ḋ_i`` on both sides of contact.
With gain and pairs matched and a fresh barrier each tick, both give the same commands and
closed loops (``tests/test_collision.py``). mink's ``CollisionAvoidanceLimit`` (mink 1.3) is the
velocity damper over MuJoCo geoms, but: its QP is over ``Δq = v·dt`` while its bound is
``gain (d − d_min) / dt``, so a tick may close ``gain / dt`` of the gap — mink's gain is this
task's ``gain / dt`` (with ``gain = 0.3``, dt = 0.01 s, read per step as its docstring says, the
Panda's hand went 3.2 mm through ``d_min``; with ``0.3 · dt`` both loops end at the same pose);
one row for every pair (no selection of the closest); ``+∞`` (inert) beyond a detection
distance; below ``d_min`` the bound is a fixed relaxation (0 by default: no further approach)
instead of a demand to separate at ``gain · (d_min − d) / dt``; and pairs whose bodies are
welded together or parent and child of a weld are left out.

Units: ``d_min`` [m], ``gain`` [-] (0 < gain <= 1), ``dt`` [s] (the controller's period).
"""

from __future__ import annotations

from wbc.checks import check_robot, checked_integer, checked_name, checked_number
from wbc.errors import InvalidValueError
from wbc.terms import Inequality, Task

from .frame import velocity_block


class CollisionAvoidance(Task):
    """Hard velocity-damper rows keeping the closest collision pairs above ``d_min`` (see the
    module docstring).

    Args:
        robot: the robot (``nv``); the one the collision model was built on and the
            :class:`~wbc.Controller` runs.
        pairs: the collision model: a :class:`wbc.robots.collision.CollisionModel` of ``robot``
            (anything with ``robot``, ``n_pairs`` and ``register(key, k) -> (distance name,
            jacobian name)``).
        d_min: the smallest distance allowed [m], ``>= 0``.
        gain: fraction of the gap above ``d_min`` one tick may close, ``0 < gain <= 1``.
        max_pairs: number of rows ``k >= 1``: the ``k`` closest pairs each tick.
        name: task name (default: the stack names it); the quantities are named after it.
        block: the joint-velocity block of the decision vector (``None``: all of it).

    Quantities it declares: ``"collision_distance[<name>]"`` (k, 1),
    ``"collision_jacobian[<name>]"`` (k, nv), ``"dt"`` (1,).
    """

    def __init__(self, robot, pairs, d_min: float = 0.01, gain: float = 0.5,
                 max_pairs: int = 4, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"CollisionAvoidance {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        if not all(hasattr(pairs, a) for a in ("robot", "n_pairs", "register")):
            raise InvalidValueError(f"pairs of {what} must be a collision model "
                                    "(wbc.robots.collision.CollisionModel(robot, ...)), got "
                                    f"{type(pairs).__name__}")
        if pairs.robot is not robot:
            raise InvalidValueError(f"pairs of {what} were built on another robot object; "
                                    "build the CollisionModel on the robot the task and the "
                                    "controller use")
        self.pairs = pairs
        self.d_min = checked_number(d_min, f"d_min of {what}")
        self.gain = checked_number(gain, f"gain of {what}", 0.0, strict=True, high=1.0)
        self.max_pairs = checked_integer(max_pairs, f"max_pairs of {what}", low=1)
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def terms(self, stack):
        what = f"CollisionAvoidance {self.name!r}"
        v = velocity_block(stack, self.block, self.nv, what)
        assert self.name is not None  # the stack names a task before asking for its terms
        distance_name, jacobian_name = self.pairs.register(self.name, self.max_pairs)
        k = self.max_pairs
        d = stack.quantity(distance_name, k)
        J = stack.quantity(jacobian_name, (k, self.nv))
        dt = stack.quantity("dt", 1)
        return [Inequality(-(J @ v), upper=self.gain * (d - self.d_min) / dt, name=self.name)]

    def __repr__(self) -> str:
        return (f"CollisionAvoidance(pairs={self.pairs!r}, d_min={self.d_min}, "
                f"gain={self.gain}, max_pairs={self.max_pairs}, name={self.name!r})")
