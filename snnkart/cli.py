"""The ``snnkart`` command line.

Each command imports what it needs inside its own function, so ``snnkart --help`` and
``import snnkart`` stay fast (no torch, pygame or Lava at start-up).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, NoReturn

import typer

app = typer.Typer(
    name="snnkart",
    help="Train spiking and ordinary PPO racing policies, export them to NIR, run them on "
    "Lava's simulated Loihi and compare their energy.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EnvOpt = Annotated[
    str, typer.Option("--env", "-e", help="grid, gazebo or steer (or grid_env, gazebo_env, ...)")
]
TrackOpt = Annotated[
    str, typer.Option("--track", "-t", help="built-in track (big_S, small_S) or a track file")
]


def _fail(message: str, code: int = 2) -> NoReturn:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code)


def _not_yet(command: str, what: str) -> NoReturn:
    _fail(
        f"`snnkart {command}` is not implemented yet in this version ({what}); "
        "see the README's roadmap",
        code=3,
    )


def _check_env_and_track(env: str, track: str) -> str:
    from snnkart.envs import resolve_env_name
    from snnkart.envs.tracks import TrackError, load_track

    try:
        name = resolve_env_name(env)
        load_track(track)
    except (ValueError, TrackError) as exc:
        _fail(str(exc))
    return name


@app.command()
def play(
    env: EnvOpt = "steer",
    track: TrackOpt = "big_S",
    seed: Annotated[int | None, typer.Option(help="seed of the first episode")] = None,
    max_steps: Annotated[
        int | None, typer.Option(help="quit after this many steps (demos, tests)")
    ] = None,
) -> None:
    """Drive a kart with the keyboard: W/A/S/D, space to brake, R to reset, Esc to quit."""
    name = _check_env_and_track(env, track)
    from snnkart.play import run_play

    run_play(name, track, max_steps=max_steps, seed=seed)


@app.command()
def demo(
    env: EnvOpt = "steer",
    track: TrackOpt = "small_S",
    out: Annotated[Path, typer.Option("--out", "-o", help="GIF to write")] = Path(
        "runs/demo/scripted.gif"
    ),
    seed: int = 0,
    every: Annotated[int, typer.Option(help="keep every n-th frame")] = 3,
) -> None:
    """Render one episode of the scripted pure-pursuit driver to a GIF (no training)."""
    name = _check_env_and_track(env, track)
    from snnkart.demo import scripted_gif

    result = scripted_gif(name, track, out, seed=seed, every=every)
    status = "finished" if result["lap_finished"] else "did not finish"
    typer.echo(
        f"{name} on {track}: {status} in {result['length']} steps "
        f"({result['elapsed_time']:.2f} s simulated), return {result['return']:.2f}"
    )
    typer.echo(f"GIF written to {out}")


@app.command()
def train() -> None:
    """Train an ANN or SNN policy with PPO (not implemented yet)."""
    _not_yet("train", "PPO training arrives with the training issue")


@app.command(name="eval")
def eval_() -> None:
    """Evaluate a trained policy (not implemented yet)."""
    _not_yet("eval", "evaluation arrives with the training issue")


@app.command()
def replay() -> None:
    """Replay the episodes recorded during training (not implemented yet)."""
    _not_yet("replay", "replay arrives with the training issue")


@app.command()
def export() -> None:
    """Export a spiking policy to NIR (not implemented yet)."""
    _not_yet("export", "NIR export arrives with the deployment issue")


@app.command()
def deploy() -> None:
    """Run an exported policy on a backend such as lava-sim (not implemented yet)."""
    _not_yet("deploy", "Lava deployment arrives with the deployment issue")


@app.command()
def report() -> None:
    """Energy report against the ANN baseline (not implemented yet)."""
    _not_yet("report", "the energy report arrives with the energy issue")


def main() -> None:
    app()


if __name__ == "__main__":
    main()
