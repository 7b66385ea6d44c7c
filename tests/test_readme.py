"""Every ```python block of the README runs as written, as a user would paste it: each in a fresh
namespace, except a block whose first line is the comment ``# continues``, which runs after the
block before it (in that block's namespace)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
CONTINUES = "# continues"


def python_blocks(text: str) -> list[tuple[int, str]]:
    """``(line number, code)`` of every ```python block."""
    return [(text[:match.start()].count("\n") + 2, match.group(1))
            for match in re.finditer(r"^```python\n(.*?)^```", text, re.S | re.M)]


BLOCKS = python_blocks(README.read_text())


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 4


@pytest.mark.parametrize("index", range(len(BLOCKS)),
                         ids=[f"line {line}" for line, _ in BLOCKS])
def test_readme_block_runs_as_written(index, tmp_path, monkeypatch):
    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)  # whatever a block writes lands here
    start = index
    while BLOCKS[start][1].startswith(CONTINUES):
        assert start > 0, "the first block cannot continue another"
        start -= 1
    namespace: dict = {"__name__": "__readme__"}
    for line, code in BLOCKS[start:index + 1]:
        exec(compile(code, f"README.md, block at line {line}", "exec"), namespace)


def test_the_api_reference_builds_without_warnings(tmp_path):
    """The README's docs command (pdoc is in the ``docs`` extra, not in the test install)."""
    pytest.importorskip("pdoc")
    import runpy

    build = runpy.run_path(str(README.parent / "docs" / "build.py"), run_name="docs_build")
    assert build["main"](["--out", str(tmp_path)]) == 0  # a warning would raise
    assert (tmp_path / "wbc.html").is_file() and (tmp_path / "wbc" / "workspace.html").is_file()
    assert ":class:" not in (tmp_path / "wbc.html").read_text()
    assert "python docs/build.py" in README.read_text()
