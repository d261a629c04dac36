"""The package's one-way layers (README, Architecture) hold: import-linter's contracts in
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
    assert "5 kept, 0 broken" in result.stdout, result.stdout[-2000:]
