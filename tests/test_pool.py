"""The process pool's worker (``python -m snnkart.app.worker``): its requests round-trip, it
ends with the command line's exit statuses, and no package module below the command line
starts the command line (the upward dependency import-linter cannot see)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from snnkart.app.worker import EvalJob, TrainJob, parse_request, request_json
from snnkart.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "request_",
    [
        TrainJob("runs/.a.config.toml", "runs/a", resume=True),
        EvalJob("runs/a", 3, 10_000, "runs/a/deploy", "lava-sim", "float"),
        EvalJob("runs/b", 1, 5, "runs/b/eval.json"),
    ],
)
def test_requests_round_trip(request_: TrainJob | EvalJob) -> None:
    assert parse_request(request_json(request_)) == request_


def test_what_is_not_a_request_is_named() -> None:
    with pytest.raises(UsageError, match="not a worker request"):
        parse_request('{"kind": "deploy"}')
    with pytest.raises(UsageError, match="not a worker request"):
        parse_request('{"kind": "eval", "run_dir": "a"}')


def _worker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "snnkart.app.worker", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)  # fmt: skip


def test_a_failing_job_exits_2_with_one_error_line(tmp_path: Path) -> None:
    bad = EvalJob(str(tmp_path / "no-such-run"), 2, 0, str(tmp_path / "eval.json"))
    result = _worker(request_json(bad))
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error: ") and "no-such-run" in line
    assert not (tmp_path / "eval.json").exists()
    assert _worker("garbage").returncode == 2


def _starts_the_command_line(path: Path) -> list[int]:
    """Lines of ``path`` with a string naming the ``snnkart.cli`` module outside docstrings."""
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    return [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and node.value.startswith("snnkart.cli")
        and id(node) not in docstrings
    ]


def test_no_layer_below_the_command_line_starts_it() -> None:
    package = ROOT / "snnkart"
    found = {
        str(path.relative_to(ROOT)): lines
        for path in sorted(package.rglob("*.py"))
        if path.relative_to(package).parts[0] != "cli" and (lines := _starts_the_command_line(path))
    }
    assert not found, f"modules that run `python -m snnkart.cli`: {found}"
