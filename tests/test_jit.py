"""`wbc.jit`: compiled C equals the virtual machine, is built once and cached, and a missing
compiler falls back to the virtual machine with a warning."""

from __future__ import annotations

import os

import numpy as np
import pytest

import wbc
from wbc.jit import cache_dir, jit_compiled
from wbc.tasks import Bounds, LinearTask


def _stack(seed: int, n: int = 5) -> wbc.Stack:
    rng = np.random.default_rng(seed)
    stack = wbc.Stack(wbc.Variables(x=n), damping={0: 0.1})
    stack.add(LinearTask(rng.standard_normal((3, n)), rng.standard_normal(3), name="a"),
              priority=0)
    stack.add(LinearTask(np.eye(n), rng.standard_normal(n), name="b"), priority=1)
    stack.constrain(Bounds(-np.ones(n), np.ones(n), name="box"))
    return stack


def _libraries(folder):
    return sorted(p.name for p in folder.glob("*.so")) if folder.exists() else []


def test_compiled_c_equals_the_virtual_machine_and_is_built_once(tmp_path, monkeypatch):
    monkeypatch.setenv("WBC_JIT_CACHE", str(tmp_path / "cache"))
    assert cache_dir() == tmp_path / "cache"
    stack = _stack(0)
    vm = stack.workspace("daqp", "tight").solve()
    fast = stack.workspace("daqp", "tight", jit=True).solve()
    np.testing.assert_allclose(fast.x, vm.x, atol=1e-12)
    built = _libraries(tmp_path / "cache")
    assert len(built) == len(stack.compile().blocks) == 3  # two levels and the min-norm level
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "cache").glob("*.so")}
    again = jit_compiled(stack.compile())  # the same functions: loaded, not rebuilt
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cache").glob("*.so")} == stamps
    assert [b.function.name() for b in again.blocks] == [
        b.function.name() for b in stack.compile().blocks]
    # task numbers are parameters: other numbers are the same code, other sizes are not
    jit_compiled(_stack(1).compile())
    assert len(_libraries(tmp_path / "cache")) == 3
    jit_compiled(_stack(1, n=6).compile())
    assert len(_libraries(tmp_path / "cache")) == 6


def test_without_a_compiler_the_virtual_machine_is_used(tmp_path, monkeypatch):
    monkeypatch.setenv("WBC_JIT_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", "no-such-compiler-wbc")
    compiled = _stack(2).compile()
    with pytest.warns(RuntimeWarning, match="no-such-compiler-wbc"):
        assert jit_compiled(compiled) is compiled
    monkeypatch.setenv("CC", "false")  # a compiler that fails
    with pytest.warns(RuntimeWarning, match="false failed"):
        assert jit_compiled(compiled) is compiled
    assert _libraries(tmp_path) == []


def test_an_unwritable_cache_falls_back_to_a_process_folder(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("WBC_JIT_CACHE", str(blocker / "cache"))  # mkdir fails
    stack = _stack(3)
    fast = wbc.Workspace(jit_compiled(stack.compile()), "daqp", "tight").solve()
    np.testing.assert_allclose(fast.x, stack.workspace("daqp", "tight").solve().x, atol=1e-12)


def test_jit_leaves_no_temporary_folder_behind(tmp_path):
    """A process folder is made only when the cache cannot be written, and removed at exit."""
    import subprocess
    import sys

    script = ("import numpy as np, wbc\nfrom wbc.jit import jit_compiled\n"
              "from wbc.tasks import LinearTask\n"
              "s = wbc.Stack(2).add(LinearTask(np.eye(2), np.ones(2), name='t'))\n"
              "print(wbc.Workspace(jit_compiled(s.compile()), 'daqp').solve().ok)\n")
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    for cache in (tmp_path / "cache", blocker / "cache"):  # writable, then not
        temp = tmp_path / f"tmp_{cache.parent.name}"
        temp.mkdir()
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                              timeout=120, env={**os.environ, "WBC_JIT_CACHE": str(cache),
                                                "TMPDIR": str(temp)})
        assert done.stdout.strip() == "True", done.stderr
        assert list(temp.iterdir()) == []
