"""Old names of moved pieces, answered on first access (PEP 562).

When a piece moves up a layer (a paper's task out of ``wbc.tasks`` into ``wbc.papers``), its
old package keeps answering the old name without importing the new home at import time: the
lower layer stays free of the upper one, and only code that asks for the old name loads it.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable, Mapping


def moved_names(package: str, moved: Mapping[str, str], modules: Iterable[str] = ()
                ) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for the module ``package``.

    Args:
        package: the module's ``__name__``.
        moved: old name -> the module that now defines it (imported on first access, then
            cached in the module's namespace, so later accesses are plain lookups).
        modules: old submodule names (alias files kept in the package's folder), answered as
            attributes without importing them first.
    """
    moved_modules = frozenset(modules)

    def __getattr__(name: str):
        if name in moved:
            value = getattr(importlib.import_module(moved[name]), name)
            setattr(sys.modules[package], name, value)
            return value
        if name in moved_modules:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(moved))

    return __getattr__, __dir__


__all__ = ["moved_names"]
