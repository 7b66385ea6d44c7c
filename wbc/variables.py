"""The decision vector of a stack, as named blocks."""

from __future__ import annotations

from collections.abc import Mapping

import casadi as ca

from .checks import MAX_SIZE, checked_name
from .errors import InvalidValueError, ShapeError, UnknownNameError


class Variables:
    """Named, contiguous blocks of the decision vector ``x``.

    The decision variable is always explicit: a stack says whether it solves for joint
    velocities, accelerations, wheel torques or anything else.

    Example:
        >>> x = Variables(qd_base=3, qd_arm=7)
        >>> x.n, x.slice("qd_arm")
        (10, slice(3, 10, None))
        >>> x["qd_arm"].shape    # the CasADi symbol of one block
        (7, 1)

    Args:
        blocks: mapping ``name -> size`` (insertion order is the layout of ``x``); may also be
            given as keyword arguments. Names are non-empty strings, sizes positive integers.
    """

    def __init__(self, blocks: Mapping[str, int] | None = None, **sizes: int) -> None:
        if blocks is not None and not isinstance(blocks, Mapping):
            raise InvalidValueError(f"Variables: blocks must be a mapping name -> size, got "
                                    f"{type(blocks).__name__} {blocks!r}"[:120])
        merged = dict(blocks or {})
        for name, size in sizes.items():
            if name in merged:
                raise ShapeError(f"variable block {name!r} is declared twice")
            merged[name] = size
        if not merged:
            raise ShapeError("Variables needs at least one block, e.g. Variables(qd=7)")
        self._slices: dict[str, slice] = {}
        start = 0
        for name, size in merged.items():
            if not checked_name(name, "a variable block's name", optional=False):
                raise InvalidValueError("a variable block's name must not be empty")
            if not isinstance(size, int) or isinstance(size, bool) or not 1 <= size <= MAX_SIZE:
                raise ShapeError(f"variable block {name!r} must have a positive integer size "
                                 f"(at most {MAX_SIZE}), got {str(size)[:40]}")
            self._slices[name] = slice(start, start + size)
            start += size
        self.n = start
        self.symbol = ca.SX.sym("x", self.n)

    @property
    def names(self) -> list[str]:
        """Block names in layout order."""
        return list(self._slices)

    def size(self, name: str) -> int:
        """Number of entries of block ``name``."""
        s = self.slice(name)
        return s.stop - s.start

    def slice(self, name: str | None) -> slice:
        """Index range of block ``name`` in ``x`` (``None``: the whole vector)."""
        if name is None:
            return slice(0, self.n)
        try:
            return self._slices[name]
        except KeyError:
            raise UnknownNameError(f"unknown variable block {name!r}; blocks are "
                                   f"{self.names}") from None

    def __getitem__(self, name: str) -> ca.SX:
        """The CasADi symbol of block ``name`` (a column of ``x``)."""
        return self.symbol[self.slice(name)]

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={self.size(k)}" for k in self._slices)
        return f"Variables({inner})"
