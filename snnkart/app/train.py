"""``snnkart train``: a PPO run with progress and a summary, reported, not printed."""

from __future__ import annotations

import signal
from pathlib import Path
from typing import TYPE_CHECKING

from snnkart.app.reporter import Reporter
from snnkart.envs.tracks import track_label
from snnkart.rl.config import TrainConfig

if TYPE_CHECKING:
    from snnkart.rl.bc import BcSummary
    from snnkart.rl.ppo import Trainer


def run_training(
    cfg: TrainConfig,
    run_dir: Path,
    reporter: Reporter,
    resume: bool = False,
    total_steps: int | None = None,
    wandb: bool = False,
) -> int:
    """Train; return the exit code (0, or 130 after Ctrl-C and 143 after SIGTERM, both with a
    checkpoint saved). A resume keeps the run's own config and length; ``total_steps`` extends
    (or shortens) it, and says so. ``wandb``: also log the scalars to Weights & Biases."""
    trainer = _trainer(cfg, run_dir, resume, total_steps, wandb)
    cfg = trainer.cfg
    total = trainer.num_iterations * cfg.batch_size
    rounded = f" (rounded up to whole rollouts: {total:,})" if total != cfg.total_steps else ""
    reporter.message(
        f"training {cfg.policy.upper()} on {_where(trainer)}, {cfg.total_steps:,} steps{rounded}, "
        f"seed {cfg.seed} -> {run_dir}"
        + (f" (resuming at step {trainer.progress.global_step:,})" if resume else "")
    )
    if trainer.bc is not None:
        reporter.message(_cloned(trainer.bc))
    before = trainer.resumed_length
    if before is not None and before != cfg.total_steps:
        reporter.message(
            f"the run was {before:,} steps long; it is now {cfg.total_steps:,} (its learning-rate "
            "and entropy schedules stretch to the new length; config.toml records it)"
        )
    with reporter.training(total, trainer.progress.global_step) as on_iteration:
        try:
            result = trainer.train(on_iteration)
        finally:
            trainer.close()
    first = result.first_finish_step
    ended = "interrupted" if trainer.interrupted else "done"
    if trainer.stopped_early:
        stop = cfg.stop
        ended = f"stopped early ({stop.checks} checks in a row at >= {stop.success:.0%} success)"
    laps = (
        f"{result.finishes:,} laps finished in {result.episodes:,} episodes; "
        + ("no lap finished yet" if first < 0 else f"the first at step {first:,}")
        if trainer.track is not None
        else f"{result.episodes:,} episodes"
    )
    reporter.message(f"{ended} at step {result.global_step:,}: {laps}")
    reporter.message(
        f"checkpoint {run_dir / 'checkpoint.pt'}, metrics {run_dir / 'metrics.jsonl'}, "
        f"TensorBoard {run_dir / 'tb'}"
    )
    if not trainer.interrupted:
        return 0
    signum = trainer.interrupted_by or signal.SIGINT
    reporter.message(
        f"interrupted ({signal.Signals(signum).name}); checkpoint saved at step "
        f"{result.global_step:,}. Resume with: snnkart train --resume --out {run_dir}"
    )
    return 128 + signum


def _where(trainer: Trainer) -> str:
    """The env a run trains on: a kart env with its track and action mode, or any other env."""
    cfg, track = trainer.cfg, trainer.track
    if track is None:
        return cfg.env
    return f"{cfg.env}/{track_label(track.name, cfg.track)} ({cfg.action_mode})"


def _trainer(
    cfg: TrainConfig, run_dir: Path, resume: bool, total_steps: int | None, wandb: bool
) -> Trainer:
    """The run's trainer, logging to W&B too with ``wandb`` (checked before anything is
    written: without the extra, a one-line install hint)."""
    from snnkart.rl.ppo import Trainer
    from snnkart.rl.wandb_log import require_wandb

    if wandb:
        require_wandb()
    trainer = Trainer(cfg, run_dir, resume=resume, total_steps=total_steps)
    if wandb:
        try:
            trainer.out.open_wandb(trainer.cfg)
        except BaseException:  # wandb.init failed: release the envs before reporting it
            trainer.close()
            raise
    return trainer


def _cloned(bc: BcSummary) -> str:
    """One line on the behaviour cloning that warm-started a run (:mod:`snnkart.rl.bc`)."""
    return (
        f"behaviour cloning of {bc['data']} ({bc['steps']:,} steps, {bc['episodes']} "
        f"episodes of {bc['driver']}): actor loss {bc['actor_loss'][0]:.3f} -> "
        f"{bc['actor_loss'][-1]:.3f} in {bc['epochs']} epochs; summary in bc.json"
    )
