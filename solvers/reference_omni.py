"""Alias: the old path of :mod:`wbc.papers.omni.closed_form`, kept for compatibility.

Each paper's library pieces live in its own package under ``wbc.papers`` (issue #22). This
module, kept so that existing imports keep working, makes the old name
``wbc.solvers.reference_omni`` refer to the moved module itself (the same object in
``sys.modules``: its private names and monkeypatching work through either name). New code
imports ``wbc.papers.omni.closed_form``. Nothing imports this module at ``import wbc.solvers``:
only an explicit import of the old path loads the paper.
"""

import sys

from wbc.papers.omni import closed_form as _moved

sys.modules[__name__] = _moved
