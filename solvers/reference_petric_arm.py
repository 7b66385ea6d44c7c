"""Alias: the old path of :mod:`wbc.papers.petric.closed_form_arm`, kept for compatibility.

Each paper's library pieces live in its own package under ``wbc.papers`` (issue #22). This
module, kept so that existing imports keep working, makes the old name
``wbc.solvers.reference_petric_arm`` refer to the moved module itself (the same object in
``sys.modules``: its private names and monkeypatching work through either name). New code
imports ``wbc.papers.petric.closed_form_arm``. Nothing imports this module at ``import
wbc.solvers``: only an explicit import of the old path loads the paper.
"""

import sys

from wbc.papers.petric import closed_form_arm as _moved

sys.modules[__name__] = _moved
