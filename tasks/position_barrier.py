"""`PositionBarrier`: a control-barrier function keeping a frame's position inside a box.

Pink's barriers (pink 4.4, ``pink/barriers/barrier.py``) at the velocity level. A barrier is a
vector function ``h(q)`` whose safe set is ``h >= 0``; the hard constraint, per row ``j``, is
the discrete control-barrier condition

    J_h v  >=  −γ_j · α(h_j(q))                     (i.e. ḣ >= −γ α(h))

with ``J_h = ∂h/∂q`` per unit of ``v``, ``γ`` the barrier gain [1/s] and ``α`` an extended
class-K function (the identity here). Pink writes it over ``Δq = v T`` as ``G Δq <= h`` with
``G = −J_h / T`` and ``h = γ α(h(q))``: the same set of ``v``, so no ``dt`` appears here.

Pink also adds, when its ``safe_displacement_gain`` ``r > 1e-6``, the cost
``r / (2 ‖J_h‖²) · ‖Δq − Δq_safe‖²`` (``‖·‖`` the Frobenius norm; after
arXiv:2404.12329), with ``Δq_safe = 0`` for its position and body-spherical barriers. Divided by
``T²`` as every pink cost is in wbc (docs: ``weight = cost²``, QP over ``v``), that is
``1/2 · r / ‖J_h‖² · ‖v‖²``: :meth:`Barrier.safe_displacement` returns it as a task to add
with ``stack.add``, while the barrier itself goes to ``stack.constrain`` (a wbc stack keeps
hard rows and costs apart). ``‖J_h‖²`` is clipped below at ``1e-12`` (pink divides by zero
there).

``PositionBarrier``: ``h = [p_I − p_min; p_max − p_I]`` for the frame origin's world position
``p`` on the axes ``I`` (``indices``), each side only if given, and ``J_h = [J_I; −J_I]`` with
``J_I`` the rows ``I`` of the frame's world-aligned linear Jacobian (``"J[<frame>]"``).
Units: positions [m], ``γ`` [1/s], ``r`` [-] (pink's unit, that of a cost²).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from wbc.checks import (
    as_float_array,
    check_frame,
    check_robot,
    checked_integer,
    checked_name,
    checked_number,
    checked_vector,
)
from wbc.errors import InvalidValueError, ShapeError
from wbc.terms import Cost, Inequality, Task

from .frame import velocity_block

__all__ = ["Barrier", "PositionBarrier", "SafeDisplacement"]

#: ``‖J_h‖²`` below this [unit of J²] is clipped in the safe-displacement weight
JACOBIAN_FLOOR = 1e-12


class Barrier(Task):
    """Base of the control-barrier constraints (module docstring): a subclass sets ``nv``,
    ``rows``, ``gain`` (one per row), ``safe_displacement_gain``, ``name``, ``block`` and
    implements :meth:`barrier` and, if not the identity, :meth:`class_k`."""

    nv: int
    rows: int
    gain: np.ndarray
    safe_displacement_gain: float
    block: str | None = None

    def _init_gains(self, gain, safe_displacement_gain, what: str, tile: int = 0) -> None:
        # numbers first: np.ndim of a ragged list or a str would raise numpy's own errors
        array = as_float_array(gain, f"gain [1/s] of {what}")
        if array.ndim == 0:
            gain = checked_number(gain, f"gain [1/s] of {what}", 0.0, strict=True)
        elif tile and array.shape == (tile,) and self.rows == 2 * tile:
            gain = np.tile(array, 2)  # as pink does
        self.gain = checked_vector(gain, self.rows, f"gain [1/s] of {what}")
        if (self.gain <= 0).any():
            raise InvalidValueError(f"gain [1/s] of {what} must be > 0, got {self.gain}")
        self.safe_displacement_gain = checked_number(
            safe_displacement_gain, f"safe_displacement_gain of {what}")

    def barrier(self, stack) -> tuple[ca.SX, ca.SX]:
        """``(h, J_h)``: the barrier values (rows,) and their Jacobian (rows, nv), as SX of the
        stack's quantities and parameters."""
        raise NotImplementedError

    def jacobian(self, stack) -> ca.SX:
        """``J_h`` alone (needs no parameter: what :class:`SafeDisplacement` uses)."""
        return self.barrier(stack)[1]

    def class_k(self, h):
        """The extended class-K function ``α`` (identity)."""
        return h

    def terms(self, stack):
        v = velocity_block(stack, self.block, self.nv, f"{type(self).__name__} {self.name!r}")
        h, J_h = self.barrier(stack)
        lower = -ca.DM(self.gain) * self.class_k(h)
        return [Inequality(J_h @ v, lower, np.inf, self.name)]

    def safe_displacement(self, name: str | None = None) -> SafeDisplacement:
        """Pink's safe-displacement cost ``1/2 · r / ‖J_h‖² · ‖v‖²`` as a task for
        ``stack.add`` (module docstring); ``r`` is ``safe_displacement_gain``."""
        return SafeDisplacement(self, name)


class SafeDisplacement(Task):
    """The safe-displacement regularisation of a :class:`Barrier` (its
    :meth:`~Barrier.safe_displacement`): ``1/2 · r / max(‖J_h‖², 1e-12) · ‖v‖²``.

    Args:
        barrier: the barrier (its ``J_h``, ``safe_displacement_gain`` ``r > 0``, ``block``).
        name: task name.
    """

    def __init__(self, barrier: Barrier, name: str | None = None) -> None:
        if not isinstance(barrier, Barrier):
            raise InvalidValueError(f"SafeDisplacement needs a barrier, got "
                                    f"{type(barrier).__name__}")
        if barrier.safe_displacement_gain <= 0:
            raise InvalidValueError(f"the safe_displacement_gain of barrier {barrier.name!r} "
                                    "is 0: there is no safe-displacement cost to add")
        self.barrier = barrier
        self.name = checked_name(name, "name of SafeDisplacement")

    def terms(self, stack):
        b = self.barrier
        v = velocity_block(stack, b.block, b.nv, f"SafeDisplacement {self.name!r}")
        norm2 = ca.fmax(ca.sumsqr(b.jacobian(stack)), JACOBIAN_FLOOR)
        return [Cost(v, 0.0, b.safe_displacement_gain / norm2, self.name)]


def _checked_side(value, size: int, what: str) -> np.ndarray | None:
    return None if value is None else checked_vector(value, size, what, allow_inf=True)


class PositionBarrier(Barrier):
    """Keep a frame's origin inside the box ``p_min <= p_I <= p_max`` (world axes ``I``), a
    hard control-barrier constraint (module docstring); add it with ``stack.constrain``.

    Relation to pink: ``pink.barriers.PositionBarrier(frame, indices, p_min, p_max, gain,
    safe_displacement_gain=r)`` is this barrier (constrained) plus, if ``r > 0``,
    ``barrier.safe_displacement()`` (added); pink's costs elsewhere map as ``weight = cost²``.

    Args:
        robot: the robot (``nv``, frame names).
        frame: the frame whose origin is kept in the box (e.g. ``"ee"``).
        p_min, p_max: the box's sides [m] on the axes ``indices``, ``None`` for none (at least
            one given; ``±inf`` entries leave an axis free). Defaults of the parameters
            ``"<name>.p_min"`` / ``"<name>.p_max"``, settable per tick
            (``controller.step(q, **{"box.p_max": ...})``).
        indices: world axes constrained, among 0, 1, 2 (x, y, z); default all three.
        gain: barrier gain ``γ > 0`` [1/s], scalar or one per row (rows: the ``p_min`` rows
            first, then the ``p_max`` ones); with both sides, one per axis is used for both,
            as pink does.
        safe_displacement_gain: pink's ``r >= 0`` (default 0: no cost), see
            :meth:`~Barrier.safe_displacement`.
        name: task name. block: the joint-velocity block of the decision vector.

    Quantities it declares: ``"pose[<frame>]"``, ``"J[<frame>]"``.
    """

    def __init__(self, robot, frame: str, p_min=None, p_max=None, indices=None,
                 gain=1.0, safe_displacement_gain: float = 0.0, name: str | None = None,
                 block: str | None = None) -> None:
        what = f"PositionBarrier {name!r}"
        self.nv = check_robot(robot, f"robot of {what}")[1]
        self.frame = checked_name(frame, f"frame of {what}", optional=False)
        check_frame(robot, frame, what)
        indices = [0, 1, 2] if indices is None else indices
        if isinstance(indices, (str, bytes)) or not hasattr(indices, "__len__"):
            raise InvalidValueError(f"indices of {what} must be a list of axes 0..2, got "
                                    f"{indices!r}")
        self.indices = [checked_integer(i, f"indices of {what}", 0, 2) for i in indices]
        if not self.indices or len(set(self.indices)) != len(self.indices):
            raise ShapeError(f"indices of {what} must be distinct axes 0..2, got {indices!r}")
        k = len(self.indices)
        self.p_min = _checked_side(p_min, k, f"p_min [m] of {what}")
        self.p_max = _checked_side(p_max, k, f"p_max [m] of {what}")
        if self.p_min is None and self.p_max is None:
            raise InvalidValueError(f"{what}: give p_min, p_max or both")
        if ((self.p_min is not None and (self.p_min == np.inf).any())
                or (self.p_max is not None and (self.p_max == -np.inf).any())):
            raise InvalidValueError(f"{what}: p_min = +inf or p_max = -inf leaves no safe set")
        if (self.p_min is not None and self.p_max is not None
                and (self.p_min > self.p_max).any()):
            raise InvalidValueError(f"{what}: p_min > p_max ({self.p_min} > {self.p_max})")
        self.rows = k * ((self.p_min is not None) + (self.p_max is not None))
        self._init_gains(gain, safe_displacement_gain, what, tile=k)
        self.name = checked_name(name, f"name of {what}")
        self.block = checked_name(block, f"block of {what}")

    def _position_rows(self, stack) -> tuple[ca.SX, ca.SX]:
        pose = stack.quantity(f"pose[{self.frame}]", (4, 4))
        J = stack.quantity(f"J[{self.frame}]", (6, self.nv))
        p = ca.vertcat(*[pose[i, 3] for i in self.indices])
        J_p = ca.vertcat(*[J[i, :] for i in self.indices])
        return p, J_p

    def barrier(self, stack):
        p, J_p = self._position_rows(stack)
        k = len(self.indices)
        values, rows = [], []
        if self.p_min is not None:
            p_min = stack.parameter(f"{self.name}.p_min", k, self.p_min, allow_inf=True)
            values.append(p - p_min)
            rows.append(J_p)
        if self.p_max is not None:
            p_max = stack.parameter(f"{self.name}.p_max", k, self.p_max, allow_inf=True)
            values.append(p_max - p)
            rows.append(-J_p)
        return ca.vertcat(*values), ca.vertcat(*rows)

    def jacobian(self, stack):
        _, J_p = self._position_rows(stack)
        sides = [J_p] * (self.p_min is not None) + [-J_p] * (self.p_max is not None)
        return ca.vertcat(*sides)

    def __repr__(self) -> str:
        return (f"PositionBarrier(frame={self.frame!r}, indices={self.indices}, "
                f"p_min={self.p_min}, p_max={self.p_max}, name={self.name!r})")
