"""Opening a trained run: the one sequence that resuming (:class:`snnkart.rl.ppo.Trainer`) and
loading (:func:`snnkart.rl.trained.load_run`) share.

read ``config.toml`` -> read the checkpoint -> the track embedded in it -> the config rebuilt
with the env config it was trained in -> make the env -> check the checkpoint fits it -> build
the policy and load its weights, and the frozen observation normaliser.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from snnkart.envs.spec import env_spec
from snnkart.envs.tracks import Track, TrackError
from snnkart.rl.checkpoint import CheckpointError, check_compatible, load_checkpoint
from snnkart.rl.config import TrainConfig, read_run_config
from snnkart.rl.kinds import policy_for
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import Progress
from snnkart.rl.run_dir import checkpoint_path, checkpoint_track, trained_config


@dataclass(frozen=True)
class RunSchedule:
    """Where a run stood in the schedules its own length sets (learning-rate and entropy
    annealing, the rate-regulariser warm-up) when its checkpoint was written."""

    total_steps: int
    """The length the run was training for (the checkpoint's config; ``config.toml`` for a
    checkpoint without one)."""
    batch_size: int
    """Env steps per iteration (``ppo.num_envs * ppo.rollout_steps``)."""
    iteration: int
    global_step: int
    learning_rate: float | None
    """The optimizer's learning rate at the checkpoint (None: no optimizer state saved)."""

    @property
    def num_iterations(self) -> int:
        """The iterations ``total_steps`` makes: the length of the annealing schedules."""
        return math.ceil(self.total_steps / self.batch_size)


@dataclass(frozen=True)
class OpenedRun:
    """A run directory with one of its checkpoints, opened and checked against its env."""

    run_dir: Path
    checkpoint: Path
    config: TrainConfig
    """``config.toml`` with the env config the checkpoint was trained in (a default that
    changed since does not change the env)."""
    track: Track | None
    """The track the checkpoint was trained on (embedded in it, or ``config.track``); None
    for a gymnasium env."""
    env_spec: dict[str, Any]
    """The spec of the env ``config`` and ``track`` make; the checkpoint fits it."""
    policy: ActorCritic
    """The policy with the checkpoint's weights, in the mode it was built in (training)."""
    obs_rms: RunningMeanStd
    progress: Progress
    schedule: RunSchedule
    state: dict[str, Any]
    """The checkpoint's state dict (optimizer, RNG states: what a resume restores besides)."""
    meta: dict[str, Any]
    """The checkpoint's metadata (versions, env spec, config, track, progress counters)."""


def open_run(run_dir: str | Path, checkpoint: str | Path | None = None) -> OpenedRun:
    """Open ``run_dir`` at ``checkpoint`` (default: its latest, ``checkpoint.pt``; ``best``,
    ``latest``, an env step or a file: :func:`~snnkart.rl.run_dir.checkpoint_path`); raise
    :class:`CheckpointError` if the checkpoint does not fit the env its config describes."""
    run_dir = Path(run_dir)
    cfg = read_run_config(run_dir)
    ckpt = checkpoint_path(run_dir, checkpoint)
    state, meta = load_checkpoint(ckpt)
    track: Track | None = None
    if cfg.kart:
        try:
            track = checkpoint_track(meta, cfg, ckpt)
        except TrackError as exc:
            raise CheckpointError(
                f"{ckpt}: {exc} (this checkpoint predates embedded tracks: put the track file "
                "back where it was trained, or retrain)"
            ) from exc
        cfg = trained_config(meta, cfg, track)  # the env it was trained in, whatever the defaults
    env = cfg.make_env(track=track)
    try:
        if track is None:  # any gymnasium env: the policy sees the wrapped env's spaces
            spec = _checked_gym_spec(cfg, env, meta, ckpt)
            policy = policy_for(cfg, env)
        else:
            check_compatible(meta, env.unwrapped, str(ckpt))  # type: ignore[arg-type]
            spec = env_spec(env.unwrapped)  # type: ignore[arg-type]
            policy = policy_for(cfg, env.unwrapped)
    finally:
        env.close()
    try:
        policy.load_state_dict(state["policy"])
    except RuntimeError as exc:
        raise CheckpointError(
            f"{ckpt}: weights do not fit the policy in config.toml ({exc})"
        ) from exc
    progress = Progress(**{k: int(v) for k, v in state.get("progress", {}).items()})
    return OpenedRun(
        run_dir,
        ckpt,
        cfg,
        track,
        spec,
        policy,
        RunningMeanStd.from_state(state["obs_rms"]),
        progress,
        _schedule(cfg, meta, state, progress),
        state,
        meta,
    )


def _checked_gym_spec(
    cfg: TrainConfig, env: Any, meta: Mapping[str, object], ckpt: Path
) -> dict[str, object]:
    """The spec of the gymnasium env ``cfg`` makes now, refused if its spaces differ from the
    checkpoint's (a different package version is a warning)."""
    from snnkart.envs.resolve import resolve_env
    from snnkart.envs.task_env import check_trained_on, gym_spec
    from snnkart.errors import EnvError

    now = gym_spec(resolve_env(cfg.env), env, cfg.env_kwargs)
    saved = meta.get("env_spec")
    if not isinstance(saved, dict):
        raise CheckpointError(f"{ckpt}: the checkpoint records no env spec; retrain the run")
    try:
        check_trained_on(saved, now, "run it on that env, or retrain", where=f"{ckpt}: ")
    except EnvError as exc:
        raise CheckpointError(f"{ckpt}: {exc}") from exc
    return now


def _schedule(
    cfg: TrainConfig, meta: dict[str, Any], state: dict[str, Any], progress: Progress
) -> RunSchedule:
    groups = state.get("optimizer", {}).get("param_groups") or [{}]
    lr = groups[0].get("lr")
    return RunSchedule(
        total_steps=int(meta.get("config", {}).get("total_steps", cfg.total_steps)),
        batch_size=cfg.batch_size,
        iteration=progress.iteration,
        global_step=progress.global_step,
        learning_rate=None if lr is None else float(lr),
    )
