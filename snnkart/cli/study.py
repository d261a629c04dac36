"""``snnkart study``: train every cell of a study for every seed, evaluate, and write the
tables and plots (:mod:`snnkart.app.study_run`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import guard


def study(
    config: Annotated[Path, typer.Argument(help="the study config (TOML, benchmarks/README.md)")],
    out: Annotated[Path, typer.Option("--out", "-o")] = Path("runs/study"),
    jobs: Annotated[int | None, typer.Option(help="runs at a time (default: one per core)")] = None,
    ray: Annotated[bool, typer.Option(help="run the trainings as Ray Tune trials")] = False,
    only: Annotated[
        list[str] | None,
        typer.Option(
            help="only the cells matching TRACK/ENV-POLICY[:VARIANT] globs, e.g. 'ring/*'"
        ),
    ] = None,
) -> None:
    """Train every track x env x policy cell for every seed (one torch thread per run,
    resumable: finished runs with the same config and training code are reused), evaluate each
    run, and write OUT/study.json, OUT/study.md and OUT/plots/. Run a long study in pieces with
    --only; the same command without it gathers every piece, reusing their runs."""
    from snnkart.app.study_run import load_study, run_study
    from snnkart.app.zoo_study import load_zoo_config, run_zoo_study
    from snnkart.cli.console import ConsoleReporter
    from snnkart.report.study_record import StudyRecord

    zoo = guard(lambda: load_zoo_config(config))
    if zoo is not None:  # one gymnasium task against SB3 with the RL Zoo's settings
        guard(
            lambda: run_zoo_study(zoo, out, ConsoleReporter()),
            "every finished run is kept; run the same command to resume",
        )
        typer.echo((out / "zoo-study.md").read_text())
        return

    def run() -> StudyRecord:
        return run_study(load_study(config), out, ConsoleReporter(), jobs, ray, only)

    record = guard(run, "every run saved its checkpoint; run the same command to resume")
    typer.echo((out / "study.md").read_text())
    w = record.wall_clock
    typer.echo(
        f"{w.runs} runs ({w.runs_reused} reused) in "
        f"{(w.train_seconds + w.eval_seconds) / 60:.1f} min; results in {out}"
    )
