"""Accuracy beside time for ``wbc bench``: the referee, per-level KKT residuals, QP export.

**Referee.** quadprog (Goldfarb–Idnani, an exact active-set method) with the ``tight`` profile
and ``time_limit=None`` (called on the caller's thread: no worker, no wall-clock bound),
through the ordinary cascade (no fused tick): :data:`REFEREE`. As in ``wbc exactness``, a
second exact solver (clarabel, ``tight``: :data:`SECOND_REFEREE`) answers every state too.
Neither is trusted on its status alone: a referee's answer counts only when it is
*certified* — every level solved and its KKT residuals (below) within :data:`KKT_TOL` times the
level's data scale (:func:`certified`). quadprog's answer is the reference when certified,
else clarabel's (counted as ``referee_switches``: on ``three_levels`` / ``far`` of mecanum_gen3,
quadprog ``tight`` returned a feasible but non-optimal level — dual residual 0.48, the last
joint 0.36 rad/s off — on 30 of 200 ticks, until its adapter checked its stationarity
residual and re-solved such levels, see :mod:`wbc.solvers.quadprog_backend`). Where both
certify, their distance is the tick's *referee gap*; as in ``wbc exactness`` a tick is judged
only where it is at most :data:`REFEREE_AGREE` — damping leaves levels near singular
configurations badly conditioned, and two certified answers then differ by up to 2 rad/s
(``three_levels`` / ``unreachable`` of mpo700_lwr4): nobody can be called wrong there
(``referee_disagreements``). A tick neither certifies is not judged either
(``referee_failures``). A backend's tick is *wrong* when the backend reports every level
solved but its command is further than :data:`WRONG_THRESHOLD` plus the tick's referee gap
from the reference (∞-norm).

**Residuals** of one QP in wbc's form (:mod:`wbc.qp`: ``min ½x'Hx + g'x``,
``lA <= Ax <= uA``, ``lb <= x <= ub``, multipliers ``y`` of the rows and ``z`` of the bounds,
``Hx + g + A'y + z = 0``), from the backend's returned ``x, y, z``:

* primal: the largest violation of a side, ``max(lA - Ax, Ax - uA, lb - x, x - ub, 0)``;
* dual: ``‖Hx + g + A'y + z‖∞``;
* duality gap: ``|x'Hx + g'x + u·y⁺ - l·y⁻ + ub·z⁺ - lb·z⁻|`` (``y⁺ = max(y, 0)``,
  ``y⁻ = max(-y, 0)``; a multiplier on an infinite side counts as a dual violation instead,
  its product here as 0) — zero at a KKT point by complementarity.

A backend that returns no multipliers (``y`` or ``z`` of ``None``) gets ``None`` for the dual
residual and the gap. The QPs are those the backend saw (:meth:`wbc.Controller.last_qps`): in an
eliminating level, the reduced QP in the null-space coordinates.

**Export.** :func:`export_qp` writes one QP as ``.npz`` in the layout of qpsolvers'
``Problem.save`` (and qpbenchmark's): ``P, q, G, h, A, b, lb, ub`` for
``min ½x'Px + q'x`` s.t. ``Gx <= h``, ``Ax = b``, ``lb <= x <= ub`` — equality rows
(``lA = uA``) in ``A, b``, the finite sides of the others as rows of ``G, h``, infinite
bounds as ``±inf`` in ``lb, ub`` (absent parts as ``None``, as ``Problem.save`` writes them) —
plus ``x_referee`` (the referee's solution of that very QP), ``label`` and ``status``.
``qpsolvers.Problem.load(path)`` reads it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from wbc.qp import Status

#: the referee: backend, profile, options
REFEREE: tuple[str, str, dict[str, Any]] = ("quadprog", "tight", {"time_limit": None})
#: the second exact solver, whose distance to the referee is the tick's referee gap
SECOND_REFEREE: tuple[str, str, dict[str, Any]] = ("clarabel", "tight", {})
#: a fully solved tick further than this plus the referee gap from the referee's command is
#: "wrong" [rad/s or rad/s², ∞-norm] (``wbc exactness``'s tolerance)
WRONG_THRESHOLD = 1e-5
#: two certified referees further apart than this leave the tick unjudged [rad/s or rad/s²]
#: (``wbc exactness`` asks 1e-6; on the saturating scenarios quadprog and clarabel, both tight
#: and certified, are 1e-6 to 1e-5 apart on a quarter of the three-level ticks)
REFEREE_AGREE = 1e-5
#: a referee's level is certified when its primal and dual residuals and duality gap are at
#: most this times ``max(1, max|H|, max|g|)`` (the helpers of the tests use the same scale)
KKT_TOL = 1e-6


def residuals(qp: tuple, result) -> dict:
    """``{"primal", "dual", "gap"}`` of ``result`` (a :class:`wbc.qp.QPResult`) on
    ``qp = (H, g, A, lA, uA, lb, ub)``; ``None`` for a failed QP."""
    if result is None or result.status is not Status.SOLVED:
        return {"primal": None, "dual": None, "gap": None}
    H, g, A, lA, uA, lb, ub = (np.asarray(a, float) for a in qp)
    x = np.asarray(result.x, float)
    Ax = A @ x if A.size else np.zeros(0)
    violation = np.concatenate([lA - Ax, Ax - uA, lb - x, x - ub, [0.0]])
    primal = float(np.max(violation[np.isfinite(violation)]))
    y, z = result.y, result.z
    if y is None or z is None:
        return {"primal": primal, "dual": None, "gap": None}
    y, z = np.asarray(y, float), np.asarray(z, float)
    dual = float(np.max(np.abs(H @ x + g + (A.T @ y if A.size else 0.0) + z), initial=0.0))
    gap = x @ H @ x + g @ x
    for mult, lower, upper in ((y, lA, uA), (z, lb, ub)):
        plus, minus = np.maximum(mult, 0.0), np.maximum(-mult, 0.0)
        gap += np.sum(np.where(np.isfinite(upper), upper, 0.0) * plus)
        gap -= np.sum(np.where(np.isfinite(lower), lower, 0.0) * minus)
    return {"primal": primal, "dual": dual, "gap": float(abs(gap))}


def certified_qp(qp: tuple, result) -> bool:
    """Whether ``result`` solves ``qp`` (see :data:`KKT_TOL`); ``False`` without multipliers."""
    res = residuals(qp, result)
    if any(value is None for value in res.values()):
        return False
    scale = max(1.0, float(np.abs(qp[0]).max(initial=0.0)),
                float(np.abs(qp[1]).max(initial=0.0)))
    return max(res.values()) <= KKT_TOL * scale


def certified(controller) -> bool:
    """Whether the last tick of ``controller`` (the ordinary cascade) is fully solved and every
    level's answer certified by its KKT residuals (:func:`certified_qp`)."""
    solution = controller.last_solution
    if solution is None or not solution.ok:
        return False
    return all(certified_qp(qp, result) for _, qp, result in controller.last_qps())


def qpsolvers_arrays(qp: tuple) -> dict:
    """``qp = (H, g, A, lA, uA, lb, ub)`` in qpsolvers' form (see the module docstring)."""
    H, g, A, lA, uA, lb, ub = (np.array(a, float) for a in qp)
    equal = np.isfinite(lA) & (lA == uA)
    upper = np.isfinite(uA) & ~equal
    lower = np.isfinite(lA) & ~equal
    G = np.vstack([A[upper], -A[lower]]) if A.size else np.zeros((0, len(g)))
    h = np.concatenate([uA[upper], -lA[lower]]) if A.size else np.zeros(0)
    return {"P": H, "q": g, "G": G if len(h) else None, "h": h if len(h) else None,
            "A": A[equal] if equal.any() else None, "b": uA[equal] if equal.any() else None,
            "lb": lb if np.isfinite(lb).any() else None,
            "ub": ub if np.isfinite(ub).any() else None}


def export_qp(path: Path, qp: tuple, label: str, status: str, x_referee) -> Path:
    """Write one QP (see the module docstring); returns the file's path."""
    arrays = qpsolvers_arrays(qp)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload: dict[str, Any] = {k: np.array(v) for k, v in arrays.items()}
    payload.update(x_referee=np.array(x_referee), label=np.array(label),
                   status=np.array(status))
    np.savez(path, **payload)
    return path


class Referee:
    """The referees' solutions of single QPs (for the export): :data:`REFEREE`'s when
    certified (:func:`certified_qp`), else :data:`SECOND_REFEREE`'s when certified, else none.
    A fresh backend per QP (stateless, like the files)."""

    def __init__(self):
        from wbc.solvers import make_backend

        self._make = make_backend

    def solve(self, qp: tuple):
        """``x`` of the QP, or ``None`` when no referee certifies an answer."""
        for name, profile, options in (REFEREE, SECOND_REFEREE):
            backend = self._make(name, profile, **options)
            backend.setup(*qp)
            result = backend.solve(None)
            if result.status is Status.SOLVED and certified_qp(qp, result):
                return result.x.copy()
        return None


def write_index(folder: Path, entries: list[dict]) -> None:
    """``folder/index.json``: what was exported (file, tick, level label, (n, m), status)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "index.json").write_text(json.dumps(entries, indent=1))
