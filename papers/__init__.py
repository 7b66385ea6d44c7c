"""The papers (``wbc.papers``): one package per paper, each holding that paper's library pieces —
its tasks, controllers, plants, stacks and closed forms — and re-exporting their public names.

* :mod:`wbc.papers.sorour` — Sorour, Cherubini & Fraisse: task sharing on a steerable base;
* :mod:`wbc.papers.petric` — Petrič & Žlajpah: the base's velocity field;
* :mod:`wbc.papers.omni` — the omnidirectional platform's torque distribution;
* :mod:`wbc.papers.xing` — Xing et al.'s adaptive motion planning (AMP).

The papers build on the core, the task library, the robot models, the backends and the
simulator; nothing below them imports a paper (the old names in ``wbc.tasks``, ``wbc.robots``
and ``wbc.solvers.reference`` import it on first access). Each paper's study — its
scenarios, metrics, claims and figures — is in :mod:`wbc.experiments.studies`, on top.
Importing ``wbc.papers`` loads no paper: import the one you use.
"""
