"""JIT compilation of a compiled stack's functions to C, cached on disk: the former home of
:func:`~wbc.passes.jit_compiled` (the pass, now in :mod:`wbc.passes`) and of the C build and its
cache (:func:`~wbc.cbuild.compiled_c`, :func:`~wbc.cbuild.cache_dir`, now in
:mod:`wbc.cbuild`, whose docstring says where libraries are kept). Both are re-exported here
under their old names.
"""

from __future__ import annotations

from .cbuild import DEFAULT_FLAGS, cache_dir, compiled_c
from .passes import jit_compiled

__all__ = ["DEFAULT_FLAGS", "cache_dir", "compiled_c", "jit_compiled"]
