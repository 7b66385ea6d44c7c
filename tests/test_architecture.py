"""The core's imports point one way: no module of ``wbc/`` (nor of ``solvers/``, which is
``wbc.solvers``) imports one that imports it back, ``import wbc`` loads no robot, solver or
experiment module, and ``import wbc.tasks`` no backend, controller, fused tick or simulator."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

CORE = Path(__file__).resolve().parents[1] / "wbc"
SOLVERS = Path(__file__).resolve().parents[1] / "solvers"  # installed as wbc.solvers
TASKS = Path(__file__).resolve().parents[1] / "tasks"  # installed as wbc.tasks
#: what the task library must not load: backends, the controller and its fused tick (with the
#: C compilation), the simulator — and, as the imports point one way, robots and studies
NOT_FOR_TASKS = ("wbc.solvers", "wbc.controller", "wbc.fused", "wbc.jit", "wbc.passes",
                 "wbc.cbuild", "wbc.sim", "wbc.robots", "wbc.experiments")


def module_name(path: Path, root: Path, package: str | None = None) -> str:
    """The dotted name of ``path`` in the package at ``root`` (named ``package``, default the
    folder's name)."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    if package:
        parts = (*package.split("."), *parts[1:])
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path, root: Path, known: set[str],
                     package_name: str | None = None) -> set[str]:
    """The modules of ``known`` that ``path`` imports, at any place in the file (lazy imports
    inside functions and ``TYPE_CHECKING`` blocks count: they are cycles all the same)."""
    name = module_name(path, root, package_name)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")
                parent = parent[:len(parent) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        found.update(t for t in targets if t in known and t != name)
    return found


def import_graph(root: Path, package: str | None = None) -> dict[str, set[str]]:
    """``module -> modules of the package at root it imports`` (``package``: the package's
    dotted name, when it is not the folder's)."""
    files = sorted(root.rglob("*.py"))
    known = {module_name(f, root, package) for f in files}
    graph = {module_name(f, root, package): imported_modules(f, root, known, package)
             for f in files}
    # a package's __init__ re-exporting its submodules is how a package is made, not a cycle
    for package in [m for m in graph if any(k.startswith(m + ".") for k in graph)]:
        graph[package] = {m for m in graph[package] if not m.startswith(package + ".")}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[str]:
    cycles = []
    for start in graph:
        stack, seen = [(start, [start])], set()
        while stack:
            node, path = stack.pop()
            for nxt in graph[node]:
                if nxt == start:
                    cycles.append(" -> ".join(path + [start]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, path + [nxt]))
    return sorted(set(cycles))


def test_core_modules_import_in_one_direction():
    graph = import_graph(CORE)
    assert "wbc.stack" in graph and "wbc.sim.simulation" in graph
    assert not import_cycles(graph), f"import cycles in wbc/: {import_cycles(graph)}"


def test_the_cycle_check_finds_a_cycle(tmp_path):
    """The check above can fail: two modules importing each other (one lazily) are reported,
    a package importing its own submodules is not."""
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("from .a import x\n")
    (package / "a.py").write_text("from . import b\nx = 1\n")
    (package / "b.py").write_text("def f():\n    from .a import x\n")
    graph = import_graph(package)
    assert graph == {"pkg": set(), "pkg.a": {"pkg", "pkg.b"}, "pkg.b": {"pkg.a"}}
    assert import_cycles(graph)
    # a folder installed under another name (solvers/ is wbc.solvers): absolute imports count
    (package / "b.py").write_text("def f():\n    from wbc.solvers.a import x\n")
    assert import_graph(package, "wbc.solvers")["wbc.solvers.b"] == {"wbc.solvers.a"}


def test_solvers_import_in_one_direction():
    """The paper modules take their linear algebra from ``linalg`` (and ``sns``), and
    ``reference`` re-exports them all: no module of ``solvers/`` imports one that imports it
    back."""
    graph = import_graph(SOLVERS, "wbc.solvers")
    papers = [m for m in graph if m.startswith("wbc.solvers.reference_")]
    assert len(papers) == 5 and "wbc.solvers.linalg" in graph["wbc.solvers.reference_xing"]
    assert set(papers) <= graph["wbc.solvers.reference"]
    assert not import_cycles(graph), f"import cycles in solvers/: {import_cycles(graph)}"


def test_import_wbc_loads_no_robot_solver_or_experiment():
    code = ("import sys, wbc, wbc.sim\n"
            "bad = [m for m in sys.modules if m.startswith(('wbc.robots', 'wbc.solvers', "
            "'wbc.experiments', 'wbc.tasks', 'pinocchio', 'daqp', 'proxsuite', 'osqp', "
            "'clarabel', 'quadprog', 'qpsolvers'))]\n"
            "print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "", f"import wbc loaded {out}"


def _loaded_in_a_fresh_interpreter(code: str) -> list[str]:
    """The ``wbc`` modules in ``sys.modules`` after running ``code`` in a new interpreter."""
    code += "\nimport sys; print(sorted(m for m in sys.modules if m.startswith('wbc')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return ast.literal_eval(out.strip().splitlines()[-1])


def _forbidden_for_tasks(modules) -> list[str]:
    return [m for m in modules if any(m == bad or m.startswith(bad + ".")
                                      for bad in NOT_FOR_TASKS)]


def test_import_wbc_tasks_loads_no_backend_controller_fused_tick_or_simulator():
    loaded = _loaded_in_a_fresh_interpreter("import wbc.tasks")
    assert "wbc.tasks.frame" in loaded and "wbc.lie" in loaded  # the probe sees the imports
    assert not _forbidden_for_tasks(loaded), f"import wbc.tasks loaded {loaded}"


def test_every_task_module_loads_no_backend_controller_fused_tick_or_simulator():
    """Also the task modules ``wbc.tasks`` does not import itself (``manipulability``)."""
    names = sorted(module_name(f, TASKS, "wbc.tasks") for f in TASKS.glob("*.py"))
    assert "wbc.tasks.manipulability" in names
    loaded = _loaded_in_a_fresh_interpreter("".join(f"import {n}\n" for n in names))
    assert not _forbidden_for_tasks(loaded), f"the task modules loaded {loaded}"


class _EveryName(set):
    """A ``known`` for :func:`imported_modules` that keeps every imported name."""

    def __contains__(self, name) -> bool:
        return True


def _forbidden_imports(path: Path, root: Path) -> list[str]:
    return sorted(_forbidden_for_tasks(imported_modules(path, root, _EveryName(), "wbc.tasks")))


def test_no_task_module_imports_a_backend_controller_or_simulator_even_lazily():
    """The static form of the two tests above: no import statement in ``tasks/`` (inside a
    function or not) names a module the task library must not load."""
    found = {f.name: _forbidden_imports(f, TASKS) for f in sorted(TASKS.glob("*.py"))}
    assert "frame.py" in found and not any(found.values()), found


def test_the_task_check_finds_a_forbidden_import(tmp_path):
    """The static check above can fail: an import of the controller inside a function and one
    of a solver module are found; a relative import of a task module is not."""
    module = tmp_path / "tasks" / "bad.py"
    module.parent.mkdir()
    module.write_text("from .frame import velocity_block\nimport wbc.solvers.reference\n"
                      "def f():\n    from wbc.controller import check_frame\n")
    assert _forbidden_imports(module, module.parent) == [
        "wbc.controller", "wbc.controller.check_frame", "wbc.solvers.reference"]


def test_the_lie_group_math_is_pure_casadi():
    """``wbc/lie.py`` imports casadi and numpy only: nothing of the core, tasks, robots or
    solvers (any module may build on it)."""
    tree = ast.parse((CORE / "lie.py").read_text())
    imported = {alias.name.split(".")[0] for node in ast.walk(tree)
                if isinstance(node, ast.Import) for alias in node.names}
    imported |= {(node.module or "").split(".")[0] or "." for node in ast.walk(tree)
                 if isinstance(node, ast.ImportFrom) and node.module != "__future__"}
    assert imported == {"casadi", "numpy"}, imported


def test_the_old_homes_still_answer():
    """``wbc.tasks.frame`` re-exports the Lie-group math it used to define (the Xing study and
    the tests import ``so3_log`` from there); ``wbc.controller.check_frame`` is importable."""
    import wbc.lie
    import wbc.tasks.frame
    from wbc.checks import check_frame
    from wbc.controller import check_frame as check_frame_of_the_controller

    for name in wbc.lie.__all__:
        assert getattr(wbc.tasks.frame, name) is getattr(wbc.lie, name), name
    assert callable(check_frame_of_the_controller) and callable(check_frame)
