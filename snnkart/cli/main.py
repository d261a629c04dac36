"""The ``snnkart`` command line.

Each command imports what it needs inside its own function, so ``snnkart --help`` and
``import snnkart`` stay fast (no torch, pygame or Lava at start-up).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.backends.defaults import BACKENDS, NIR_BACKENDS, default_help, precision_help
from snnkart.cli.console import ConsoleReporter, print_headline
from snnkart.cli.export import export
from snnkart.cli.guard import ForceOpt, fail, guard, refuse_other_files
from snnkart.cli.help import finish_help
from snnkart.cli.nir import nir_app
from snnkart.cli.record import record
from snnkart.cli.replay import replay
from snnkart.cli.report_commands import plot_app, report
from snnkart.cli.ros import ros_app
from snnkart.cli.study import study
from snnkart.cli.sweep import sweep
from snnkart.cli.track import track_app
from snnkart.cli.train import train
from snnkart.errors import SnnkartError

app = typer.Typer(
    name="snnkart",
    help="Train spiking and ordinary PPO racing policies, export them to NIR, run them on "
    "Lava's simulated Loihi and compare their energy.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _print_version(value: bool) -> None:
    if value:
        from snnkart import __version__

        typer.echo(f"snnkart {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_print_version,
            is_eager=True,
            help="print snnkart's version and exit",
        ),
    ] = False,
) -> None:
    """Options before the command."""


EnvOpt = Annotated[
    str, typer.Option("--env", "-e", help="grid, gazebo or steer (or grid_env, gazebo_env, ...)")
]
TrackOpt = Annotated[
    str, typer.Option("--track", "-t", help="built-in track (big_S, small_S) or a track file")
]


def _check_env_and_track(env: str, track: str) -> str:
    from snnkart.envs import resolve_env_name
    from snnkart.envs.tracks import load_track

    try:
        name = resolve_env_name(env)
        load_track(track)
    except SnnkartError as exc:
        fail(str(exc))
    return name


@app.command()
def play(
    env: EnvOpt = "steer",
    track: TrackOpt = "big_S",
    seed: Annotated[int | None, typer.Option(help="seed of the first episode")] = None,
    max_steps: Annotated[
        int | None, typer.Option(help="quit after this many steps (demos, tests)")
    ] = None,
    record: Annotated[
        Path | None, typer.Option(help="record the steps to this .npz (expert data)")
    ] = None,
) -> None:
    """Drive a kart with the keyboard: W/A/S/D, space to brake, R to reset, Esc to quit."""
    name = _check_env_and_track(env, track)
    from snnkart.cli.play import run_play

    run_play(name, track, max_steps=max_steps, seed=seed, record=record)


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="directory for everything")] = Path(
        "runs/demo"
    ),
    steps: Annotated[int, typer.Option(help="training steps of the SNN")] = 300_000,
    ann_steps: Annotated[int, typer.Option(help="training steps of the ANN baseline")] = 300_000,
    lava_episodes: Annotated[int, typer.Option(help="episodes on lava-sim (fixed)")] = 20,
    eval_episodes: Annotated[
        int, typer.Option(help="seeded episodes scoring the torch policy and its fixed-point twin")
    ] = 50,
    scripted_gif: Annotated[
        Path | None,
        typer.Option(help="instead: render the scripted driver on steer/small_S to this GIF"),
    ] = None,
    force: ForceOpt = False,
) -> None:
    """The main job: train a spiking policy and its same-width ANN baseline on grid/small_S,
    export the SNN to NIR, drive the kart on Lava's simulated Loihi, and report its energy
    against the ANN's, printing success rates, parity, the energy table and where files are."""
    if scripted_gif is not None:
        from snnkart.app.demo import scripted_gif as render_gif

        try:
            result = render_gif("steer", "small_S", scripted_gif, ConsoleReporter())
        except SnnkartError as exc:
            fail(str(exc))
        status = "finished" if result.finished else "did not finish"
        typer.echo(f"scripted driver on steer/small_S: {status}; GIF written to {scripted_gif}")
        return
    if min(steps, ann_steps, lava_episodes, eval_episodes) < 1:
        fail("--steps, --ann-steps, --lava-episodes and --eval-episodes must be >= 1")
    from snnkart import faults
    from snnkart.app.pipeline import main_job_files, run_pipeline

    refuse_other_files(out, main_job_files(), force)  # its own files: it resumes in them
    from snnkart.report.document import headline

    finished = guard(
        lambda: run_pipeline(
            out, ConsoleReporter(), steps, lava_episodes, eval_episodes, ann_steps
        ),
        "run the same command again to continue where it stopped",
    )
    if not finished:
        raise typer.Exit(128 + (faults.last_signal or 2))
    print_headline(finished["report"], headline(finished["report"]))


app.command()(train)  # here: the help lists the commands in this order


CHECKPOINT_HELP = "latest (default), best (needs eval.every_steps), an env step or a file"
"""Which of a run's checkpoints eval runs (:func:`snnkart.rl.run_dir.checkpoint_path`)."""
_VideoOption = Annotated[
    Path | None, typer.Option(help="film episodes to a GIF, or an MP4 (needs the video extra)")
]
_SigmaDeltaOption = Annotated[
    bool,
    typer.Option(
        "--sigma-delta",
        help="with nir-ref/lava-sim: convert a ReLU ANN run to a sigma-delta network first",
    ),
]
_VideoEpisodesOption = Annotated[
    int, typer.Option(help="with --video: film the first K episodes; all are scored")
]


_PrecisionOption = Annotated[
    str | None,
    typer.Option(help=precision_help(BACKENDS), show_default=default_help()),
]


@app.command(name="eval")
def eval_(
    run_dir: Annotated[Path, typer.Argument(help="a run directory, a checkpoint or a policy.nir")],
    episodes: Annotated[int, typer.Option(help="number of seeded episodes")] = 20,
    seed: Annotated[int, typer.Option(help="seed of the first episode")] = 10_000,
    checkpoint: Annotated[str | None, typer.Option(help=CHECKPOINT_HELP)] = None,
    render: Annotated[bool, typer.Option(help="show the episodes in a window")] = False,
    video: _VideoOption = None,
    video_episodes: _VideoEpisodesOption = 3,
    out: Annotated[
        Path | None, typer.Option(help="JSON results (default RUN_DIR/eval.json)")
    ] = None,
    backend: Annotated[
        str, typer.Option(help="torch (the trained network), nir-ref or lava-sim")
    ] = "torch",
    precision: _PrecisionOption = None,
    env: Annotated[
        str | None,
        typer.Option("--env", "-e", help="a NIR file's env (default: the manifest's)"),
    ] = None,
    track: Annotated[
        str | None,
        typer.Option("--track", "-t", help="another track (default: the one trained on)"),
    ] = None,
    sigma_delta: _SigmaDeltaOption = False,
) -> None:
    """Evaluate the deterministic policy with frozen normalisation; print and write JSON.

    With ``--backend nir-ref|lava-sim`` RUN_DIR may also be an exported ``policy.nir``; a run
    directory is exported to NIR first. The policy runs on the track it was trained on
    (carried in its checkpoint and manifest), or on ``--track``."""
    from snnkart.app.evaluate import run_eval, run_eval_exported
    from snnkart.app.opener import choose

    target = guard(lambda: choose(run_dir, backend, precision, checkpoint, sigma_delta=sigma_delta))
    where = target.run_dir or target.path
    if backend != "torch":
        request = guard(lambda: target.deploy_request(episodes, seed, env, track, out))
        guard(
            lambda: run_eval_exported(
                where, target.checkpoint, request, ConsoleReporter(), sigma_delta=sigma_delta
            ),
            _deploy_interrupted(backend),
        )
        return
    if episodes < 1:
        fail(f"--episodes must be >= 1, got {episodes}")
    if env is not None:
        fail("--env is for NIR files; a run directory is evaluated on the env it trained on")
    reporter, which = ConsoleReporter(), target.checkpoint
    guard(
        lambda: run_eval(
            where, episodes, seed, which, render, video, out, reporter, track, video_episodes
        ),
        "no results were written",
    )


def _deploy_interrupted(backend: str) -> str:
    stopped = "no Lava process is left running; " if backend == "lava-sim" else ""
    return f"{stopped}no results were written"


@app.command()
def deploy(
    nir_file: Annotated[Path, typer.Argument(help="policy.nir (its manifest must be beside it)")],
    backend: Annotated[str, typer.Option(help="lava-sim or nir-ref")] = "lava-sim",
    precision: Annotated[
        str | None, typer.Option(help=precision_help(), show_default=default_help())
    ] = None,
    env: Annotated[str | None, typer.Option("--env", "-e", help="default: the manifest's")] = None,
    track: Annotated[
        str | None, typer.Option("--track", "-t", help="default: the manifest's")
    ] = None,
    episodes: Annotated[int, typer.Option(help="number of seeded episodes")] = 10,
    seed: Annotated[int, typer.Option(help="seed of the first episode")] = 10_000,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="deploy.json's directory (default: deploy-BACKEND-PRECISION beside the NIR file)",
        ),
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Run an exported policy in closed loop on Lava's simulated Loihi (or the reference),
    checked step by step against the numpy reference; print and write metrics and counts."""
    from snnkart.app.deploy import run_deploy_reported
    from snnkart.app.opener import choose

    target = guard(lambda: choose(nir_file, backend, precision, backends=NIR_BACKENDS))
    if target.nir_file is None:
        fail(
            f"deploy runs an exported policy.nir; evaluate the run {nir_file} with: "
            f"snnkart eval {nir_file} --backend {backend}"
        )
    if out is None:
        out = nir_file.parent / f"deploy-{backend}-{target.precision}"
    else:
        from snnkart.report.document import REPORT_FILES  # a report may share the directory

        refuse_other_files(out, {"deploy.json", *REPORT_FILES}, force)
    request = guard(lambda: target.deploy_request(episodes, seed, env, track, out))
    guard(lambda: run_deploy_reported(request, ConsoleReporter()), _deploy_interrupted(backend))


app.command()(export)
app.command()(record)
app.command()(replay)
app.command()(report)
app.command()(sweep)
app.command()(study)
app.add_typer(plot_app, name="plot")
app.add_typer(nir_app, name="nir")
app.add_typer(ros_app, name="ros")
app.add_typer(track_app, name="track")
finish_help(app)  # after every command: examples and tidy help for each


def main() -> None:
    """The console entry point: SIGTERM stops a command the way Ctrl-C does."""
    from snnkart import faults

    faults.install()
    try:
        app()
    except SystemExit as exc:
        # typer turns a KeyboardInterrupt that no command reported into exit status 130
        if exc.code == 130 and faults.last_signal not in (None, 2):
            raise SystemExit(128 + faults.last_signal) from None
        raise


if __name__ == "__main__":
    main()
