"""The ``wbc`` command line and everything it runs: paper studies, benchmarks, peer comparisons
and the campaigns that gate CI.

* the command line, at this level: :mod:`~wbc.experiments.cli` (the verbs),
  :mod:`~wbc.experiments.reproduce` (``wbc reproduce``: every study, the bench and the peers in
  one report) and the helpers the verbs share — :mod:`~wbc.experiments.arguments` (backend
  arguments), :mod:`~wbc.experiments.progress`, :mod:`~wbc.experiments.machine`;
* :mod:`wbc.experiments.studies` — the four paper studies (``wbc study NAME``) and the output
  contract they share;
* :mod:`wbc.experiments.benchmarks` — timing: ``wbc bench``, ``wbc demo`` and the loop-timing
  helper;
* :mod:`wbc.experiments.peers` — head-to-heads with pink, mink and placo (``wbc pink`` /
  ``mink`` / ``placo``);
* :mod:`wbc.experiments.campaigns` — ``wbc fuzz``, ``wbc audit``, ``wbc exactness``: campaigns
  whose exit code gates CI.

The flat module paths of before the split (``wbc.experiments.xing``, ``wbc.experiments.fuzz``,
...) are kept as aliases: each is a small module at the old place that makes the old name refer
to the moved module itself (the same module object), so old imports, private names and
monkeypatching keep working. New code imports the subpackage paths.
"""
