"""Model quantities: what a robot can compute each tick, offered to the controller by name.

A *model quantity* is a number a task needs from the robot model at the current state — a frame
pose, a Jacobian, a drift ``J̇v``, the centre of mass, a manipulability gradient, wheel normal
forces. Tasks declare them with :meth:`wbc.Stack.quantity` (or, for compatibility, as plain
parameters whose names the robot recognises); the :class:`~wbc.Controller` fills them from the
robot's :class:`QuantityRegistry` every tick. The core never knows which quantities exist: a
robot registers what it offers, so a new kind of quantity needs no change to the controller.

Names are ``"<kind>"`` (e.g. ``"com"``) or ``"<kind>[<argument>]"`` (e.g. ``"pose[ee]"``, the
argument usually a frame). Every quantity has

* a **shape** ``(rows, cols)``, derived from the robot (``J[ee]`` is ``(6, nv)``);
* a **numeric filler** ``fill(out)`` writing the value at the robot's last
  ``update(q, v)`` into ``out`` (an array of that shape, possibly a column-major view into a
  compiled stack's parameter vector: fillers must write element-wise, never rebind);
* optionally a **symbolic form**: a CasADi ``Function`` of ``q`` — or of ``(q, v)`` when
  :attr:`Quantity.needs_v` — giving the same value, which ``kinematics="compiled"`` inlines into
  the compiled level functions (no robot call on the tick).

The controller's own state quantities ``"q"``, ``"v"`` and ``"dt"`` are not in any registry: the
controller writes them itself.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .errors import UnknownNameError, WbcError

STATE_QUANTITIES = ("q", "v", "dt")
"""Quantities the controller fills from its own state, for every robot."""

_NAME = re.compile(r"^(?P<kind>[A-Za-z_][A-Za-z0-9_]*)(?:\[(?P<argument>.+)\])?$")


@dataclass(frozen=True)
class Quantity:
    """One model quantity of one robot, resolved (see the module docstring).

    Attributes:
        name: the full name, e.g. ``"J[ee]"``.
        shape: ``(rows, cols)``.
        fill: ``fill(out)`` writes the value at the robot's last update into ``out``.
        needs_v: the value depends on the velocity ``v`` (the update must be given ``v``; the
            symbolic form takes ``(q, v)``).
        symbolic: ``symbolic()`` builds the CasADi function (``q -> value`` or ``(q, v) ->
            value``), or ``None`` when the robot has no symbolic form of it.
        doc: what it is, with units.
    """

    name: str
    shape: tuple[int, int]
    fill: Callable[[np.ndarray], None]
    needs_v: bool = False
    symbolic: Callable[[], ca.Function] | None = None
    doc: str = ""


@dataclass(frozen=True)
class _Kind:
    shape: Callable[[str | None], tuple[int, int]]
    fill: Callable[[str | None, np.ndarray], None]
    needs_v: bool
    symbolic: Callable[[str | None], ca.Function] | None
    argument: str | None
    arguments: Callable[[], list[str]] | None
    doc: str


class QuantityRegistry:
    """The quantities a robot offers, by kind.

    Example (what a robot does in its constructor)::

        registry = QuantityRegistry()
        registry.register("com", shape=lambda _: (3, 1), fill=lambda _, out: robot.com(None, out),
                          doc="centre of mass [m], world")
        registry.register("J", argument="frame", arguments=lambda: robot.frame_names,
                          shape=lambda frame: (6, robot.nv),
                          fill=lambda frame, out: robot.frame_jacobian(None, frame, out=out),
                          symbolic=lambda frame: jacobian_function(frame))
        registry.get("J[ee]").shape      # (6, nv)
    """

    def __init__(self) -> None:
        self._kinds: dict[str, _Kind] = {}

    def register(self, kind: str, *, shape: Callable[[str | None], tuple[int, int]],
                 fill: Callable[[str | None, np.ndarray], None], needs_v: bool = False,
                 symbolic: Callable[[str | None], ca.Function] | None = None,
                 argument: str | None = None, arguments: Callable[[], list[str]] | None = None,
                 doc: str = "") -> None:
        """Offer quantities of ``kind``.

        Args:
            kind: the name before ``[...]``; an identifier. Registering a kind again replaces it.
            shape: ``shape(argument) -> (rows, cols)``.
            fill: ``fill(argument, out)`` writes the value at the last update into ``out``.
            needs_v: see :attr:`Quantity.needs_v`.
            symbolic: ``symbolic(argument) -> casadi.Function``, or ``None``.
            argument: what the bracketed argument names (e.g. ``"frame"``); ``None`` for a kind
                without argument (``"com"``).
            arguments: the valid arguments, for early errors and :meth:`offered` (``None``:
                any argument is tried and ``shape``/``fill`` raise for bad ones).
            doc: what it is, with units.
        """
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", kind) or kind in STATE_QUANTITIES:
            raise WbcError(f"bad quantity kind {kind!r}: an identifier other than "
                           f"{list(STATE_QUANTITIES)}")
        self._kinds[kind] = _Kind(shape, fill, bool(needs_v), symbolic, argument, arguments, doc)

    def offered(self) -> list[str]:
        """Name patterns of what is offered, e.g. ``["pose[<frame>]", "com"]``."""
        return [f"{k}[<{d.argument}>]" if d.argument else k for k, d in self._kinds.items()]

    def resolve(self, name: str) -> Quantity | None:
        """The quantity called ``name``, or ``None`` if ``name`` is not of a registered kind.

        Raises:
            UnknownNameError: the kind is registered but the argument is missing, superfluous or
                not among the valid ones (the message lists them).
        """
        match = _NAME.match(name)
        if match is None or match["kind"] not in self._kinds:
            return None
        kind, argument = match["kind"], match["argument"]
        spec = self._kinds[kind]
        if (argument is None) != (spec.argument is None):
            form = f"{kind}[<{spec.argument}>]" if spec.argument else kind
            raise UnknownNameError(f"quantity {name!r}: write it {form!r}")
        if argument is not None and spec.arguments is not None:
            valid = spec.arguments()
            if argument not in valid:
                raise UnknownNameError(f"quantity {name!r}: unknown {spec.argument} "
                                       f"{argument!r}; known: {sorted(valid)}")
        build = spec.symbolic
        symbolic = None if build is None else (lambda: build(argument))
        rows, cols = spec.shape(argument)
        return Quantity(name, (rows, cols),
                        lambda out: spec.fill(argument, out), spec.needs_v, symbolic, spec.doc)

    def get(self, name: str) -> Quantity:
        """Like :meth:`resolve`, but an unknown name raises :class:`~wbc.UnknownNameError`
        listing what is offered."""
        quantity = self.resolve(name)
        if quantity is None:
            raise UnknownNameError(f"unknown model quantity {name!r}; the robot offers "
                                   f"{self.offered() + list(STATE_QUANTITIES)}")
        return quantity

    def __contains__(self, name: str) -> bool:
        try:
            return self.resolve(name) is not None
        except UnknownNameError:
            return False


def registry_of(robot) -> QuantityRegistry:
    """``robot.quantities``, or — for a robot written to the older, getter-only protocol — a
    registry offering ``pose[<frame>]``, ``J[<frame>]`` and ``Jdot_v[<frame>]`` through its
    ``frame_pose`` / ``frame_jacobian`` / ``frame_drift`` getters (and ``symbolic_frame`` /
    ``symbolic_drift`` when it has them)."""
    registry = getattr(robot, "quantities", None)
    if isinstance(registry, QuantityRegistry):
        return registry
    registry = QuantityRegistry()
    names = getattr(robot, "frame_names", None)
    arguments = (lambda: list(robot.frame_names)) if names is not None else None
    nv = int(robot.nv)
    symbolic_frame = getattr(robot, "symbolic_frame", None)
    symbolic_drift = getattr(robot, "symbolic_drift", None)

    def frame_output(index: int):
        if symbolic_frame is None:
            return None

        def build(frame: str) -> ca.Function:
            function = symbolic_frame(frame)
            q = ca.SX.sym("q", function.size1_in(0))
            return ca.Function(f"{function.name()}_{index}", [q], [function(q)[index]])
        return build

    registry.register("pose", argument="frame", arguments=arguments, shape=lambda f: (4, 4),
                      fill=lambda f, out: robot.frame_pose(None, f, out=out),
                      symbolic=frame_output(0), doc="world pose (4, 4) [m]")
    registry.register("J", argument="frame", arguments=arguments, shape=lambda f: (6, nv),
                      fill=lambda f, out: robot.frame_jacobian(None, f, "world", out=out),
                      symbolic=frame_output(1),
                      doc="frame Jacobian (6, nv), rows [linear; angular], world axes")
    registry.register("Jdot_v", argument="frame", arguments=arguments, shape=lambda f: (6, 1),
                      fill=lambda f, out: robot.frame_drift(None, None, f, out=out.reshape(-1)),
                      needs_v=True, symbolic=symbolic_drift,
                      doc="drift J̇v (6,) [m/s², rad/s²], world axes")
    return registry
