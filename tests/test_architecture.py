"""The core's imports point one way: no module of ``wbc/`` (nor of ``solvers/``, which is
``wbc.solvers``, nor of ``papers/``, ``wbc.papers``) imports one that imports it back,
``import wbc`` loads no robot, solver or experiment module, ``import wbc.tasks`` no backend,
controller, fused tick or simulator, and the task library, the robot models and the backends
load no paper; the papers' old names there still answer (imported on first access)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

CORE = Path(__file__).resolve().parents[1] / "wbc"
SOLVERS = Path(__file__).resolve().parents[1] / "solvers"  # installed as wbc.solvers
TASKS = Path(__file__).resolve().parents[1] / "tasks"  # installed as wbc.tasks
PAPERS = Path(__file__).resolve().parents[1] / "papers"  # installed as wbc.papers
#: what the task library must not load: backends, the controller and its fused tick (with the
#: C compilation), the simulator — and, as the imports point one way, robots and studies
NOT_FOR_TASKS = ("wbc.solvers", "wbc.controller", "wbc.fused", "wbc.jit", "wbc.passes",
                 "wbc.cbuild", "wbc.sim", "wbc.robots", "wbc.experiments", "wbc.papers")
#: what none of the three lower layers (tasks, robot models, backends) loads on import
NOT_FOR_LOWER_LAYERS = ("wbc.papers", "wbc.controller", "wbc.fused", "wbc.sim", "wbc.experiments")


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
    """No module of ``solvers/`` imports one that imports it back; the papers' closed forms
    (in ``papers/``) take their linear algebra from ``linalg`` (and ``sns``), and nothing in
    ``solvers/`` but the five aliases ``reference_<paper>`` names a paper."""
    graph = import_graph(SOLVERS, "wbc.solvers")
    aliases = sorted(m for m in graph if m.startswith("wbc.solvers.reference_"))
    assert len(aliases) == 5 and all(_is_alias(_path_of(m, SOLVERS)) for m in aliases)
    assert not import_cycles(graph), f"import cycles in solvers/: {import_cycles(graph)}"
    papers = import_graph(PAPERS, "wbc.papers")
    xing = imported_modules(PAPERS / "xing" / "closed_form.py", PAPERS, _EveryName(),
                            "wbc.papers")
    assert {"wbc.solvers.linalg", "wbc.solvers.sns"} <= xing
    assert "wbc.papers.xing.closed_form" in papers


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
    """Also the task modules ``wbc.tasks`` does not import itself (``manipulability``); not the
    aliases of the papers' old module paths (``velocity_field``, ...), which load the paper."""
    names = sorted(module_name(f, TASKS, "wbc.tasks") for f in TASKS.glob("*.py")
                   if not _is_alias(f))
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
    function or not) names a module the task library must not load (the aliases of the papers'
    old module paths aside)."""
    found = {f.name: _forbidden_imports(f, TASKS) for f in sorted(TASKS.glob("*.py"))
             if not _is_alias(f)}
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


# ------------------------------------------------------------------------------- the papers
#: the old module paths of the papers' pieces, each an alias of its new module
ALIASES = {
    "wbc.tasks.task_sharing": "wbc.papers.sorour.task_sharing",
    "wbc.robots.steerable_control": "wbc.papers.sorour.steering",
    "wbc.solvers.reference_sorour": "wbc.papers.sorour.closed_form",
    "wbc.tasks.velocity_field": "wbc.papers.petric.velocity_field",
    "wbc.solvers.reference_petric": "wbc.papers.petric.closed_form",
    "wbc.solvers.reference_petric_arm": "wbc.papers.petric.closed_form_arm",
    "wbc.tasks.torque_distribution": "wbc.papers.omni.distribution_tasks",
    "wbc.robots.omni_control": "wbc.papers.omni.control",
    "wbc.robots.omni_dynamics": "wbc.papers.omni.dynamics",
    "wbc.solvers.reference_omni": "wbc.papers.omni.closed_form",
    "wbc.solvers.reference_xing": "wbc.papers.xing.closed_form",
}


def _path_of(module: str, root: Path) -> Path:
    """The file of ``module`` in the folder ``root`` (installed as ``wbc.<root's name>``)."""
    return root.joinpath(*module.split(".")[2:]).with_suffix(".py")


def _is_alias(path: Path) -> bool:
    """``path`` is a compatibility alias: it makes its name refer to a moved module."""
    return "sys.modules[__name__] = _moved" in path.read_text()


def _forbidden(modules, bad_prefixes) -> list[str]:
    return [m for m in modules if any(m == bad or m.startswith(bad + ".") for bad in bad_prefixes)]


def test_the_lower_layers_load_no_paper_controller_simulator_or_study():
    """``import wbc.tasks``, ``import wbc.robots``, ``import wbc.solvers`` (and the closed-form
    catalogue ``wbc.solvers.reference``), each in a fresh interpreter, load no paper, controller,
    fused tick, simulator or study: the papers' names there are imported on first access. Robot
    models import only the core (no backend either)."""
    for package in ("wbc.tasks", "wbc.robots", "wbc.solvers", "wbc.solvers.reference"):
        loaded = _loaded_in_a_fresh_interpreter(f"import {package}")
        assert package in loaded
        bad = _forbidden(loaded, NOT_FOR_LOWER_LAYERS)
        assert not bad, f"import {package} loaded {bad}"
    loaded = _loaded_in_a_fresh_interpreter("import wbc.robots")
    assert "wbc.robots.catalogue" in loaded
    assert not _forbidden(loaded, ("wbc.solvers", "wbc.tasks")), loaded


def test_no_statement_of_the_lower_layers_imports_a_paper():
    """The static form: no import statement in ``tasks/``, ``robots/``, ``solvers/`` (inside a
    function or not) names ``wbc.papers``, except the aliases of the old module paths (the
    ``__getattr__`` of the packages imports by name, through :mod:`importlib`)."""
    for root in (TASKS, Path(__file__).resolve().parents[1] / "robots", SOLVERS):
        package = f"wbc.{root.name}"
        for path in sorted(root.glob("*.py")):
            if _is_alias(path):
                continue
            found = _forbidden(imported_modules(path, root, _EveryName(), package),
                               ("wbc.papers",))
            assert not found, f"{path.name} imports {found}"


def test_the_papers_import_no_study_and_have_no_cycle():
    """``wbc.papers.*`` import no ``wbc.experiments`` module (statically, anywhere in a file, and
    when loaded) and no module of ``papers/`` imports one that imports it back."""
    graph = import_graph(PAPERS, "wbc.papers")
    assert {"wbc.papers.sorour", "wbc.papers.petric", "wbc.papers.omni",
            "wbc.papers.xing"} <= set(graph)
    assert not import_cycles(graph), f"import cycles in papers/: {import_cycles(graph)}"
    for path in sorted(PAPERS.rglob("*.py")):
        found = _forbidden(imported_modules(path, PAPERS, _EveryName(), "wbc.papers"),
                           ("wbc.experiments",))
        assert not found, f"{path} imports {found}"
    loaded = _loaded_in_a_fresh_interpreter(
        "import wbc.papers.sorour, wbc.papers.petric, wbc.papers.omni, wbc.papers.xing")
    assert not _forbidden(loaded, ("wbc.experiments",)), loaded


def test_the_old_names_of_the_papers_pieces_are_the_new_objects():
    """``wbc.tasks.VelocityField``, ``wbc.robots.OmniDynamics``, ``wbc.solvers.reference.amp``,
    ... are the papers' objects; they are listed by ``__all__`` and ``dir()``; the old module
    paths are the new modules; the studies' old names (``wbc.experiments.xing.amp_stack``) are
    the papers'."""
    import importlib

    import wbc.papers.omni as omni
    import wbc.papers.petric as petric
    import wbc.papers.sorour as sorour
    import wbc.papers.xing as xing
    import wbc.robots
    import wbc.solvers.reference
    import wbc.tasks

    assert wbc.tasks.VelocityField is petric.velocity_field.VelocityField
    assert wbc.tasks.TorqueDistribution is omni.distribution_tasks.TorqueDistribution
    assert wbc.tasks.share_task is sorour.task_sharing.share_task
    assert wbc.robots.SteerableController is sorour.steering.SteerableController
    assert wbc.robots.OmniDynamics is omni.dynamics.OmniDynamics
    assert wbc.robots.OmniForceControl is omni.control.OmniForceControl
    assert wbc.solvers.reference.amp is xing.closed_form.amp
    assert wbc.solvers.reference.torque_distribution is omni.closed_form.torque_distribution
    assert wbc.solvers.reference.task_sharing_factor is sorour.closed_form.task_sharing_factor
    assert wbc.solvers.reference.PETRIC_LAMBDA == petric.closed_form_arm.PETRIC_LAMBDA
    assert wbc.solvers.reference.rate_limited_twist is petric.closed_form.rate_limited_twist
    for module in (wbc.tasks, wbc.robots, wbc.solvers.reference):
        for name in module.__all__:
            assert hasattr(module, name), (module.__name__, name)
            assert name in dir(module), (module.__name__, name)
        try:
            module.no_such_name  # noqa: B018
        except AttributeError:
            pass
        else:
            raise AssertionError(f"{module.__name__} answers any name")
    for old, new in ALIASES.items():
        assert importlib.import_module(old) is importlib.import_module(new), old
    assert wbc.tasks.velocity_field is petric.velocity_field  # as an attribute, too
    assert wbc.robots.omni_dynamics is omni.dynamics
    from wbc.experiments import petric as petric_study
    from wbc.experiments import sorour as sorour_study
    from wbc.experiments import xing as xing_study
    from wbc.experiments.xing import amp_stack

    assert amp_stack is xing.amp_stack and xing_study.add_amp_levels is xing.add_amp_levels
    assert xing_study.amp_controller is xing.amp_controller
    assert petric_study.arm_stack is petric.arm_stack
    assert petric_study.whole_body_stack is petric.whole_body_stack
    assert petric_study.DecoupledController is petric.DecoupledController
    assert petric_study.WholeBodyController is petric.WholeBodyController
    assert sorour_study.SorourController is sorour.SorourController


def test_every_paper_package_says_what_lives_where():
    """Each paper's ``__init__`` has a docstring naming its modules, and re-exports the public
    names of each (their ``__all__``); no re-exported name hides a module of the package (as
    a function ``amp`` would hide a module ``amp``: ``from wbc.papers.xing import amp`` would
    not be the module)."""
    import importlib

    for paper in ("sorour", "petric", "omni", "xing"):
        package = importlib.import_module(f"wbc.papers.{paper}")
        modules = sorted(p.stem for p in (PAPERS / paper).glob("*.py") if p.stem != "__init__")
        for name in modules:
            assert name not in package.__all__, (paper, name)
            assert f"wbc.papers.{paper}.{name}" in (package.__doc__ or ""), (paper, name)
            module = importlib.import_module(f"wbc.papers.{paper}.{name}")
            for public in module.__all__:
                assert getattr(package, public) is getattr(module, public), (paper, public)
                assert public in package.__all__, (paper, public)


ROOT = Path(__file__).resolve().parents[1]
#: folder -> (package name, layer): 0 the core, 1 tasks / robot models / backends and closed
#: forms, 2 the simulator, the viewer and the papers' pieces, 3 the command line, studies and
#: campaigns
LAYERS = {"wbc": ("wbc", 0), "tasks": ("wbc.tasks", 1), "robots": ("wbc.robots", 1),
          "solvers": ("wbc.solvers", 1), "wbc/sim": ("wbc.sim", 2), "wbc/viz": ("wbc.viz", 2),
          "papers": ("wbc.papers", 2), "experiments": ("wbc.experiments", 3)}
#: the one upward edge of the rule, and why
ALLOWED = {("wbc.workspace", "wbc.solvers"):
           "a backend *name* is resolved through the solvers' registry, lazily, when a "
           "workspace is made (a backend factory needs no import)"}


def _package_graph() -> dict[str, set[str]]:
    """Every module of the package -> the modules of the package it imports (any statement)."""
    files = {}
    for folder, (package, _) in LAYERS.items():
        root = ROOT / folder
        for f in root.rglob("*.py"):
            if folder == "wbc" and ((ROOT / "wbc/sim") in f.parents or
                                    (ROOT / "wbc/viz") in f.parents):
                continue
            files[module_name(f, root, package)] = (f, root, package)
    known = set(files)
    graph = {name: imported_modules(f, root, known, package)
             for name, (f, root, package) in files.items()}
    # a package importing its submodules is how a package is made, and ``from . import x``
    # names the package too: edges between a package and what it contains are not cycles
    return {name: {t for t in targets if not (t.startswith(name + ".") or
                                               name.startswith(t + "."))}
            for name, targets in graph.items()}


def _layer(module: str) -> tuple[str, int]:
    """``(folder's package, layer)`` of a module, the longest matching package first."""
    for package, layer in sorted(LAYERS.values(), key=lambda item: -len(item[0])):
        if module == package or module.startswith(package + "."):
            return package, layer
    raise AssertionError(module)


def _compatibility_alias(module: str, graph_source: dict[str, Path]) -> bool:
    """An old module path kept as an alias of a moved module: it loads the upper layer on
    purpose, and only when used. (Packages answering moved names use
    :func:`wbc.aliases.moved_names`, which imports by name: no statement to exempt.)"""
    return "sys.modules[__name__] =" in graph_source[module].read_text()


def test_every_import_of_the_package_points_down_the_layers():
    """The dependency rule of the README's layout, over the whole package: a module imports
    only its own folder and lower layers; in layer 1, tasks, robot models and backends import
    only the core, not each other. Exceptions: :data:`ALLOWED`, and the compatibility aliases
    of moved modules (loaded only by code that asks for the old name)."""
    graph = _package_graph()
    sources = {}
    for folder, (package, _) in LAYERS.items():
        for f in (ROOT / folder).rglob("*.py"):
            sources.setdefault(module_name(f, ROOT / folder, package), f)
    assert len(graph) > 120 and "wbc.papers.xing.stacks" in graph
    wrong = []
    for module, targets in graph.items():
        home, layer = _layer(module)
        for target in targets:
            there, target_layer = _layer(target)
            if there == home or (module, target.rpartition(".")[0] or target) in ALLOWED \
                    or (module, target) in ALLOWED:
                continue
            if target_layer > layer or (target_layer == layer and layer == 1):
                if not _compatibility_alias(module, sources):
                    wrong.append(f"{module} -> {target}")
    assert not wrong, "imports against the layers:\n" + "\n".join(sorted(wrong))
    assert not import_cycles(graph), import_cycles(graph)
