"""What ``snnkart train``, ``eval`` and ``replay`` do, with progress bars and summaries."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from snnkart import faults
from snnkart.envs.constants import RENDER_FPS
from snnkart.envs.tracks import track_label
from snnkart.errors import UsageError
from snnkart.rl.config import TrainConfig

console = Console(stderr=True)


def _fmt(value: float | None, spec: str = ".2f") -> str:
    return "-" if value is None else format(value, spec)


def run_training(cfg: TrainConfig, run_dir: Path, resume: bool = False) -> int:
    """Train with a live progress bar; return the exit code (130 after Ctrl-C, 143 after
    SIGTERM, both with a checkpoint saved)."""
    from snnkart.rl.ppo import Trainer

    trainer = Trainer(cfg, run_dir, resume=resume)
    cfg = trainer.cfg
    console.print(
        f"training {cfg.policy.upper()} on {cfg.env}/{track_label(trainer.track.name, cfg.track)} "
        f"({cfg.action_mode}), "
        f"{cfg.total_steps:,} steps, seed {cfg.seed} -> {run_dir}"
        + (f" (resuming at step {trainer.progress.global_step:,})" if resume else "")
    )
    columns = (
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed:,}/{task.total:,} steps"),
        TextColumn("{task.fields[sps]} steps/s"),
        TextColumn("return {task.fields[ret]}"),
        TextColumn("finishes {task.fields[fin]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    total = trainer.num_iterations * cfg.batch_size
    with Progress(*columns, console=console) as progress:
        task = progress.add_task(
            "PPO", total=total, completed=trainer.progress.global_step, sps="-", ret="-", fin=0
        )

        def on_iteration(record: dict[str, Any]) -> None:
            progress.update(
                task,
                completed=record["global_step"],
                sps=f"{record['charts/SPS']:,.0f}",
                ret=_fmt(record["charts/episodic_return"]),
                fin=f"{record['charts/cumulative_finishes']:,}",
            )

        try:
            result = trainer.train(on_iteration)
        finally:
            trainer.close()
    first = result.first_finish_step
    console.print(
        f"{'interrupted' if trainer.interrupted else 'done'} at step {result.global_step:,}: "
        f"{result.finishes:,} finished episodes of {result.episodes:,}; first finish at "
        f"{'never' if first < 0 else f'step {first:,}'}"
    )
    console.print(
        f"checkpoint {run_dir / 'checkpoint.pt'}, metrics {run_dir / 'metrics.jsonl'}, "
        f"TensorBoard {run_dir / 'tb'}"
    )
    if trainer.interrupted:
        import signal

        signum = trainer.interrupted_by or signal.SIGINT
        console.print(
            f"interrupted ({signal.Signals(signum).name}); checkpoint saved at step "
            f"{result.global_step:,}. Resume with: snnkart train --resume --out {run_dir}"
        )
        return 128 + signum
    return 0


def run_eval(
    run_dir: Path,
    episodes: int,
    seed: int,
    checkpoint: Path | None,
    render: bool,
    video: Path | None,
    out: Path | None,
    track: str | None = None,
) -> None:
    from snnkart.envs.tracks import embed_track, load_track, track_sha256
    from snnkart.eval.episodes import EvalSummary, run_episodes, write_eval
    from snnkart.eval.video import check_video_path, video_writer
    from snnkart.rl.run import TorchPredictor, load_run

    if video is not None:
        check_video_path(video)
        if render:
            raise UsageError("choose either --render (a window) or --video (a file), not both")
    run = load_run(run_dir, checkpoint)
    assert run.track is not None
    trained = embed_track(run.track, run.config.track)
    del trained["toml"]
    chosen, given = (
        (load_track(track), track) if track is not None else (run.track, run.config.track)
    )
    override = track_sha256(chosen) != trained["sha256"]
    label = track_label(chosen.name, given)
    mode = "human" if render else ("rgb_array" if video is not None else None)
    env = run.config.make_env(render_mode=mode, track=chosen)
    predictor = TorchPredictor(run, seed=seed)
    with contextlib.ExitStack() as stack:
        stack.callback(env.close)
        stack.enter_context(faults.caught())  # Ctrl-C is taken between env steps
        progress = stack.enter_context(Progress(console=console, transient=True))
        task = progress.add_task("evaluating", total=episodes)
        on_step = None
        if video is not None:
            writer = stack.enter_context(video_writer(video, fps=RENDER_FPS / 2))

            def on_step(e: Any) -> None:
                if e.unwrapped.episode_steps % 2 == 0:
                    writer.append_data(e.render())

        results = run_episodes(
            env, predictor, episodes, seed, on_step=on_step,
            on_episode=lambda r: progress.advance(task),
        )  # fmt: skip
    summary = EvalSummary.of(results)
    path = out or run_dir / "eval.json"
    write_eval(
        path,
        summary,
        results,
        {
            "run": str(run_dir),
            "checkpoint": str(run.checkpoint),
            "global_step": run.meta.get("global_step"),
            "policy": run.config.policy,
            "env": run.config.env,
            "track": chosen.name,
            "track_given": str(given),
            "track_sha256": track_sha256(chosen),
            "trained_track": trained,
            "track_override": override,
            "first_seed": seed,
        },
    )
    print(
        f"{run.config.policy.upper()} {run.config.env}/{label} "
        f"(step {run.meta.get('global_step', 0):,}), {episodes} episodes: "
        f"success {summary.success_rate:.0%}, return {summary.mean_return:.2f} "
        f"+- {summary.std_return:.2f}, lap time {_fmt(summary.mean_lap_time)} s, "
        f"crashes {summary.crashes}, stood still {summary.stood_still}, "
        f"time-outs {summary.timeouts}"
    )
    if override:
        print(
            f"note: track {label} is not the track the policy was trained on "
            f"({track_label(trained['name'], trained['given'])})"
        )
    print(f"results written to {path}")


def run_replay(run_dir: Path, mode: str, out: Path | None, every: int) -> None:
    from snnkart.envs.render import Renderer
    from snnkart.eval.replay import frames, load_ghosts
    from snnkart.eval.video import check_video_path, video_writer
    from snnkart.rl.checkpoint import load_checkpoint
    from snnkart.rl.config import read_run_config
    from snnkart.rl.ppo import checkpoint_track

    if every < 1:
        raise UsageError(f"--every must be >= 1, got {every}")
    if out is not None:
        check_video_path(out)
    cfg = read_run_config(run_dir)
    ghosts = load_ghosts(run_dir)
    latest = run_dir / "checkpoint.pt"  # carries the track, which may have moved since
    track = checkpoint_track(load_checkpoint(latest)[1], cfg, latest) if latest.is_file() else None
    env = cfg.make_env(track=track).unwrapped
    renderer = Renderer(env, human=out is None)  # type: ignore[arg-type]
    try:
        if out is None:
            import pygame

            for positions, colours, lines in frames(ghosts, mode, every):
                renderer.draw_ghosts(positions, colours, lines)
                if any(e.type == pygame.QUIT or (e.type == pygame.KEYDOWN and e.key == pygame.K_ESCAPE)
                       for e in pygame.event.get()):  # fmt: skip
                    break
        else:
            with video_writer(out, fps=RENDER_FPS / every) as writer:
                for positions, colours, lines in frames(ghosts, mode, every):
                    writer.append_data(renderer.draw_ghosts(positions, colours, lines))
            print(f"replay of {len(ghosts)} episodes written to {out}")
    finally:
        renderer.close()
        env.close()
