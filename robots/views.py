"""Views into flat parameter buffers, so that getters write where compiled stacks read.

CasADi stores matrices column-major. A ``(rows, cols)`` block starting at ``offset`` of a flat
parameter vector ``p`` is therefore ``p[offset:offset + rows*cols]`` reshaped in Fortran order —
a *view*: writing into it writes into ``p``, with no copy and no conversion::

    J_view = column_major_view(p, offset, (6, robot.nv))
    robot.frame_jacobian(q, "ee", out=J_view)      # p now holds J, column-major
"""

from __future__ import annotations

import numpy as np

from wbc.errors import ShapeError

__all__ = ["column_major_view"]


def column_major_view(buffer: np.ndarray, offset: int, shape: tuple[int, ...]) -> np.ndarray:
    """A column-major view of ``shape`` into the flat float ``buffer`` starting at ``offset``.

    Raises:
        ShapeError: the buffer is not a contiguous 1-D array or is too short.
    """
    if buffer.ndim != 1 or not buffer.flags.c_contiguous:
        raise ShapeError(f"buffer must be a contiguous 1-D array, got shape {buffer.shape}")
    size = int(np.prod(shape))
    if offset < 0 or offset + size > buffer.shape[0]:
        raise ShapeError(
            f"a block of shape {shape} at offset {offset} does not fit a buffer of size "
            f"{buffer.shape[0]}"
        )
    view = buffer[offset : offset + size].reshape(shape, order="F")
    if not np.shares_memory(view, buffer):  # pragma: no cover - reshape of a 1-D slice is a view
        raise ShapeError("could not create a view")
    return view
