"""The pages for pink and mink users run as written: every ```python block of
docs/from_pink.md and docs/from_mink.md, the wbc blocks of a page in order in one namespace and
the peer's blocks likewise (skipped, with the reason, when the peer is not installed)."""

from __future__ import annotations

import importlib.util
import re
import warnings
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
PAGES = {"from_pink.md": "pink", "from_mink.md": "mink"}
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def blocks(page: str) -> dict[str, list[str]]:
    """The page's python blocks by side: the first line of each says ``# wbc`` or the peer."""
    sides: dict[str, list[str]] = {}
    for code in BLOCK.findall((DOCS / page).read_text()):
        first = code.splitlines()[0].strip()
        assert first in ("# wbc", f"# {PAGES[page]}"), (
            f"{page}: a python block must open with '# wbc' or '# {PAGES[page]}', got {first!r}")
        sides.setdefault(first[2:], []).append(code)
    return sides


@pytest.mark.parametrize("page", sorted(PAGES))
def test_the_page_has_both_sides_for_each_topic(page):
    sides = blocks(page)
    assert len(sides["wbc"]) >= 6 and len(sides[PAGES[page]]) >= 4
    text = (DOCS / page).read_text()
    for topic in ("cost²", "ρ² = d", "MissingLimitsWarning", "priority=", "wbc.lie",
                  "pose_error_world_jacobian", "Model quantities", "What raises where"):
        assert topic in text, f"{page} does not mention {topic!r}"


@pytest.mark.parametrize("page,side", [(page, side) for page, peer in sorted(PAGES.items())
                                       for side in ("wbc", peer)])
def test_the_code_blocks_run(page, side):
    if side != "wbc" and importlib.util.find_spec(side) is None:
        pytest.skip(f"{side} is not installed")
    namespace: dict = {"__name__": f"docs_{page}_{side}"}
    with warnings.catch_warnings():
        # the pages show the missing-limits warning on purpose (caught in the block itself);
        # any other warning from a block is a defect of the page
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", module="qpsolvers")  # dense matrices to quadprog
        for number, code in enumerate(blocks(page)[side], start=1):
            try:
                exec(compile(code, f"{page}[{side} block {number}]", "exec"), namespace)
            except Exception as err:  # the block, named, with its own traceback
                raise AssertionError(f"{page}, {side} block {number} failed: "
                                     f"{type(err).__name__}: {err}") from err
