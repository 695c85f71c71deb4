"""The layering rule of ``docs/architecture.md``, checked on every import of the project's own modules, those inside
functions included:

* the package graph points one way: ``wwcore`` ← ``plant_sim``, ``service`` (never each other) ← the application
  (``windwarden.evaluation`` ← ``windwarden.kinds`` ← the studies ← ``windwarden.live``) ← the edges (``api``,
  ``dashboards``) ← the command line (``windwarden.cli``, ``windwarden.commands``);
* the module graph, with the imports inside functions as edges, has no cycle: no import is deferred into a
  function to dodge one;
* the numerical core imports no transport: every module of wwcore, plant_sim and service, imported in a fresh
  interpreter, leaves zenoh, rerun and fastapi unloaded.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("wwcore", "plant_sim", "service", "windwarden", "api", "dashboards")
CORE = ("wwcore", "plant_sim", "service")
EDGES = ("zenoh", "rerun", "fastapi", "uvicorn", "starlette")

# (module prefix, layer): the longest matching prefix decides; a module may import its own layer's modules (within
# its own group: the prefix, or the group STUDIES names) and every lower layer's.
LAYERS = (
    ("wwcore", 0),
    ("plant_sim", 1),
    ("service", 1),
    ("windwarden.evaluation", 2),
    ("windwarden.bench", 2),
    ("windwarden.kinds", 3),  # one object per plant kind: its evaluator (below) and its live conversions
    ("windwarden.evaluation.detectability", 4),  # studies: many evaluations of generated scenarios, through the kinds
    ("windwarden.evaluation.random_scenarios", 4),
    ("windwarden.live", 5),
    ("api", 6),
    ("dashboards", 6),
    ("windwarden", 7),  # the command line: windwarden.cli, windwarden.commands
)
STUDIES = frozenset({"windwarden.evaluation.detectability", "windwarden.evaluation.random_scenarios"})
SIBLINGS = {frozenset({"plant_sim", "service"}), frozenset({"api", "dashboards"})}  # never import each other


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def project_modules() -> dict[str, Path]:
    return {module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}


def imports_of(name: str, path: Path, known: set[str]) -> list[tuple[str, int, bool]]:
    """(imported project module, line, inside a function) for every import statement of the module."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    in_function: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            in_function.update(id(sub) for sub in ast.walk(node) if isinstance(sub, (ast.Import, ast.ImportFrom)))
    found = []
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            # "from pkg import mod" imports a module when pkg.mod is one
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.append((target, node.lineno, id(node) in in_function))
    return found


def layer_of(module: str) -> tuple[str, int]:
    """(group, layer) of a module: the group is its longest matching prefix, or ``"studies"`` for those."""
    prefix, layer = max(
        ((p, n) for p, n in LAYERS if module == p or module.startswith(p + ".")), key=lambda item: len(item[0])
    )
    return ("studies" if prefix in STUDIES else prefix), layer


@pytest.fixture(scope="module")
def graph() -> dict[str, list[tuple[str, int, bool]]]:
    modules = project_modules()
    known = set(modules)
    return {name: imports_of(name, path, known) for name, path in modules.items()}


def test_every_import_points_down_the_layers(graph):
    wrong = []
    for module, imports in graph.items():
        group, layer = layer_of(module)
        for target, line, _ in imports:
            target_group, target_layer = layer_of(target)
            siblings = frozenset({group.split(".")[0], target_group.split(".")[0]}) in SIBLINGS
            if target_layer > layer or (target_layer == layer and target_group != group) or siblings:
                wrong.append(f"{module}:{line} imports {target}")
    assert not wrong, "imports against the layering:\n" + "\n".join(sorted(wrong))


def test_no_import_cycle_even_through_imports_inside_functions(graph):
    edges = {m: sorted({t for t, _, _ in imports}) for m, imports in graph.items()}
    state: dict[str, int] = {}  # 1: on the path, 2: done
    cycles: list[list[str]] = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in edges.get(node, ()):
            if state.get(nxt) == 1:
                cycles.append([*path[path.index(nxt) :], nxt])
            elif nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = 2

    for start in sorted(edges):
        if start not in state:
            visit(start, [start])
    # a package's __init__ importing its own modules is how Python packages work, not a cycle between modules
    real = [c for c in cycles if not any(c[i + 1].startswith(c[i] + ".") for i in range(len(c) - 1))]
    assert not real, "import cycles:\n" + "\n".join(" → ".join(c) for c in real)


PROBE = """
import importlib, json, pkgutil, sys
names = []
for package in {core!r}:
    root = importlib.import_module(package)
    names.append(package)
    for info in pkgutil.walk_packages(root.__path__, package + "."):
        importlib.import_module(info.name)
        names.append(info.name)
loaded = sorted(m for m in sys.modules if m.split(".")[0] in {edges!r})
print(json.dumps({{"modules": names, "edges": loaded}}))
"""


def test_core_imports_no_transport():
    code = PROBE.format(core=CORE, edges=EDGES)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert "wwcore.wire" in result["modules"] and "plant_sim.turbine.plant" in result["modules"]
    assert len(result["modules"]) > 30
    assert result["edges"] == [], f"the core loaded {result['edges']}"


def test_the_checker_sees_imports_inside_functions(tmp_path):
    """The checker itself: a deferred import is found, relative imports resolve, and a cycle through one is named."""
    source = "import os\n\ndef f():\n    from .b import g\n    return g\n"
    (tmp_path / "a.py").write_text(source)
    found = imports_of("pkg.a", tmp_path / "a.py", {"pkg.a", "pkg.b"})
    assert found == [("pkg.b", 4, True)]
