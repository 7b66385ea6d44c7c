"""What every paper study shares: claims, the output contract, timing summaries, figures.

A study (``experiments/studies/<name>.py``) reruns a paper's experiments in simulation
(:mod:`wbc.sim`) and puts our numbers beside the paper's. Its module defines

* ``run(backend: str, out_dir: pathlib.Path, quick: bool, options: StudyOptions) ->
  StudyResult`` (``out_dir`` is the study's own folder, ``DIR/<name>``, where it saves its
  figures; ``options`` default :data:`DOCUMENTED`, the single documented run on the kinematic
  plant);
* ``PARAMETERS_SWEPT``: ``KEY -> (default, description with units)``, the constants of its setup
  ``wbc sweep NAME --param KEY=V1,V2`` and ``wbc study NAME --param KEY=V`` may change (a key not
  listed is refused by :meth:`StudyOptions.check`);
* ``RANDOM_ELEMENTS``: in words, what one ``seed`` draws (noise, servo errors, wheel radii, start
  jitter; for a deterministic study, the documented perturbation of its start and targets);
* ``main(argv) = study_main("<name>", run, argv)``; ``wbc study <name>`` calls that ``main``.

The plants (``--plant``): ``"kinematic"`` (default) integrates the truth through the study's own
actuation models; ``"mujoco"`` runs the same controllers on :class:`wbc.sim.MujocoPlant`
(physics, real wheels; the kinematic actuation models are dropped, the physics replaces them).
The claims keep their ids on both plants.

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
  - ``"plant"`` (``"kinematic"`` or ``"mujoco"``), ``"seed"`` (``null``: the documented single
    run) and ``"params"`` (the ``--param`` overrides);
  - ``"plant_timing"``: ``{"plant", "wall_s", "step_median_s", "step_p95_s", "steps"}`` — the
    study's wall time and, on a physics plant, the plant's step time per control period;

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

__all__ = ["DOCUMENTED", "PLANTS", "Claim", "StudyOptions", "StudyResult", "cell",
           "interleaved_timing", "make_plant", "parse_params", "plant_timing", "save_figure",
           "study_main", "timing_summary"]

#: the plants a study runs on (``--plant``)
PLANTS = ("kinematic", "mujoco")


@dataclass(frozen=True)
class StudyOptions:
    """How a study runs beyond its backend and horizon.

    Attributes:
        plant: ``"kinematic"`` or ``"mujoco"`` (see the module docstring).
        seed: ``None``: the study's documented single run (its own fixed seeds; the claims the
            README reports); an integer: one Monte-Carlo draw of the study's random elements
            (``RANDOM_ELEMENTS``) from ``numpy.random.default_rng(seed)``.
        params: overrides of the study's ``PARAMETERS_SWEPT`` (``KEY -> value``).
        main_only: the main runs and their claims only — no timing over the backends, no
            figures, no replay record, no side campaigns (what ``wbc sweep`` runs per seed).
    """

    plant: str = "kinematic"
    seed: int | None = None
    params: dict = field(default_factory=dict)
    main_only: bool = False

    def __post_init__(self) -> None:
        from wbc.errors import InvalidValueError

        if self.plant not in PLANTS:
            raise InvalidValueError(f"plant must be one of {PLANTS}, got {self.plant!r}")
        if self.seed is not None and (isinstance(self.seed, bool) or int(self.seed) != self.seed
                                      or self.seed < 0):
            raise InvalidValueError(f"seed must be an integer >= 0 or None, got {self.seed!r}")

    def check(self, swept: dict) -> None:
        """Refuse a ``params`` key the study does not sweep (``swept``: its
        ``PARAMETERS_SWEPT``) or a value that is not a finite number."""
        from wbc.errors import InvalidValueError, UnknownNameError

        for key, value in self.params.items():
            if key not in swept:
                raise UnknownNameError(f"unknown parameter {key!r}; this study's: "
                                       f"{', '.join(sorted(swept)) or 'none'}")
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise InvalidValueError(f"parameter {key} must be a finite number, got "
                                        f"{value!r}")

    def value(self, key: str, swept: dict) -> float:
        """The value of ``key``: the override, else the study's default (``swept[key][0]``)."""
        return float(self.params.get(key, swept[key][0]))


#: the documented single run on the kinematic plant (every study's ``run`` default)
DOCUMENTED = StudyOptions()


def make_plant(robot, options: StudyOptions, **kwargs):
    """``None`` on the kinematic plant, else ``wbc.sim.MujocoPlant(robot, **kwargs)``."""
    if options.plant == "kinematic":
        return None
    from wbc.sim import MujocoPlant

    return MujocoPlant(robot, **kwargs)


def plant_timing(options: StudyOptions, wall_s: float, runs: Sequence = ()) -> dict:
    """The study's ``"plant_timing"``: its wall time [s] and, on a physics plant, the median and
    95th percentile of the plant's step per control period over the ``runs``
    (:class:`wbc.sim.Run` objects, their ``"plant_step_s"`` signal)."""
    steps = np.concatenate([np.asarray(r.signals["plant_step_s"], dtype=float) for r in runs
                            if "plant_step_s" in r.signals] or [np.zeros(0)])
    out: dict = {"plant": options.plant, "wall_s": float(wall_s), "steps": int(steps.size)}
    if steps.size:
        out.update(step_median_s=float(np.median(steps)),
                   step_p95_s=float(np.percentile(steps, 95)))
    return out


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
        missing: for a claim that does not hold because the model cannot reach it, the
            mechanism the model lacks (e.g. "roller compliance"); empty otherwise.
        verdict: derived, one of :data:`VERDICTS`: ``"holds"``, ``"fails"`` (the model could
            show it and does not), ``"not reproducible with this model"`` (``missing`` names why).
    """

    id: str
    statement: str
    paper: object
    ours: object
    holds: bool
    note: str = ""
    missing: str = ""
    verdict: str = field(init=False)

    def __post_init__(self) -> None:
        self.holds = bool(self.holds)  # numpy booleans are not JSON
        if self.holds and self.missing:
            raise ValueError(f"claim {self.id!r} holds, so nothing is missing from the model "
                             f"(got missing={self.missing!r})")
        self.verdict = verdict(self.holds, self.missing)


#: a claim's verdicts, in the order tables count them
VERDICTS = ("holds", "fails", "not reproducible with this model")


def verdict(holds: bool, missing: str = "") -> str:
    """The verdict of a claim: it holds, it fails, or the model lacks ``missing`` to show it."""
    return VERDICTS[0] if holds else VERDICTS[2] if missing else VERDICTS[1]


def verdict_cell(claim: dict | Claim) -> str:
    """A claim's verdict as a table cell (a JSON dict from an older run counts as held/failed)."""
    data = asdict(claim) if isinstance(claim, Claim) else claim
    kind = data.get("verdict") or verdict(bool(data["holds"]), data.get("missing", ""))
    if kind == VERDICTS[0]:
        return "yes"
    if kind == VERDICTS[2]:
        return f"**not reproducible** (lacks {data['missing']})"
    return "**no**"


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
        options: how it ran (plant, seed, parameter overrides).
        plant_timing: :func:`plant_timing` (``wall_s`` is set by :func:`study_main` when the
            study left it out).
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
    options: StudyOptions = field(default_factory=StudyOptions)
    plant_timing: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"name": self.name, "claims": [asdict(c) for c in self.claims],
                "runs": self.runs, "timing": self.timing, "figures": self.figures,
                "parameters": self.parameters, "summary": self.summary_md,
                "failures": self.failures, "plant": self.options.plant,
                "seed": self.options.seed, "params": dict(self.options.params),
                "plant_timing": self.plant_timing, "machine": describe_machine()}

    def markdown(self) -> str:
        lines = [f"# Study `{self.name}`", ""]
        held = sum(c.holds for c in self.claims)
        setting = f"plant: {self.options.plant}"
        if self.options.seed is not None:
            setting += f", seed {self.options.seed}"
        if self.options.params:
            setting += ", " + ", ".join(f"{k} = {v:g}" for k, v in self.options.params.items())
        unreachable = sum(c.verdict == VERDICTS[2] for c in self.claims)
        lines += [f"{held} of {len(self.claims)} claims reproduced ({setting})" + (
            f"; {unreachable} not reproducible with this model" if unreachable else "") + ".", ""]
        if self.failures:
            lines += ["**Failures:**", *[f"- {f}" for f in self.failures], ""]
        lines += ["| claim | paper | ours | holds | note |", "|---|---|---|:---:|---|"]
        for c in self.claims:
            lines.append(f"| {c.statement} (`{c.id}`) | {cell(c.paper)} | {cell(c.ours)} | "
                         f"{verdict_cell(c)} | {c.note} |")
        if self.timing:
            lines += ["", "| backend | tick median [µs] | tick p95 [µs] | ticks | console lines |",
                      "|---|---:|---:|---:|---:|"]
            for backend, t in self.timing.items():
                lines.append(f"| {backend} | {1e6 * t['tick_median_s']:.1f} | "
                             f"{1e6 * t['tick_p95_s']:.1f} | {t['ticks']} | "
                             f"{t.get('console_lines', 0)} |")
        if self.plant_timing:
            p = self.plant_timing
            line = f"Wall time {p['wall_s']:.1f} s on the {p['plant']} plant"
            if "step_median_s" in p:
                line += (f"; plant step per control period median {1e3 * p['step_median_s']:.2f}"
                         f" ms, p95 {1e3 * p['step_p95_s']:.2f} ms ({p['steps']} steps)")
            lines += ["", line + "."]
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


def cell(value) -> str:
    """A claim's value in a markdown table cell: floats to 4 significant digits, dicts as
    ``key: value`` pairs."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {cell(v)}" for k, v in value.items())
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


def interleaved_timing(fast, ordinary, states: Sequence, *, passes: int = 1,
                       budget_s: float = 0.0, reset: Callable | None = None,
                       share: Callable | None = None, warm_up: int = 0) -> dict:
    """A controller's default (fast) tick against the same controller with its fast path off,
    interleaved tick by tick over recorded ``states`` ``(q, v, references)`` — which of the two
    goes first alternates — so that the machine's load and caches weigh on both alike.

    Args:
        fast, ordinary: controllers (``step(q, v, **references) -> command``).
        passes: passes over ``states`` at least; more while ``budget_s`` [s] is not spent.
        reset: ``fn(controller)`` before each pass (controllers with state, e.g. a latch).
        share: ``fn(fast) -> seconds``, a share of each fast tick (e.g. its QP): its median is
            added as ``"qp_median_s"``.
        warm_up: first ticks left out of both summaries.

    Returns:
        :func:`timing_summary` of the fast ticks, ``"ordinary_tick_median_s"``,
        ``"ordinary_tick_p95_s"`` [s], ``"passes"`` and ``"max_command_difference"`` (the
        largest ``|fast − ordinary|`` of any command entry over every tick).
    """
    clock = time.perf_counter
    fast_ticks: list[float] = []
    ordinary_ticks: list[float] = []
    shares: list[float] = []
    worst, done, started = 0.0, 0, clock()
    while done < passes or clock() - started < budget_s:
        if reset is not None:
            reset(fast)
            reset(ordinary)
        for k, (q, v, references) in enumerate(states):
            pair = ((fast, fast_ticks), (ordinary, ordinary_ticks))
            commands = {}
            for controller, ticks in pair if k % 2 else pair[::-1]:
                t0 = clock()
                commands[controller is fast] = controller.step(q, v, **references)
                ticks.append(clock() - t0)
            worst = max(worst, float(np.max(np.abs(commands[True] - commands[False]))))
            if share is not None:
                shares.append(share(fast))
        done += 1
    ordinary_summary = timing_summary(ordinary_ticks[warm_up:])
    out = {**timing_summary(fast_ticks[warm_up:]),
           "ordinary_tick_median_s": ordinary_summary["tick_median_s"],
           "ordinary_tick_p95_s": ordinary_summary["tick_p95_s"], "passes": done,
           "max_command_difference": worst}
    if share is not None:
        out["qp_median_s"] = float(np.median(shares))
    return out


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


def parse_params(items: Sequence[str], swept: dict) -> dict[str, list[float]]:
    """``["KEY=V1,V2", ...]`` -> ``{KEY: [V1, V2]}`` (floats), keys checked against the study's
    ``PARAMETERS_SWEPT``.

    Raises:
        InvalidValueError: an item without ``=``, a value that is not a finite number, a key
            given twice. UnknownNameError: a key the study does not sweep.
    """
    from wbc.errors import InvalidValueError

    out: dict[str, list[float]] = {}
    for item in items:
        key, equals, values = item.partition("=")
        key = key.strip()
        if not equals or not key or not values.strip():
            raise InvalidValueError(f"--param takes KEY=V1[,V2...], got {item!r}")
        if key in out:
            raise InvalidValueError(f"--param {key} given twice")
        try:
            numbers = [float(v) for v in values.split(",")]
        except ValueError:
            raise InvalidValueError(f"--param {key}: the values must be numbers, got "
                                    f"{values!r}") from None
        for number in numbers:
            StudyOptions(params={key: number}).check(swept)
        out[key] = numbers
    return out


def study_main(name: str, run: Callable[..., StudyResult],
               argv: Sequence[str] | None = None) -> int:
    """Command line of a study: ``wbc study NAME [--backend B] [--out DIR] [--quick]
    [--plant {kinematic,mujoco}] [--seed N] [--param KEY=V ...]``.

    Adds ``"console_lines"`` to the timing of each backend that printed during the run (what
    every solve of that backend printed, the figures' runs included; see
    :data:`wbc.solvers.base.CONSOLE_LINES`).

    Exit codes: 0 when the study ran (whatever its claims say), 1 when it failed, 2 for a bad
    argument.
    """
    import matplotlib

    matplotlib.use("Agg")
    from wbc.errors import WbcError
    from wbc.solvers import available_backends
    from wbc.solvers.base import CONSOLE_LINES

    module = sys.modules.get(run.__module__)
    swept = getattr(module, "PARAMETERS_SWEPT", {})
    drawn = getattr(module, "RANDOM_ELEMENTS", "")
    parser = argparse.ArgumentParser(prog=f"wbc study {name}",
                                     description=f"Rerun the {name} paper study in simulation.",
                                     epilog=f"What a --seed draws: {drawn}" if drawn else None)
    parser.add_argument("--backend", default="daqp",
                        help="QP backend of the figures' runs (default daqp); timing covers "
                             "every available backend")
    parser.add_argument("--out", type=Path, default=Path("results"),
                        help="output folder (default: results); files go to OUT/%(prog)s")
    parser.add_argument("--quick", action="store_true",
                        help="short horizons, for tests and CI (claims still computed)")
    parser.add_argument("--plant", choices=PLANTS, default="kinematic",
                        help="what the truth moves with: the kinematic plant and the study's "
                             "actuation models (default), or MuJoCo physics (the [mujoco] "
                             "extra); the JSON records it")
    parser.add_argument("--seed", type=int, default=None,
                        help="one Monte-Carlo draw of the study's random elements (default: "
                             "the documented single run)")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=V",
                        help="override a constant of the study's setup; keys: "
                             + (", ".join(f"{k} ({d[1]}; default {d[0]:g})"
                                          for k, d in swept.items()) or "none"))
    args = parser.parse_args(argv)
    if args.backend not in available_backends():
        parser.error(f"unknown or unavailable backend {args.backend!r}; available: "
                     f"{available_backends()}")
    try:
        params = parse_params(args.param, swept)
        if any(len(values) > 1 for values in params.values()):
            raise WbcError("wbc study takes one value per --param (wbc sweep takes several)")
        options = StudyOptions(plant=args.plant, seed=args.seed,
                               params={k: v[0] for k, v in params.items()})
    except WbcError as err:
        parser.error(str(err))
    started = time.perf_counter()
    printed_before = dict(CONSOLE_LINES)
    result = run(args.backend, args.out / name, args.quick, options)
    result.options = options  # the JSON records what ran, whatever the study passed on
    for backend, t in result.timing.items():
        printed = CONSOLE_LINES.get(backend, 0) - printed_before.get(backend, 0)
        if printed:
            t["console_lines"] = printed
    result.plant_timing = {**(result.plant_timing or plant_timing(options, 0.0)),
                           "wall_s": time.perf_counter() - started}
    folder = result.write(args.out)
    held = sum(c.holds for c in result.claims)
    print(f"{name} ({options.plant} plant): {held}/{len(result.claims)} claims reproduced; "
          f"{time.perf_counter() - started:.1f} s; wrote {folder}/", file=sys.stderr)
    print(result.markdown())
    return 0
