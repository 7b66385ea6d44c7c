"""Timing of wbc itself.

* :mod:`~wbc.experiments.benchmarks.solver_timing` — ``wbc bench``: the whole control tick per
  robot, stack and backend, and the scaling with the number of joints;
* :mod:`~wbc.experiments.benchmarks.microbench` — ``wbc demo``: one stack on every backend,
  agreement and timing;
* :mod:`~wbc.experiments.benchmarks.loops` — timing closed loops side by side (tick by tick,
  or in blocks as dedicated loops), used by ``wbc bench`` and the peer comparisons.
"""
