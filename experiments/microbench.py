"""Alias: the old path of :mod:`wbc.experiments.benchmarks.microbench`.

``experiments/`` was split into subpackages by purpose (issue #22). This module, kept so
that existing imports keep working, makes the old name ``wbc.experiments.microbench`` refer to
the moved module itself (the same object in ``sys.modules``: its private names and
monkeypatching work through either name). New code imports
``wbc.experiments.benchmarks.microbench``.
"""

import sys

from .benchmarks import microbench as _moved

if __name__ == "__main__":  # ``python -m wbc.experiments.microbench``, as before
    raise SystemExit(_moved.main())
sys.modules[__name__] = _moved
