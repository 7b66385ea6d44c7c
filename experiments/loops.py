"""Alias: the old path of :mod:`wbc.experiments.benchmarks.loops`.

``experiments/`` was split into subpackages by purpose (issue #22). This module, kept so
that existing imports keep working, makes the old name ``wbc.experiments.loops`` refer to
the moved module itself (the same object in ``sys.modules``: its private names and
monkeypatching work through either name). New code imports
``wbc.experiments.benchmarks.loops``.
"""

import sys

from .benchmarks import loops as _moved

sys.modules[__name__] = _moved
