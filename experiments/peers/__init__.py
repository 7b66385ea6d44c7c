"""Head-to-head comparisons with other whole-body / differential-IK libraries on one problem
(the Panda, a frame task, a posture task, limits): timing and agreement of the commands.

* :mod:`~wbc.experiments.peers.vs_pink` — ``wbc pink`` (the problem and the shared machinery);
* :mod:`~wbc.experiments.peers.vs_mink` — ``wbc mink``;
* :mod:`~wbc.experiments.peers.vs_placo` — ``wbc placo``.

Each peer is an optional extra (``pip install ".[pink]"``, ...); without it the verb fails with
the install hint.
"""
