"""What every paper study shares: claims, the output contract, timing summaries, figures.

A study (``experiments/studies/<name>.py``) reruns a paper's experiments in simulation
(:mod:`wbc.sim`) and puts our numbers beside the paper's. Its module defines
``run(backend: str, out_dir: pathlib.Path, quick: bool) -> StudyResult`` (``out_dir`` is the
study's own folder, ``DIR/<name>``, where it saves its figures) and
``main(argv) = study_main("<name>", run, argv)``; ``wbc study <name>`` calls that ``main``.

Output contract (the same for every paper), written by :meth:`StudyResult.write` into
``DIR/<name>/``:

* ``<name>.json`` with

  - ``"claims"``: a list of ``{"id", "statement", "paper", "ours", "holds", "note"}`` — every
    ``ours`` and ``holds`` computed from the runs, never typed in; a claim we do not reproduce
    has ``holds: false`` and the reason in ``note``;
  - ``"runs"``: per scenario and method the raw series (at least ``"t"`` [s],
    ``"base_velocity"``, ``"ee_error"`` [m], plus what the claims are computed from);
  - ``"timing"``: per backend ``{"tick_median_s", "tick_p95_s", "ticks"}``, and
    ``"console_lines"`` when the backend printed during the study (lines its library printed
    while solving, kept off the terminal and counted by :mod:`wbc.solvers`; added by
    :func:`study_main`);
  - ``"machine"``: :func:`wbc.experiments.machine.describe_machine`;
  - ``"parameters"`` and ``"summary"``: what the study chose, in words;

* ``<name>.md``: the claims table, the timing table and the summary, for a person;
* the PNG figures the study saved with :func:`save_figure` (labelled axes with units);
* ``<name>_replay.npz``: what ``wbc view DIR`` replays — per run (``"<scenario>/<method>"``)
  the configurations per tick, the status per tick and the target / end-effector traces,
  float32, thinned to 50 frames per second (``wbc.viz.record``; not in the JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..machine import describe_machine

__all__ = ["Claim", "StudyResult", "save_figure", "study_main", "timing_summary"]


@dataclass
class Claim:
    """One claim of a paper, beside our number.

    Attributes:
        id: short identifier, e.g. ``"base_still_r01"``.
        statement: the claim in words.
        paper: what the paper reports (a number, or words where it gives none).
        ours: what our runs give (computed from them).
        holds: whether our runs reproduce the claim.
        note: how ``ours`` was computed, and why a claim does not hold.
    """

    id: str
    statement: str
    paper: object
    ours: object
    holds: bool
    note: str = ""

    def __post_init__(self) -> None:
        self.holds = bool(self.holds)  # numpy booleans are not JSON


@dataclass
class StudyResult:
    """Everything a study produced (see the module docstring for the files it becomes).

    Attributes:
        name: the study's name (``"xing"``, ...).
        claims: the claims table.
        runs: ``scenario -> method -> series`` (JSON-ready dicts, e.g. ``Run.series()``).
        timing: ``backend -> timing_summary(...)``.
        figures: file names of the figures saved in the study's folder.
        summary_md: markdown: models and parameters chosen, discussion.
        parameters: the study's parameters (JSON-ready).
        failures: what failed and why (a study that lost a scenario says so here).
        replays: ``"<scenario>/<method>" -> wbc.viz.record.Recording`` of the runs,
            written to ``<name>_replay.npz`` (not part of the JSON).
        robot: the catalogue name of the robot the replays move.
    """

    name: str
    claims: list[Claim]
    runs: dict
    timing: dict
    figures: list[str] = field(default_factory=list)
    summary_md: str = ""
    parameters: dict = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)
    replays: dict = field(default_factory=dict)
    robot: str = ""

    def to_json(self) -> dict:
        return {"name": self.name, "claims": [asdict(c) for c in self.claims],
                "runs": self.runs, "timing": self.timing, "figures": self.figures,
                "parameters": self.parameters, "summary": self.summary_md,
                "failures": self.failures, "machine": describe_machine()}

    def markdown(self) -> str:
        lines = [f"# Study `{self.name}`", ""]
        held = sum(c.holds for c in self.claims)
        lines += [f"{held} of {len(self.claims)} claims reproduced.", ""]
        if self.failures:
            lines += ["**Failures:**", *[f"- {f}" for f in self.failures], ""]
        lines += ["| claim | paper | ours | holds | note |", "|---|---|---|:---:|---|"]
        for c in self.claims:
            lines.append(f"| {c.statement} (`{c.id}`) | {_cell(c.paper)} | {_cell(c.ours)} | "
                         f"{'yes' if c.holds else '**no**'} | {c.note} |")
        if self.timing:
            lines += ["", "| backend | tick median [µs] | tick p95 [µs] | ticks | console lines |",
                      "|---|---:|---:|---:|---:|"]
            for backend, t in self.timing.items():
                lines.append(f"| {backend} | {1e6 * t['tick_median_s']:.1f} | "
                             f"{1e6 * t['tick_p95_s']:.1f} | {t['ticks']} | "
                             f"{t.get('console_lines', 0)} |")
        if self.summary_md:
            lines += ["", self.summary_md.strip()]
        if self.figures:
            lines += ["", *[f"![{f}]({f})" for f in self.figures]]
        return "\n".join(lines) + "\n"

    def write(self, out_dir: Path) -> Path:
        """Write ``out_dir/<name>/<name>.json`` and ``.md``; returns the study's folder."""
        folder = Path(out_dir) / self.name
        folder.mkdir(parents=True, exist_ok=True)
        with open(folder / f"{self.name}.json", "w") as f:
            json.dump(self.to_json(), f, default=_json_default, allow_nan=False)
        (folder / f"{self.name}.md").write_text(self.markdown())
        if self.replays:
            from wbc.viz.record import save_recordings

            save_recordings(folder / f"{self.name}_replay.npz", self.replays, self.robot)
        return folder


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {_cell(v)}" for k, v in value.items())
    return str(value)


def _json_default(value):
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    if isinstance(value, np.generic):
        return _finite(value.item())
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def _finite(value):
    """NaN and ±inf have no JSON form: ``None`` in their place."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def timing_summary(samples_s: Sequence[float]) -> dict:
    """``{"tick_median_s", "tick_p95_s", "ticks"}`` of tick durations [s]."""
    samples = np.asarray(samples_s, dtype=float)
    if samples.size == 0:
        raise ValueError("timing_summary needs at least one sample")
    return {"tick_median_s": float(np.median(samples)),
            "tick_p95_s": float(np.percentile(samples, 95)), "ticks": int(samples.size)}


def replay_timing(backends: Sequence[str], make_controller: Callable, states: Sequence,
                  tick: Callable, budget_s: float,
                  part: tuple[str, Callable] | None = None) -> tuple[dict, list[str]]:
    """Wall time of a study's control tick per backend, replayed over recorded states.

    Args:
        backends: backend names.
        make_controller: ``backend -> controller``.
        states: the inputs replayed, one per tick (e.g. states of the daqp run).
        tick: ``(controller, state) -> None``, one control tick (the part timed).
        budget_s: at most this wall time per backend [s] (the replay stops early).
        part: ``(key, controller -> seconds)``: the median of a share of each tick (e.g. its
            QP), added under ``key``.

    Returns:
        ``(timing, failed)``: ``backend ->`` :func:`timing_summary` (+ the part), and one line
        ``"timing on B: error"`` per backend whose controller raised a :class:`wbc.WbcError`.
    """
    import wbc

    out, failed = {}, []
    for backend in backends:
        ticks, shares, started = [], [], time.perf_counter()
        try:
            controller = make_controller(backend)
            for state in states:
                t0 = time.perf_counter()
                tick(controller, state)
                ticks.append(time.perf_counter() - t0)
                if part is not None:
                    shares.append(part[1](controller))
                if time.perf_counter() - started > budget_s:
                    break
        except wbc.WbcError as err:
            failed.append(f"timing on {backend}: {err}")
            continue
        out[backend] = timing_summary(ticks)
        if part is not None:
            out[backend][part[0]] = float(np.median(shares))
    return out, failed


def save_figure(fig, path: Path) -> str:
    """Save a matplotlib figure as PNG after checking that every axis has a label (units are
    the caller's part of the label); closes it and returns the file name."""
    import matplotlib.pyplot as plt

    for ax in fig.axes:
        if not ax.get_visible() or not ax.has_data():
            continue
        missing = [which for which, label in (("x", ax.get_xlabel()), ("y", ax.get_ylabel()))
                   if not label]
        if missing and getattr(ax, "name", "") != "polar":
            raise ValueError(f"figure {Path(path).name}: axis {ax.get_title()!r} has no "
                             f"{' or '.join(missing)} label")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path.name


def study_main(name: str, run: Callable[[str, Path, bool], StudyResult],
               argv: Sequence[str] | None = None) -> int:
    """Command line of a study: ``wbc study NAME [--backend B] [--out DIR] [--quick]``.

    Adds ``"console_lines"`` to the timing of each backend that printed during the run (what
    every solve of that backend printed, the figures' runs included; see
    :data:`wbc.solvers.base.CONSOLE_LINES`).

    Exit codes: 0 when the study ran (whatever its claims say), 1 when it failed, 2 for a bad
    argument.
    """
    import matplotlib

    matplotlib.use("Agg")
    from wbc.solvers import available_backends
    from wbc.solvers.base import CONSOLE_LINES

    parser = argparse.ArgumentParser(prog=f"wbc study {name}",
                                     description=f"Rerun the {name} paper study in simulation.")
    parser.add_argument("--backend", default="daqp",
                        help="QP backend of the figures' runs (default daqp); timing covers "
                             "every available backend")
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="output folder (default: results); files go to OUT/%(prog)s")
    parser.add_argument("--quick", action="store_true",
                        help="short horizons, for tests and CI (claims still computed)")
    args = parser.parse_args(argv)
    if args.backend not in available_backends():
        parser.error(f"unknown or unavailable backend {args.backend!r}; available: "
                     f"{available_backends()}")
    started = time.perf_counter()
    printed_before = dict(CONSOLE_LINES)
    result = run(args.backend, args.out / name, args.quick)
    for backend, t in result.timing.items():
        printed = CONSOLE_LINES.get(backend, 0) - printed_before.get(backend, 0)
        if printed:
            t["console_lines"] = printed
    folder = result.write(args.out)
    held = sum(c.holds for c in result.claims)
    print(f"{name}: {held}/{len(result.claims)} claims reproduced; "
          f"{time.perf_counter() - started:.1f} s; wrote {folder}/", file=sys.stderr)
    print(result.markdown())
    return 0
