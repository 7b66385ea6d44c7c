"""The paper studies, one module per paper, each rerunning that paper's experiments on
:mod:`wbc.sim` and putting our numbers beside the paper's (``wbc study NAME``, and steps of
``wbc reproduce``).

* :mod:`~wbc.experiments.studies.study` — what every study shares: claims, the output contract
  (JSON, markdown, figures), timing summaries, ``study_main``;
* :mod:`~wbc.experiments.studies.sorour` — Sorour et al., task sharing on a steerable base;
* :mod:`~wbc.experiments.studies.petric` — Petrič & Žlajpah, velocity field for a
  differential-drive base;
* :mod:`~wbc.experiments.studies.omni` — omni platform, slip-avoiding torque distribution;
* :mod:`~wbc.experiments.studies.xing` — Xing et al., adaptive motion planning at the
  acceleration level.

A study named ``NAME`` is the module ``wbc.experiments.studies.NAME`` with a ``main(argv)``.
"""
