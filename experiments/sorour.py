"""Alias: the old path of :mod:`wbc.experiments.studies.sorour`.

``experiments/`` was split into subpackages by purpose (issue #22). This module, kept so
that existing imports keep working, makes the old name ``wbc.experiments.sorour`` refer to
the moved module itself (the same object in ``sys.modules``: its private names and
monkeypatching work through either name). New code imports
``wbc.experiments.studies.sorour``.
"""

import sys

from .studies import sorour as _moved

if __name__ == "__main__":  # ``python -m wbc.experiments.sorour``, as before
    raise SystemExit(_moved.main())
sys.modules[__name__] = _moved
