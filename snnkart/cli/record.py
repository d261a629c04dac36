"""``snnkart record``: expert data from a scripted driver, for ``train --pretrain-bc``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import guard


def record(
    out: Annotated[Path, typer.Option("--out", "-o", help="the recording (.npz) to write")],
    driver: Annotated[str, typer.Option(help="scripted driver: pursuit")] = "pursuit",
    episodes: Annotated[int, typer.Option(help="episodes to record")] = 10,
    env: Annotated[str, typer.Option("--env", "-e", help="grid, gazebo or steer")] = "steer",
    track: Annotated[
        str, typer.Option("--track", "-t", help="built-in track (big_S, small_S) or a track file")
    ] = "small_S",
    action_mode: Annotated[str, typer.Option(help="discrete or continuous")] = "discrete",
    seed: Annotated[int, typer.Option(help="seed of the first episode")] = 0,
) -> None:
    """Record a scripted driver's episodes (observations, actions, rewards, episode ends and
    the env spec) for behaviour cloning: snnkart train --pretrain-bc OUT."""
    from snnkart.eval.expert import record_driver

    def run() -> None:
        rec = record_driver(env, track, driver, episodes, seed, action_mode)
        rec.save(out)
        ends = [e["end"] for e in rec.meta["episodes"]]
        typer.echo(
            f"{driver} on {rec.spec['env']}/{rec.spec['track']}: {len(rec.obs):,} steps in "
            f"{rec.episodes} episodes, {ends.count('finished')} finished -> {out}"
        )

    guard(run)
