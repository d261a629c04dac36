"""Every command's and group's ``--help`` at 80 columns: examples of that command, prose that
wraps cleanly (no line broken early by a docstring's hard newline), no RST double backquotes,
no ``<bool>`` beside a plain flag, and no line wider than the terminal."""

from __future__ import annotations

from collections.abc import Iterator
from itertools import pairwise
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from snnkart.cli import app

WIDTH = 80


def _paths(command: Any, path: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    yield path
    for name, sub in getattr(command, "commands", {}).items():  # a group's commands
        yield from _paths(sub, (*path, name))


PATHS = list(_paths(typer.main.get_command(app)))


def _help(path: tuple[str, ...]) -> str:
    result = CliRunner().invoke(app, [*path, "--help"], env={"COLUMNS": str(WIDTH)})
    assert result.exit_code == 0, result.output
    return result.output


def _ragged(lines: list[str]) -> list[str]:
    """Prose lines (before the first panel) that end although the next line's first word fit."""
    prose = []
    for line in lines:
        if line.lstrip().startswith("╭"):
            break
        prose.append(line.strip())
    room = WIDTH - 2  # rich pads the text by one column each side
    return [
        a
        for a, b in pairwise(prose)
        if a and b and not a.startswith("Usage:") and len(a) + 1 + len(b.split()[0]) <= room
    ]


def test_every_command_is_walked() -> None:
    assert {("train",), ("eval",), ("nir", "info"), ("ros", "drive"), ("plot", "raster")} <= set(
        PATHS
    )


@pytest.mark.parametrize("path", PATHS, ids=lambda p: " ".join(p) or "snnkart")
def test_help_has_examples_and_reads_cleanly(path: tuple[str, ...]) -> None:
    text = _help(path)
    lines = text.splitlines()
    examples = lines[next(i for i, line in enumerate(lines) if "Examples:" in line) :]
    command = " ".join(("snnkart", *path))
    assert any(line.strip().startswith(command) for line in examples), (command, examples)
    assert all(line.strip().startswith("snnkart ") for line in examples[1:] if line.strip())
    assert "``" not in text
    assert "<bool>" not in text
    assert max(len(line.rstrip()) for line in lines) <= WIDTH
    assert _ragged(lines) == [], _ragged(lines)
