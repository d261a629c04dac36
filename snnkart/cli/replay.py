"""``snnkart replay``: training's episodes drawn together, or trained policies side by side."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.console import ConsoleReporter
from snnkart.cli.guard import fail, guard


def replay(
    run_dirs: Annotated[list[Path], typer.Argument(help="a training run (--compare: 1 to 4)")],
    mode: Annotated[
        str,
        typer.Option(
            help="batch: iteration by iteration; all: everything at once. Each episode is "
            "shown whole, from its reset pose, in the iteration it ended in (as training "
            "counts it); episodes unfinished when training stopped or resumed are not "
            "shown, and the output says how many",
        ),
    ] = "batch",
    compare: Annotated[
        bool, typer.Option(help="race the runs' trained policies on one track, one colour each")
    ] = False,
    seed: Annotated[int, typer.Option(help="--compare: the episode's seed")] = 10_000,
    track: Annotated[
        str | None, typer.Option("--track", "-t", help="--compare: default the first run's")
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="GIF or MP4 instead of a window")
    ] = None,
    every: Annotated[int, typer.Option(help="show every n-th time step")] = 2,
) -> None:
    """Replay the episodes recorded during training, several karts at once; or, with
    --compare, the trained policies of up to four runs side by side (e.g. ANN vs SNN)."""
    from snnkart.app.replay import run_compare, run_replay

    if compare:
        guard(lambda: run_compare(run_dirs, out, seed, track, every, ConsoleReporter()))
        return
    if len(run_dirs) != 1:
        fail(f"replay takes one run ({len(run_dirs)} given); use --compare for several")
    guard(lambda: run_replay(run_dirs[0], mode, out, every, ConsoleReporter()))
