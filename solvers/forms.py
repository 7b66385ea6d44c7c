"""Conversions of the QP of :mod:`wbc.qp` into the forms solvers want.

- :class:`StackedConstraints` — bounds as extra rows: ``l <= C x <= u`` with ``C = [A; I]``.
- :class:`OneSidedRows` — the finite sides only, as ``G x <= h`` with the equalities first, and
  the map of the solver's multipliers back to the sign convention of :mod:`wbc.qp`.
- :class:`CscPattern` — a fixed sparse (CSC) pattern over a dense matrix, explicit zeros
  included, and the gather of its values from a dense buffer, for solvers that are updated with
  the value vector of an unchanged pattern (osqp, clarabel).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class CscPattern:
    """The CSC pattern of the ``True`` entries of a boolean mask, explicit zeros included.

    Args:
        mask: ``(rows, cols)`` boolean array of the structural entries.
    """

    def __init__(self, mask: np.ndarray):
        mask = np.asarray(mask, dtype=bool)
        self.shape = mask.shape
        self.cols, self.rows = np.nonzero(mask.T)  # entries in column-major (CSC) order
        self.indptr = np.concatenate(([0], np.cumsum(mask.sum(axis=0))))

    @property
    def nnz(self) -> int:
        return len(self.rows)

    def matrix(self, values: np.ndarray) -> sp.csc_matrix:
        """The sparse matrix with these ``values`` (in CSC order); zeros stay structural."""
        return sp.csc_matrix((values, self.rows, self.indptr), shape=self.shape)


class UpperTriangle(CscPattern):
    """The upper triangle of a dense symmetric ``(n, n)`` matrix as a CSC pattern."""

    def __init__(self, n: int):
        super().__init__(np.triu(np.ones((n, n), dtype=bool)))
        self._flat_f = self.rows + self.cols * n  # positions in column-major memory
        self._flat_c = self.rows * n + self.cols  # positions in row-major memory

    def gather(self, H: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Write the upper-triangle values of ``H`` (either memory order) into ``out``."""
        if H.flags.f_contiguous:
            return np.take(H.reshape(-1, order="F"), self._flat_f, out=out)
        return np.take(np.ascontiguousarray(H).reshape(-1), self._flat_c, out=out)


class StackedConstraints:
    """All constraints as rows: ``l <= C x <= u`` with ``C = [A; I]``, ``l = [lA; lb]``,
    ``u = [uA; ub]``. ``C`` is a column-major buffer whose identity part is written once.

    Args:
        n: number of variables.
        m: number of rows of ``A``.
    """

    def __init__(self, n: int, m: int):
        self.n, self.m = n, m
        self.C = np.zeros((m + n, n), order="F")
        self.C[m:] = np.eye(n)
        self.l = np.empty(m + n)
        self.u = np.empty(m + n)

    def load(self, A, lA, uA, lb, ub) -> None:
        """Copy new data into the buffers (any memory order of ``A``)."""
        m = self.m
        self.C[:m] = A
        self.l[:m] = lA
        self.l[m:] = lb
        self.u[:m] = uA
        self.u[m:] = ub

    def pattern(self, source: np.ndarray) -> tuple[CscPattern, np.ndarray]:
        """CSC pattern of the rows ``C[source]`` and where its values sit in ``C``.

        A row of ``A`` is dense; a bound row has its single entry. Returns the pattern and the
        flat column-major indices into ``C`` of its values (for :meth:`gather`).
        """
        m, n = self.m, self.n
        source = np.asarray(source, dtype=np.intp)
        mask = np.zeros((len(source), n), dtype=bool)
        from_a = source < m
        mask[from_a] = True
        bound_rows = np.flatnonzero(~from_a)
        mask[bound_rows, source[bound_rows] - m] = True
        pattern = CscPattern(mask)
        return pattern, source[pattern.rows] + pattern.cols * (m + n)

    def gather(self, index: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Values of ``C`` at the flat column-major ``index`` (from :meth:`pattern`)."""
        return np.take(self.C.reshape(-1, order="F"), index, out=out)

    def complementarity_gap(self, x: np.ndarray, lam: np.ndarray) -> float:
        """``sum_i |lam_i| * |gap_i|`` over the rows of ``C``, where ``gap_i`` is the distance of
        ``C_i x`` to the side that the sign of ``lam_i`` designates (convention of
        :mod:`wbc.qp`), capped at 1e6 so that a multiplier on an infinite side counts 1e6 times.
        Zero at a KKT point; with primal and dual feasibility, it is the duality gap.
        """
        Cx = self.C @ x
        upper = np.abs(np.minimum(self.u - Cx, 1e6)) @ np.maximum(lam, 0.0)
        lower = np.abs(np.minimum(Cx - self.l, 1e6)) @ np.maximum(-lam, 0.0)
        return float(upper + lower)


class OneSidedRows:
    """The finite sides of two-sided constraints ``l <= C x <= u`` as rows ``G x <= h``.

    ``G = [C_eq; C_up; -C_lo]`` and ``h = [u_eq; u_up; -l_lo]``: first the equalities
    (``l == u``), then every other finite upper side, then every other finite lower side. Sides
    at ``±inf`` are dropped, so a row with both sides infinite disappears.

    Args:
        l: lower sides, ``-inf`` for none.
        u: upper sides, ``+inf`` for none.
    """

    def __init__(self, l: np.ndarray, u: np.ndarray):
        eq, has_l, has_u = self._sides(l, u)
        self._size = len(l)
        self._key = self.pattern(l, u)
        self.eq = np.flatnonzero(eq)
        self.up = np.flatnonzero(has_u & ~eq)
        self.lo = np.flatnonzero(has_l & ~eq)
        self.n_eq = len(self.eq)
        self.n_ineq = len(self.up) + len(self.lo)
        self.source = np.concatenate((self.eq, self.up, self.lo))
        self.sign = np.ones(len(self.source))
        self.sign[len(self.source) - len(self.lo):] = -1.0

    @staticmethod
    def _sides(l, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        has_l = l > -np.inf
        has_u = u < np.inf
        return has_l & (l == u), has_l, has_u

    @classmethod
    def pattern(cls, l: np.ndarray, u: np.ndarray) -> bytes:
        """A key of the equalities and finite sides of ``(l, u)``: equal keys, equal rows."""
        return b"".join(mask.tobytes() for mask in cls._sides(l, u))

    def same_pattern(self, l: np.ndarray, u: np.ndarray) -> bool:
        """Whether ``(l, u)`` has the same equalities and finite sides as at construction."""
        return self.pattern(l, u) == self._key

    def matrix(self, C: np.ndarray) -> np.ndarray:
        """``G`` (dense, row-major) from the two-sided matrix ``C``."""
        return C[self.source] * self.sign[:, None]

    def rhs(self, l: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``h`` from the sides ``l``, ``u``."""
        h = u[self.source]
        h[len(h) - len(self.lo):] = -l[self.lo]
        return h

    def multipliers(self, lam: np.ndarray) -> np.ndarray:
        """Multipliers of the rows of ``C`` in the convention of :mod:`wbc.qp`, from those of
        the rows of ``G`` (KKT ``H x + g + G' lam = 0``, ``lam >= 0`` on inequalities)."""
        n_eq, n_up = self.n_eq, len(self.up)
        full = np.zeros(self._size)
        full[self.eq] = lam[:n_eq]
        full[self.up] += lam[n_eq:n_eq + n_up]
        full[self.lo] -= lam[n_eq + n_up:]
        return full
