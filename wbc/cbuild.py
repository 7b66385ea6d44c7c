"""CasADi functions (and Python extension modules) built as C shared libraries, cached on disk.

CasADi generates the C code of a function (each block function of a compiled stack, for
:func:`wbc.passes.jit_compiled`; the fused tick, for :class:`wbc.fused.FusedWorkspace`); the
system compiler (``$CC``, default ``cc``) builds it into a shared library that
:func:`casadi.external` loads (:func:`compiled_c`). :func:`compiled_extension` builds a Python
extension module from C source the same way (the control tick's input checks,
:data:`wbc.checks.STAGE_SOURCE`). Libraries are kept in a cache folder under a hash of the C
source, the compiler and its flags, so a function is compiled once per machine, however many
controllers, backends or processes use it: the first build costs ≈ 0.1–0.5 s per function,
every later one ≈ 1 ms. Evaluation drops from the CasADi virtual machine's ≈ 10 µs to ≈ 1 µs
for a Panda pose + posture level.

Cache folder: ``$WBC_JIT_CACHE`` if set, else ``$XDG_CACHE_HOME/wbc/jit`` (``~/.cache/wbc/jit``).
If it cannot be written, libraries go to a temporary folder for this process only. Builds
write to a temporary file and rename it, so concurrent processes never load a partial library.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.machinery
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Callable
from functools import cache
from pathlib import Path
from types import ModuleType

import casadi as ca

DEFAULT_FLAGS = ("-O2",)


def cache_dir() -> Path:
    """The folder the shared libraries are kept in (see the module docstring)."""
    if os.environ.get("WBC_JIT_CACHE"):
        return Path(os.environ["WBC_JIT_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "wbc" / "jit"


@cache
def _process_dir() -> Path:
    """A temporary folder for this process, when the cache folder is not writable; removed
    when the process exits (a loaded library stays mapped after its file is gone)."""
    folder = tempfile.mkdtemp(prefix="wbc-jit-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return Path(folder)


def compiled_c(function: ca.Function, flags: tuple[str, ...] = DEFAULT_FLAGS,
               link: tuple[str, ...] = (),
               patch: Callable[[str], str] | None = None) -> ca.Function:
    """``function`` (same name, inputs and outputs) evaluated by compiled C from the cache,
    building the library first if needed. ``link``: extra compiler arguments placed after the
    source, e.g. ``-I`` folders and static libraries the generated code calls (CasADi's daqp:
    see :func:`wbc.passes.daqp_link_arguments`); they are part of the cache key. ``patch``: a
    correction applied to the generated source before it is hashed and compiled. Raises
    ``RuntimeError`` if the compiler (or ``patch``) fails."""
    library = compiled_library(function, flags, link, patch)
    return ca.external(function.name(), str(library))


def compiled_library(function: ca.Function, flags: tuple[str, ...] = DEFAULT_FLAGS,
                     link: tuple[str, ...] = (),
                     patch: Callable[[str], str] | None = None) -> Path:
    """The path of the shared library :func:`compiled_c` loads (same arguments): CasADi's
    generated C of ``function``, which exports the C function ``function.name()`` and its
    ``<name>_work``, ``<name>_checkout``, ... (what :data:`wbc.checks.STAGE_SOURCE`'s
    ``fused_call`` calls directly)."""
    generator = ca.CodeGenerator(f"{function.name()}.c", {"with_header": False})
    generator.add(function)
    source = generator.dump()
    if patch is not None:
        source = patch(source)
    return cached_library(function.name(), source, flags, link)


def compiled_extension(name: str, source: str, flags: tuple[str, ...] = DEFAULT_FLAGS,
                       link: tuple[str, ...] = ()) -> ModuleType:
    """The Python extension module ``name`` (its C ``source`` defines ``PyInit_<name>``),
    built against this interpreter's headers into the cache if needed, and loaded. ``flags``
    (e.g. ``-I`` folders) and ``link`` (arguments after the source, e.g. ``-ldl``) are part of
    the cache key, and so are the interpreter's version and ABI. Raises ``RuntimeError`` if the
    compiler fails (no compiler, no Python headers)."""
    include = sysconfig.get_paths()["include"]
    stamp = f"/* CPython {sys.version.split()[0]} {sysconfig.get_config_var('EXT_SUFFIX')} */\n"
    path = cached_library(name, stamp + source, (*flags, f"-I{include}"), link)
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, path, loader=loader)
    if spec is None:
        raise RuntimeError(f"cannot load {path} as a Python extension")
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def cached_library(stem: str, source: str, flags: tuple[str, ...] = DEFAULT_FLAGS,
                   link: tuple[str, ...] = ()) -> Path:
    """The path of the shared library built from C ``source`` with ``flags`` and ``link``
    (arguments placed after the source) by ``$CC``, in the cache under ``stem`` and a hash of
    all of them — built first if it is not there (see the module docstring). Raises
    ``RuntimeError`` if the compiler fails or no folder is writable."""
    compiler = os.environ.get("CC", "cc")
    key = hashlib.sha256("\0".join([source, compiler, *flags, *link]).encode()).hexdigest()[:24]
    name = f"{stem}_{key}.so"
    for folder in (cache_dir, _process_dir):  # the process folder only if the cache fails
        library = folder() / name
        try:
            if not library.exists():
                _build(source, library, compiler, (*flags, "-shared", "-fPIC"), link)
            return library
        except OSError:  # not writable: next folder
            continue
    raise RuntimeError(f"no writable folder for JIT libraries (tried {cache_dir()})")


def _build(source: str, library: Path, compiler: str, flags: tuple[str, ...],
           link: tuple[str, ...]) -> None:
    library.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=library.parent) as tmp:
        c_file, built = Path(tmp) / "block.c", Path(tmp) / library.name
        c_file.write_text(source)
        try:
            done = subprocess.run([compiler, *flags, "-o", str(built), str(c_file), *link],
                                  capture_output=True, text=True)
        except FileNotFoundError as err:
            raise RuntimeError(f"C compiler {compiler!r} not found") from err
        if done.returncode != 0:
            raise RuntimeError(f"{compiler} failed: {done.stderr.strip()[:400]}")
        os.replace(built, library)  # atomic: readers see no library or a whole one


def compiler_available() -> bool:
    """Whether the C compiler (``$CC``, default ``cc``) is on the path."""
    return shutil.which(os.environ.get("CC", "cc")) is not None


__all__ = ["DEFAULT_FLAGS", "cache_dir", "cached_library", "compiled_c", "compiled_extension",
           "compiled_library", "compiler_available"]
