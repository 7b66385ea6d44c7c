"""DAQP (dual active set, dense) behind the :class:`wbc.qp.Backend` contract.

One ``daqp.Model`` per backend: ``setup`` allocates its workspace, every tick ``update`` refreshes
the data (a new Cholesky factor of ``H``, the constraint transform) without a new setup, and the
solve restarts from the previous active set — that is DAQP's warm start; the primal guess passed
to :meth:`solve` is not used. DAQP takes simple bounds first, then the rows of ``A``, with
``blower <= . <= bupper`` and ``±inf`` for no bound; equalities (``l == u``) are flagged with
``sense = 5`` (active and immutable). When that flag pattern changes, or after a failed solve,
the sense vector is passed again, which resets the active set (a cold start).

Semidefinite Hessians: ``eps_prox`` (negative = automatic, DAQP 0.11's default ``-1e-6``) turns
on DAQP's own proximal-point iterations when ``H`` is singular, so LPs and rank-deficient ``H``
work. Their stopping tolerance ``eta_prox`` matters, and both profiles set it to ``1e-10``: with
DAQP's default (``1e-6``) the multipliers of an LP are only good to ≈1e-4, and a cascade of
singular levels moves far from its solution — on the AMP cascade of ``wbc study xing`` (scaling
LP, three undamped levels; 1000 random states of the study's sampler), DAQP's default left the
commands more than 1e-3 from the ``tight`` profile's in 54 states (up to 4.8 rad/s²), while
``eta_prox = 1e-10`` alone brings every state within 7.6e-4 of it (the distance between
``tight`` daqp and ``tight`` quadprog, 2 active-set solvers, on the same states), at no
measurable cost in time (median tick 126 vs 147 µs). The tighter tolerance costs robustness on
badly scaled problems: on the 1200 random stacks of ``wbc fuzz`` (data scaled by up to
1e±12), 18 that DAQP's default solved — mostly to 1e-11 of quadprog's answer — failed with it
("iteration limit", "unbounded"; with ``1e-12`` even well-posed singular levels of a cascade
fail so). So a solve that fails with a tolerance below DAQP's default is retried once, with a
new model, at DAQP's default (:data:`LOOSE_ETA_PROX`), unless DAQP found it infeasible; its
answer is then as good as DAQP's default makes it, and the result's message says so. The retry
costs a setup and a solve, on failed solves only. With the retry, 3 of those 1200 cases still
fail where DAQP's default solved them warm (a cold solve fails on them with either tolerance).

Multipliers: ``info["lam"]`` = bounds then rows, with the sign convention of :mod:`wbc.qp`.
Profiles: ``default`` is DAQP's defaults but ``eta_prox = 1e-10`` (see above); ``tight`` also
sets ``primal_tol = 1e-10``, and reaches ≈1e-14 on positive-definite QPs, ≈1e-9 with a singular
Hessian, ≈1e-12 on LPs (tests).
"""

from __future__ import annotations

import numpy as np

from wbc.qp import QPResult, Status

from .base import BackendBase, check_option_names, clock, failure, import_solver

_EQUALITY = 5  # DAQP sense flags: ACTIVE (1) | IMMUTABLE (4)
_EXIT = {
    1: (Status.SOLVED, "optimal"),
    2: (Status.SOLVED, "soft optimal"),
    -1: (Status.INFEASIBLE, "infeasible"),
    -2: (Status.NUMERICAL, "cycling detected"),
    -3: (Status.NUMERICAL, "unbounded"),
    -4: (Status.MAX_ITER, "iteration limit reached"),
    -5: (Status.NUMERICAL, "nonconvex problem"),
    -6: (Status.NUMERICAL, "overdetermined initial active set"),
}
_SOLVED_FLAGS = (1, 2)  # the flags _EXIT maps to SOLVED
_INFEASIBLE = -1  # not retried: the tolerance of the proximal iterations does not decide it
#: DAQP's own ``eta_prox``: the tolerance of the retry after a failed solve (module docstring).
LOOSE_ETA_PROX = 1e-6


def _exit(flag: int) -> tuple[Status, str]:
    return _EXIT.get(flag, (Status.NUMERICAL, f"exit flag {flag}"))


class DaqpBackend(BackendBase):
    """DAQP, kept alive between ticks. See the module docstring."""

    name = "daqp"
    package = "daqp"
    PROFILES = {
        "default": {"eta_prox": 1e-10},
        "tight": {"primal_tol": 1e-10, "eta_prox": 1e-10},
    }

    def __init__(self, profile: str = "default", **options):
        super().__init__(profile, **options)
        self._daqp = import_solver("daqp", self.name)
        check_option_names(self.name, self.options, self._daqp.Model().settings)

    def _library_defaults(self) -> dict:
        return dict(self._daqp.Model().settings)

    def _setup(self, H, g, A, lA, uA, lb, ub) -> None:
        n, m = self._n, self._m
        self._H = np.empty((n, n))
        self._f = np.empty(n)
        self._A = np.empty((m, n))
        self._upper = np.empty(n + m)  # DAQP's order: bounds first, then the rows
        self._lower = np.empty(n + m)
        self._equal = np.empty(n + m, dtype=bool)
        self._pattern = b""  # the equality flags as bytes, to notice when they change
        self._load_sides(lA, uA, lb, ub)
        self._build(H, g, A)

    def _build(self, H, g, A) -> None:
        """A new model on copies of ``H, g, A`` and the loaded sides (``self._model`` is None
        if DAQP refuses it)."""
        self._H[...] = H
        self._f[...] = g
        self._A[...] = A
        self._data = (self._H, self._f, self._A)  # the loaded QP (for _solve_loosely)
        self._read_equalities()
        t0 = clock()
        self._model = self._daqp.Model()
        self._model.settings = self.options  # kept by setup
        self._flag, _ = self._model.setup(
            self._H, self._f, self._A, self._upper, self._lower, self._sense
        )
        self.library_time += clock() - t0
        if self._flag < 0:
            self._model = None
        self._cold = False

    def _load_sides(self, lA, uA, lb, ub) -> None:
        n = self._n
        self._upper[:n] = ub
        self._lower[:n] = lb
        if self._m:
            self._upper[n:] = uA
            self._lower[n:] = lA

    def _read_equalities(self) -> bool:
        """Flag the equalities (``l == u``) of the loaded sides; whether the flags changed."""
        pattern = np.equal(self._lower, self._upper, out=self._equal).tobytes()
        if pattern == self._pattern:
            return False
        self._pattern = pattern
        self._sense = np.where(self._equal, _EQUALITY, 0).astype(np.intc)
        return True

    def _update(self, H, g, A, lA, uA, lb, ub) -> None:
        self._load_sides(lA, uA, lb, ub)
        if self._model is None:
            self._build(H, g, A)
            return
        # DAQP copies what update() is given (converting the memory order if needed), so H, g
        # and A go in as they are; the references are kept for a retry (see _solve_loosely).
        self._data = (H, g, A)
        A = A if self._m else None
        t0 = clock()
        if self._read_equalities() or self._cold:  # passing the flags resets the active set
            self._flag = self._model.update(H, g, A, self._upper, self._lower, self._sense)
            self._cold = False
        else:
            self._flag = self._model.update(H, g, A, self._upper, self._lower)
        self.library_time += clock() - t0

    def _solve(self, warm_start) -> QPResult:
        n, m = self._n, self._m
        if self._model is None or self._flag < 0:
            self._cold = True
            status, words = _exit(self._flag)
            return failure(n, m, status, f"daqp: setup/update failed: {words}")
        t0 = clock()
        x, _, flag, info = self._model.solve()
        self.library_time += clock() - t0
        note = ""
        if flag not in _SOLVED_FLAGS:
            self._cold = True
            if flag != _INFEASIBLE and self.options.get("eta_prox", LOOSE_ETA_PROX) < \
                    LOOSE_ETA_PROX:
                retried = self._solve_loosely()
                if retried is not None:
                    note = f"solved with eta_prox 1e-6 after {_exit(flag)[1]}"
                    x, _, flag, info = retried
            if flag not in _SOLVED_FLAGS:
                status, words = _exit(flag)
                return failure(n, m, status, f"daqp: {words}", info["iterations"])
        lam = info["lam"]
        return QPResult(x, Status.SOLVED, lam[n:], lam[:n], info["iterations"], note)

    def _solve_loosely(self) -> tuple | None:
        """DAQP's ``solve()`` outputs on the loaded QP with ``eta_prox`` at DAQP's default, on a
        model of its own (the regular one keeps its settings); ``None`` if its setup fails."""
        t0 = clock()
        model = self._daqp.Model()
        model.settings = {**self.options, "eta_prox": LOOSE_ETA_PROX}
        H, g, A = self._data
        flag, _ = model.setup(H, g, A, self._upper, self._lower, self._sense)
        answer = None if flag < 0 else model.solve()
        self.library_time += clock() - t0
        return answer
