"""``snnkart sweep``: a hyperparameter search on Ray Tune (Optuna searcher, ASHA early stopping)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import fail, guard
from snnkart.rl import kinds


def sweep(
    param: Annotated[
        list[str], typer.Option(help="KEY=uniform:LOW:HIGH | loguniform | choice:A,B")
    ],
    env: Annotated[str, typer.Option("--env", "-e")] = "grid",
    policy: Annotated[str, typer.Option(help=kinds.choices_help())] = "ann",
    track: Annotated[str, typer.Option("--track", "-t")] = "small_S",
    steps: Annotated[int, typer.Option(help="env steps per trial")] = 100_000,
    samples: Annotated[int, typer.Option(help="trials")] = 8,
    grace: Annotated[int, typer.Option(help="iterations before ASHA may stop a trial")] = 1,
    point: Annotated[
        list[str] | None, typer.Option(help="a trial to run first: KEY=VALUE[,KEY=VALUE]")
    ] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", help="fixed KEY=VALUE")] = None,
    address: Annotated[str | None, typer.Option(help="a Ray cluster (HEAD:6379)")] = None,
    cpus: Annotated[int | None, typer.Option(help="local Ray: CPUs (default: all)")] = None,
    out: Annotated[Path, typer.Option("--out", "-o")] = Path("runs/sweep"),
) -> None:
    """Search hyperparameters: every trial is a training run (one CPU), scored by its mean
    episodic return per iteration; ASHA stops the weaker half at each rung. Writes
    out/sweep.json and one run directory per trial."""
    try:
        from snnkart.app.launch_ray import run_sweep
    except ImportError as exc:
        fail(f"snnkart sweep needs Ray Tune and Optuna: pip install -e '.[ray]' ({exc})")
    from snnkart.rl.config import load_config, parse_override

    def run() -> dict:
        base = load_config(
            overrides={"env": env, "policy": policy, "track": track, "total_steps": steps},
            sets=set_,
        )
        points = [dict(parse_override(kv) for kv in p.split(",")) for p in point or []]
        return run_sweep(base, param, out, samples, points, grace, address, cpus)

    record = guard(run, "Ray stopped the trials; each run directory keeps its last checkpoint")
    best = record["best"]
    stopped = sum(t["stopped_early"] for t in record["trials"])
    typer.echo(
        f"{len(record['trials'])} trials, {stopped} stopped early by ASHA; best: "
        f"{best['settings'] if best else 'none'}; results in {out / 'sweep.json'}"
    )
