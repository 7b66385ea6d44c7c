"""Which hard constraints conflict: an irreducible infeasible subset (IIS) of named constraints.

When a level's QP is infeasible, the rows ``lA <= A x <= uA`` and bounds ``lb <= x <= ub`` that
cannot hold together are found from LPs, in two steps.

**Rows and bounds** (:func:`infeasible_subset`), by Farkas' lemma. Write every finite side as a
row ``g_k x <= h_k`` (rows normalised to ``|g_k| = 1``). The system is infeasible exactly when
some ``y >= 0`` has ``Gᵀ y = 0`` and ``hᵀ y < 0``; the LP

    minimise hᵀ y   subject to   Gᵀ y = 0,  1ᵀ y = 1,  y >= 0

finds one at a vertex (dual simplex). A vertex of this polytope is an extreme ray of the cone
``{y >= 0, Gᵀ y = 0}``: its support is minimal, so the sides it uses are an IIS — drop any one
and the rest is feasible (Gleeson & Ryan, 1990). ``-hᵀ y`` is the margin of the conflict (how far,
in the normalised rows' units, the constraints miss each other); a conflict below ``tol`` is
not reported (the solver then failed within its tolerance, not because of the data).

**Named constraints** (:func:`named_subset`). What a user can drop is a constraint — all the
rows and bounds it contributes — not one side, and an IIS of sides, named, need not be
irreducible by name: a table height the arm cannot reach uses the position limits of some
joints and the velocity limits of others, yet without the position limits the velocity limits
alone may still forbid it. And bounds of several constraints on one variable are merged into
one ``lb``/``ub``: only the constraint(s) whose value is the binding one take part, and dropping
one leaves the others' values (``HardNames.bound_values``, evaluated at the QP's parameters
``p``; a :class:`Diagnosis` given no ``p`` drops the names bounding one variable only together,
so that its set conflicts but may name one too many there). A deletion filter over the names
of the first conflict keeps exactly those whose removal makes the rest feasible: the names
reported conflict, and without any one of them the others can hold.

This runs only after a level failed (one LP, then one per name of its conflict: ≈ 10 ms for
three names, and importing scipy the first time, ≈ 0.2 s), never on a solved tick — and not on
the failed tick either: a failed QP keeps a :class:`Diagnosis` (a copy of its arrays), and the
LPs run when the conflict or the message is first read, so that the tick hands its fallback
command over in time.
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

#: A group of variable bounds that holds while all its names do: ``(names, lower, upper)``,
#: ``lower``/``upper`` over ``x`` (±inf where the group does not bound), in ``x``'s units.
BoundGroup = tuple[tuple[str, ...], np.ndarray, np.ndarray]


def named_subset(A: np.ndarray, lA: np.ndarray, uA: np.ndarray, row_names: list[str],
                 bounds: list[BoundGroup], tol: float = 1e-9) -> list[tuple[str, Conflict]]:
    """An irreducible infeasible set of *named constraints*, by a deletion filter.

    A name owns its rows (``row_names[i]`` is row ``i``'s) and the bounds of the groups that
    name it; the variable bounds of a set ``S`` of names are the row-wise max/min of the groups
    whose names are all in ``S``. Starting from the names of one :func:`infeasible_subset` of
    everything, each name is dropped in turn: if the others still conflict (again by
    :func:`infeasible_subset`), it goes, and the set shrinks to the names of that new conflict;
    otherwise it stays. Every name left is needed (drop it and the rest meets, within ``tol``)
    and together they conflict: one LP per name of the first conflict.

    Returns:
        The sides of the last conflict found, each with the name it is attributed to (a row:
        its owner; a bound: every name of a group that sets that side's value), largest
        multiplier first; empty if the whole system is feasible (within ``tol``).
    """
    n = A.shape[1]

    def system(names: set[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        rows = np.array([name in names for name in row_names], dtype=bool)
        lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
        for group, lower, upper in bounds:
            if names.issuperset(group):
                np.maximum(lb, lower, out=lb)
                np.minimum(ub, upper, out=ub)
        return np.where(rows, lA, -np.inf), np.where(rows, uA, np.inf), lb, ub

    def attributed(names: set[str]) -> list[tuple[str, Conflict]]:
        low, up, lb, ub = system(names)
        found = []
        for c in infeasible_subset(A, low, up, lb, ub, tol):
            if c.kind == "row":
                found.append((row_names[c.index], c))
                continue
            side = 2 if c.side == UPPER else 1  # in a group (names, lower, upper)
            value = (ub if side == 2 else lb)[c.index]
            found += [(name, c) for group in bounds
                      if names.issuperset(group[0]) and group[side][c.index] == value
                      for name in group[0]]
        return found

    found = attributed(set(row_names).union(*(group for group, _, _ in bounds)))
    kept = {name for name, _ in found}
    for candidate in list(dict.fromkeys(name for name, _ in found)):
        if candidate in kept:
            smaller = attributed(kept - {candidate})
            if smaller:
                found, kept = smaller, {name for name, _ in smaller}
    return found


def _bound_groups(block, lb: np.ndarray, ub: np.ndarray,
                  p: np.ndarray | None) -> list[BoundGroup]:
    """The variable bounds of ``block`` by name: one group per constraint from
    ``HardNames.bound_values(p)`` when ``p`` is known and they combine into ``lb``/``ub``;
    otherwise the combined bounds, one group per set of names bounding the same variables (the
    names of an overlap are then dropped only together: the conflict found holds, but may not
    be irreducible where bounds overlap)."""
    hard_names = block.hard_names
    if hard_names is not None and hard_names.bound_values is not None and p is not None:
        L, U = (np.array(v, dtype=float).reshape(len(lb), -1)
                for v in hard_names.bound_values(p))
        # bounds of parameters not set yet (see Workspace.fixed_conflict) bound nothing
        L, U = np.where(np.isnan(L), -np.inf, L), np.where(np.isnan(U), np.inf, U)
        if (np.array_equal(L.max(axis=1, initial=-np.inf), lb)
                and np.array_equal(U.min(axis=1, initial=np.inf), ub)):
            return [((name,), L[:, j], U[:, j]) for j, name in enumerate(hard_names.bound_owners)]
    owners = [names or ("variable bounds",)
              for names in (hard_names.bounds if hard_names else [()] * len(lb))]
    return [(names, np.where(mask, lb, -np.inf), np.where(mask, ub, np.inf))
            for names in dict.fromkeys(owners)
            for mask in [np.array([o == names for o in owners], dtype=bool)]]


def level_conflict(block, A: np.ndarray, lA: np.ndarray, uA: np.ndarray, lb: np.ndarray,
                   ub: np.ndarray, variables,
                   p: np.ndarray | None = None) -> tuple[tuple[str, ...], str]:
    """The conflicting hard constraints of one failed QP of the cascade.

    Args:
        block: its :class:`~wbc.compiler.QPBlock` (row layout and :class:`HardNames`).
        A, lA, uA, lb, ub: the arrays the backend was given (``A`` over ``z = [x; ...]``).
        variables: the stack's :class:`~wbc.Variables` (to name ``x``'s entries).
        p: the stack's parameter vector of that QP, to split the variable bounds by the
            constraint that set them (``HardNames.bound_values``); without it, overlapping
            bounds are named together (see :func:`_bound_groups`).

    Returns:
        ``(names, details)``: the names of an irreducible infeasible set of the hard
        constraints, "the levels above" (the frozen rows) taking part as one
        (:func:`named_subset`), and a sentence naming each row or bound involved; ``((), "")``
        if none is found.
    """
    n = variables.n
    hard_names = block.hard_names
    kept = np.concatenate([np.arange(block.m_hard), np.arange(block.m_top, block.m_total)])
    row_names = [ABOVE if row >= block.m_hard else
                 hard_names.rows[row] if hard_names else "hard constraints" for row in kept]
    found = named_subset(A[kept, :n], lA[kept], uA[kept], row_names,
                         _bound_groups(block, lb[:n], ub[:n], p))
    if not found:
        return (), ""
    # constraint name -> what -> indices (variables or the constraint's own rows)
    parts: dict[str, dict[str, list[int]]] = {}
    for name, c in found:
        whats = parts.setdefault(name, {})
        if c.kind == "bound":
            whats.setdefault(f"{c.side} bound of", []).append(c.index)
        elif name == ABOVE:
            whats.setdefault("their optimum", [])
        else:
            row = int(kept[c.index])
            local = row - hard_names.rows.index(name) if hard_names else row
            whats.setdefault(f"{c.side} side of row", []).append(local)
    details = "; ".join(f"{name!r} ({_listing(whats, variables)})"
                        for name, whats in parts.items())
    return tuple(parts), f"hard constraints that cannot hold together: {details}"


def fixed_conflict(compiled, p: np.ndarray) -> tuple[str, tuple[str, ...], str] | None:
    """Hard constraints that contradict each other whatever the state: those whose values are
    known before the first tick and no ``x`` meets.

    Args:
        compiled: a :class:`~wbc.compiler.CompiledStack` whose QP functions are symbolic (not
            yet built to C: the dependencies are read from them).
        p: its parameter vector, NaN where not set yet (model quantities, references).

    Returns:
        ``(QP label, names, details)`` of the first QP with such a conflict (an irreducible
        set, as :func:`level_conflict`), else ``None``. A row or bound is known when it depends
        on no parameter that is unset (constants and parameters with defaults, e.g. a
        :class:`~wbc.tasks.Bounds`' sides): one evaluation and one Jacobian sparsity per QP,
        an LP only when rows are known or bounds cross.
    """
    n = compiled.n
    unknown = np.isnan(p)
    for block in compiled.blocks:
        fn, m = block.function, block.m_hard
        values = [np.array(v, dtype=float) for v in fn(np.where(unknown, 0.0, p))]
        # a value is known when its Jacobian has no entry on an unset parameter
        known = [~_depends(fn, i, unknown) for i in range(len(values))]
        # outputs: H, g, Aᵀ of the top rows, their sides, lb, ub, Eᵀ (see wbc.compiler)
        m_top = block.m_top
        A = values[2].reshape(m_top, block.n_z)[:m, :n]  # Aᵀ column-major = A row-major
        rows = known[2].reshape(m_top, block.n_z)[:m, :n].all(axis=1)
        rows &= known[3].reshape(-1)[:m] & known[4].reshape(-1)[:m]
        lb = np.where(known[5].reshape(-1)[:n], values[5].reshape(-1)[:n], -np.inf)
        ub = np.where(known[6].reshape(-1)[:n], values[6].reshape(-1)[:n], np.inf)
        if not rows.any() and np.all(lb <= ub):
            continue  # known bounds only, in order: nothing to look for
        A_all = np.zeros((block.m_total, block.n_z))
        lA = np.full(block.m_total, -np.inf)
        uA = np.full(block.m_total, np.inf)
        A_all[:m, :n][rows] = A[rows]
        lA[:m][rows] = values[3].reshape(-1)[:m][rows]
        uA[:m][rows] = values[4].reshape(-1)[:m][rows]
        names, details = level_conflict(block, A_all, lA, uA, lb, ub, compiled.variables,
                                        np.where(unknown, np.nan, p))
        if names:
            return block.label, names, details
    return None


def _depends(fn, output: int, inputs: np.ndarray) -> np.ndarray:
    """Per entry of ``fn``'s output ``output`` (column-major): whether it depends on an entry
    of its input 0 where ``inputs`` is true (from the Jacobian's sparsity)."""
    sparsity = fn.sparsity_jac(0, output)
    rows, cols = sparsity.get_triplet()
    depends = np.zeros(sparsity.size1(), dtype=bool)
    hit = inputs[np.asarray(cols, dtype=int)]
    depends[np.asarray(rows, dtype=int)[hit]] = True
    return depends


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
        block, A, lA, uA, lb, ub, variables, p: as :func:`level_conflict`.
    """

    __slots__ = ("_arguments", "_found")

    def __init__(self, block, A: np.ndarray, lA: np.ndarray, uA: np.ndarray, lb: np.ndarray,
                 ub: np.ndarray, variables, *, p: np.ndarray | None = None) -> None:
        self._arguments: tuple | None = (block, A.copy(), lA.copy(), uA.copy(), lb.copy(),
                                         ub.copy(), variables, None if p is None else p.copy())
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
