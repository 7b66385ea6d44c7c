"""Which hard constraints conflict: an irreducible infeasible subset (IIS) of a level's rows.

When a level's QP is infeasible, the rows ``lA <= A x <= uA`` and bounds ``lb <= x <= ub`` that
cannot hold together are found from one LP, by Farkas' lemma. Write every finite side as a row
``g_k x <= h_k`` (rows normalised to ``|g_k| = 1``). The system is infeasible exactly when some
``y >= 0`` has ``Gᵀ y = 0`` and ``hᵀ y < 0``; the LP

    minimise hᵀ y   subject to   Gᵀ y = 0,  1ᵀ y = 1,  y >= 0

finds one at a vertex (dual simplex). A vertex of this polytope is an extreme ray of the cone
``{y >= 0, Gᵀ y = 0}``: its support is minimal, so the rows it uses are an IIS — drop any one
and the rest is feasible (Gleeson & Ryan, 1990). ``-hᵀ y`` is the margin of the conflict (how far,
in the normalised rows' units, the constraints miss each other); a conflict below ``tol`` is
not reported (the solver then failed within its tolerance, not because of the data).

This runs only after a level failed (one small LP, ≈ 1–3 ms, and importing scipy the first
time, ≈ 0.2 s), never on a solved tick — and not on the failed tick either: a failed QP keeps a
:class:`Diagnosis` (a copy of its arrays), and the LP runs when the conflict or the message is
first read, so that the tick hands its fallback command over in time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UPPER, LOWER = "upper", "lower"


@dataclass(frozen=True)
class Conflict:
    """One side of a row or bound in an infeasible subset.

    Attributes:
        kind: ``"row"`` (a row of ``A``) or ``"bound"`` (a variable bound).
        index: the row of ``A`` or the variable's index in ``x``.
        side: ``"upper"`` or ``"lower"``.
        weight: its Farkas multiplier (how much it contributes to the conflict).
    """

    kind: str
    index: int
    side: str
    weight: float


def infeasible_subset(A: np.ndarray, lA: np.ndarray, uA: np.ndarray, lb: np.ndarray,
                      ub: np.ndarray, tol: float = 1e-9) -> list[Conflict]:
    """An irreducible set of sides of ``lA <= A x <= uA``, ``lb <= x <= ub`` that no ``x``
    meets (see the module docstring), largest multiplier first; empty if the system is
    feasible or misses by less than ``tol``. Rows with both sides infinite are ignored."""
    from scipy.optimize import linprog  # only after a failure: keeps `import wbc` light

    A = np.asarray(A, dtype=float)
    n = A.shape[1]
    rows_g: list[np.ndarray] = []
    rows_h: list[float] = []
    labels: list[tuple[str, int, str]] = []
    for kind, rows, lower, upper in (("row", A, lA, uA), ("bound", np.eye(n), lb, ub)):
        norms = np.linalg.norm(rows, axis=1)
        for side, values, sign in ((UPPER, upper, 1.0), (LOWER, lower, -1.0)):
            for i in np.flatnonzero(np.isfinite(values)):
                if norms[i] == 0.0:  # 0 <= u: either always true or a conflict by itself
                    if sign * values[i] < -tol:
                        return [Conflict(kind, int(i), side, 1.0)]
                    continue
                rows_g.append(sign * rows[i] / norms[i])
                rows_h.append(sign * values[i] / norms[i])
                labels.append((kind, int(i), side))
    if not rows_g:
        return []
    G, h = np.array(rows_g), np.array(rows_h)
    k = len(h)
    equalities = np.vstack([G.T, np.ones((1, k))])
    rhs = np.concatenate([np.zeros(n), [1.0]])
    lp = linprog(h, A_eq=equalities, b_eq=rhs, bounds=(0, None), method="highs-ds")
    if lp.status != 0 or lp.fun > -tol:
        return []
    y = lp.x
    support = np.flatnonzero(y > 1e-9 * y.max())
    order = support[np.argsort(-y[support])]
    return [Conflict(labels[i][0], labels[i][1], labels[i][2], float(y[i])) for i in order]


ABOVE = "the levels above"  # the name of the frozen rows a lower level keeps


def level_conflict(block, A: np.ndarray, lA: np.ndarray, uA: np.ndarray, lb: np.ndarray,
                   ub: np.ndarray, variables) -> tuple[tuple[str, ...], str]:
    """The conflicting hard constraints of one failed QP of the cascade.

    Args:
        block: its :class:`~wbc.compiler.QPBlock` (row layout and :class:`HardNames`).
        A, lA, uA, lb, ub: the arrays the backend was given (``A`` over ``z = [x; ...]``).
        variables: the stack's :class:`~wbc.Variables` (to name ``x``'s entries).

    Returns:
        ``(names, details)``: the names of the constraints in an irreducible infeasible subset
        of the hard rows, bounds and frozen rows (:func:`infeasible_subset`), and a sentence
        naming each row or bound involved; ``((), "")`` if none is found.
    """
    n = variables.n
    hard = np.arange(block.m_hard)
    frozen = np.arange(block.m_top, block.m_total)
    kept = np.concatenate([hard, frozen])
    conflicts = infeasible_subset(A[kept, :n], lA[kept], uA[kept], lb[:n], ub[:n])
    if not conflicts:
        return (), ""
    hard_names = block.hard_names
    # constraint name -> what -> indices (variables or the constraint's own rows)
    parts: dict[str, dict[str, list[int]]] = {}
    for c in conflicts:
        if c.kind == "bound":
            owners = (hard_names.bounds[c.index] if hard_names else ()) or ("variable bounds",)
            for owner in owners:
                parts.setdefault(owner, {}).setdefault(f"{c.side} bound of", []).append(c.index)
            continue
        row = int(kept[c.index])
        if row < block.m_hard:
            owner = hard_names.rows[row] if hard_names else "hard constraints"
            local = row - hard_names.rows.index(owner) if hard_names else row
            parts.setdefault(owner, {}).setdefault(f"{c.side} side of row", []).append(local)
        else:
            parts.setdefault(ABOVE, {}).setdefault("their optimum", [])
    details = "; ".join(f"{name!r} ({_listing(whats, variables)})"
                        for name, whats in parts.items())
    return tuple(parts), f"hard constraints that cannot hold together: {details}"


def _listing(whats: dict[str, list[int]], variables) -> str:
    """``{"upper bound of": [1, 0]}`` -> ``"upper bound of x[0], x[1]"`` (rows: their
    numbers, bounds: the variables' names), in index order."""
    return ", ".join(" ".join([what, ", ".join(
        _entry(variables, i) if what.endswith("bound of") else str(i) for i in sorted(items))
    ]).strip() for what, items in whats.items())


def _entry(variables, index: int) -> str:
    """``"block[i]"`` for entry ``index`` of the decision vector."""
    for name in variables.names:
        sl = variables.slice(name)
        if sl.start <= index < sl.stop:
            return f"{name}[{index - sl.start}]"
    return f"x[{index}]"


class Diagnosis:
    """The conflict of one failed QP of the cascade (:func:`level_conflict`), found the first
    time it is asked for (see the module docstring); the arrays are copied when the QP fails
    (the workspace's buffers are the next tick's).

    Args:
        block, A, lA, uA, lb, ub, variables: as :func:`level_conflict`.
    """

    __slots__ = ("_arguments", "_found")

    def __init__(self, block, A: np.ndarray, lA: np.ndarray, uA: np.ndarray, lb: np.ndarray,
                 ub: np.ndarray, variables) -> None:
        self._arguments: tuple | None = (block, A.copy(), lA.copy(), uA.copy(), lb.copy(),
                                         ub.copy(), variables)
        self._found: tuple[tuple[str, ...], str] | None = None

    def found(self) -> tuple[tuple[str, ...], str]:
        """``(names, details)`` of :func:`level_conflict`, computed once."""
        if self._found is None:
            assert self._arguments is not None  # released only once found
            self._found = level_conflict(*self._arguments)
            self._arguments = None
        return self._found

    @property
    def conflict(self) -> tuple[str, ...]:
        return self.found()[0]

    @property
    def details(self) -> str:
        return self.found()[1]
