"""Conversions of the QP of :mod:`wbc.qp` into the forms solvers want.

- :class:`StackedConstraints` — bounds as extra rows: ``l <= C x <= u`` with ``C = [A; I]``.
- :class:`RowTable` — the same rows in one row-major table ``[C | l | u]``, from which a single
  gather picks rows of ``C`` together with one side each, and a cheap key of its finite sides.
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


class RowTable:
    """All constraints as rows ``l <= C x <= u`` (``C = [A; I]``) in one row-major table whose row
    ``i`` is ``[C_i, l_i, u_i]``, so that one gather (``flat.take``) picks any rows of ``C`` with
    one side each. The identity rows are written once; ``l`` and ``u`` are (strided) views of
    the table's last two columns.

    Args:
        n: number of variables.
        m: number of rows of ``A``.
    """

    def __init__(self, n: int, m: int):
        self.n, self.m = n, m
        self.data = np.zeros((m + n, n + 2))
        self.data[m:, :n] = np.eye(n)
        self.flat = self.data.reshape(-1)  # a view: flat index of (i, j) is i * (n + 2) + j
        self.l = self.data[:, n]
        self.u = self.data[:, n + 1]
        self._mask = np.empty((3, m + n), dtype=bool)
        self._has_l, self._has_u, self._equal = self._mask  # views, written by pattern()
        self._minus_inf, self._plus_inf = np.array(-np.inf), np.array(np.inf)

    def load(self, A, lA, uA, lb, ub) -> None:
        """Copy new data into the table (any memory order of ``A``)."""
        m, n = self.m, self.n
        if m:  # bounds only: spare three empty copies (a numpy call each)
            self.data[:m, :n] = A
            self.l[:m] = lA
            self.u[:m] = uA
        self.l[m:] = lb
        self.u[m:] = ub

    def copy(self) -> RowTable:
        """An independent table with the same contents."""
        other = RowTable(self.n, self.m)
        other.data[...] = self.data
        return other

    def pattern(self) -> bytes:
        """A key of the finite sides and the equal sides of ``(l, u)``, written into a buffer
        allocated once (three ufunc calls: this runs every tick). Equal keys mean equal
        :class:`OneSidedRows`, whose equalities are the rows with ``-inf < l == u``.
        """
        np.greater(self.l, self._minus_inf, out=self._has_l)
        np.less(self.u, self._plus_inf, out=self._has_u)
        np.equal(self.l, self.u, out=self._equal)
        return self._mask.tobytes()


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
