"""Alias: the old path of :mod:`wbc.experiments.studies.omni`.

``experiments/`` was split into subpackages by purpose (issue #22). This module, kept so
that existing imports keep working, makes the old name ``wbc.experiments.omni`` refer to
the moved module itself (the same object in ``sys.modules``: its private names and
monkeypatching work through either name). New code imports
``wbc.experiments.studies.omni``.
"""

import sys

from .studies import omni as _moved

sys.modules[__name__] = _moved
