"""Stopping a run once it has learned (the ``stop`` section of the train config).

Every ``stop.every`` env steps, once the run has ``stop.finishes`` finished training
episodes, the deterministic policy (argmax or mean, normalisation frozen: what ``snnkart
eval`` runs in torch) drives ``stop.episodes`` seeded episodes; ``stop.checks`` checks in a
row at or above ``stop.success`` stop the run. A check draws nothing from the training
generators, so a run that is not stopped computes exactly what it would without the rule.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import torch

from snnkart.envs.tracks import Track
from snnkart.rl.config import StopConfig, TrainConfig
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import Progress
from snnkart.rl.trained import LoadedRun, TorchPredictor


def check_due(cfg: TrainConfig, progress: Progress) -> bool:
    """A check is due when the run crossed a multiple of ``stop.every`` not yet handled, before
    its last iteration (after it, the run ends anyway)."""
    stop = cfg.stop
    return (
        stop.finishes is not None
        and progress.global_step // stop.every > progress.stop_mark
        and progress.global_step < cfg.total_steps
    )


def stopped(stop: StopConfig, progress: Progress) -> bool:
    return stop.finishes is not None and progress.stop_streak >= stop.checks


def eval_success(
    cfg: TrainConfig,
    policy: ActorCritic,
    obs_rms: RunningMeanStd,
    track: Track,
    interrupted: Callable[[], bool],
) -> float | None:
    """The deterministic policy's success rate over the check's episodes, or None if an
    interrupt came first."""
    scores = seeded_episodes(
        cfg, policy, obs_rms, track, cfg.stop.episodes, cfg.stop.seed, interrupted
    )
    return None if scores is None else scores[0]


def seeded_episodes(
    cfg: TrainConfig,
    policy: ActorCritic,
    obs_rms: RunningMeanStd,
    track: Track,
    episodes: int,
    seed: int,
    interrupted: Callable[[], bool],
) -> tuple[float, float] | None:
    """The deterministic policy's success rate and mean return over ``episodes`` episodes
    with seeds ``seed``, ``seed + 1``, ... in a fresh env, or None if an interrupt came
    first. Draws nothing from the training generators (torch's global one is forked)."""
    run = LoadedRun(Path(), cfg, policy, obs_rms, {}, Path(), track)
    predictor = TorchPredictor(run, seed=seed)
    env = cfg.make_env(track=track)
    finished, total = 0, 0.0
    try:
        with torch.no_grad():
            for k in range(episodes):
                obs, info = env.reset(seed=seed + k)
                done = False
                while not done:
                    if interrupted():
                        return None
                    obs, reward, terminated, truncated, info = env.step(predictor.predict(obs))
                    total += float(reward)
                    done = terminated or truncated
                finished += bool(info["lap_finished"])
    finally:
        env.close()
    return finished / episodes, total / episodes


def check(
    cfg: TrainConfig,
    progress: Progress,
    policy: ActorCritic,
    obs_rms: RunningMeanStd,
    track: Track,
    interrupted: Callable[[], bool],
) -> dict[str, float]:
    """Run the check if one is due; update ``progress``; return what the metrics record."""
    stop = cfg.stop
    if not check_due(cfg, progress):
        return {}
    assert stop.finishes is not None
    mark = progress.global_step // stop.every
    if progress.finishes < stop.finishes:
        progress.stop_mark = mark
        return {}
    success = eval_success(cfg, policy, obs_rms, track, interrupted)
    if success is None:
        return {}  # still due: the next iteration (or the resumed run) checks again
    progress.stop_mark = mark
    progress.stop_streak = progress.stop_streak + 1 if success >= stop.success else 0
    return {"stop/eval_success": success, "stop/streak": progress.stop_streak}
