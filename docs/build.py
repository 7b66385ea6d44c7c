"""Build the API reference of wbc from its docstrings (pdoc), with warnings as errors.

    pip install -e ".[docs]" && python docs/build.py            # writes docs/api/index.html

The docstrings are Google style with Sphinx cross-reference roles (``:class:`~wbc.Stack```);
pdoc renders Google sections but not Sphinx roles, so each role is rewritten to a plain code
span (``wbc.Stack``), which pdoc links to the documented object. Every warning pdoc raises
(an unresolvable annotation, a broken docstring) fails the build, except one: pdoc cannot
evaluate the postponed annotations of a ``typing.NamedTuple``'s generated ``__new__`` (it looks
for ``np`` in the wrong namespace), which is pdoc's limitation, not a fault of the docstrings.
"""

from __future__ import annotations

import argparse
import re
import sys
import warnings
from pathlib import Path

# The package (its public names), then every module whose docstring explains a part (``wbc``
# has an ``__all__``, so pdoc would not list its modules by itself).
MODULES = ["wbc", "wbc.variables", "wbc.terms", "wbc.stack", "wbc.compiler", "wbc.workspace",
           "wbc.controller", "wbc.solution", "wbc.qp", "wbc.quantities", "wbc.infeasibility",
           "wbc.passes", "wbc.cbuild", "wbc.jit", "wbc.fused", "wbc.checks", "wbc.lie",
           "wbc.aliases", "wbc.errors", "wbc.sim", "wbc.viz", "wbc.tasks", "wbc.robots",
           "wbc.solvers", "wbc.solvers.reference", "wbc.papers", "wbc.experiments.studies.study"]
ROLE = re.compile(r":(?:class|func|meth|mod|attr|data|exc|obj):`~?([^`]+)`")
NAMEDTUPLE_LIMITATION = r"Error parsing type annotation .* for wbc\.robots\.\w+\.__init__\."


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "api",
                        help="output folder (default: docs/api)")
    args = parser.parse_args(argv)
    import pdoc
    import pdoc.docstrings
    import pdoc.render

    convert = pdoc.docstrings.convert

    def without_roles(docstring: str, docformat: str, source_file):
        return convert(ROLE.sub(r"`\1`", docstring), docformat, source_file)

    pdoc.docstrings.convert = without_roles
    # wbc imports Controller on first use (a module __getattr__, so that the task library does
    # not load the fused tick); pdoc reads the module's namespace, so put it there first
    import wbc

    vars(wbc).setdefault("Controller", wbc.Controller)
    # likewise the papers' names that wbc.tasks, wbc.robots and wbc.solvers.reference keep for
    # compatibility (imported from wbc.papers on first access) and the viewer's (imported when
    # first asked for, so that wbc.viz works without viser)
    import importlib

    for name in ("wbc.tasks", "wbc.robots", "wbc.solvers.reference", "wbc.viz"):
        module = importlib.import_module(name)
        for public in module.__all__:
            vars(module).setdefault(public, getattr(module, public))
    pdoc.render.configure(docformat="google", show_source=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", NAMEDTUPLE_LIMITATION, UserWarning)
        pdoc.pdoc(*MODULES, output_directory=args.out)
    print(f"wrote {args.out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
