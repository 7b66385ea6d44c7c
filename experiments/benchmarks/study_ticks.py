"""The papers' controllers' ticks in ``wbc bench``: each study's own daqp timing — the
controller's default (fast) path against the same controller with ``fused=False``, timed
interleaved tick by tick over the study's recorded states (:func:`wbc.experiments.studies.study.
interleaved_timing`) — read from the JSON the study wrote (``wbc study NAME --out DIR`` writes
``DIR/NAME/NAME.json``; ``wbc reproduce`` runs the studies before the bench).

Read, not timed again: the figures are the ones each study's section reports (same states, same
run), and ``wbc bench`` stays as long as it was. A study whose JSON is absent, or holds no daqp
timing (a study run with ``main_only``), is reported as missing, with the command that writes it.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["CONTROLLERS", "markdown", "study_ticks"]

#: ``(study, row label, where the timing is in the study's JSON, what the tick covers)``, in
#: the order of the report; the path's keys lead to a dict with ``tick_median_s`` and
#: ``ordinary_tick_median_s`` (:func:`~wbc.experiments.studies.study.interleaved_timing`).
CONTROLLERS: tuple[tuple[str, str, tuple[str, ...], str], ...] = (
    ("sorour", "sorour", ("timing", "daqp"),
     "the compensated controller: the stack and the ICR steering QP"),
    ("petric", "petric", ("timing", "daqp"),
     "the paper's decoupled controller: the field and the arm's cascade (eq. 26)"),
    ("petric", "petric (whole-body)", ("parameters", "timing_whole_body", "daqp"),
     "beyond the paper: the field and the whole-body QP cascade"),
    ("omni", "omni", ("timing", "daqp"),
     "the force control: the wheel-torque distribution QP and the platform's model"),
    ("xing", "xing", ("timing", "daqp"),
     "AMP: the scaling LP and the cascade's three levels"),
)


def study_ticks(folder: Path) -> dict[str, dict | None]:
    """Row label of :data:`CONTROLLERS` -> the study's daqp timing found under ``folder``
    (``folder/NAME/NAME.json``), or ``None`` when the JSON or its daqp timing is absent:
    ``fast_tick_median_s`` and ``ordinary_tick_median_s`` [s], ``ratio`` (fast / ordinary),
    ``max_command_difference`` (``None`` if the study did not record it), ``ticks`` (the fast
    ticks timed, every pass), ``passes`` and ``source`` (the JSON's path)."""
    found: dict[str, dict | None] = {}
    loaded: dict[str, dict | None] = {}
    for study, label, keys, _ in CONTROLLERS:
        if study not in loaded:
            path = folder / study / f"{study}.json"
            loaded[study] = json.loads(path.read_text()) if path.is_file() else None
        timing = loaded[study]
        for key in keys:
            timing = timing.get(key) if isinstance(timing, dict) else None
        if not isinstance(timing, dict) or "ordinary_tick_median_s" not in timing:
            found[label] = None
            continue
        fast, ordinary = timing["tick_median_s"], timing["ordinary_tick_median_s"]
        found[label] = {
            "fast_tick_median_s": fast, "ordinary_tick_median_s": ordinary,
            "ratio": fast / ordinary, "max_command_difference":
            timing.get("max_command_difference"), "ticks": timing.get("ticks"),
            "passes": timing.get("passes"), "source": str(folder / study / f"{study}.json")}
    return found


def markdown(ticks: dict[str, dict | None], folder: Path) -> list[str]:
    """The report's section on the studies' ticks (lines), from :func:`study_ticks`'s
    answer for ``folder``."""
    out = ["### The papers' controllers on daqp (each study's own timing)", "",
           "Each study times its controller's tick on the default (fast) path against the same "
           "controller with `fused=False`, interleaved tick by tick over the states of one of "
           f"its runs; read from the studies' JSONs under `{folder}`. Times in µs.", "",
           "| study | tick | fast path (median) | ordinary path (median) | fast / ordinary | "
           "max command difference | timed ticks (passes) |", "|---|---|---|---|---|---|---|"]
    missing = []
    for study, label, _, covers in CONTROLLERS:
        row = ticks.get(label)
        if row is None:
            missing.append(study)
            out.append(f"| {label} | {covers} | – | – | – | – | – |")
            continue
        difference = row["max_command_difference"]
        out.append(f"| {label} | {covers} | {1e6 * row['fast_tick_median_s']:.1f} | "
                   f"{1e6 * row['ordinary_tick_median_s']:.1f} | {row['ratio']:.2f} | "
                   f"{'–' if difference is None else f'{difference:.1e}'} | "
                   f"{row['ticks']} ({row['passes']}) |")
    if missing:
        names = list(dict.fromkeys(missing))
        out += ["", "No timing found for " + ", ".join(f"`{name}`" for name in names)
                + ": run " + ", ".join(f"`wbc study {name} --out {folder}`" for name in names)
                + " (or `wbc reproduce`) first, then `wbc bench --studies "
                f"{folder}`."]
    return out + [""]
