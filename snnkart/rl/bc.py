"""Behaviour cloning: warm-start a policy from a recording before PPO (``bc`` config section,
``snnkart train --pretrain-bc DATA.npz``).

The actor is fitted to the recorded actions by maximum likelihood under its own action
distribution: cross-entropy of the logits for discrete actions, the Gaussian negative
log-likelihood (the mean, and the learned log std) for continuous ones. The critic is fitted
to the recorded returns-to-go (recomputed with the run's ``ppo.gamma``) by mean squared error.
The observation normaliser starts from the recording's mean and variance, so the policy sees
the observations it was cloned on. A stateful SNN actor (``snn.stateful``), whose state runs
across env steps, is cloned on windows of consecutive steps with a burn-in (:data:`WINDOW`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TypedDict

import numpy as np
import torch

from snnkart.envs.recording import Recording, returns_to_go
from snnkart.errors import ConfigError
from snnkart.io import write_json
from snnkart.rl.config import TrainConfig
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.optim import adam
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import normalize_obs

BC_SCHEMA = "snnkart/bc/v1"
"""Schema of a run's ``bc.json``: the recording cloned (path, sha256, steps, episodes, driver)
and the losses and accuracy after each epoch."""


class BcSummary(TypedDict):
    """What a run keeps of its behaviour cloning (``bc.json`` without its schema)."""

    data: str
    sha256: str
    steps: int
    episodes: int
    driver: str | None
    epochs: int
    value: bool
    actor_loss: list[float]  # per epoch
    value_loss: list[float]
    accuracy: list[float | None]  # None: continuous actions or a stateful actor


def load_for(cfg: TrainConfig, spec: Mapping[str, object]) -> Recording:
    """The config's recording, checked against the env being trained (``spec``): another env,
    action mode, observation layout or env config is refused; another track is not."""
    assert cfg.bc is not None
    rec = Recording.load(cfg.bc.data)
    rec.check(spec, f"--pretrain-bc {cfg.bc.data}", any_track=True)
    return rec


def behaviour_clone(
    policy: ActorCritic, obs_rms: RunningMeanStd, cfg: TrainConfig, rec: Recording
) -> BcSummary:
    """Fit ``policy`` (in place) to ``rec`` for ``cfg.bc.epochs`` epochs; ``obs_rms`` takes
    the recording's statistics. Returns the summary (losses per epoch) that the run keeps."""
    bc = cfg.bc
    assert bc is not None
    if cfg.ppo.norm_obs:
        obs_rms.update(rec.obs.astype(np.float64))
    raw = torch.as_tensor(rec.obs, dtype=torch.float32)
    obs = torch.as_tensor(normalize_obs(obs_rms, cfg.ppo, rec.obs), dtype=torch.float32)
    actions = torch.as_tensor(rec.actions)
    returns = torch.as_tensor(returns_to_go(rec.rewards, rec.episode_starts, cfg.ppo.gamma))
    optimizer = adam(policy.parameters(), lr=bc.learning_rate, eps=1e-5, foreach=None)
    gen = torch.Generator().manual_seed(cfg.seed)
    actor_losses: list[float] = []
    value_losses: list[float] = []
    accuracies: list[float | None] = []
    policy.train()
    for _ in range(bc.epochs):
        sums = np.zeros(3)
        for rows, extra, kept in _batches(policy, rec, bc.batch_size, gen):
            out = policy(obs[rows], raw[rows], action=actions[rows], **extra)
            actor_loss = -out.log_prob[kept].mean()
            value_loss = ((out.value - returns[rows])[kept] ** 2).mean()
            loss = actor_loss + (bc.value_coef * value_loss if bc.value else 0.0)
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), cfg.ppo.max_grad_norm)
            optimizer.step()
            policy.clamp_parameters()
            n = int(kept.sum())
            sums += [n * actor_loss.item(), n * value_loss.item(), n]
        actor_losses.append(float(sums[0] / sums[2]))
        value_losses.append(float(sums[1] / sums[2]))
        accuracies.append(_accuracy(policy, obs, raw, actions))
    return {
        "data": str(bc.data),
        "sha256": _sha256(Path(bc.data)),
        "steps": len(obs),
        "episodes": rec.episodes,
        "driver": rec.meta.get("driver"),
        "epochs": bc.epochs,
        "value": bc.value,
        "actor_loss": actor_losses,
        "value_loss": value_losses,
        "accuracy": accuracies,
    }


WINDOW, BURN_IN = 64, 16
"""A stateful actor is cloned on windows of ``WINDOW`` consecutive steps of one episode, run
from a zero state at the window's first step; the first ``BURN_IN`` steps of each window only
build up the state (their loss is not counted), as in R2D2's burn-in."""


def _batches(
    policy: ActorCritic, rec: Recording, batch_size: int, gen: torch.Generator
) -> Iterator[tuple[torch.Tensor, dict[str, torch.Tensor], torch.Tensor]]:
    """One epoch's minibatches: (the recording's rows, the policy's extra arguments, which
    rows count in the loss). Shuffled steps; for a stateful actor, shuffled windows (rows
    time-major, ``s * E + e``) with their zero initial state and ``starts``."""
    n = len(rec.obs)
    if not policy.carries_state:
        for idx in torch.randperm(n, generator=gen).split(batch_size):
            yield idx, {}, torch.ones(len(idx), dtype=torch.bool)
        return
    windows = torch.as_tensor(_windows(rec.episode_starts, n, WINDOW))
    if len(windows) == 0:
        raise ConfigError(
            f"--pretrain-bc: a stateful actor needs episodes of at least {WINDOW} steps"
        )
    per_batch = max(1, batch_size // WINDOW)
    for pick in torch.randperm(len(windows), generator=gen).split(per_batch):
        e = len(pick)
        starts = torch.zeros(WINDOW, e)
        starts[0] = 1.0
        kept = (torch.arange(WINDOW) >= BURN_IN).repeat_interleave(e)
        state = policy.initial_state(e)  # type: ignore[operator]
        yield windows[pick].T.reshape(-1), {"state": state, "starts": starts}, kept


def _windows(episode_starts: np.ndarray, n: int, length: int) -> np.ndarray:
    """``[W, length]`` step indices: every episode cut into windows of ``length`` steps (the
    last one ending at the episode's end, overlapping the one before); shorter episodes are
    left out."""
    ends = [*episode_starts[1:].tolist(), n]
    out = []
    for a, b in zip(episode_starts.tolist(), ends, strict=True):
        firsts = list(range(a, b - length + 1, length))
        if firsts and firsts[-1] + length < b:
            firsts.append(b - length)
        out += [np.arange(f, f + length) for f in firsts]
    return np.array(out, dtype=np.int64).reshape(-1, length)


def _accuracy(
    policy: ActorCritic, obs: torch.Tensor, raw: torch.Tensor, actions: torch.Tensor
) -> float | None:
    """Share of steps whose deterministic (argmax) action is the recorded one (discrete;
    None for continuous actions and stateful actors, whose action depends on the steps before)."""
    if not policy.discrete or policy.carries_state:
        return None
    return float((policy.act_deterministic(obs, raw) == actions).float().mean().item())


def warm_start(
    policy: ActorCritic,
    obs_rms: RunningMeanStd,
    cfg: TrainConfig,
    spec: Mapping[str, object],
    run_dir: Path,
    new_run: bool = True,
) -> BcSummary | None:
    """Clone the config's recording (``cfg.bc``; None: nothing to do) into a new run's
    ``policy`` and keep the summary in ``run_dir/bc.json``; a resumed run (not ``new_run``)
    does not clone again: its checkpoint holds the result."""
    if cfg.bc is None or not new_run:
        return None
    summary = behaviour_clone(policy, obs_rms, cfg, load_for(cfg, spec))
    write_json(run_dir / "bc.json", {"schema": BC_SCHEMA, **summary})
    return summary


def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()
