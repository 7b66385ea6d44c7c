"""quadprog (Goldfarb–Idnani dual active set) behind the :class:`wbc.qp.Backend` contract.

quadprog is stateless and needs a strictly positive-definite Hessian: every solve passes the
finite sides of the constraints (bounds included, as rows; :class:`~wbc.solvers.forms.OneSidedRows`)
and, when ``H`` is not numerically positive definite (a Cholesky pivot below
``1e-12 max(diag H)``), runs proximal-point iterations (:mod:`wbc.solvers.proximal`) instead of a
single solve. The warm start (or else the previous solution) is the proximal starting point; it
has no effect on a positive-definite problem.

quadprog has no feasibility tolerance: when the active constraints are linearly dependent — in
the cascade, frozen rows of an earlier level through a vertex of the bounds, so the feasible set
is a point up to roundoff — it reports "constraints are inconsistent". The adapter then retries
once with every finite side relaxed by ``feas_tol * max(1, |side|)`` (equalities become narrow
two-sided rows); only if that fails too is the problem reported INFEASIBLE.

Multipliers: quadprog solves ``min 1/2 x'Gx - a'x`` s.t. ``C'x >= b`` with ``G x - a = C lam``,
``lam >= 0``; with ``C = -G_rows'`` (rows ``G_rows x <= h``) ``lam`` is exactly the multiplier of
those rows, mapped back as :meth:`~wbc.solvers.forms.OneSidedRows.multipliers` does.

Cost per tick: on control-sized QPs each numpy call costs about as much as quadprog's arithmetic,
so the adapter makes few of them. The data live in one :class:`~wbc.solvers.forms.RowTable`;
for each pattern of finite sides (a bytes key, checked every tick) the index arrays are computed
once, and quadprog's ``C`` and ``b`` are then gathered by one ``take`` and one sign
multiplication into a buffer allocated once. The multipliers come back through one
matrix-vector product. quadprog gets ``H`` itself, not the inverse Cholesky factor
(``factorized=True``) that the positive-definiteness test could provide: at the sizes of the
stacks here (``n <= 13``) the extra LAPACK call (``dtrtri``) costs about what it spares quadprog,
and it would change the results in the last bits (on degenerate problems, which of the valid
multipliers comes out).

Options (profiles ``default`` and ``tight``): ``feas_tol``, and ``prox_mu``, ``prox_tol``,
``prox_max_iter`` of :class:`~wbc.solvers.proximal.ProximalPoint`.
Accuracy on the tests (``tight``): ≈1e-14 on positive-definite QPs, ≈1e-11 with a singular
Hessian or an LP.
"""

from __future__ import annotations

import numpy as np

from wbc.qp import QPResult, Status

from . import proximal
from .base import BackendBase, check_option_names, failure, import_solver
from .forms import OneSidedRows, RowTable


class _NotConverged(Exception):
    """The proximal iterations hit their limit."""


class _Constraints:
    """quadprog's constraints ``C' x >= b`` for one pattern of finite sides of a table:
    ``C = -G'`` and ``b = -h`` of the :class:`OneSidedRows` ``G x <= h`` (equalities first).

    ``C`` and ``b`` are views of one buffer that holds ``-G`` row-major (which is ``C``
    column-major, the layout quadprog copies its input to), then ``b``. :meth:`gather` fills it
    from a table of this pattern.

    Args:
        table: the table whose current sides set the pattern.
    """

    def __init__(self, table: RowTable):
        self.key = table.pattern()
        rows = OneSidedRows(table.l, table.u)
        n, k = table.n, len(rows.source)
        self.n_eq = rows.n_eq
        # Row i of G is sign_i C_source_i, and h_i is sign_i u (upper sides and equalities,
        # sign +1) or sign_i l (lower sides, sign -1): index C_source_i and that side in the
        # table, and scale by -sign_i.
        start = rows.source * (n + 2)
        side = np.where(rows.sign > 0, n + 1, n)  # column of u, or of l
        self._index = np.concatenate(((start[:, None] + np.arange(n)).ravel(), start + side))
        self._scale = -np.concatenate((np.repeat(rows.sign, n), rows.sign))
        self._buffer = np.empty(k * (n + 1))
        if k:
            self.C, self.b = self._buffer[:k * n].reshape(k, n).T, self._buffer[k * n:]
        else:  # quadprog wants None, not an empty matrix
            self.C = self.b = None
        # Multiplier of table row r: sum of sign_i lam_i over the rows i of G taken from r. At
        # least one column: without constraints quadprog returns one (zero) multiplier.
        self._to_table = np.zeros((len(table.l), max(k, 1)))
        self._to_table[rows.source, np.arange(k)] = rows.sign

    def gather(self, table: RowTable) -> None:
        """Write ``C`` and ``b`` from the current data of ``table`` (of this pattern)."""
        # The indices are in range: mode "wrap" spares the buffered copy "raise" makes with out=.
        table.flat.take(self._index, out=self._buffer, mode="wrap")
        np.multiply(self._buffer, self._scale, out=self._buffer)

    def multipliers(self, lam: np.ndarray) -> np.ndarray:
        """Multipliers of the table's rows in the convention of :mod:`wbc.qp`, from quadprog's
        ``lam``: the values of :meth:`OneSidedRows.multipliers` (the map has entries 0 and ±1,
        at most two per row, so the product is exact)."""
        return self._to_table.dot(lam)


class QuadprogBackend(BackendBase):
    """quadprog, with proximal iterations for singular Hessians. See the module docstring."""

    name = "quadprog"
    PROFILES = {
        "default": {"feas_tol": 1e-10, "prox_mu": 1e-3, "prox_tol": 1e-8, "prox_max_iter": 100},
        "tight": {"feas_tol": 1e-10, "prox_mu": 1e-3, "prox_tol": 1e-10, "prox_max_iter": 500},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        check_option_names(self.name, self.options, ("feas_tol", *proximal.OPTION_NAMES))
        self._quadprog = import_solver("quadprog", self.name)
        self._proximal = proximal.ProximalPoint.from_options(self.options)
        self._feas_tol = self.options.get("feas_tol", 1e-10)

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H = np.empty((self.n, self.n))
        self._g = np.empty(self.n)
        self._table = RowTable(self.n, self.m)
        self._x = np.zeros(self.n)
        self._update(H, g, A, lA, uA, lb, ub)
        self._constraints = _Constraints(self._table)

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H[...] = H
        self._g[...] = g
        self._table.load(A, lA, uA, lb, ub)

    def _solve(self, warm_start) -> QPResult:
        n, m = self.n, self.m
        table = self._table
        if table.pattern() != self._constraints.key:
            self._constraints = _Constraints(table)
        constraints = self._constraints
        constraints.gather(table)
        x0 = self._x if warm_start is None else np.asarray(warm_start, dtype=float)
        try:
            try:
                x, lam, iterations = self._attempt(constraints, x0)
            except ValueError as exc:
                if "inconsistent" not in str(exc):
                    raise
                relaxed = self._relaxed(table)
                constraints = _Constraints(relaxed)
                constraints.gather(relaxed)
                x, lam, iterations = self._attempt(constraints, x0)
        except ValueError as exc:  # quadprog's only failure signal
            status = Status.INFEASIBLE if "inconsistent" in str(exc) else Status.NUMERICAL
            return failure(n, m, status, f"quadprog: {exc}")
        except _NotConverged as exc:
            return failure(n, m, Status.MAX_ITER, str(exc), exc.args[1])
        self._x = x
        multipliers = constraints.multipliers(lam)
        # Positional: keyword arguments make the dataclass's __init__ cost 0.8 µs more.
        return QPResult(x, Status.SOLVED, multipliers[:m], multipliers[m:], iterations)

    def _relaxed(self, table: RowTable) -> RowTable:
        """A copy of ``table`` with every finite side moved out by ``feas_tol * max(1, |side|)``."""
        relaxed = table.copy()
        relaxed.l -= self._feas_tol * np.maximum(1.0, np.abs(relaxed.l))
        relaxed.u += self._feas_tol * np.maximum(1.0, np.abs(relaxed.u))
        return relaxed

    def _attempt(self, constraints: _Constraints, x0) -> tuple[np.ndarray, np.ndarray, int]:
        """``(x, lam, iterations)`` under the gathered ``constraints``; raises quadprog's
        ``ValueError`` or :class:`_NotConverged`."""
        C, b, n_eq = constraints.C, constraints.b, constraints.n_eq
        if proximal.is_positive_definite(self._H):
            x, _, _, iterations, lam, _ = self._quadprog.solve_qp(self._H, -self._g, C, b, n_eq)
            return x, lam, iterations.item(0)  # quadprog's main iterations, as an int

        def solve(H, g):
            x, _, _, _, lam, _ = self._quadprog.solve_qp(H, -g, C, b, n_eq)
            return x, lam

        x, lam, iterations, converged = self._proximal.run(solve, self._H, self._g, x0)
        if not converged:
            raise _NotConverged("proximal iterations did not converge", iterations)
        return x, lam, iterations
