"""Shared test helpers: random instances with controlled spectra, KKT residuals, a controller
commanding a constant vector (for wbc.sim), and the paper studies' output contract."""

from __future__ import annotations

import numpy as np

import wbc


def random_matrix(rng: np.random.Generator, m: int, n: int, rank: int | None = None,
                  smin: float = 0.3, smax: float = 3.0) -> np.ndarray:
    """An ``(m, n)`` matrix of exactly ``rank`` (default: full) with nonzero singular values in
    ``[smin, smax]``, so that the tests probe rank deficiency, not ill-conditioning."""
    rank = min(m, n) if rank is None else rank
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = rng.uniform(smin, smax, rank)
    return (U[:, :rank] * s) @ V[:, :rank].T


def kkt_residuals(qp: tuple, result: wbc.QPResult) -> dict[str, float]:
    """Stationarity, primal feasibility and complementarity of a backend's answer, in the sign
    convention of :mod:`wbc.qp` (``H x + g + Aᵀ y + z = 0``)."""
    H, g, A, lA, uA, lb, ub = qp
    x, y, z = result.x, result.y, result.z
    Ax = A @ x
    stationarity = np.abs(H @ x + g + A.T @ y + z).max(initial=0.0)
    primal = max(np.max(lA - Ax, initial=0.0), np.max(Ax - uA, initial=0.0),
                 np.max(lb - x, initial=0.0), np.max(x - ub, initial=0.0))
    comp = 0.0
    for val, lo, up, mult in ((Ax, lA, uA, y), (x, lb, ub, z)):
        upper_gap = np.where(np.isfinite(up), up - val, np.inf)
        lower_gap = np.where(np.isfinite(lo), val - lo, np.inf)
        pos, neg = np.maximum(mult, 0.0), np.maximum(-mult, 0.0)
        with np.errstate(invalid="ignore"):
            terms = np.concatenate([np.where(pos > 0, pos * upper_gap, 0.0),
                                    np.where(neg > 0, neg * lower_gap, 0.0)])
        comp = max(comp, float(np.max(np.abs(terms), initial=0.0)))
    return {"stationarity": float(stationarity), "primal": float(primal),
            "complementarity": comp}


def assert_kkt(ws: wbc.Workspace, tol: float = 1e-6) -> None:
    """Every QP of the last tick satisfies its KKT conditions to ``tol`` (scaled by the data)."""
    for label, qp, result in ws.last_qps():
        scale = max(1.0, np.abs(qp[0]).max(), np.abs(qp[1]).max(initial=0.0))
        res = kkt_residuals(qp, result)
        for what, value in res.items():
            assert value <= tol * scale, f"{label}: KKT {what} residual {value:.2e}"


class Constant:
    """A ``wbc.sim`` controller commanding the same vector every tick."""

    last_solution = None

    def __init__(self, command):
        self.command = np.asarray(command, dtype=float)

    def step(self, q, v=None, **references):
        return self.command


def assert_study_contract(data: dict) -> None:
    """The JSON of ``wbc study NAME`` keeps the contract of the paper issues: its top-level
    keys, and every claim with exactly ``id, statement, paper, ours, holds, note, missing,
    verdict``, a boolean ``holds`` and a verdict that agrees with it (a claim the model cannot
    reach names what it lacks)."""
    assert {"claims", "runs", "timing", "machine", "parameters", "summary"} <= set(data)
    assert data["claims"]
    for claim in data["claims"]:
        assert set(claim) == {"id", "statement", "paper", "ours", "holds", "note", "missing",
                              "verdict"}, claim
        assert isinstance(claim["holds"], bool), claim["id"]
        expected = ("holds" if claim["holds"] else
                    "not reproducible with this model" if claim["missing"] else "fails")
        assert claim["verdict"] == expected, claim


# Level 1 of wbc study petric's whole-body stack at the start pose: qpOASES' first
# attempt fails there with "Division by zero", its cold retry solves it.
PETRIC_A = np.array([
    [-9.6303398848038868e-01, -2.2804360321921050e-16, -2.2804360321921050e-16,
     -2.4777136099362315e-01, -1.2958422174118701e-16, -2.3594332717769482e-02,
     -5.5238427079922229e-17, -1.0304463676740155e-01, 0.0],
    [3.3550882491192020e-16, -4.2973338404012207e-01, -5.3853083663769197e-01,
     -3.3257467822110141e-17, -7.0004191494248813e-01, -5.4458284007669683e-17,
     -1.8776334561193522e-01, 8.0657797761728779e-17, 0.0],
    [9.4817689116476200e-02, -5.6556035781892700e-17, -1.4436738906469700e-17,
     -5.1677132977978557e-01, 8.2524569792639479e-17, 8.3464074978255731e-01,
     -4.6930452115573300e-17, 1.6532337206412800e-01, 1.2065569735464764e-48]])
PETRIC_UPPER = np.array([1.0, 1.0, 2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
PETRIC_LEVEL = (np.diag([1.0, 1.0] + [0.0] * 7), np.zeros(9), PETRIC_A, np.zeros(3),
                np.zeros(3), -PETRIC_UPPER, PETRIC_UPPER)
