"""Citations of the design document resolve: every docstring or comment of the repository's
``.py`` files that cites ``docs/DESIGN.md`` names a math note or a section that is a heading of
that file, and no citation of the design uses an older form (``DESIGN math note 3``, a bare
``math note 3``, ``design note``) that names no file."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "docs" / "DESIGN.md"
#: folders whose .py files are scanned: the package (its five folders), tests, examples, docs
FOLDERS = ("wbc", "tasks", "robots", "solvers", "experiments", "tests", "examples", "docs")

#: ``docs/DESIGN.md, math note 3``, ``docs/DESIGN.md, math notes 1–6``,
#: ``docs/DESIGN.md, section "Robots and tasks"`` (whitespace may break the line)
CITATION = re.compile(
    r"docs/DESIGN\.md(?P<what>,\s+(?:math\s+notes?\s+(?P<first>\d+)(?:\s*[–-]\s*(?P<last>\d+))?"
    r"|section\s+\"(?P<section>[^\"]+)\"))?")
#: forms that cite the design without naming the file: stale
STALE = re.compile(r"\bDESIGN\b|(?i:\bmath\s+notes?\s+\d|\bdesign\s+(?:math\s+)?notes?\b)")


def headings(markdown: str) -> tuple[set[str], set[int]]:
    """``(titles, math notes)`` of a markdown text: every heading's text (fenced code blocks
    skipped) and the numbers of the headings ``Math note N ...``."""
    titles: set[str] = set()
    fenced = False
    for line in markdown.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (match := re.match(r"#{1,6}\s+(.+?)\s*#*\s*$", line)):
            titles.add(match.group(1))
    notes = {int(m.group(1)) for t in titles if (m := re.match(r"Math note (\d+)\b", t))}
    return titles, notes


def unresolved(text: str, titles: set[str], notes: set[int]) -> list[str]:
    """The citations in ``text`` that do not resolve, each with what is wrong."""
    problems = []
    spans = []
    for match in CITATION.finditer(text):
        spans.append(match.span())
        cited = " ".join(match.group(0).split())
        if match.group("what") is None:
            problems.append(f"{cited!r} names no math note or section")
        elif match.group("section") is not None:
            section = " ".join(match.group("section").split())
            if section not in titles:
                problems.append(f"{cited!r}: no heading {section!r}")
        else:
            first = int(match.group("first"))
            last = int(match.group("last") or first)
            missing = [k for k in range(first, last + 1) if k not in notes]
            if missing or last < first:
                problems.append(f"{cited!r}: no math note {missing or (first, last)}")
    for match in STALE.finditer(text):
        start = match.start()
        if not any(a <= start < b for a, b in spans):
            line = text[:start].count("\n") + 1
            problems.append(f"line {line}: {match.group(0)!r} cites the design without "
                            "'docs/DESIGN.md, math note N' or 'docs/DESIGN.md, section \"...\"'")
    return problems


def python_files() -> list[Path]:
    here = Path(__file__).resolve()
    return sorted(path for folder in FOLDERS for path in (ROOT / folder).rglob("*.py")
                  if path.resolve() != here)


def test_every_citation_of_the_design_resolves():
    titles, notes = headings(DESIGN.read_text(encoding="utf-8"))
    assert notes, "docs/DESIGN.md has no 'Math note N' heading"
    problems = [f"{path.relative_to(ROOT)}: {problem}" for path in python_files()
                for problem in unresolved(path.read_text(encoding="utf-8"), titles, notes)]
    assert not problems, "citations of docs/DESIGN.md that do not resolve:\n" + "\n".join(
        problems)


def test_the_citations_are_found():
    """The scan sees the citations (a pattern that matched nothing would pass vacuously)."""
    cited = [m for path in python_files()
             for m in CITATION.finditer(path.read_text(encoding="utf-8"))]
    assert len(cited) >= 20
    assert any(m.group("section") for m in cited) and any(m.group("first") for m in cited)


def test_the_check_finds_broken_citations():
    titles, notes = {"Math note 1 — a", "Robots and tasks"}, {1}
    good = ('x (docs/DESIGN.md, math note 1) and docs/DESIGN.md,\n    section "Robots and '
            'tasks" and (docs/DESIGN.md, math notes 1-1)')
    assert unresolved(good, titles, notes) == []
    assert unresolved("by design, a design choice", titles, notes) == []
    for bad in ("(docs/DESIGN.md, math note 2)", "(docs/DESIGN.md, math notes 1–2)",
                'docs/DESIGN.md, section "Robots"', "see docs/DESIGN.md.",
                "(DESIGN math note 1)", "(math note 1)", "(Math Note 1)", "(design note 1)",
                "the DESIGN says"):
        assert unresolved(bad, titles, notes), bad
    assert headings("# T\n```\n# not a heading\n```\n### Math note 7 — x\n") == (
        {"T", "Math note 7 — x"}, {7})
