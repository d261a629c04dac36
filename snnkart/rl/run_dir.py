"""A training run's directory: its config, checkpoints, metrics, TensorBoard and trajectories.

run_dir/config.toml            the resolved config (``--resume`` reads it back)
run_dir/checkpoint.pt (.json)  the latest checkpoint; checkpoints/iter_NNNNNN.pt the history
run_dir/best.pt (.json)        the best periodic evaluation's policy (``eval.every_steps``)
run_dir/metrics.jsonl          one JSON record per iteration
run_dir/tb/                    TensorBoard scalars (``run.tensorboard``)
run_dir/wandb/                 the same scalars for Weights & Biases (``train --wandb``)
run_dir/trajectories/          kart positions per iteration (``run.trajectories``), for replay
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.envs.base import KartEnv
from snnkart.envs.spec import env_spec, spec_hash, trained_env_config
from snnkart.envs.tracks import Track, TrackError, embedded_track, load_track
from snnkart.errors import CheckpointError, RunError
from snnkart.io import atomic_path
from snnkart.rl.checkpoint import CheckpointMeta, CheckpointState, save_checkpoint
from snnkart.rl.config import TrainConfig, read_run_config
from snnkart.rl.wandb_log import WandbLogger


def checkpoint_track(meta: Mapping[str, object], cfg: TrainConfig, source: Path) -> Track:
    """The track a checkpoint was trained on: the one embedded in it, or for checkpoints
    written before tracks were embedded, ``cfg.track`` (which must then still exist)."""
    track = meta.get("track")
    if not track:
        return load_track(cfg.track)
    if not isinstance(track, dict):
        raise TrackError(f"{source}: malformed embedded track (not a table: {track!r})")
    return embedded_track(track, str(source))


def trained_config(meta: Mapping[str, object], cfg: TrainConfig, track: Track) -> TrainConfig:
    """``cfg``; or, where the env it describes today is not the one the checkpoint was trained
    in (a default changed since), ``cfg`` with the env config the checkpoint was trained with
    (:func:`snnkart.envs.spec.trained_env_config`) under the settings ``cfg`` makes itself."""
    env = cfg.make_env(track=track)
    try:
        today = env_spec(env.unwrapped)  # type: ignore[arg-type]
        same = meta.get("env_spec_hash") == spec_hash(today)
    finally:
        env.close()
    saved = meta.get("env_spec")
    trained = None if same or not isinstance(saved, dict) else trained_env_config(saved)
    if trained is None:
        return cfg
    # what the run's config sets stays set (a contradiction is then reported, not hidden)
    return cfg.model_copy(update={"env_config": _merged(trained, cfg.env_config)})


def resolved_env_config(cfg: TrainConfig, env: KartEnv) -> TrainConfig:
    """``cfg`` with its env config written out in full: every parameter at the value ``env``
    (the env ``cfg`` makes) has, so a run's ``config.toml`` alone says what was trained and
    makes the same env again. Unset parameters (None: the env's own default, e.g. the track's
    time limit) stay unset, as TOML has no None and setting them would change the env spec."""
    data = env.config.model_dump(mode="json", exclude_none=True)
    return cfg.model_copy(update={"env_config": data})


def checkpoint_path(run_dir: str | Path, which: str | Path | None = None) -> Path:
    """The checkpoint ``which`` names in ``run_dir``: ``latest`` (or None) the latest,
    ``best`` the best periodic evaluation's, a whole number the one saved at that env step;
    anything else is a checkpoint file's path."""
    run_dir = Path(run_dir)
    word = "latest" if which is None else str(which)
    if word == "latest":
        return run_dir / "checkpoint.pt"
    if word == "best":
        path = run_dir / "best.pt"
        if not path.is_file():
            raise CheckpointError(_no_best(run_dir))
        return path
    if word.isdigit():
        steps = saved_steps(run_dir)
        if int(word) not in steps:
            saved = ", ".join(str(s) for s in sorted(steps)) or "none"
            raise CheckpointError(
                f"no checkpoint at step {int(word)} in {run_dir}; its checkpoints are at steps "
                f"{saved} (or pass best or latest)"
            )
        return steps[int(word)]
    return Path(word)


def saved_steps(run_dir: Path) -> dict[int, Path]:
    """A run's checkpoints (its history, then the latest) by the env step they were saved at."""
    found: dict[int, Path] = {}
    for path in [*sorted((run_dir / "checkpoints").glob("iter_*.pt")), run_dir / "checkpoint.pt"]:
        meta = path.with_suffix(".json")
        if path.is_file() and meta.is_file():
            try:
                found.setdefault(int(json.loads(meta.read_text())["global_step"]), path)
            except (ValueError, KeyError, TypeError):
                continue  # a .json cut short by a kill: its .pt holds the same step anyway
    return found


def _no_best(run_dir: Path) -> str:
    every = read_run_config(run_dir).eval.every_steps
    if every == 0:
        return (
            "no best checkpoint: this run was trained without periodic evaluation "
            "(set eval.every_steps)"
        )
    return (
        f"no best checkpoint in {run_dir} yet: its first periodic evaluation comes at step "
        f"{every}; pass latest instead"
    )


def _merged(base: Mapping[str, object], over: Mapping[str, object]) -> dict[str, object]:
    out = dict(base)
    for key, value in over.items():
        old = out.get(key)
        out[key] = (
            _merged(old, value) if isinstance(old, dict) and isinstance(value, dict) else value
        )
    return out


def _iteration_of(line: str) -> float:
    """A metrics line's iteration; infinity for a line cut short by a kill."""
    try:
        return int(json.loads(line)["iteration"]) if line.endswith("\n") else math.inf
    except (ValueError, KeyError, TypeError):
        return math.inf


class RunDir:
    """Writes everything a run keeps; every file is replaced atomically or appended to."""

    def __init__(self, path: Path, tensorboard: bool) -> None:
        self.path = Path(path)
        self.metrics_path = self.path / "metrics.jsonl"
        self.tensorboard = tensorboard
        self.writer: Any = None
        self.wandb: WandbLogger | None = None

    @property
    def latest(self) -> Path:
        return self.path / "checkpoint.pt"

    @property
    def best(self) -> Path:
        """The best periodic evaluation's checkpoint (:mod:`snnkart.rl.periodic_eval`)."""
        return self.path / "best.pt"

    def trim_metrics(self, iteration: int) -> int:
        """Drop the records of iterations after ``iteration`` (those a killed run logged
        after its last checkpoint: resuming runs them again). Returns how many were dropped."""
        if not self.metrics_path.is_file():
            return 0
        lines = self.metrics_path.read_text().splitlines(keepends=True)
        keep = [ln for ln in lines if _iteration_of(ln) <= iteration]
        if len(keep) != len(lines):
            with atomic_path(self.metrics_path) as tmp:
                tmp.write_text("".join(keep))
        return len(lines) - len(keep)

    def write_config(self, cfg: TrainConfig) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.path / "config.toml") as tmp:
            tmp.write_text(cfg.to_toml())

    def save(
        self, state: CheckpointState, meta: CheckpointMeta, iteration: int, history: bool = True
    ) -> Path:
        """Write ``checkpoint.pt`` (latest) and, with ``history``, a copy under
        ``checkpoints/``."""
        save_checkpoint(self.latest, state, meta)
        if history:
            save_checkpoint(self.path / "checkpoints" / f"iter_{iteration:06d}.pt", state, meta)
        return self.latest

    def save_best(self, state: CheckpointState, meta: CheckpointMeta) -> Path:
        """Write ``best.pt`` (and its .json), replacing the previous best."""
        save_checkpoint(self.best, state, meta)
        return self.best

    def open_tensorboard(self) -> None:
        if self.tensorboard and self.writer is None:
            from torch.utils.tensorboard import SummaryWriter

            self.writer = SummaryWriter(str(self.path / "tb"))

    def open_wandb(self, cfg: TrainConfig) -> None:
        """Also log the scalars to Weights & Biases (:mod:`snnkart.rl.wandb_log`)."""
        if self.wandb is None:
            self.wandb = WandbLogger(self.path, cfg.model_dump(mode="json"))

    def log(self, record: Mapping[str, float | None], global_step: int) -> None:
        """Append the iteration's record to metrics.jsonl and its scalars to TensorBoard (and
        W&B)."""
        with open(self.metrics_path, "a") as f:
            f.write(json.dumps(record) + "\n")
        if self.writer is not None:
            for key, value in record.items():
                if "/" in key and value is not None:
                    self.writer.add_scalar(key, value, global_step)
        if self.wandb is not None:
            self.wandb.log(record, global_step)

    def write_trajectories(
        self, iteration: int, global_step: int, arrays: dict[str, np.ndarray]
    ) -> None:
        """Write one rollout's kart poses (:meth:`snnkart.rl.rollout.Rollout.trajectory`) for ``replay``."""
        path = self.path / "trajectories" / f"iter_{iteration:06d}.npz"
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays, global_step=np.int64(global_step))

    def flush(self) -> None:
        if self.writer is not None:
            self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        if self.wandb is not None:
            self.wandb.close()
            self.wandb = None


def config_to_train(
    cfg: TrainConfig, run_dir: Path, resume: bool, total_steps: int | None
) -> TrainConfig:
    """The config to train with: ``cfg``, or on resume the run's own, with its own length
    unless ``total_steps`` extends (or shortens) it explicitly."""
    config_path = run_dir / "config.toml"
    if resume:
        if not config_path.is_file():
            raise RunError(f"nothing to resume in {run_dir}: no config.toml there")
        saved = read_run_config(run_dir)
        if total_steps is not None and total_steps != saved.total_steps:
            saved = saved.model_copy(update={"total_steps": total_steps})
        return saved
    if config_path.exists():
        raise RunError(
            f"{run_dir} already holds a run; pass --resume to continue it or choose another --out"
        )
    return cfg
