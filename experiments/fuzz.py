"""Alias: the old path of :mod:`wbc.experiments.campaigns.fuzz`.

``experiments/`` was split into subpackages by purpose (issue #22). This module, kept so
that existing imports keep working, makes the old name ``wbc.experiments.fuzz`` refer to
the moved module itself (the same object in ``sys.modules``: its private names and
monkeypatching work through either name). New code imports
``wbc.experiments.campaigns.fuzz``.
"""

import sys

from .campaigns import fuzz as _moved

sys.modules[__name__] = _moved
