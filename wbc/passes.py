"""Compile passes: a :class:`~wbc.compiler.CompiledStack` turned, once, into what the tick
evaluates.

A compiled stack is immutable: each pass returns a new object and leaves its input as it was.
The passes, in the order :class:`~wbc.Controller` applies them:

* :func:`compiled_kinematics` (``CompiledStack -> CompiledStack``, ``kinematics="compiled"``):
  the model quantities that have a symbolic form (frame poses, Jacobians, drifts) computed
  inside the level functions from ``"q"`` (and ``"v"``); their parameters leave the layout.
* then either :func:`jit_compiled` (``CompiledStack -> CompiledStack``, ``jit=True``, the
  ordinary path): every block function evaluated as compiled C (:mod:`wbc.cbuild`);
* or :func:`fused_function` (``CompiledStack -> casadi.Function``, ``fused=True``): the whole
  cascade — the level functions, one daqp node per QP, the frozen rows of the levels above,
  the certificate, the clipping — as one function ``p -> x``, which
  :class:`~wbc.fused.FusedWorkspace` builds as C (with :func:`fused_settings`,
  :func:`daqp_link_arguments` and :func:`initialise_success`) and calls every tick.

The design of the fused cascade — the band of the frozen task rows, the certificate of the exact
level problems, which stacks are fused and why, and the measurements behind each constant — is
the module docstring of :mod:`wbc.fused`. The passes' former homes re-export them
(``wbc.controller.compiled_kinematics``, ``wbc.jit.jit_compiled``, ``wbc.fused.fused_function``
and the fused constants).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import casadi as ca
import numpy as np

from .cbuild import DEFAULT_FLAGS, compiled_c
from .compiler import LEVEL, MIN_NORM, CompiledStack
from .errors import ShapeError, WbcError
from .quantities import STATE_QUANTITIES, registry_of
from .workspace import _ABS_RANK_TOL


# ------------------------------------------------------------------ kinematics
def compiled_kinematics(compiled: CompiledStack, robot) -> CompiledStack:
    """A copy of ``compiled`` whose level functions compute every model quantity that has a
    symbolic form (``robot.quantities``, e.g. ``"pose[<frame>]"``, ``"J[<frame>]"``,
    ``"Jdot_v[<frame>]"``) from parameters ``"q"`` (and ``"v"`` for quantities that need it)
    inside the compiled functions. Those parameters leave the layout; ``"q"`` and ``"v"`` are
    appended if the stack needs them and had none.

    Raises:
        WbcError: no quantity of the stack has a symbolic form on this robot.
    """
    registry = registry_of(robot)
    replaced, numeric_only = {}, []  # parameter name -> Quantity; names without symbolic form
    for name in compiled.parameters:
        if name in STATE_QUANTITIES:
            continue
        quantity = (registry.get(name) if name in compiled.quantities else
                    registry.resolve(name))
        if quantity is not None:
            if quantity.symbolic is not None:
                replaced[name] = quantity
            else:
                numeric_only.append(name)
    if not replaced:
        if numeric_only:
            raise WbcError(f"kinematics='compiled' needs symbolic forms of the model quantities "
                           f"{numeric_only} (e.g. robot.symbolic_frame(frame) -> "
                           f"casadi.Function); {type(robot).__name__} offers none")
        return compiled
    params = dict(compiled.parameters)
    n_p = compiled.defaults.shape[0]
    needs_v = any(quantity.needs_v for quantity in replaced.values())
    appended: list[int] = []
    for name, size, needed in (("q", int(robot.nq), True), ("v", int(robot.nv), needs_v)):
        if needed and name not in params:
            params[name] = (n_p + sum(appended), (size, 1), False)
            appended.append(size)
    defaults = np.concatenate([compiled.defaults, np.full(sum(appended), np.nan)])
    p = ca.SX.sym("p", defaults.shape[0])

    def column(name: str) -> ca.SX:
        offset, (rows, _), _ = params[name]
        return p[offset:offset + rows]

    entries = [p[i] for i in range(n_p)]
    for name, quantity in replaced.items():
        offset, shape, _ = params.pop(name)
        build = quantity.symbolic
        assert build is not None  # replaced holds the quantities with a symbolic form only
        function = build()
        inputs = [column("q"), column("v")] if quantity.needs_v else [column("q")]
        value = function(*inputs)
        if value.shape != shape:
            raise ShapeError(f"the symbolic form of {name!r} gives shape {value.shape}, the "
                             f"stack declares {shape}")
        for c in range(shape[1]):
            for r in range(shape[0]):
                entries[offset + c * shape[0] + r] = value[r, c]
    p_in = ca.vertcat(*entries)
    blocks = []
    for block in compiled.blocks:
        fn = block.function
        outputs = fn.call([p_in])
        new = ca.Function(f"{fn.name()}_kin", [p], outputs, fn.name_in(), fn.name_out())
        names = block.hard_names
        if names is not None and names.bound_values is not None:  # a function of p too
            bounds = names.bound_values
            names = dataclasses.replace(names, bound_values=ca.Function(
                f"{bounds.name()}_kin", [p], bounds.call([p_in])))
        blocks.append(dataclasses.replace(block, function=new, hard_names=names))
    residuals = compiled.residuals
    if residuals is not None:
        x = ca.SX.sym("x", compiled.n)
        residuals = ca.Function("residuals_kin", [p, x], residuals.call([p_in, x]))
    quantities = compiled.quantities - replaced.keys()
    if appended:
        quantities = quantities | {"q"} | ({"v"} if needs_v else set())
    return dataclasses.replace(compiled, parameters=params, defaults=defaults,
                               blocks=tuple(blocks), quantities=frozenset(quantities),
                               residuals=residuals)


# ------------------------------------------------------------------------- JIT
def jit_compiled(compiled: CompiledStack,
                 flags: tuple[str, ...] = DEFAULT_FLAGS) -> CompiledStack:
    """A copy of ``compiled`` whose block functions are compiled C (same inputs and outputs).

    The compiled stack is immutable: this returns a new one (``dataclasses.replace``). If no C
    compiler works, warns and returns ``compiled`` unchanged (the CasADi virtual machine).
    """
    try:
        blocks = tuple(dataclasses.replace(block, function=compiled_c(block.function, flags))
                       for block in compiled.blocks)
    except RuntimeError as err:
        warnings.warn(f"JIT compilation failed, using CasADi's virtual machine: {err}",
                      RuntimeWarning, stacklevel=2)
        return compiled
    return dataclasses.replace(compiled, blocks=blocks)


# ------------------------------------------------------------- the fused tick
#: Settings of the DAQP bundled with casadi (``DAQPSettings`` in ``casadi/include/daqp``).
DAQP_SETTINGS = frozenset({"primal_tol", "dual_tol", "zero_tol", "pivot_tol", "progress_tol",
                           "cycle_tol", "iter_limit", "fval_bound", "eps_prox", "eta_prox",
                           "rho_soft", "rel_subopt", "abs_subopt"})


#: DAQP's default ``primal_tol`` (``DEFAULT_PRIM_TOL`` in ``casadi/include/daqp/constants.h``).
DAQP_PRIMAL_TOL = 1e-6
#: Relative half-width of the band the frozen task rows of a fused cascade are kept in (see
#: :mod:`wbc.fused`).
FROZEN_BAND = 1e-11
#: The largest ``primal_tol`` of the generated daqp of a cascade (see :mod:`wbc.fused`).
CASCADE_PRIMAL_TOL = 1e-10
#: The certificate of a cascade's levels (see :mod:`wbc.fused`): relative distance to its
#: side within which a bound or inequality with a multiplier counts as active, and relative
#: violation of a side it accepts.
CERTIFICATE_TOL = 1e-9
#: The kinds of QP the fused tick solves (task-scaling LPs are not fused).
FUSED_KINDS = frozenset({LEVEL, MIN_NORM})


def daqp_link_arguments() -> tuple[str, ...]:
    """Compiler arguments that build generated code calling daqp: the include folder and the
    static library shipped in the casadi wheel. Raises :class:`~wbc.WbcError` if the wheel has
    none (a casadi built without daqp)."""
    root = Path(ca.__file__).parent
    include, library = root / "include", root / "libdaqpstat.a"
    if not (include / "daqp" / "api.h").exists() or not library.exists():
        raise WbcError(f"casadi at {root} ships no daqp headers and static library "
                       "(include/daqp, libdaqpstat.a)")
    return (f"-I{include}", str(library), "-lm")


_SETUP_FAILED = "if (flag<0) return 1;"


def initialise_success(source: str) -> str:
    """Correct CasADi's generated daqp code (casadi 3.6–3.8): when daqp's setup fails (e.g. a
    Hessian that is not positive definite), ``casadi_daqp_solve`` returns before it writes the
    QP's ``success`` flag, and the caller, which ignores that return value, reads the flag
    uninitialised from the stack — a failed setup can then pass for a solved QP, with garbage
    in ``x``. The patch writes ``success = 0`` on that path.

    Raises:
        RuntimeError: the generated code does not have the expected shape (another casadi).
    """
    if source.count(_SETUP_FAILED) != 1:
        raise RuntimeError("the daqp code CasADi generates has changed (expected one "
                           f"{_SETUP_FAILED!r}); the fused tick is not built")
    return source.replace(_SETUP_FAILED, "if (flag<0) { d_qp->success = 0; return 1; }")


def why_not_fused(compiled: CompiledStack, options: dict) -> str | None:
    """Why ``compiled`` cannot take the fused path with daqp ``options``, or ``None`` if it
    can (see :mod:`wbc.fused`)."""
    lps = [b.label for b in compiled.blocks if b.kind not in FUSED_KINDS]
    if lps:
        return (f"the cascade has task-scaling LPs ({', '.join(lps)}); only least-squares "
                "levels and the min-norm level are fused")
    unknown = sorted(set(options) - DAQP_SETTINGS)
    if unknown:
        return f"the daqp bundled with casadi has no setting {unknown}"
    return None


def fused_settings(compiled: CompiledStack, options: dict) -> dict:
    """The daqp settings of the generated solver: ``options``, with ``primal_tol`` at most
    :data:`CASCADE_PRIMAL_TOL` in a cascade (see :mod:`wbc.fused`)."""
    settings = dict(options)
    if len(compiled.blocks) > 1:
        settings["primal_tol"] = min(settings.get("primal_tol", DAQP_PRIMAL_TOL),
                                     CASCADE_PRIMAL_TOL)
    return settings


def _frozen_rows(E: ca.MX, x: ca.MX, lb: ca.MX, ub: ca.MX, band: float, rank_tol: float):
    """Rows ``(R, lower, upper)`` keeping ``E x`` where it is at ``x`` within a band: each row
    without the variables this level fixes (``lb == ub``, as the ordinary path does), scaled to
    unit norm, held in ``|r·y − r·x| <= band·(1 + |r·x|)``. A row whose norm is at most
    ``max(1e-12, rank_tol·ρ)`` (``ρ`` the largest row norm, 1 if a variable is fixed: the
    ordinary path's first pivot) is zero for the ordinary path's rank decision, and is made
    zero here (inert) — scaled to unit norm, rounding noise (a Jacobian row of 1e-11) would be
    frozen as a constraint the ordinary path does not have."""
    fixed = lb == ub
    free = ca.repmat((1 - fixed).T, E.shape[0], 1)
    E = E * free
    norms = ca.sqrt(ca.sum2(E * E))
    floor = ca.fmax(_ABS_RANK_TOL, rank_tol * ca.fmax(ca.mmax(norms), ca.mmax(fixed)))
    kept = norms > floor
    E = E * ca.repmat(kept / ca.if_else(kept, norms, 1.0), 1, E.shape[1])
    c = E @ x
    half = band * (1 + ca.fabs(c))
    return E, c - half, c + half


def _cascade(compiled: CompiledStack, p: ca.MX, solve) -> tuple[ca.MX, list[dict]]:
    """The fused cascade, symbolically: for every block its QP (``h, g, a, lba, uba, lbx,
    ubx``, the frozen rows of the levels above appended), solved by ``solve(index, qp) -> (z,
    cost, lam_a, lam_x)``, and the level's ``x`` (``z[:n]`` clipped into the bounds). Returns
    the last ``x`` and, per block, a dict of the QP and its results."""
    n = compiled.n
    band = FROZEN_BAND
    cost_rows: list[ca.MX] = []  # weighted task rows of the levels solved
    soft: list[tuple[ca.MX, ca.MX, ca.MX]] = []  # their soft rows, shifted by the slacks
    x = ca.MX.zeros(n)  # Stack.x_above() is 0 at the first level
    levels = []
    for i, block in enumerate(compiled.blocks):
        p_in = p if compiled.x_above_offset is None else _substituted(
            p, compiled.x_above_offset, x)
        H, g, AT, lA, uA, lb, ub, ET = block.function(p_in)
        n_z = block.n_z
        # A variable its bounds fix (lb == ub: pinned by a zero mobility, whose metric M⁺ has a
        # zero there) gets 1 on H's diagonal: constant on the feasible set, so the same
        # optimum, and the Cholesky factorisation daqp's setup needs exists.
        fixed = ca.vertcat(lb == ub, ca.DM.zeros(n_z - n))
        H = H + ca.diag(fixed)
        rows, lower, upper = [AT.T], [lA], [uA]
        if block.n_frozen_soft:
            C = ca.vertcat(*[s[0] for s in soft])
            rows.append(ca.horzcat(C, ca.MX(C.shape[0], n_z - n)))
            lower += [s[1] for s in soft]
            upper += [s[2] for s in soft]
        if block.n_frozen_cost:
            R, low, up = _frozen_rows(ca.vertcat(*cost_rows), x, lb, ub, band,
                                       compiled.rank_tol)
            rows.append(ca.horzcat(R, ca.MX(R.shape[0], n_z - n)))
            lower.append(low)
            upper.append(up)
        free = ca.DM.inf(n_z - n)  # slack columns of soft rows are free
        qp = {"h": H, "g": g, "a": ca.vertcat(*rows), "lba": ca.vertcat(*lower),
              "uba": ca.vertcat(*upper), "lbx": ca.vertcat(lb, -free),
              "ubx": ca.vertcat(ub, free)}
        z, cost, lam_a, lam_x = solve(i, qp)
        x = ca.fmin(ca.fmax(z[:n], lb), ub)
        if block.m_cost:
            cost_rows.append(ET.T)
        if block.m_soft:
            own = slice(block.m_hard, block.m_hard + block.m_soft)
            slack = z[n:]
            soft.append((AT.T[own, :n], lA[own] + slack, uA[own] + slack))
        levels.append({"qp": qp, "x": x, "z": z, "cost": cost, "lam_a": lam_a,
                       "lam_x": lam_x})
    return x, levels


def _certified(compiled: CompiledStack, levels: list[dict]) -> ca.MX:
    """1 if every level below the first passes the certificate of :mod:`wbc.fused` (the
    generated daqp's ``z`` and multipliers meet the KKT conditions of the exact level problem,
    frozen task rows as equalities, to :data:`CERTIFICATE_TOL`; stationarity holds by daqp's
    construction and is not evaluated), else 0."""
    ok = []
    for block, level in zip(compiled.blocks[1:], levels[1:], strict=True):
        qp, z, lam_a, lam_x = level["qp"], level["z"], level["lam_a"], level["lam_x"]
        A = qp["a"]
        # primal feasibility and complementarity, bounds then rows; a pinned variable's bounds
        # are one equality (both sides met: either sign); the frozen task rows are equalities
        # of the exact problem (either sign), held in their band: feasibility only
        for value, lower, upper, lam, signed in (
                (z, qp["lbx"], qp["ubx"], lam_x, z.shape[0]),
                (A @ z, qp["lba"], qp["uba"], lam_a, block.m_top + block.n_frozen_soft)):
            if value.shape[0] == 0:
                continue
            tol_l = CERTIFICATE_TOL * (1 + ca.fabs(lower))
            tol_u = CERTIFICATE_TOL * (1 + ca.fabs(upper))
            ok.append(ca.sum1((value < lower - tol_l) + (value > upper + tol_u)) == 0)
            if signed:  # (written so that a multiplier of an infinite side counts as off)
                v, lam = value[:signed], lam[:signed]
                at_upper = v >= upper[:signed] - tol_u[:signed]
                at_lower = v <= lower[:signed] + tol_l[:signed]
                off = (lam > 0) * (1 - at_upper) + (lam < 0) * (1 - at_lower)
                ok.append(ca.sum1(off) == 0)
    return ca.sum1(ca.vertcat(*ok)) == len(ok) if ok else ca.MX(1)


def _substituted(p: ca.MX, offset: int, value: ca.MX) -> ca.MX:
    """``p`` with ``p[offset:offset + len(value)]`` replaced by ``value`` (an empty slice of an
    MX column is 1×0, which vertcat refuses: those are left out)."""
    end = offset + value.shape[0]
    return ca.vertcat(*([p[:offset]] if offset else []), value,
                      *([p[end:]] if end < p.shape[0] else []))


def fused_function(compiled: CompiledStack, options: dict) -> ca.Function:
    """The CasADi function ``p -> (x, done, [x_i,] z_i, y_i, z_bounds_i for each QP i)`` of a
    cascade of least-squares levels (and the min-norm level): every level's function, daqp
    (CasADi's conic node with ``options``) on its QP with the frozen rows of the levels above
    (see :mod:`wbc.fused`), and ``x`` clipped into ``[lb, ub]``. ``done`` is the sum of the
    costs; unwritten, as every later output, if a daqp call fails or sides cross. Per QP ``i``:
    ``x_i`` (every QP but the last, whose ``x_i`` is ``x``), its solution ``z_i`` (slacks
    included) and its multipliers (rows, bounds; the sign convention of :mod:`wbc.qp`).
    Evaluates on CasADi's virtual machine as it is; :func:`compiled_c` makes it C.

    Raises:
        WbcError: the stack has a task-scaling LP, or an option is not a daqp setting.
    """
    reason = why_not_fused(compiled, options)
    if reason:
        raise WbcError(f"cannot fuse: {reason}")

    def solve(i: int, qp: dict):
        n_z, m = qp["h"].shape[0], qp["a"].shape[0]
        solver = ca.conic(f"daqp_{i}", "daqp", {"h": ca.Sparsity.dense(n_z, n_z),
                                                "a": ca.Sparsity.dense(m, n_z)},
                          {"daqp": dict(options), "error_on_fail": True})
        # The daqp bundled with casadi does not check lower <= upper: when sides cross, it is
        # given H = −I instead, which its setup refuses (not convex), so that the call fails as
        # a whole and writes no output (the previous command stays for the "last" fallback).
        crossed = ca.sum1(qp["lbx"] > qp["ubx"]) + ca.sum1(qp["lba"] > qp["uba"])
        result = solver(**{**qp, "h": ca.if_else(crossed == 0, qp["h"], -ca.MX.eye(n_z))})
        return result["x"], result["cost"], result["lam_a"], result["lam_x"]

    p = ca.MX.sym("p", compiled.defaults.shape[0])
    x, levels = _cascade(compiled, p, solve)
    done = sum(level["cost"] for level in levels)
    if len(levels) > 1:
        # A cascade's answer is kept when the certificate (wbc.fused) holds (the
        # exact lexicographic optimum, to tolerance); else "done" stays NaN, as after a failed
        # solve, and the ordinary path answers the tick.
        done = ca.if_else(_certified(compiled, levels), done, math.nan)
    outputs, names = [x, done], ["x", "done"]
    for i, level in enumerate(levels):
        if i < len(levels) - 1:
            outputs.append(level["x"])
            names.append(f"x_{i}")
        outputs += [level["z"], level["lam_a"], level["lam_x"]]
        names += [f"z_{i}", f"y_{i}", f"z_bounds_{i}"]
    # "done" is written after every solve succeeded only: see FusedWorkspace.solve
    return ca.Function("fused_tick", [p], outputs, ["p"], names)


def fused_qps(compiled: CompiledStack) -> ca.Function:
    """For diagnostics (:meth:`FusedWorkspace.last_qps`): ``(p, z_0, z_1, ...) -> (H, g, A,
    lA, uA, lb, ub)`` of every QP of the fused cascade, each solved by the given ``z_i``."""
    p = ca.MX.sym("p", compiled.defaults.shape[0])
    zs = [ca.MX.sym(f"z_{i}", b.n_z) for i, b in enumerate(compiled.blocks)]
    _, levels = _cascade(compiled, p, lambda i, qp: (zs[i], None, None, None))
    return ca.Function("fused_qps", [p, *zs],
                       [level["qp"][key] for level in levels
                        for key in ("h", "g", "a", "lba", "uba", "lbx", "ubx")])


__all__ = ["CASCADE_PRIMAL_TOL", "CERTIFICATE_TOL", "DAQP_PRIMAL_TOL", "DAQP_SETTINGS",
           "FROZEN_BAND", "FUSED_KINDS", "compiled_kinematics", "daqp_link_arguments",
           "fused_function", "fused_qps", "fused_settings", "initialise_success",
           "jit_compiled", "why_not_fused"]
