"""The package's one-way layers (docs/architecture.md) hold: import-linter's contracts in
pyproject.toml, run on the installed code. A new module outside the layers, an upward import,
rl and backends importing each other, or torch, Lava, pygame, typer or rich imported outside
their packages makes this fail."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept() -> None:
    tool = Path(sys.executable).parent / "lint-imports"
    assert tool.exists(), "import-linter is not installed; install the dev extra"
    result = subprocess.run(
        [str(tool), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert "8 kept, 0 broken" in result.stdout, result.stdout[-2000:]


# Size limits (issue 14: modules of about 400 lines, functions of about 60). The exceptions
# below are the ones left; none may grow and no new one may appear. Remove an entry when its
# code is split; "kernel" marks documented arithmetic kernels, which may stay long.
MODULE_LINES, FUNCTION_LINES = 420, 60
LONG_MODULES: dict[str, int] = {}
LONG_FUNCTIONS = {
    "snnkart/envs/geodesic.py::geodesic_field": 95,  # kernel: the distance-field sweep
}


def test_modules_and_functions_stay_short() -> None:
    import ast

    too_long, lengths = [], {}
    for path in sorted((ROOT / "snnkart").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        text = path.read_text()
        limit = LONG_MODULES.get(rel, MODULE_LINES)
        if len(text.splitlines()) > limit:
            too_long.append(f"{rel}: {len(text.splitlines())} lines (limit {limit})")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                lengths[f"{rel}::{node.name}"] = max(length, lengths.get(f"{rel}::{node.name}", 0))
                limit = LONG_FUNCTIONS.get(f"{rel}::{node.name}", FUNCTION_LINES)
                if length > limit:
                    too_long.append(f"{rel}::{node.name}: {length} lines (limit {limit})")
    assert not too_long, "split these:\n" + "\n".join(too_long)
    # an exception that is no longer needed comes off the list, so the list only shrinks
    stale = [k for k in LONG_FUNCTIONS if lengths.get(k, 0) <= FUNCTION_LINES]
    assert not stale, f"within the limit now; remove from LONG_FUNCTIONS: {stale}"
