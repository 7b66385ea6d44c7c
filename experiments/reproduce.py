"""``wbc reproduce``: every paper study, the solver-timing study and the peer comparisons, in one
report (``OUT/REPORT.md``, figures beside it).

Steps, each run through its own command-line entry point with its output captured in
``OUT/logs/<step>.log``: the four paper studies on the kinematic plant (``wbc study NAME``, into
``OUT/NAME``, one after the other in this process: they time their controllers) and on MuJoCo
(``--plant mujoco``, into ``OUT/mujoco/NAME``; skipped with its install hint without the
``mujoco`` package; one spawned process per core runs them side by side — their tick timings
are taken on the kinematic plant and repeat the kinematic studies', so the report reads those),
a Monte-Carlo sweep of each study
(``wbc sweep NAME --seeds`` :data:`SWEEP_SEEDS`, into ``OUT/sweeps``, on a local Dask cluster of
one worker per core when ``distributed`` is installed, else in this process), ``wbc bench``
and the head-to-heads with the peers (``wbc pink``, ``wbc mink``, ``wbc placo``; a peer that is
not installed is reported as skipped with its install hint). A step that fails does not stop the
others: the report says what failed and why (the log's last lines). ``--quick`` shortens every
step (short horizons, few ticks, one backend for the peers) so that the whole command runs in
about a minute, for CI; its timings are not meant to be read.

The report: an opening summary (claims reproduced per paper and plant, failures), one section per
paper with its claims table — each claim on both plants side by side (same ids) and "holds in k of
N seeds" with the median's interval beside the single run — and figures, the timing tables of ``wbc
bench``, the peer table, the machine. Each paper's section also shows a strip of the robot at four
instants of the study's main run (:data:`MAIN_RUNS`), rendered from the study's replay record on
full runs: by the 3-D viewer through headless Chromium (:func:`wbc.viz.strip.render_strip`) where
the ``[viz]`` extra and a Chromium are installed, otherwise by matplotlib offline
(:func:`wbc.viz.strip_offline.render_strip_offline`); the report says which.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import io
import json
import shutil
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .campaigns.sweep import interval, seeds_held
from .machine import describe_machine
from .progress import report_progress
from .studies.study import VERDICTS, cell, verdict_cell

PAPERS = {"sorour": "Sorour, Cherubini, Fraisse — steerable wheeled mobile manipulation",
          "petric": "Petrič, Žlajpah — spatially modulated velocity fields",
          "omni": "Omnidirectional platform with torque redundancy — slip-avoiding distribution",
          "xing": "Xing et al. — adaptive motion planning (AMP)"}
#: the run each paper's strip shows (a key of the study's ``<name>_replay.npz``)
MAIN_RUNS = {"sorour": "table_ii/compensated", "petric": "sine_large/whole_body",
             "omni": "diagonal/proportional", "xing": "circle_r025/amp_qp"}
#: the MuJoCo studies, longest first (they run two at a time on two cores: the longest one
#: beside the others)
PHYSICS_ORDER = ("xing", "petric", "sorour", "omni")
#: the environment of the processes that run steps side by side (read by numpy's BLAS when it
#: loads in them)
SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: seeds of each study's sweep (``--quick``: :data:`SWEEP_SEEDS_QUICK`, the studies' quick mode)
SWEEP_SEEDS = 16
SWEEP_SEEDS_QUICK = 2
PEERS = {"pink": ("wbc.experiments.peers.vs_pink", "pink", "pip install 'wbc[pink]'"),
         "mink": ("wbc.experiments.peers.vs_mink", "mink", "pip install 'wbc[mink]'"),
         "placo": ("wbc.experiments.peers.vs_placo", "placo", "pip install 'wbc[placo]'")}


@dataclass
class Step:
    """One piece of the reproduction."""

    name: str
    module: str
    argv: list[str]
    requires: str | None = None  # an importable package the step needs (a peer)
    hint: str = ""
    status: str = "pending"  # "ok", "failed", "skipped"
    reason: str = ""
    seconds: float = 0.0
    #: may run beside its neighbours that are concurrent too, one per core (it times nothing
    #: the report reads as its own: the MuJoCo studies' tick timings repeat the kinematic ones)
    concurrent: bool = False


def plan(out: Path, quick: bool) -> list[Step]:
    """The steps of a full (or ``quick``) reproduction writing into ``out``."""
    short = ["--quick"] if quick else []
    steps = [Step(f"study {name}", f"wbc.experiments.studies.{name}",
                  ["--out", str(out), *short]) for name in PAPERS]
    steps += [Step(f"study {name} (mujoco)", f"wbc.experiments.studies.{name}",
                   ["--out", str(out / "mujoco"), "--plant", "mujoco", *short], "mujoco",
                   "pip install 'wbc[mujoco]'", concurrent=True) for name in PHYSICS_ORDER]
    workers = sweep_workers()
    steps += [Step(f"sweep {name}", "wbc.experiments.campaigns.sweep",
                   [name, "--seeds", str(SWEEP_SEEDS_QUICK if quick else SWEEP_SEEDS),
                    "--out", str(out / "sweeps"), *short,
                    *(["--workers", str(workers)] if workers else [])]) for name in PAPERS]
    bench = (["--robots", "mecanum_gen3", "--stacks", "one_level", "three_levels", "--ticks",
              "60", "--warmup", "5", "--scaling-ticks", "20", "--scaling-joints", "7", "30"]
             # 100 ticks per cell and scenario after 20 warm-up ones (three scenarios, every
             # tick also solved by two certified referees) and the scaling sweep up to 50
             # joints: ≈ 2 min on 2 cores (600 ticks took 4.7 min, 200 3.3 min, which with the
             # studies on MuJoCo and their sweeps put the report over its 10 minutes); `wbc
             # bench` alone keeps its own defaults, and 3000 (issue #17's protocol, one
             # scenario, no referees) would take ≈ 25 min
             if quick else ["--ticks", "100", "--warmup", "20", "--scaling-ticks", "300",
                            "--scaling-joints", "7", "15", "30", "50"])
    steps.append(Step("bench", "wbc.experiments.benchmarks.solver_timing",
                      [*bench, "--out", str(out / "bench"), "--studies", str(out)]))
    for peer, (module, package, hint) in PEERS.items():
        # 1500 ticks per backend (3000 before the MuJoCo studies and the sweeps joined)
        ticks = ["--ticks", "150", "--backends", "daqp"] if quick else ["--ticks", "1500"]
        steps.append(Step(peer, module, [*ticks, "--out", str(out / f"vs_{peer}")], package,
                          hint))
    return steps


def cores() -> int:
    """The cores this process may run on."""
    import os

    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
               else os.cpu_count() or 1)


def sweep_workers() -> int | None:
    """Worker processes of the sweeps: one per core when dask's ``distributed`` is installed
    (``None``, in this process, otherwise)."""
    if importlib.util.find_spec("distributed") is None:
        return None
    return cores()


def run_step(step: Step, log_dir: Path) -> None:
    """Run one step, capturing its output; never raises."""
    log = log_dir / f"{step.name.replace(' ', '_')}.log"
    if step.requires and importlib.util.find_spec(step.requires) is None:
        step.status, step.reason = "skipped", f"{step.requires} is not installed ({step.hint})"
        log.write_text(step.reason + "\n")
        return
    buffer = io.StringIO()
    started = time.perf_counter()
    try:
        with contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
            code = importlib.import_module(step.module).main(step.argv)
        step.status = "ok" if code in (0, None) else "failed"
        if step.status == "failed":
            step.reason = f"exit code {code}: {_last_line(buffer.getvalue())}"
    except SystemExit as exit_:  # argparse errors
        step.status, step.reason = "failed", f"exit {exit_.code}: {_last_line(buffer.getvalue())}"
    except Exception as err:  # one failing step must not lose the others
        buffer.write(traceback.format_exc())
        step.status, step.reason = "failed", f"{type(err).__name__}: {err}"
    step.seconds = time.perf_counter() - started
    log.write_text(buffer.getvalue())


def _run_step_in_child(step: Step, log_dir: Path) -> Step:
    run_step(step, log_dir)
    return step


def run_concurrently(steps: list[Step], log_dir: Path, on_done: Callable[[Step], None]) -> None:
    """Run ``steps`` as :func:`run_step` does, in one fresh process per core (spawned: no state
    of this process is inherited), in their order as processes free up; each step's status,
    reason and seconds are copied back into it. One core: in this process, one by one."""
    workers = min(len(steps), cores())
    if workers <= 1:
        for step in steps:
            run_step(step, log_dir)
            on_done(step)
        return
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # one BLAS thread per process, as Dask's workers get (the sweeps): OpenBLAS's own threads
    # on small matrices, one set per process, would contend for the same cores. The children
    # are spawned as steps are submitted and read it when numpy loads in them.
    saved = {name: os.environ.get(name) for name in SINGLE_THREADED}
    os.environ.update(SINGLE_THREADED)
    try:
        with ProcessPoolExecutor(workers,
                                 mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {pool.submit(_run_step_in_child, step, log_dir): step for step in steps}
            for future in as_completed(futures):
                step = futures[future]
                try:
                    done = future.result()
                    step.status, step.reason, step.seconds = (done.status, done.reason,
                                                              done.seconds)
                except Exception as err:  # the child died (run_step itself never raises)
                    step.status, step.reason = "failed", f"{type(err).__name__}: {err}"
                on_done(step)
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name)
            else:
                os.environ[name] = value


def _last_line(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return lines[-1][:300] if lines else "(no output)"


# ---------------------------------------------------------------------------- the report
def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _not_reproducible(claims: list[dict], prefix: str = "; ") -> str:
    """``"; k not reproducible with this model"`` for a claims list with k such verdicts, or
    ``""`` (``prefix`` replaces ``"; "``)."""
    k = sum(c.get("verdict") == VERDICTS[2] for c in claims)
    return f"{prefix}{k} not reproducible with this model" if k else ""


def _paper_section(name: str, out: Path, steps: dict[str, Step]
                   ) -> tuple[list[str], list[str]]:
    """A paper's section and its summary line: its claims on the kinematic plant, on MuJoCo
    (``OUT/mujoco/NAME``) and over the sweep's seeds (``OUT/sweeps/sweep_NAME``), side by side
    by claim id."""
    step = steps[f"study {name}"]
    lines = [f"## {PAPERS[name]} (`wbc study {name}`)", ""]
    data = _read_json(out / name / f"{name}.json")
    if step.status != "ok" or data is None:
        lines += [f"**Not reproduced: the study failed** — {step.reason or 'no JSON written'} "
                  f"(log: `logs/{step.name.replace(' ', '_')}.log`).", ""]
        return lines, [f"- **{name}**: study failed"]
    physics_step = steps.get(f"study {name} (mujoco)")
    physics = _read_json(out / "mujoco" / name / f"{name}.json") \
        if physics_step is not None and physics_step.status == "ok" else None
    sweep_step = steps.get(f"sweep {name}")
    swept = _read_json(out / "sweeps" / f"sweep_{name}" / f"sweep_{name}.json") \
        if sweep_step is not None and sweep_step.status in ("ok", "failed") else None
    claims = data["claims"]
    held = sum(bool(c["holds"]) for c in claims)
    unreachable = _not_reproducible(claims)
    summary = (f"- **{name}**: {held} of {len(claims)} claims reproduced (kinematic plant"
               f"{unreachable})")
    lines.append(f"{held} of {len(claims)} claims reproduced on the kinematic plant "
                 f"({step.seconds:.0f} s{unreachable}).")
    by_id_physics = {c["id"]: c for c in (physics or {}).get("claims", [])}
    by_id_sweep = {c["id"]: c for c in (swept or {}).get("claims", [])}
    if physics is not None and physics_step is not None:
        held_physics = sum(bool(c["holds"]) for c in physics["claims"])
        unreachable = _not_reproducible(physics["claims"])
        summary += (f"; {held_physics} of {len(physics['claims'])} on MuJoCo"
                    + (f" ({_not_reproducible(physics['claims'], '')})" if unreachable else ""))
        lines.append(f"On MuJoCo: {held_physics} of {len(physics['claims'])} "
                     f"({physics_step.seconds:.0f} s{unreachable}; {_plant_line(physics)}; "
                     "what the plant "
                     f"changes and why: [mujoco/{name}/{name}.md](mujoco/{name}/{name}.md))"
                     + ("; it ran beside another MuJoCo study, one per core, so its timing "
                        "claims (ticks timed on the kinematic plant) are the kinematic "
                        "column's to read" if physics_step.concurrent and cores() > 1 else "")
                     + ".")
    else:
        lines.append("On MuJoCo: not run — " + (physics_step.reason if physics_step else
                                                "not part of this run") + ".")
    if swept is not None:
        fragile = [c["id"] for c in swept["claims"] if c["holds_fraction"] < 0.95]
        summary += (f"; over {swept['seeds']} seeds, {len(fragile)} claim(s) hold in fewer "
                    "than 95 % of them" + (f" ({', '.join(fragile)})" if fragile else ""))
        lines.append(f"Sweep: {swept['seeds']} seeds ({swept['first_seed']}…"
                     f"{swept['first_seed'] + swept['seeds'] - 1}; `wbc sweep {name}`), "
                     f"{swept['timing']['wall_s']:.0f} s" + (
                         f"; **{len(swept['defects'])} case(s) failed**"
                         if swept.get("defects") else "") + ".")
    else:
        lines.append("Sweep: not run — " + (sweep_step.reason if sweep_step else
                                            "not part of this run") + ".")
    lines += ["", "| claim | paper | ours (kinematic) | holds | ours (MuJoCo) | holds | "
              "holds in k of N seeds | median [95 % interval] over the seeds | note |",
              "|---|---|---|:---:|---|:---:|---:|---|---|"]
    for c in claims:
        p = by_id_physics.get(c["id"])
        w = by_id_sweep.get(c["id"])
        physics_cells = (f"{cell(p['ours'])} | {verdict_cell(p)}"
                         if p else "— | —")
        if w:
            seeds = seeds_held(w) + (
                "" if w["holds_fraction"] >= 0.95 else " (**< 95 %**)")
            spread = interval(w)
        else:
            seeds, spread = "—", "—"
        lines.append(f"| {c['statement']} (`{c['id']}`) | {cell(c['paper'])} | "
                     f"{cell(c['ours'])} | {verdict_cell(c)} | "
                     f"{physics_cells} | {seeds} | {spread} | {c.get('note', '')} |")
    timing = data.get("timing") or {}
    if timing:
        lines += ["", "| backend | tick median [µs] | tick p95 [µs] |", "|---|---:|---:|"]
        for backend, t in timing.items():
            lines.append(f"| {backend} | {1e6 * t['tick_median_s']:.1f} | "
                         f"{1e6 * t['tick_p95_s']:.1f} |")
    for figure in data.get("figures", [])[:3]:
        lines += ["", f"![{figure}]({name}/{figure})"]
    if swept is not None and swept.get("figure"):
        lines += ["", f"![{swept['figure']}](sweeps/sweep_{name}/{swept['figure']})"]
    strip = out / name / f"{name}_strip.png"
    if strip.exists():
        lines += ["", f"The robot in `{MAIN_RUNS[name]}` (`wbc view {out} --run "
                  f"{name}/{MAIN_RUNS[name]}` replays it):", "",
                  f"![{strip.name}]({name}/{strip.name})"]
    lines.append("")
    return lines, [summary]


def _plant_line(data: dict) -> str:
    """The plant's step time per control period from a study JSON's ``plant_timing``."""
    timing = data.get("plant_timing") or {}
    if "step_median_s" not in timing:
        return "no plant step recorded"
    return (f"MuJoCo step per control period median {1e3 * timing['step_median_s']:.2f} ms "
            f"over {timing['steps']} periods")


def render_strips(out: Path, quick: bool) -> str:
    """Render each study's strip (``OUT/<name>/<name>_strip.png``) from its replay record;
    returns a line for the report: what was rendered and by which renderer, or why not. The
    3-D viewer through headless Chromium where the ``[viz]`` extra and a Chromium are here
    (or if it fails), matplotlib offline otherwise (:mod:`wbc.viz.strip_offline`: core
    dependencies only). Never raises."""
    if quick:
        return "Robot strips: not rendered in a quick run (`wbc reproduce` renders them)."
    try:
        from wbc.errors import WbcError
        from wbc.viz.record import read_recordings
        from wbc.viz.strip_offline import render_strip_offline
    except ImportError as err:  # a broken install: the report must still be written
        return f"Robot strips: none ({err})."
    jobs, missing = [], []
    for name, run in MAIN_RUNS.items():
        try:
            recording = read_recordings(out / name / f"{name}_replay.npz")[run]
            jobs.append((recording, out / name / f"{name}_strip.png", ""))
        except (WbcError, KeyError) as err:  # the study failed or wrote no record
            missing.append(f"{name} ({str(err)[:120]})")
    renderer = ""
    reason = _chromium_unavailable_reason()
    if not reason and jobs:
        try:
            from wbc.viz.strip import render_strips as render_in_chromium

            render_in_chromium(jobs)
            renderer = "the 3-D viewer in headless Chromium"
        except Exception as err:  # the offline renderer stands in
            reason = f"Chromium failed: {type(err).__name__}: {str(err)[:160]}"
    if not renderer:
        renderer = f"matplotlib, offline ({reason})"
        done = []
        for job in jobs:
            try:
                render_strip_offline(job[0], job[1], title=job[2])
                done.append(job)
            except Exception as err:  # one bad record must not lose the other strips
                missing.append(f"{job[1].parent.name} ({type(err).__name__}: "
                               f"{str(err)[:120]})")
        jobs = done
    if not jobs:
        return "Robot strips: none" + (f" ({'; '.join(missing)})" if missing else "") + "."
    names = [str(path.parent.name) for _, path, _ in jobs]
    return (f"Robot strips rendered for {', '.join(names)} by {renderer}"
            + (f"; none for {', '.join(missing)}" if missing else "") + ".")


def _chromium_unavailable_reason() -> str | None:
    """Why the viewer cannot photograph the strips here (``None`` when it can): the
    ``[viz]`` extra (viser, playwright) or a Chromium is missing."""
    try:
        from wbc.viz import require_viser
        from wbc.viz.browser import browser_unavailable_reason

        require_viser()  # VizUnavailableError without the [viz] extra
        return browser_unavailable_reason()
    except Exception as err:  # whatever it is, the offline renderer stands in
        if type(err).__name__ == "VizUnavailableError":
            return "viser is not installed: no [viz] extra"
        return f"{type(err).__name__}: {str(err)[:160]}"


def _peer_rows(out: Path, steps: dict[str, Step]) -> list[str]:
    lines = ["## Peers", "", "Same Panda problem (frame task, posture, position and velocity "
             "limits), in one process; ratio = wbc tick / peer tick. Interleaved: the two loops "
             "take turns tick by tick (each finds the caches as the other left them); "
             "dedicated: they take turns in blocks of 100 ticks (each loop's caches warm).", "",
             "| peer | backend | wbc median [µs] | peer median [µs] | wbc / peer | dedicated: "
             "wbc / peer [µs] | dedicated ratio |", "|---|---|---:|---:|---:|---:|---:|"]
    for peer in PEERS:
        step = steps[peer]
        data = _read_json(out / f"vs_{peer}" / f"vs_{peer}.json")
        if step.status != "ok" or data is None:
            lines.append(f"| {peer} | — | — | — | {step.status}: {step.reason} | — | — |")
            continue
        for backend, r in data.get("backends", {}).items():
            d = r["dedicated"]
            lines.append(f"| {peer} | {backend} | {1e6 * r['wbc_median_s']:.1f} | "
                         f"{1e6 * r[f'{peer}_median_s']:.1f} | {r['ratio']:.3f} | "
                         f"{1e6 * d['wbc_median_s']:.1f} / {1e6 * d[f'{peer}_median_s']:.1f} | "
                         f"{d['ratio']:.3f} |")
    return lines + [""]


def write_report(out: Path, steps: list[Step], quick: bool, strips: str = "") -> Path:
    by_name = {s.name: s for s in steps}
    for name in [*(f"study {p}" for p in PAPERS), "bench", *PEERS]:
        by_name.setdefault(name, Step(name, "", [], status="not run",
                                      reason="not part of this run"))
    sections, summary = [], []
    for name in PAPERS:
        lines, line = _paper_section(name, out, by_name)
        sections += lines
        summary += line
    bench = out / "bench" / "solver_timing.md"
    sections += ["## Solver timing (`wbc bench`)", ""]
    if by_name["bench"].status == "ok" and bench.exists():
        sections += [bench.read_text(), ""]
    else:
        sections += [f"**Failed**: {by_name['bench'].reason}", ""]
    sections += _peer_rows(out, by_name)
    failed = [s for s in steps if s.status == "failed"]
    skipped = [s for s in steps if s.status == "skipped"]
    machine = describe_machine()
    head = ["# wbc — reproduction report", "",
            f"Machine: {machine['cpu']}, {machine['cores']} cores, {machine['platform']}, "
            f"Python {machine['python']}." + (" **Quick run: short horizons, timings not "
                                               "meaningful.**" if quick else ""), "",
            "## Summary", "", *summary]
    if strips:
        head += ["", strips]
    if failed:
        head += ["", "Failed steps:", *[f"- `{s.name}`: {s.reason}" for s in failed]]
    if skipped:
        head += ["", "Skipped:", *[f"- `{s.name}`: {s.reason}" for s in skipped]]
    head += ["", "| step | status | time [s] |", "|---|---|---:|",
             *[f"| {s.name} | {s.status} | {s.seconds:.1f} |" for s in steps], ""]
    report = out / "REPORT.md"
    report.write_text("\n".join(head + sections) + "\n")
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="wbc reproduce",
        description="Run every paper study, the solver-timing study and the peer comparisons; "
                    "write OUT/REPORT.md.")
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="output folder (default: results)")
    parser.add_argument("--quick", action="store_true",
                        help="short horizons and few ticks (about a minute; for CI)")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    args.out.mkdir(parents=True, exist_ok=True)
    log_dir = args.out / "logs"
    shutil.rmtree(log_dir, ignore_errors=True)
    log_dir.mkdir()
    steps = plan(args.out, args.quick)
    started = time.perf_counter()
    finished: list[Step] = []

    def progress(step: Step) -> None:
        finished.append(step)
        report_progress(len(finished), len(steps),
                        f"{step.name}: {step.status} ({step.seconds:.0f} s)")

    k = 0
    while k < len(steps):
        group = [steps[k]]
        while steps[k].concurrent and k + len(group) < len(steps) \
                and steps[k + len(group)].concurrent:
            group.append(steps[k + len(group)])
        if len(group) > 1:
            run_concurrently(group, log_dir, progress)
        else:
            run_step(group[0], log_dir)
            progress(group[0])
        k += len(group)
    strips = render_strips(args.out, args.quick)
    report = write_report(args.out, steps, args.quick, strips)
    failed = [s.name for s in steps if s.status == "failed"]
    print(f"wrote {report} in {time.perf_counter() - started:.0f} s"
          + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
