"""Head-to-head with placo (Rhoban/placo: C++ kinematics solver, Python bindings) on the Panda
problem of ``wbc pink``.

wbc's side is :func:`wbc.experiments.peers.vs_pink.build_wbc` unchanged (frame task on the hand with
gain ``FRAME_GAIN`` and Levenberg-Marquardt damping, posture, configuration limits with gain
``LIMIT_GAIN``, velocity limits, Tikhonov damping; daqp on the fused path by default). placo's
side is the nearest problem placo can state (placo 0.10, read from its source):

* model: the same URDF (:func:`~wbc.experiments.peers.vs_mink.panda_urdf_without_meshes`: no meshes,
  fingers fixed); placo adds a floating base, pinned with ``mask_fbase`` (hard equalities it
  eliminates by a QR decomposition);
* frame task ``configure("ee", "soft", 1, 1)``: position error ``p* − p`` (world) with the
  world-aligned Jacobian, orientation error ``log3(R* Rᵀ)`` (world) with the world angular
  Jacobian, weights 1;
* posture: a joints task to ``Q0`` with weight ``POSTURE_COST²`` (wbc's weight);
* ``enable_joint_limits`` / ``enable_velocity_limits`` with ``dt = DT``;
* the QP in ``Δq``: ``min ½ Σ w‖A Δq − e‖² + ½ 10⁻⁸ ‖Δq‖²`` (placo's built-in
  regularisation), solved by eiquadprog (dense Goldfarb–Idnani); ``v = Δq / dt``.

Where the two formulations differ (so the commands differ by design, not by error):

1. **gains** — placo's tasks and joint limits have none: each tick asks for the full error
   (``J Δq = e``) and lets ``q + Δq`` reach a joint limit; wbc (and pink) ask for ``gain · e``
   (0.5) and ``Δq ≥ gain · (q_min − q)`` (0.5);
2. **orientation error** — placo: ``log3`` of the world-frame rotation error with the plain
   angular Jacobian; wbc/pink: ``log6`` of the SE(3) error in the hand frame with the
   Jacobian of the log map (couples position and orientation);
3. **Levenberg-Marquardt damping** — wbc/pink add ``lm_damping · ‖e‖²`` to the frame task's
   Hessian; placo has none;
4. **regularisation** — placo ``10⁻⁸`` on ``Δq`` (relative to the task weights:
   ``10⁻⁸ / dt²`` on ``v``), wbc/pink ``10⁻¹²`` on ``v``.

Two measures of agreement follow from this, every tick at placo's state, untimed:

* ``mirror_diff_max``: placo's command against wbc solving *placo's* QP (the mirror: the
  same errors, Jacobians, weights, bounds and regularisation as numbers, on daqp, tight) —
  checks that the formulation above is placo's, to ``COMMAND_TOL``;
* ``formulation_diff_*``: placo's command against wbc's own controller at the same state —
  the size of the differences 1–4 (reported, not a pass/fail).

Closed loops and timing as in ``vs_pink``: each side integrates its own ``q ← q + v·dt``,
ticks interleaved in one process with a rotating order, medians and p95 over every tick. A
placo tick is ``robot.state.q = q`` + ``update_kinematics()`` + (when the target changes)
``frame_task.T_world_frame = T`` + ``solver.solve(False)`` + ``Δq / dt``; a wbc tick is
``controller.step(q, ee=T)``. Taking turns with them in the rotation, on wbc's QP of the tick:
the bare call of the fused function (``bare_median_s``: model stage, assembly and solve in C,
nothing else) and DAQP's own Python call ``daqp.solve`` on the very same QP arrays
(``raw_daqp_median_s``, the arrays built beforehand, untimed). Then, as in ``vs_pink``, both
loops again in blocks of 100 ticks, each a dedicated control loop (``dedicated``, with the
bare call in blocks of its own).

placo pins pinocchio 3.8 (``pin==3.8``) where wbc's CI installs pinocchio 4: install it in an
environment of its own (``pip install 'wbc[placo]'``).

Run: ``wbc placo --ticks 3000 --out results/vs_placo``; writes ``vs_placo.json`` and prints a
markdown table.
"""

from __future__ import annotations

import argparse
import gc
import json
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..arguments import installed_backends
from .vs_mink import HAND, panda_urdf_without_meshes
from .vs_pink import DT, POSE_TOL, POSTURE_COST, Q0, build_wbc, dedicated_loops, targets

BACKENDS = ("daqp",)
PLACO_REGULARIZATION = 1e-8  # placo's Problem::regularization, on Δq
COMMAND_TOL = 1e-6  # [rad/s]: the mirror of placo's QP against placo
INSTALL_HINT = "pip install 'wbc[placo]' (in an environment of its own: placo pins pin 3.8)"


def placo_panda(folder: Path):
    """placo's ``RobotWrapper`` of the Panda (see the module docstring); the URDF is written
    into ``folder``."""
    import placo

    path = Path(folder) / "panda.urdf"
    path.write_text(ET.tostring(panda_urdf_without_meshes(), encoding="unicode"))
    return placo.RobotWrapper(str(path), placo.Flags.ignore_collisions)


class PlacoLoop:
    """placo's side: robot, solver, tasks and limits; :meth:`tick` is what is timed."""

    name = "placo"

    def __init__(self, folder: Path) -> None:
        import placo

        self.robot = placo_panda(folder)
        self.solver = solver = placo.KinematicsSolver(self.robot)
        solver.mask_fbase(True)
        solver.dt = DT
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        self.frame_task = solver.add_frame_task(HAND, np.eye(4))
        self.frame_task.configure("ee", "soft", 1.0, 1.0)
        posture = solver.add_joints_task()
        posture.set_joints({f"panda_joint{i + 1}": float(q) for i, q in enumerate(Q0)})
        posture.configure("posture", "soft", POSTURE_COST ** 2)
        self._q = self.robot.state.q.copy()  # floating base (7, identity) then the 7 joints

    @staticmethod
    def target(T: np.ndarray) -> np.ndarray:
        """``T`` (world, (4, 4)) as placo's target: itself."""
        return T

    def tick(self, q: np.ndarray, target: np.ndarray | None = None) -> np.ndarray:
        self._q[7:] = q
        self.robot.state.q = self._q
        self.robot.update_kinematics()
        if target is not None:
            self.frame_task.T_world_frame = target
        return self.solver.solve(False)[6:] / DT


def mirror_stack(robot):
    """placo's QP as a wbc stack on ``v`` (see the module docstring): the frame and posture
    rows and the bounds are numbers set every tick by :func:`mirror_values`."""
    import wbc
    from wbc.tasks import Bounds, LinearTask

    n = robot.nv
    stack = wbc.Stack(wbc.Variables(v=n), damping=np.sqrt(PLACO_REGULARIZATION))
    stack.add(LinearTask(np.zeros((6, n)), np.zeros(6), name="frame"))
    stack.add(LinearTask(np.eye(n), np.zeros(n), weight=POSTURE_COST ** 2, name="posture"))
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="limits"))
    return stack


def mirror_values(robot, q: np.ndarray, target: np.ndarray) -> dict:
    """The mirror's numbers at ``q`` for the hand target ``target`` (world, (4, 4)):
    placo's errors divided by ``dt`` (the QP is in ``v``), its Jacobians and bounds."""
    import pinocchio as pin

    T = robot.frame_pose(q, "ee")
    J = robot.frame_jacobian(q, "ee")  # rows [linear; angular], world-aligned at the hand
    error = np.r_[target[:3, 3] - T[:3, 3], pin.log3(target[:3, :3] @ T[:3, :3].T)]
    limits = robot.limits
    return {"frame.A": J, "frame.b": error / DT, "posture.b": (Q0 - q) / DT,
            "limits.lower": np.maximum(-limits.v_upper, (limits.q_lower - q) / DT),
            "limits.upper": np.minimum(limits.v_upper, (limits.q_upper - q) / DT)}


def _percentiles(samples: np.ndarray) -> tuple[float, float]:
    return float(np.median(samples)), float(np.percentile(samples, 95))


def run_backend(backend: str, ticks: int) -> dict:
    """The two closed loops on one wbc backend, interleaved tick by tick (rotating order), with
    the untimed agreement checks and, on the fused path, the bare call and DAQP's own call on
    the same QP (see the module docstring)."""
    from wbc.robots.fixed_base import load_panda

    robot = load_panda()
    controller = build_wbc(robot, backend)
    at_placo = build_wbc(robot, backend)  # untimed: wbc's command at placo's state
    mirror = mirror_stack(robot).workspace("daqp", "tight")
    folder = Path(tempfile.mkdtemp(prefix="wbc-placo-"))
    placo_loop = PlacoLoop(folder)
    goals = targets(robot.frame_pose(Q0, "ee").copy())
    per_goal = max(1, ticks // len(goals))
    q = {"wbc": Q0.copy(), "placo": Q0.copy()}
    v: dict = {}
    times = {name: np.empty(ticks) for name in q}
    bare, raw = np.full(ticks, np.nan), np.full(ticks, np.nan)
    mirror_diff, formulation_diff = np.empty(ticks), np.empty(ticks)
    failures = 0
    fused = getattr(controller, "fused", False)
    raw_daqp = _raw_daqp() if fused else None
    clock = time.perf_counter

    def run(name: str, goal: int | None) -> float:
        """One contestant's turn; its time [s]."""
        target = None if goal is None else goals[goal]
        t0 = clock()
        if name == "placo":
            v[name] = placo_loop.tick(q[name], target)
        elif name == "bare":  # on the parameters of wbc's last tick
            controller.workspace.bare_call()
        elif name == "raw":
            return _raw_solve(controller.workspace, raw_daqp, clock)
        elif target is None:
            v[name] = controller.step(q[name])
        else:
            v[name] = controller.step(q[name], ee=target)
        return clock() - t0

    # The bare call and daqp.solve take turns in the rotation too: measured right after a
    # wbc tick, they would find the caches warm where the tick itself does not.
    order = ["wbc", "placo", *(("bare", "raw") if fused else ())]
    samples = {**times, "bare": bare, "raw": raw}
    gc.collect()
    gc.disable()
    try:
        for k in range(ticks):
            g = min(k // per_goal, len(goals) - 1)
            new_goal = g if k == 0 or g != min((k - 1) // per_goal, len(goals) - 1) else None
            for i in range(len(order)):
                name = order[(k + i) % len(order)]
                if name in ("bare", "raw") and k == 0:
                    continue  # no wbc tick yet: no parameters
                samples[name][k] = run(name, new_goal)
            failures += not controller.last_solution.ok
            # agreement at placo's state (untimed)
            v_mirror = mirror.set(**mirror_values(robot, q["placo"], goals[g])).solve().x
            mirror_diff[k] = np.abs(v_mirror - v["placo"]).max()
            v_wbc_there = at_placo.step(q["placo"], ee=goals[g])
            formulation_diff[k] = np.abs(v_wbc_there - v["placo"]).max()
            for name in q:
                q[name] = q[name] + DT * v[name]
    finally:
        gc.enable()
    goal = goals[min((ticks - 1) // per_goal, len(goals) - 1)]
    T_w, T_p = robot.frame_pose(q["wbc"], "ee").copy(), robot.frame_pose(q["placo"], "ee").copy()
    wbc_med, wbc_p95 = _percentiles(times["wbc"])
    placo_med, placo_p95 = _percentiles(times["placo"])
    result = {
        "wbc_median_s": wbc_med, "wbc_p95_s": wbc_p95,
        "placo_median_s": placo_med, "placo_p95_s": placo_p95,
        "ratio": wbc_med / placo_med,
        "fused": fused, "ticks": ticks, "wbc_failures": failures,
        "mirror_diff_max": float(mirror_diff.max()),
        "mirror_agrees": bool(mirror_diff.max() <= COMMAND_TOL),
        "command_tol": COMMAND_TOL,
        "formulation_diff_median": float(np.median(formulation_diff)),
        "formulation_diff_max": float(formulation_diff.max()),
        "final_position_error_wbc_m": float(np.linalg.norm(T_w[:3, 3] - goal[:3, 3])),
        "final_position_error_placo_m": float(np.linalg.norm(T_p[:3, 3] - goal[:3, 3])),
        "final_position_diff_m": float(np.linalg.norm(T_w[:3, 3] - T_p[:3, 3])),
        "pose_tol": POSE_TOL,
        "dedicated": dedicated_loops(build_wbc(robot, backend), PlacoLoop(folder), goals, ticks),
    }
    if fused:
        bare_med, bare_p95 = _percentiles(bare[1:])
        raw_med, raw_p95 = _percentiles(raw[1:])
        result.update({"bare_median_s": bare_med, "bare_p95_s": bare_p95,
                       "step_over_bare": wbc_med / bare_med,
                       "raw_daqp_median_s": raw_med, "raw_daqp_p95_s": raw_p95,
                       "step_over_raw_daqp": wbc_med / raw_med,
                       "fallback_solves": controller.workspace.fallback_solves})
    return result


def _raw_daqp():
    """DAQP's own one-shot Python call ``daqp.solve(H, f, A, bupper, blower, sense)``."""
    import daqp

    return daqp.solve


def _raw_solve(workspace, raw_daqp, clock) -> float:
    """``daqp.solve`` on the QP of the workspace's current parameters (its arrays evaluated
    and converted beforehand, untimed) [s]."""
    (_, (H, g, A, lA, uA, lb, ub), _), = workspace.last_qps()
    upper, lower = np.r_[ub, uA], np.r_[lb, lA]
    sense = np.where(lower == upper, 5, 0).astype(np.intc)
    H, g, A = H.copy(), g.copy(), A.copy()
    t0 = clock()
    raw_daqp(H, g, A, upper, lower, sense)
    return clock() - t0


def markdown_table(results: dict) -> str:
    rows = ["| backend | wbc median / p95 [µs] | placo median / p95 [µs] | wbc / placo | "
            "bare fused call [µs] | step / bare | daqp.solve [µs] | dedicated loops: wbc / "
            "placo [µs] (ratio), step / bare | mirror Δv max [rad/s] | formulation Δv median / "
            "max [rad/s] |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in results.items():
        bare = (f"{r['bare_median_s'] * 1e6:.1f} | {r['step_over_bare']:.2f} | "
                f"{r['raw_daqp_median_s'] * 1e6:.1f}" if r["fused"] else "– | – | –")
        d = r["dedicated"]
        dedicated = (f"{d['wbc_median_s'] * 1e6:.1f} / {d['placo_median_s'] * 1e6:.1f} "
                     f"({d['ratio']:.3f})"
                     + (f", {d['step_over_bare']:.2f}" if "step_over_bare" in d else ""))
        rows.append(
            f"| {name}{' (fused)' if r['fused'] else ''} | {r['wbc_median_s'] * 1e6:.1f} / "
            f"{r['wbc_p95_s'] * 1e6:.1f} | {r['placo_median_s'] * 1e6:.1f} / "
            f"{r['placo_p95_s'] * 1e6:.1f} | {r['ratio']:.3f} | {bare} | {dedicated} | "
            f"{r['mirror_diff_max']:.0e} | {r['formulation_diff_median']:.2g} / "
            f"{r['formulation_diff_max']:.2g} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="wbc placo",
        description="wbc vs placo on the Panda problem of 'wbc pink': median tick, ratio, "
                    "agreement, and the fused tick against its bare call.")
    parser.add_argument("--ticks", type=int, default=3000, help="ticks per backend")
    parser.add_argument("--backends", nargs="+", default=list(BACKENDS),
                        help="wbc backends (placo always uses its own eiquadprog)")
    parser.add_argument("--out", type=Path, default=Path("results/vs_placo"),
                        help="output folder for vs_placo.json")
    args = parser.parse_args(argv)
    if args.ticks < 1:
        parser.error("--ticks must be >= 1")
    backends = installed_backends(parser, args.backends)
    try:
        import placo  # noqa: F401
    except ImportError as err:
        from wbc.errors import MissingDependencyError

        raise MissingDependencyError(f"wbc placo needs 'placo', which is not installed "
                                     f"({err}): {INSTALL_HINT}") from None
    from wbc.experiments.machine import describe_machine
    from wbc.experiments.progress import report_progress

    results, errors = {}, {}
    for done, backend in enumerate(backends, start=1):
        try:
            results[backend] = run_backend(backend, args.ticks)
        except Exception as err:  # one broken backend must not hide the others' results
            errors[backend] = f"{type(err).__name__}: {err}"
        report_progress(done, len(backends), backend)
    machine = describe_machine()
    report = {"problem": {"robot": "panda (example-robot-data, fingers locked)", "dt": DT,
                          "q0": Q0.tolist(), "posture_weight": POSTURE_COST ** 2,
                          "placo_regularization": PLACO_REGULARIZATION,
                          "differences": ["gains (placo: none)", "orientation error (placo: "
                                          "world log3; wbc: hand-frame log6)",
                                          "Levenberg-Marquardt damping (placo: none)",
                                          "regularisation (placo 1e-8 on dq; wbc 1e-12 on v)"]},
              "backends": results, "errors": errors, "machine": machine}
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "vs_placo.json"
    path.write_text(json.dumps(report, indent=2))
    print(markdown_table(results))
    print(f"\nmachine: {machine['cpu']}, {machine['cores']} cores, {machine['platform']}, "
          f"python {machine['python']}; {args.ticks} ticks per backend")
    for backend, message in errors.items():
        print(f"failed: {backend}: {message}")
    print(f"wrote {path}")
    return 0 if results else 1


if __name__ == "__main__":
    raise SystemExit(main())
