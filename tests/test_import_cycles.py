"""No import loop anywhere in ``snnkart``, lazy imports included, and no import by name outside
the backend registry.

import-linter sees only what grimp sees; here every ``import`` statement counts, wherever it is:
at module level, inside a function, under ``if TYPE_CHECKING:`` (relative imports resolved). A
loop made of function-level imports runs today and breaks the day someone hoists one of them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "snnkart"
REGISTRIES = ("snnkart.backends.registry", "snnkart.rl.kinds", "snnkart.envs.resolve")
"""The modules that import by name: the backend registry (its table of backend classes) and the
kinds registry (a kind's module, named by its registry line, imported when the kind is used)."""


def module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(root: Path = PACKAGE) -> dict[str, Path]:
    return {module_name(path, root): path for path in sorted(root.rglob("*.py"))}


def _resolve(node: ast.ImportFrom, name: str, is_package: bool) -> str:
    """The absolute module an ``ImportFrom`` in module ``name`` names."""
    if not node.level:
        return node.module or ""
    base = name.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Every snnkart module ``name`` imports, anywhere in its source."""
    tree = ast.parse(path.read_text(), str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = _resolve(node, name, path.name == "__init__.py")
            targets = [f"{module}.{alias.name}" for alias in node.names] + [module]
            targets = [t for t in targets if t in known][:1] or [module]
        for target in targets:
            while target and target not in known:  # `import a.b.c` of a function or class
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    found = modules(root)
    return {name: imports(name, path, set(found)) for name, path in found.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import loop (its modules in order, the first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (cycle := visit(nxt)) is not None:
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)) is not None:
            return cycle
    return None


def imports_by_name(path: Path) -> list[int]:
    """Lines calling ``importlib.import_module``/``__import__`` or importing them."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call):
            func = node.func
            named = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if named in ("import_module", "__import__"):
                lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.module == "importlib":
            if any(alias.name == "import_module" for alias in node.names):
                lines.append(node.lineno)
    return lines


def test_the_import_graph_has_no_cycle() -> None:
    graph = import_graph()
    assert len(graph) > 100 and "snnkart.backends.registry" in graph
    assert "snnkart.backends.lava_sim" not in graph["snnkart.backends.base"]
    cycle = find_cycle(graph)
    assert cycle is None, "import loop: " + " -> ".join(cycle or [])


def test_only_the_registry_imports_by_name() -> None:
    offenders = {
        name: lines
        for name, path in modules().items()
        if name not in REGISTRIES and (lines := imports_by_name(path))
    }
    assert not offenders, f"import by name outside {REGISTRIES} (module: lines): {offenders}"


def test_the_checker_finds_a_lazy_loop_and_a_type_only_one(tmp_path: Path) -> None:
    """The checker itself, on a package written for it: a loop closed by a function-level
    relative import, one closed under TYPE_CHECKING, and an import by name."""
    pkg = tmp_path / "snnkart"
    (pkg / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "sub/__init__.py": "",
        "sub/a.py": "from snnkart.sub.b import f\n",
        "sub/b.py": "def f():\n    from . import a\n",
        "c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .d import D\n",
        "d.py": "import snnkart.c\nD = 1\n",
        "e.py": "import importlib\nm = importlib.import_module('json')\n",
    }
    for rel, text in files.items():
        (pkg / rel).write_text(text)
    graph = import_graph(pkg)
    assert graph["snnkart.sub.b"] == {"snnkart.sub.a"}
    assert graph["snnkart.c"] == {"snnkart.d"}
    assert find_cycle(graph) == ["snnkart.c", "snnkart.d", "snnkart.c"]
    del graph["snnkart.d"]
    assert find_cycle(graph) == ["snnkart.sub.a", "snnkart.sub.b", "snnkart.sub.a"]
    assert imports_by_name(pkg / "e.py") == [2]


@pytest.mark.parametrize("where", ["module", "function"])
def test_resolve_relative_imports(where: str, tmp_path: Path) -> None:
    pkg = tmp_path / "snnkart"
    (pkg / "x").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "x" / "__init__.py").write_text("from .y import Y\n")
    body = "from ..z import g\n"
    if where == "function":
        body = "def h():\n    " + body
    (pkg / "x" / "y.py").write_text(body + "Y = 1\n")
    (pkg / "z.py").write_text("def g():\n    pass\n")
    graph = import_graph(pkg)
    assert graph["snnkart.x"] == {"snnkart.x.y"}
    assert graph["snnkart.x.y"] == {"snnkart.z"}
