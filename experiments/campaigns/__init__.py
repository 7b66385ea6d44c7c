"""Campaigns that gate CI: each runs many seeded cases and exits 1 when it finds a defect.

* :mod:`~wbc.experiments.campaigns.fuzz` — ``wbc fuzz``: bad stacks, data and states on every
  backend; a defect is anything but a clean error, a failure status or a solved tick;
* :mod:`~wbc.experiments.campaigns.audit` — ``wbc audit``: closed-loop limit audits on every
  catalogue robot and exact backend;
* :mod:`~wbc.experiments.campaigns.exactness` — ``wbc exactness``: every backend against an
  exact referee on random, saturating and strict-priority states;
* :mod:`~wbc.experiments.campaigns.cluster` — how fuzz and audit spread their seeded cases over
  Dask workers (``--workers N``, ``--scheduler ADDRESS``): same results wherever they run,
  killed workers' cases re-run, ``DIR/NAME.partial.json`` to resume.
"""
