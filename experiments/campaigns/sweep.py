"""``wbc sweep NAME``: Monte-Carlo sweeps of a paper study — its claims over many seeds and over
values of its hand-tuned constants, with the spread of every claim.

A study's claims rest on one seeded run (``wbc study NAME``). A sweep reruns the study's main
runs (:class:`~wbc.experiments.studies.study.StudyOptions` ``main_only``) for the seeds
``FIRST .. FIRST + N − 1`` — each seed draws the study's random elements (its
``RANDOM_ELEMENTS``: noise, servo errors, wheel radii, odometry scale, start jitter, or for a
deterministic study a documented perturbation of its start and targets) — and, with ``--param
KEY=V1,V2``, for every value of the study's ``PARAMETERS_SWEPT`` constants (the Cartesian
product of the lists). One case is one (setting, seed) run; the cases run on
:mod:`wbc.experiments.campaigns.cluster` (this process, ``--workers N`` or ``--scheduler
ADDRESS``), so the result is the same wherever they ran, a killed worker's cases are re-run
and an interrupted sweep resumes from ``DIR/sweep_NAME/sweep_NAME.partial.json``.

Written to ``DIR/sweep_NAME/``:

* ``sweep_NAME.json``: ``"name"``, ``"study"``, ``"seeds"`` (N), ``"first_seed"``,
  ``"plant"``, ``"quick"``, ``"grid"`` (``KEY -> values``), ``"claims"`` — one entry per claim
  ``"id"`` of the first setting (the study's own when no ``--param``), the study JSON's shape:
  ``"id"``, ``"statement"``, ``"paper"``, ``"holds_fraction"`` (0–1), ``"holds"`` (seeds it
  held in), ``"seeds"`` (seeds that computed it), ``"not_reproducible"`` (seeds whose verdict
  was "not reproducible with this model"), and for a numeric ``ours`` (a number, or a
  dict of numbers: then per key) ``"ours_median"`` and ``"ours_ci95"`` (a percentile
  bootstrap interval of the median: :data:`BOOTSTRAP` resamples, fixed generator) —,
  ``"settings"`` (per setting: ``"params"`` and its ``"claims"``), ``"defects"`` (cases that
  raised, hung or killed their workers, each with its seed and a one-line reproduction
  command), ``"timing"`` (``"wall_s"``, ``"case_median_s"``), ``"machine"`` and ``"cluster"``;
* ``sweep_NAME.md``: the claims table ("holds in k of N seeds", the median and interval);
* ``sweep_NAME.png``: the spread of each numeric claim's value over the seeds (one box per
  claim, values divided by their median) and the fraction of seeds each claim holds in.

A claim that holds in fewer than :data:`ROBUST` of the seeds is marked as not robust.
"""

from __future__ import annotations

import argparse
import importlib
import itertools
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from wbc.errors import UnknownNameError

from ..arguments import add_cluster_arguments, cluster_options
from ..machine import describe_machine
from ..studies.study import PLANTS, VERDICTS, StudyOptions, cell, parse_params
from . import cluster

__all__ = ["BOOTSTRAP", "ROBUST", "STUDIES", "aggregate", "main", "plan", "run_case",
           "seeds_held", "sweep"]

#: the studies a sweep can run
STUDIES = ("sorour", "petric", "omni", "xing")
#: bootstrap resamples of the median's interval
BOOTSTRAP = 2000
#: a claim holding in fewer than this fraction of the seeds is not robust
ROBUST = 0.95


def study_module(name: str):
    """The study's module (``wbc.experiments.studies.NAME``)."""
    return importlib.import_module(f"wbc.experiments.studies.{name}")


def plan(grid: dict[str, list[float]], seeds: int, first_seed: int) -> list[dict]:
    """The cases of a sweep in order (setting, then seed): each with its ``"key"``
    (``"KEY=V,.../seedS"``, ``"default/seedS"`` without a grid), its ``"seed"`` (the study's
    seed) and its ``"params"``."""
    keys = list(grid)
    settings = [dict(zip(keys, values, strict=True))
                for values in itertools.product(*(grid[k] for k in keys))]
    cases = []
    for params in settings:
        label = ",".join(f"{k}={v:g}" for k, v in params.items()) or "default"
        cases += [{"key": f"{label}/seed{s}", "seed": s, "params": params}
                  for s in range(first_seed, first_seed + seeds)]
    return cases


def run_case(context: dict, case: dict, deadline: float | None = None) -> dict:
    """One seed of one setting (on whichever process): the study's main runs and claims,
    ``{"claims": [{"id", "statement", "paper", "ours", "holds"}], "wall_s"}``."""
    module = study_module(context["study"])  # the context is the sweep's identity
    options = StudyOptions(plant=context["plant"], seed=case["seed"], params=case["params"],
                           main_only=True)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="wbc_sweep_") as folder:
        result = module.run(context["backend"], Path(folder), context["quick"], options)
    claims = [{"id": c.id, "statement": c.statement, "paper": c.paper, "ours": c.ours,
               "holds": bool(c.holds), "verdict": c.verdict} for c in result.claims]
    return {"claims": claims, "wall_s": time.perf_counter() - started}


def _numeric(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, bool) and math.isfinite(float(value))


def _median_ci(values: list[float]) -> tuple[float, list[float]]:
    """The median and its 95 % percentile-bootstrap interval (a fixed generator: the same
    values give the same interval)."""
    data = np.asarray(values, dtype=float)
    rng = np.random.default_rng(0)
    medians = np.median(data[rng.integers(0, data.size, (BOOTSTRAP, data.size))], axis=1)
    low, high = np.percentile(medians, [2.5, 97.5])
    return float(np.median(data)), [float(low), float(high)]


def aggregate(results: list[list[dict]]) -> list[dict]:
    """Per claim id (in the order they first appear), over the seeds' claim lists: the
    statement, the paper's value, ``holds_fraction``, ``holds``, ``seeds``,
    ``not_reproducible`` (seeds whose verdict was "not reproducible with this model") and,
    where ``ours`` is numeric (or a dict of numbers), ``ours_median`` and ``ours_ci95``."""
    order: dict[str, dict] = {}
    for claims in results:
        for c in claims:
            entry = order.setdefault(c["id"], {"id": c["id"], "statement": c["statement"],
                                               "paper": c["paper"], "values": [], "held": 0,
                                               "unreachable": 0})
            entry["values"].append(c["ours"])
            entry["held"] += bool(c["holds"])
            entry["unreachable"] += c.get("verdict") == VERDICTS[2]
    out = []
    for entry in order.values():
        values = entry.pop("values")
        held, unreachable = entry.pop("held"), entry.pop("unreachable")
        claim = {**entry, "holds_fraction": held / len(values), "holds": held,
                 "seeds": len(values), "not_reproducible": unreachable}
        if all(_numeric(v) for v in values):
            claim["ours_median"], claim["ours_ci95"] = _median_ci(values)
        elif all(isinstance(v, dict) for v in values):
            keys = [k for k in values[0] if all(_numeric(v.get(k)) for v in values)]
            if keys:
                stats = {k: _median_ci([v[k] for v in values]) for k in keys}
                claim["ours_median"] = {k: s[0] for k, s in stats.items()}
                claim["ours_ci95"] = {k: s[1] for k, s in stats.items()}
        out.append(claim)
    return out


def sweep(name: str, seeds: int, *, grid: dict[str, list[float]] | None = None,
          first_seed: int = 0, plant: str = "kinematic", quick: bool = False,
          backend: str = "daqp", out: Path | None = None, workers: int | None = None,
          scheduler: str | None = None, time_limit: float = cluster.TIME_LIMIT_S,
          only: str | None = None, progress: bool = True) -> dict:
    """Run the sweep (see the module docstring) and return its JSON-ready result (also the
    per-seed values: ``"settings"[i]["values"]``, ``claim id -> [ours per seed]``)."""
    grid = dict(grid or {})
    cases = plan(grid, seeds, first_seed)
    identity = {"study": name, "seeds": seeds, "first_seed": first_seed, "grid": grid,
                "plant": plant, "quick": quick, "backend": backend}
    folder = None if out is None else Path(out) / f"sweep_{name}"
    if only is not None:
        cases = [c for c in cases if c["key"] == only]
        if not cases:
            raise UnknownNameError(f"no case {only!r} in this sweep (keys look like "
                                   f"'{plan(grid, 1, first_seed)[0]['key']}')")
    started = time.perf_counter()
    finished = cluster.run_cases(run_case, cases, identity, name=f"sweep_{name}",
                                 out=None if only else folder, identity=identity,
                                 workers=workers, scheduler=scheduler, time_limit=time_limit,
                                 progress=progress)
    by_case = dict(zip((c["key"] for c in cases), finished.results, strict=True))
    settings = []
    for params in {json.dumps(c["params"], sort_keys=True): c["params"] for c in cases}.values():
        rows = [by_case[c["key"]] for c in cases if c["params"] == params]
        done = [r for r in rows if r is not None]
        values: dict[str, list] = {}
        for r in done:
            for c in r["claims"]:
                values.setdefault(c["id"], []).append(c["ours"])
        settings.append({"params": params, "seeds_run": len(done),
                         "claims": aggregate([r["claims"] for r in done]), "values": values})
    walls = [r["wall_s"] for r in finished.results if r is not None]
    defects = [{"case": f["key"], "seed": f["seed"], "defect": f["failure"],
                "message": f["message"], "attempts": f["attempts"],
                "reproduce": _reproduction(name, plant, quick, backend, f["key"], cases)}
               for f in finished.failures]
    return {"name": f"sweep_{name}", "study": name, "seeds": seeds, "first_seed": first_seed,
            "plant": plant, "quick": quick, "backend": backend, "grid": grid,
            "claims": settings[0]["claims"] if settings else [], "settings": settings,
            "defects": defects,
            "timing": {"wall_s": time.perf_counter() - started,
                       "case_median_s": float(np.median(walls)) if walls else None},
            "machine": describe_machine(), "cluster": finished.cluster}


def _reproduction(name: str, plant: str, quick: bool, backend: str, key: str,
                  cases: list[dict]) -> str:
    """``wbc study NAME --seed S --param K=V ...``: the one run a failed case was."""
    case = next(c for c in cases if c["key"] == key)
    parts = [f"wbc study {name} --seed {case['seed']} --plant {plant} --backend {backend}"]
    parts += [f"--param {k}={v:g}" for k, v in case["params"].items()]
    return " ".join(parts + (["--quick"] if quick else []))


def markdown(result: dict) -> str:
    """The claims per setting: holds in k of N seeds, median and interval."""
    lines = [f"# Sweep of `wbc study {result['study']}`: {result['seeds']} seeds "
             f"({result['first_seed']}…{result['first_seed'] + result['seeds'] - 1}), "
             f"{result['plant']} plant" + (", quick" if result["quick"] else ""), ""]
    for setting in result["settings"]:
        if setting["params"]:
            lines += ["## " + ", ".join(f"{k} = {v:g}" for k, v in setting["params"].items()),
                      ""]
        lines += ["| claim | paper | holds in | median [95 % interval] | robust |",
                  "|---|---|---:|---|:---:|"]
        for c in setting["claims"]:
            lines.append(f"| {c['statement']} (`{c['id']}`) | {cell(c['paper'])} | "
                         f"{seeds_held(c)} | {interval(c)} | "
                         f"{'yes' if c['holds_fraction'] >= ROBUST else '**no**'} |")
        lines.append("")
    for d in result["defects"]:
        lines.append(f"- case `{d['case']}`: {d['defect']} — {d['message']}; rerun: "
                     f"`{d['reproduce']}`")
    return "\n".join(lines) + "\n"


def seeds_held(claim: dict) -> str:
    """``k of N`` seeds a sweep claim held in, and how many of the others the model could not
    reproduce (the study's verdict)."""
    unreachable = claim.get("not_reproducible", 0)
    return f"{claim['holds']} of {claim['seeds']}" + (
        f" ({unreachable} not reproducible with this model)" if unreachable else "")


def interval(claim: dict) -> str:
    """``median [low, high]`` of a sweep claim (per key for a dict), ``—`` when not numeric."""
    if "ours_median" not in claim:
        return "—"
    median, ci = claim["ours_median"], claim["ours_ci95"]
    if isinstance(median, dict):
        return "; ".join(f"{k}: {median[k]:.4g} [{ci[k][0]:.4g}, {ci[k][1]:.4g}]"
                         for k in median)
    return f"{median:.4g} [{ci[0]:.4g}, {ci[1]:.4g}]"


def figure(result: dict, path: Path) -> str | None:
    """The spread of each numeric claim over the seeds (values over their median) and the
    fraction of seeds each claim holds in, for the first setting; ``None`` when no seed ran."""
    import matplotlib.pyplot as plt

    from ..studies.study import save_figure

    if not result["settings"] or not result["settings"][0]["claims"]:
        return None
    setting = result["settings"][0]
    claims = setting["claims"]
    spread, labels = [], []
    for c in claims:
        values = setting["values"][c["id"]]
        if all(_numeric(v) for v in values) and float(np.median(values)) != 0.0:
            spread.append(np.asarray(values, dtype=float) / float(np.median(values)))
            labels.append(c["id"])
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 0.35 * len(claims) + 2.0),
                                      gridspec_kw={"width_ratios": [2, 1]})
    if spread:
        left.boxplot(spread, vert=False, tick_labels=labels)
        left.axvline(1.0, color="0.6", linewidth=0.8)
    left.set_xlabel("claim value / its median over the seeds [-]")
    left.set_ylabel("numeric claim")
    left.set_title(f"{result['study']}: spread over {result['seeds']} seeds")
    y = np.arange(len(claims))
    right.barh(y, [c["holds_fraction"] for c in claims],
               color=["tab:green" if c["holds_fraction"] >= ROBUST else "tab:red"
                      for c in claims])
    right.set_yticks(y, [c["id"] for c in claims], fontsize=7)
    right.axvline(ROBUST, color="0.4", linestyle="--", linewidth=0.8)
    right.set_xlim(0, 1)
    right.set_xlabel("fraction of seeds the claim holds in [-]")
    right.set_ylabel("claim")
    return save_figure(fig, path)


def write(result: dict, out: Path) -> Path:
    """``OUT/sweep_NAME/{sweep_NAME.json, .md, .png}``; returns the folder."""
    folder = Path(out) / result["name"]
    folder.mkdir(parents=True, exist_ok=True)
    result["figure"] = figure(result, folder / f"{result['name']}.png")
    (folder / f"{result['name']}.json").write_text(json.dumps(result, indent=1,
                                                              default=_json_default))
    (folder / f"{result['name']}.md").write_text(markdown(result))
    return folder


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def main(argv=None) -> int:
    """``wbc sweep NAME --seeds N [--param KEY=V1,V2 ...] [--plant P] [--first-seed S]
    [--quick] [--backend B] [--out DIR] [--workers W | --scheduler A]``."""
    import matplotlib

    matplotlib.use("Agg")
    from wbc.errors import WbcError
    from wbc.solvers import available_backends

    parser = argparse.ArgumentParser(
        prog="wbc sweep", description="Monte-Carlo sweep of a paper study: its claims over "
        "seeds and over values of its constants, with their spread.")
    parser.add_argument("study", choices=STUDIES, help="the paper study")
    parser.add_argument("--seeds", type=int, default=16, help="seeds per setting (default 16)")
    parser.add_argument("--first-seed", type=int, default=0,
                        help="the first seed (default 0): seeds S .. S + N - 1")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=V1,V2",
                        help="sweep a constant of the study's setup over these values "
                             "(repeatable: the Cartesian product); `wbc study NAME --help` "
                             "lists the keys")
    parser.add_argument("--plant", choices=PLANTS, default="kinematic")
    parser.add_argument("--backend", default="daqp")
    parser.add_argument("--quick", action="store_true", help="the study's short horizons")
    parser.add_argument("--out", type=Path, default=Path("results"))
    add_cluster_arguments(parser)
    args = parser.parse_args(argv)
    where = cluster_options(parser, args)
    if args.seeds < 1 or args.first_seed < 0:
        parser.error("--seeds must be >= 1 and --first-seed >= 0")
    if args.backend not in available_backends():
        parser.error(f"unknown or unavailable backend {args.backend!r}")
    try:
        grid = parse_params(args.param, getattr(study_module(args.study), "PARAMETERS_SWEPT",
                                                {}))
    except WbcError as err:
        parser.error(str(err))
    result = sweep(args.study, args.seeds, grid=grid, first_seed=args.first_seed,
                   plant=args.plant, quick=args.quick, backend=args.backend, out=args.out,
                   **where)
    folder = write(result, args.out)
    print(markdown(result))
    print(f"wrote {folder}/", file=sys.stderr)
    return 1 if result["defects"] else 0


if __name__ == "__main__":
    sys.exit(main())
