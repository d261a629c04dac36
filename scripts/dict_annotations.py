"""Count the ``dict[str, Any]``-like annotations in snnkart: ``dict``/``Dict``/``Mapping``/
``MutableMapping`` of ``str`` to ``Any``, in parameters, return types, variables and fields,
with simple module-level aliases (``Record = dict[str, Any]``, ``Record: TypeAlias = ...``)
resolved, also inside unions and containers (``list[dict[str, Any]] | None`` counts once).

Usage: ``python scripts/dict_annotations.py [PACKAGE_DIR]`` (default: ``snnkart`` beside this
script's folder); prints the count per file (files with none are left out) and the total.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

MAPPINGS = {"dict", "Dict", "Mapping", "MutableMapping"}


def _name(node: ast.expr) -> str | None:
    """``dict``, ``typing.Dict``, ``collections.abc.Mapping`` -> the last part of the name."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def _parse_string(node: ast.expr) -> ast.expr:
    """A string annotation (``"dict[str, Any]"``) as the expression it spells."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        try:
            return ast.parse(node.value, mode="eval").body
        except SyntaxError:
            return node
    return node


def is_str_any_mapping(node: ast.expr, aliases: set[str]) -> bool:
    """Whether ``node`` mentions a str-to-Any mapping, directly or through an alias."""
    node = _parse_string(node)
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name) and sub.id in aliases:
            return True
        if isinstance(sub, ast.Subscript) and _name(sub.value) in MAPPINGS:
            args = sub.slice
            if isinstance(args, ast.Tuple) and len(args.elts) == 2:
                key, value = (_parse_string(e) for e in args.elts)
                if _name(key) == "str" and _name(value) == "Any":
                    return True
        if sub is not node and isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            if is_str_any_mapping(sub, aliases):
                return True
    return False


def _aliases(tree: ast.Module) -> set[str]:
    """Module-level names bound to a str-to-Any mapping type (resolved transitively)."""
    found: set[str] = set()
    changed = True
    while changed:
        changed = False
        for stmt in tree.body:
            if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1:
                target, value = stmt.targets[0], stmt.value
            elif isinstance(stmt, ast.AnnAssign) and stmt.value is not None:
                if _name(stmt.annotation) != "TypeAlias":
                    continue
                target, value = stmt.target, stmt.value
            else:
                continue
            if (isinstance(target, ast.Name) and target.id not in found
                    and is_str_any_mapping(value, found)):  # fmt: skip
                found.add(target.id)
                changed = True
    return found


def annotations(tree: ast.Module) -> list[ast.expr]:
    """Every annotation in a module: arguments, returns, annotated assignments."""
    out: list[ast.expr] = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            a = node.args
            for arg in [*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg]:
                if arg is not None and arg.annotation is not None:
                    out.append(arg.annotation)
            if node.returns is not None:
                out.append(node.returns)
        elif isinstance(node, ast.AnnAssign) and _name(node.annotation) != "TypeAlias":
            out.append(node.annotation)
    return out


def count(path: Path) -> int:
    tree = ast.parse(path.read_text(), str(path))
    aliases = _aliases(tree)
    return sum(is_str_any_mapping(a, aliases) for a in annotations(tree))


def main(argv: list[str]) -> int:
    root = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parents[1] / "snnkart"
    total = 0
    for path in sorted(root.rglob("*.py")):
        n = count(path)
        if n:
            print(f"{n:4d}  {path.relative_to(root.parent)}")
        total += n
    print(f"{total:4d}  total")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
