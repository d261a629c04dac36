"""Behaviour cloning: warm-start a policy from a recording before PPO (``bc`` config section,
``snnkart train --pretrain-bc DATA.npz``).

The actor is fitted to the recorded actions by maximum likelihood under its own action
distribution: cross-entropy of the logits for discrete actions, the Gaussian negative
log-likelihood (the mean, and the learned log std) for continuous ones. The critic is fitted
to the recorded returns-to-go (recomputed with the run's ``ppo.gamma``) by mean squared error.
The observation normaliser starts from the recording's mean and variance, so the policy sees
the observations it was cloned on. A stateful SNN actor (``snn.stateful``) is refused: its
state runs across steps and cloning it would need whole-episode sequences (the config
refuses it; :func:`behaviour_clone` too, for a policy built by hand).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from snnkart.envs.recording import Recording, returns_to_go
from snnkart.errors import ConfigError
from snnkart.io import write_json
from snnkart.rl.config import STATEFUL_BC, TrainConfig
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.policies import ActorCritic
from snnkart.rl.rollout import normalize_obs

BC_SCHEMA = "snnkart/bc/v1"
"""Schema of a run's ``bc.json``: the recording cloned (path, sha256, steps, episodes, driver)
and the losses and accuracy after each epoch."""


def load_for(cfg: TrainConfig, spec: dict[str, Any]) -> Recording:
    """The config's recording, checked against the env being trained (``spec``): another env,
    action mode, observation layout or env config is refused; another track is not."""
    assert cfg.bc is not None
    rec = Recording.load(cfg.bc.data)
    rec.check(spec, f"--pretrain-bc {cfg.bc.data}", any_track=True)
    return rec


def behaviour_clone(
    policy: ActorCritic, obs_rms: RunningMeanStd, cfg: TrainConfig, rec: Recording
) -> dict[str, Any]:
    """Fit ``policy`` (in place) to ``rec`` for ``cfg.bc.epochs`` epochs; ``obs_rms`` takes
    the recording's statistics. Returns the summary (losses per epoch) that the run keeps."""
    bc = cfg.bc
    assert bc is not None
    if getattr(policy, "stateful", False):
        raise ConfigError(STATEFUL_BC)
    if cfg.ppo.norm_obs:
        obs_rms.update(rec.obs.astype(np.float64))
    raw = torch.as_tensor(rec.obs, dtype=torch.float32)
    obs = torch.as_tensor(normalize_obs(obs_rms, cfg.ppo, rec.obs), dtype=torch.float32)
    actions = torch.as_tensor(rec.actions)
    returns = torch.as_tensor(returns_to_go(rec.rewards, rec.episode_starts, cfg.ppo.gamma))
    optimizer = torch.optim.Adam(policy.parameters(), lr=bc.learning_rate, eps=1e-5)
    gen = torch.Generator().manual_seed(cfg.seed)
    history: dict[str, list[Any]] = {"actor_loss": [], "value_loss": [], "accuracy": []}
    policy.train()
    for _ in range(bc.epochs):
        sums = np.zeros(2)
        for idx in torch.randperm(len(obs), generator=gen).split(bc.batch_size):
            out = policy(obs[idx], raw[idx], action=actions[idx])
            actor_loss = -out.log_prob.mean()
            value_loss = ((out.value - returns[idx]) ** 2).mean()
            loss = actor_loss + (bc.value_coef * value_loss if bc.value else 0.0)
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), cfg.ppo.max_grad_norm)
            optimizer.step()
            policy.clamp_parameters()
            sums += len(idx) * np.array([actor_loss.item(), value_loss.item()])
        history["actor_loss"].append(float(sums[0] / len(obs)))
        history["value_loss"].append(float(sums[1] / len(obs)))
        history["accuracy"].append(_accuracy(policy, obs, raw, actions))
    return {
        "data": str(bc.data), "sha256": _sha256(Path(bc.data)), "steps": len(obs),
        "episodes": rec.episodes, "driver": rec.meta.get("driver"), "epochs": bc.epochs,
        "value": bc.value, **history,
    }  # fmt: skip


def _accuracy(
    policy: ActorCritic, obs: torch.Tensor, raw: torch.Tensor, actions: torch.Tensor
) -> float | None:
    """Share of steps whose deterministic (argmax) action is the recorded one (discrete;
    None for continuous actions)."""
    if not policy.discrete:
        return None
    return float((policy.act_deterministic(obs, raw) == actions).float().mean().item())


def warm_start(
    policy: ActorCritic,
    obs_rms: RunningMeanStd,
    cfg: TrainConfig,
    spec: dict[str, Any],
    run_dir: Path,
    new_run: bool = True,
) -> dict[str, Any] | None:
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
