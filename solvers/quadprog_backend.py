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

No hang, ever. quadprog's C loop has no iteration limit, and on degenerate problems it can
cycle forever (upstream issues quadprog#32 and #37; here: two equal rows of ``C'x >= b`` with
an ill- or well-conditioned ``H`` hang about one random problem in ten, a row that is the sum of
two others about one in 10⁴ — ``tests/test_regressions.py`` holds such problems). Two measures,
in this order:

* *the degeneracy is removed before the call*: inequality rows that point the same way as
  another row (cosine > ``1 - 1e-10``) are dropped unless they are the tightest of their group,
  and an inequality or equality parallel to an equality it agrees with is dropped
  (:func:`parallel_rows`). This is what duplicated hard constraints of a user produce, and it
  leaves the solution unchanged (a dropped row gets multiplier 0, which is a valid multiplier
  of an implied row). It costs a Gram matrix of the rows per solve (≈ 20 µs with 30 rows;
  the two sides of a bound are opposite rows that never make each other redundant, so they
  do not enter the Python loop).
* *the call is bounded*: quadprog runs on a worker thread (it releases the GIL) and the backend
  waits at most ``time_limit`` seconds (default 1, the campaign's definition of a hang: a
  wall-clock limit must leave room for a loaded machine; quadprog needs < 1 ms on the stacks
  here). A call that has not returned by then is reported ``NUMERICAL`` ("did not return"),
  and that worker is abandoned — it keeps one core busy until the process ends, which is why
  the first measure exists: rows combining several others can still cycle, and then the
  controller gets a status (and falls back) instead of waiting forever. A hand-off to the
  worker costs 15–50 µs per call (more on a loaded machine: two thread wake-ups);
  ``time_limit=None`` calls quadprog on the caller's thread, unbounded.

Refusing the input was rejected: dependent rows are legitimate (bounds plus a general row meet
at a vertex every time a task saturates) and the cascade itself produces them. Isolating
quadprog in a process would make the bound clean (the child can be killed) but costs a
pickling round trip per call, more than quadprog's arithmetic.

Not optimal, yet "solved". On a positive-definite but ill-conditioned ``H`` (a cascade level
whose only curvature in some directions is the damping, eigenvalues 1e-6 beside 1e2) at a
degenerate vertex (active rows dependent to roundoff), quadprog can return a primal-feasible
point with multipliers of 1e14–1e19 that do not balance the gradient: the level's objective
−2.4258 where the optimum is −2.5116 (``tests/data/quadprog_nonoptimal_level.npz``), commands
up to 6.2 rad/s off on saturating three-level ticks of ``wbc bench``. Goldfarb–Idnani keeps
stationarity ``Hx + g = C lam`` by construction, so its residual measures the roundoff: every
answer on a positive-definite ``H`` is checked (two products and a dot: a few µs), and one
whose residual exceeds ``dual_tol * max(1, max|H|, max|g|)`` is handled as an "inconsistent" one —
solved once more with the sides relaxed by ``feas_tol`` (which moved quadprog off the
degenerate vertex on every such QP measured) — and reported ``NUMERICAL`` if that answer fails
the check too. Measured on the 24 velocity cells of ``wbc bench`` (4 robots, two- and
three-level stacks, 3 scenarios, 350 ticks; 21 000 solves): the relative residual is below
1e-5 on every solve but 11, and above 1e-3 on those 11 (the non-optimal ones); the default
``dual_tol = 1e-4`` sits in that gap.

Options (profiles ``default`` and ``tight``): ``feas_tol``, ``dual_tol``, ``time_limit`` [s], and
``prox_mu``, ``prox_tol``, ``prox_max_iter`` of :class:`~wbc.solvers.proximal.ProximalPoint`.
Accuracy on the tests (``tight``): ≈1e-14 on positive-definite QPs, ≈1e-11 with a singular
Hessian or an LP.
"""

from __future__ import annotations

import threading

import numpy as np

from wbc.qp import QPResult, Status

from . import proximal
from .base import BackendBase, check_option_names, clock, failure, import_solver
from .forms import OneSidedRows, RowTable


class _NotConverged(Exception):
    """The proximal iterations hit their limit."""


class _TimedOut(Exception):
    """quadprog did not return within the time limit."""


class _NotOptimal(Exception):
    """quadprog's answer fails its stationarity check (see the module docstring)."""


PARALLEL = 1.0 - 1e-10
"""Cosine above which two constraint rows count as parallel (same direction)."""


def parallel_rows(C: np.ndarray, b: np.ndarray, n_eq: int) -> np.ndarray | None:
    """Which constraints of quadprog's ``C' x >= b`` (the first ``n_eq`` equalities) to keep so
    that no two kept rows are parallel where one makes the other redundant; ``None`` when
    every row is kept (the common case: one Gram matrix, no Python loop).

    Dropped: an inequality pointing the same way as a tighter inequality (of two equal ones,
    the later), an inequality implied by an equality parallel to it (either sign), and an
    equality parallel to an earlier one with the same value (within ``1e-10`` relative).
    Contradicting parallel rows are all kept: quadprog then reports the problem inconsistent.
    """
    k = C.shape[1]
    if k < 2:
        return None
    norms = np.sqrt(np.einsum("ij,ij->j", C, C))
    norms[norms == 0.0] = 1.0
    unit = C / norms
    cosine = unit.T @ unit
    np.fill_diagonal(cosine, 0.0)
    # Pairs that can make a row redundant: rows pointing the same way, or opposite ones where
    # one is an equality. Two opposite inequalities bound a slab (the two sides of every
    # two-sided bound): never redundant, and skipping them keeps the common case loop-free.
    paired = cosine > PARALLEL
    if n_eq:
        opposite = cosine < -PARALLEL
        opposite[n_eq:, n_eq:] = False
        paired |= opposite
    if not paired.any():
        return None
    level = b / norms  # the side of each row along its unit normal
    keep = np.ones(k, dtype=bool)
    for i, j in np.argwhere(np.triu(paired, 1)):
        if not (keep[i] and keep[j]):
            continue
        sign = 1.0 if cosine[i, j] > 0 else -1.0
        close = abs(level[i] - sign * level[j]) <= 1e-10 * max(1.0, abs(level[i]))
        if i < n_eq and j < n_eq:  # two equalities: the second is redundant if they agree
            keep[j] = not close
        elif i < n_eq:  # an inequality n'x >= c beside the equality n'x = e: implied if c <= e
            keep[j] = not (level[j] <= sign * level[i] + 1e-10 * max(1.0, abs(level[i])))
        elif sign > 0:  # two inequalities the same way: keep the tighter
            keep[i if level[i] < level[j] else j] = False
    return None if keep.all() else keep


class _Worker:
    """A daemon thread that runs quadprog calls, so that the caller can stop waiting.

    Idle workers are kept in a process-wide pool (:func:`_call`): one per thread calling
    quadprog at the same time, not one per backend.
    """

    def __init__(self, solve_qp) -> None:
        self._solve_qp = solve_qp
        # plain locks used as binary semaphores (held = no signal): threading.Semaphore is a
        # Condition in Python and made each hand-off cost ~100 µs on this machine
        self._start, self._done = threading.Lock(), threading.Lock()
        self._start.acquire()
        self._done.acquire()
        self._args: tuple = ()
        self._out: tuple | BaseException = ()
        threading.Thread(target=self._loop, daemon=True, name="quadprog").start()

    def _loop(self) -> None:
        while True:
            self._start.acquire()
            try:
                self._out = self._solve_qp(*self._args)
            except BaseException as exc:  # handed to the caller, which raises it
                self._out = exc
            self._done.release()

    def call(self, time_limit: float, args: tuple) -> tuple | BaseException | None:
        """quadprog's outputs or exception for ``args``; ``None`` after ``time_limit`` [s]."""
        self._args = args
        self._start.release()
        return self._out if self._done.acquire(timeout=time_limit) else None


_IDLE: list[_Worker] = []  # idle workers; list.pop / append are atomic in CPython


def _call(solve_qp, time_limit: float | None, *args) -> tuple:
    """``solve_qp(*args)`` on an idle worker; raises quadprog's exception, or
    :class:`_TimedOut` (the worker, still inside quadprog, is abandoned). ``time_limit=None``:
    a direct call on this thread (no bound)."""
    if time_limit is None:
        return solve_qp(*args)
    try:
        worker = _IDLE.pop()
    except IndexError:
        worker = _Worker(solve_qp)
    out = worker.call(time_limit, args)
    if out is None:
        raise _TimedOut(f"quadprog did not return within {time_limit} s (it cycles on "
                        "degenerate constraints); its thread is abandoned")
    _IDLE.append(worker)
    if isinstance(out, BaseException):
        raise out
    return out


class _Constraints:
    """quadprog's constraints ``C' x >= b`` for one pattern of finite sides of a table:
    ``C = -G'`` and ``b = -h`` of the :class:`OneSidedRows` ``G x <= h`` (equalities first).

    ``C`` and ``b`` are views of one buffer that holds ``-G`` row-major (which is ``C``
    column-major, the layout quadprog copies its input to), then ``b``. :meth:`gather` fills it
    from a table of this pattern.

    Args:
        table: the table whose current sides set the pattern.
    """

    C: np.ndarray | None  # both None without constraints
    b: np.ndarray | None

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
    package = "quadprog"
    PROFILES = {
        "default": {"feas_tol": 1e-10, "dual_tol": 1e-4, "time_limit": 1.0, "prox_mu": 1e-3,
                    "prox_tol": 1e-8, "prox_max_iter": 100},
        "tight": {"feas_tol": 1e-10, "dual_tol": 1e-4, "time_limit": 1.0, "prox_mu": 1e-3,
                  "prox_tol": 1e-10, "prox_max_iter": 500},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        check_option_names(self.name, self.options,
                           ("feas_tol", "dual_tol", "time_limit", *proximal.OPTION_NAMES))
        self._quadprog = import_solver("quadprog", self.name)
        limit = self.options.get("time_limit", 1.0)
        self._time_limit = None if limit is None else float(limit)
        self._proximal = proximal.ProximalPoint.from_options(self.options)
        self._feas_tol = self.options.get("feas_tol", 1e-10)
        self._dual_tol = float(self.options.get("dual_tol", 1e-4))

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H = np.empty((self._n, self._n))
        self._g = np.empty(self._n)
        self._table = RowTable(self._n, self._m)
        self._x = np.zeros(self._n)
        self._update(H, g, A, lA, uA, lb, ub)
        self._constraints = _Constraints(self._table)

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._H[...] = H
        self._g[...] = g
        self._table.load(A, lA, uA, lb, ub)

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        table = self._table
        if table.pattern() != self._constraints.key:
            self._constraints = _Constraints(table)
        constraints = self._constraints
        constraints.gather(table)
        x0 = self._x if warm_start is None else np.asarray(warm_start, dtype=float)
        try:
            try:
                x, lam, iterations = self._attempt(constraints, x0)
            except (ValueError, _NotOptimal) as exc:
                # a false "inconsistent" or a non-optimal answer: both are quadprog at a
                # degenerate vertex, which the relaxed sides move it off
                if isinstance(exc, ValueError) and "inconsistent" not in str(exc):
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
        except (_TimedOut, _NotOptimal) as exc:
            return failure(n, m, Status.NUMERICAL, str(exc))
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

    def _check_stationarity(self, x: np.ndarray, lam: np.ndarray, C: np.ndarray | None) -> None:
        """Raise :class:`_NotOptimal` unless ``‖Hx + g − C lam‖∞ <= dual_tol · max(1, max|H|,
        max|g|)`` (``lam`` of every gathered row: a row dropped as parallel has 0)."""
        residual = self._H.dot(x)
        residual += self._g
        if C is not None:
            residual -= C.dot(lam)
        if residual.dot(residual) <= self._dual_tol ** 2:  # ‖r‖∞ <= ‖r‖₂, and the scale >= 1
            return
        worst = float(np.abs(residual).max())
        scale = max(1.0, float(np.abs(self._H).max()), float(np.abs(self._g).max()))
        if worst > self._dual_tol * scale:  # (False for NaN: a non-finite x is reported so)
            raise _NotOptimal(f"quadprog: answer not optimal (stationarity residual {worst:.1e}, "
                              f"tolerance {self._dual_tol:.0e} x {scale:.2g}; multipliers up to "
                              f"{float(np.abs(lam).max(initial=0.0)):.1e})")

    def _attempt(self, constraints: _Constraints, x0) -> tuple[np.ndarray, np.ndarray, int]:
        """``(x, lam, iterations)`` under the gathered ``constraints``; raises quadprog's
        ``ValueError``, :class:`_NotConverged` or (positive-definite ``H``) :class:`_NotOptimal`."""
        C, b, n_eq = constraints.C, constraints.b, constraints.n_eq
        keep: np.ndarray | None = None
        if C is not None and b is not None:  # (both or neither)
            keep = parallel_rows(C, b, n_eq)
            if keep is not None:
                C, b, n_eq = C[:, keep], b[keep], int(keep[:n_eq].sum())
        solve_qp, time_limit = self._quadprog.solve_qp, self._time_limit

        def solve(H, g):
            t0 = clock()  # (with a time limit, the worker's hand-off is inside)
            try:
                x, _, _, iterations, lam, _ = _call(solve_qp, time_limit, H, -g, C, b, n_eq)
            finally:
                self.library_time += clock() - t0
            if keep is not None:  # a dropped row is implied: multiplier 0
                full = np.zeros(len(keep))
                full[keep] = lam
                lam = full
            return x, lam, iterations.item(0)  # quadprog's main iterations, as an int

        if proximal.is_positive_definite(self._H):
            x, lam, iterations = solve(self._H, self._g)
            self._check_stationarity(x, lam, constraints.C)
            return x, lam, iterations

        x, lam, iterations, converged = self._proximal.run(lambda H, g: solve(H, g)[:2],
                                                           self._H, self._g, x0)
        if not converged:
            raise _NotConverged("proximal iterations did not converge", iterations)
        return x, lam, iterations
