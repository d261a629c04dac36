"""PPO for ANN and SNN policies: one loop, the policy is a parameter.

Laid out like CleanRL's ``ppo.py`` (one readable iteration: LR anneal, rollout into
preallocated ``[steps, envs, ...]`` tensors, GAE under ``no_grad``, minibatch epochs) and split
like Stable-Baselines3 (:func:`compute_gae` and :meth:`Trainer.update` are separate and tested).

Details that matter:

* gymnasium 1.x vector envs run in ``SAME_STEP`` autoreset mode, so every stored transition
  is a real one (no training on a reset step); the terminal observation comes from
  ``info["final_obs"]``.
* Time-limit truncation is bootstrapped: ``r_t += gamma * V(final_obs)``, then the episode is
  cut for GAE. Termination (finish, crash, standing still) is not bootstrapped.
* Per-minibatch advantage normalisation, clipped surrogate, entropy bonus, value loss,
  gradient-norm clipping, linear LR annealing, optional target-KL early stop, orthogonal init,
  running observation normalisation stored with the checkpoint.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from snnkart import faults
from snnkart.envs.base import KartEnv
from snnkart.envs.spec import env_spec, spec_hash
from snnkart.envs.tracks import Track, embed_track, embedded_track, load_track
from snnkart.errors import RunError
from snnkart.io import atomic_path
from snnkart.rl.checkpoint import (
    RunningMeanStd,
    check_compatible,
    load_checkpoint,
    save_checkpoint,
)
from snnkart.rl.config import PPOConfig, TrainConfig, read_run_config
from snnkart.rl.policies import ActorCritic, build_policy


def compute_gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    episode_end: torch.Tensor,
    last_value: torch.Tensor,
    gamma: float,
    gae_lambda: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Generalised advantage estimation over ``[steps, envs]`` tensors.

    ``episode_end[t]`` is 1 where the episode ended *after* step ``t`` (terminated or
    truncated; truncations already carry their bootstrap in ``rewards[t]``). ``last_value`` is
    V of the observation after the last step. Returns (advantages, returns).
    """
    # Small per-step arrays: numpy's scalar-loop overhead is far below torch's.
    r, v, end = rewards.numpy(), values.numpy(), episode_end.numpy()
    next_values = np.concatenate([v[1:], last_value.numpy()[None]], axis=0)
    nonterminal = 1.0 - end
    deltas = r + gamma * next_values * nonterminal - v
    adv = np.zeros_like(r)
    last_gae = np.zeros_like(r[0])
    for t in reversed(range(r.shape[0])):
        last_gae = deltas[t] + gamma * gae_lambda * nonterminal[t] * last_gae
        adv[t] = last_gae
    advantages = torch.from_numpy(adv)
    return advantages, advantages + values


class EpisodeEndInfo(gym.Wrapper):  # type: ignore[type-arg]
    """Pass on only what training reads, and only at episode ends.

    The vector env merges every info key of every env on every step; the kart envs report a
    dozen keys (a nested dict among them), which cost more than the env step itself.
    """

    KEYS = ("lap_finished", "crashed", "elapsed_time", "position")

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated or truncated:
            return obs, reward, terminated, truncated, {k: info[k] for k in self.KEYS}
        return obs, reward, terminated, truncated, {}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, _ = self.env.reset(**kwargs)
        return obs, {}


def normalize_obs(rms: RunningMeanStd, ppo: PPOConfig, raw: np.ndarray) -> np.ndarray:
    """The float32 observation the critic and the ANN actor see (the policy's input)."""
    if ppo.norm_obs:
        return rms.normalize(raw, ppo.clip_obs)
    return np.asarray(raw, dtype=np.float32)


def checkpoint_track(meta: dict[str, Any], cfg: TrainConfig, source: Path) -> Track:
    """The track a checkpoint was trained on: the one embedded in it, or for checkpoints
    written before tracks were embedded, ``cfg.track`` (which must then still exist)."""
    if meta.get("track"):
        return embedded_track(meta["track"], str(source))
    return load_track(cfg.track)


def policy_for(cfg: TrainConfig, env: KartEnv) -> ActorCritic:
    space = env.action_space
    if isinstance(space, gym.spaces.Discrete):
        discrete, action_dim = True, int(space.n)
    elif isinstance(space, gym.spaces.Box):
        discrete, action_dim = False, int(space.low.shape[0])
    else:
        raise TypeError(f"unsupported action space {space}")
    obs_space = env.observation_space
    return build_policy(
        cfg.policy,
        int(obs_space.low.shape[0]),
        action_dim,
        discrete,
        cfg.ann,
        cfg.snn,
        obs_space.low.astype(np.float64),
        obs_space.high.astype(np.float64),
        cfg.ppo.init_log_std,
    )


@dataclass
class Progress:
    """Counters that survive a resume."""

    global_step: int = 0
    iteration: int = 0
    episodes: int = 0
    finishes: int = 0
    first_finish_step: int = -1

    def state(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class IterationStats:
    returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    finishes: int = 0
    crashes: int = 0
    lap_times: list[float] = field(default_factory=list)
    rates: list[np.ndarray] = field(default_factory=list)


class Trainer:
    """Owns a run directory: config, checkpoints, metrics, trajectories."""

    def __init__(self, cfg: TrainConfig, run_dir: Path, resume: bool = False) -> None:
        self.run_dir = Path(run_dir)
        config_path = self.run_dir / "config.toml"
        if resume:
            if not config_path.is_file():
                raise RunError(f"nothing to resume in {self.run_dir}: no config.toml there")
            saved = read_run_config(self.run_dir)
            if cfg.total_steps != saved.total_steps:
                saved = saved.model_copy(update={"total_steps": cfg.total_steps})
            cfg = saved
        elif config_path.exists():
            raise RunError(
                f"{self.run_dir} already holds a run; pass --resume to continue it "
                "or choose another --out"
            )
        self.cfg = cfg
        # A resumed run trains on the track its checkpoint carries: the file may have moved.
        latest = self.run_dir / "checkpoint.pt"
        if resume and latest.is_file():
            self.track = checkpoint_track(load_checkpoint(latest)[1], cfg, latest)
        else:
            self.track = load_track(cfg.track)
        torch.set_num_threads(cfg.run.torch_threads)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        with atomic_path(config_path) as tmp:
            tmp.write_text(cfg.to_toml())

        p = cfg.ppo
        self.envs = gym.vector.SyncVectorEnv(
            [lambda: EpisodeEndInfo(cfg.make_env(track=self.track))] * p.num_envs,
            autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
        )
        self.karts: list[KartEnv] = [e.unwrapped for e in self.envs.envs]  # type: ignore[misc]
        self.env0 = self.karts[0]
        self.spec = env_spec(self.env0)
        torch.manual_seed(cfg.seed)
        self.policy = policy_for(cfg, self.env0)
        self.optimizer = torch.optim.Adam(self.policy.parameters(), lr=p.learning_rate, eps=1e-5)
        self.ent_coef = p.ent_coef  # annealed with the learning rate when ppo.anneal_ent
        self.obs_rms = RunningMeanStd.zeros(self.spec["obs_dim"])
        self.progress = Progress()
        self.rng = np.random.default_rng(cfg.seed)
        if resume and (self.run_dir / "checkpoint.pt").is_file():
            self._restore(self.run_dir / "checkpoint.pt")
        self.num_iterations = math.ceil(cfg.total_steps / cfg.batch_size)
        self.metrics_path = self.run_dir / "metrics.jsonl"
        self.writer: Any = None

    # -- checkpoints -------------------------------------------------------------------------

    def _restore(self, path: Path) -> None:
        state, meta = load_checkpoint(path)
        check_compatible(meta, self.env0, str(path))
        self.policy.load_state_dict(state["policy"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.obs_rms = RunningMeanStd.from_state(state["obs_rms"])
        self.progress = Progress(**{k: int(v) for k, v in state["progress"].items()})
        torch.set_rng_state(state["torch_rng"])
        self.rng = np.random.default_rng(int(state["numpy_seed"]))

    def save(self) -> Path:
        """Write ``checkpoint.pt`` (latest) and a copy under ``checkpoints/``."""
        state = {
            "policy": self.policy.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "obs_rms": self.obs_rms.state(),
            "progress": self.progress.state(),
            "torch_rng": torch.get_rng_state(),
            "numpy_seed": int(self.rng.integers(2**62)),
        }
        meta = {
            "policy": self.cfg.policy,
            "env_spec": self.spec,
            "env_spec_hash": spec_hash(self.spec),
            "config": self.cfg.model_dump(mode="json", by_alias=True),
            "track": embed_track(self.track, self.cfg.track),
            **self.progress.state(),
        }
        latest = self.run_dir / "checkpoint.pt"
        save_checkpoint(latest, state, meta)
        history = self.run_dir / "checkpoints" / f"iter_{self.progress.iteration:06d}.pt"
        save_checkpoint(history, state, meta)
        return latest

    # -- the loop ------------------------------------------------------------------------------

    def train(self, on_iteration: Callable[[dict[str, Any]], None] | None = None) -> Progress:
        """Run until ``total_steps``; Ctrl-C or SIGTERM saves a checkpoint before returning
        (``self.interrupted_by`` is then the signal). The interrupt is taken between env
        steps; a rollout cut short is dropped, so the checkpoint holds the last whole
        iteration."""
        cfg, p = self.cfg, self.cfg.ppo
        S, E = p.num_steps, p.num_envs
        obs_dim = self.spec["obs_dim"]
        discrete = self.policy.discrete
        act_shape: tuple[int, ...] = () if discrete else (self.policy.action_dim,)
        T = cfg.snn.num_steps
        rate = cfg.policy == "snn" and cfg.snn.encoding == "rate"

        obs_buf = torch.zeros(S, E, obs_dim)
        raw_buf = torch.zeros(S, E, obs_dim)
        act_buf = torch.zeros((S, E, *act_shape), dtype=torch.long if discrete else torch.float32)
        logp_buf = torch.zeros(S, E)
        rew_buf = torch.zeros(S, E)
        end_buf = torch.zeros(S, E)
        val_buf = torch.zeros(S, E)
        spk_buf = torch.zeros(S, E, T, obs_dim, dtype=torch.bool) if rate else None

        if cfg.run.tensorboard and self.writer is None:
            from torch.utils.tensorboard import SummaryWriter

            self.writer = SummaryWriter(str(self.run_dir / "tb"))

        next_raw, _ = self.envs.reset(seed=cfg.seed + 7919 * self.progress.iteration)
        ep_return = np.zeros(E)
        ep_length = np.zeros(E, dtype=np.int64)

        def interrupted() -> bool:
            return faults.pending() is not None

        self.policy.train()
        stack = contextlib.ExitStack()
        stack.enter_context(faults.caught())  # Ctrl-C/SIGTERM set a flag checked below
        try:
            while self.progress.iteration < self.num_iterations and not interrupted():
                it_start = time.perf_counter()
                before = copy.deepcopy((self.progress, self.obs_rms))  # restored if cut short
                self.progress.iteration += 1
                frac = 1.0 - (self.progress.iteration - 1) / self.num_iterations
                if p.anneal_lr:
                    self.optimizer.param_groups[0]["lr"] = frac * p.learning_rate
                self.ent_coef = frac * p.ent_coef if p.anneal_ent else p.ent_coef
                stats = IterationStats()
                positions = np.zeros((S, E, 2), dtype=np.float32)
                ends = np.zeros((S, E), dtype=bool)

                # -- rollout ---------------------------------------------------------------
                for step in range(S):
                    self.progress.global_step += E
                    if p.norm_obs:
                        self.obs_rms.update(next_raw)
                    obs_t = torch.from_numpy(normalize_obs(self.obs_rms, p, next_raw))
                    raw_t = torch.from_numpy(np.asarray(next_raw, dtype=np.float32))
                    with torch.no_grad():
                        out = self.policy(obs_t, raw_t)
                    obs_buf[step], raw_buf[step] = obs_t, raw_t
                    act_buf[step], logp_buf[step], val_buf[step] = (
                        out.action,
                        out.log_prob,
                        out.value,
                    )
                    if spk_buf is not None and out.input_spikes is not None:
                        spk_buf[step] = out.input_spikes.bool()
                    if out.rates is not None:
                        stats.rates.append(out.rates.numpy())
                    action = out.action.numpy()
                    if not discrete:
                        action = np.clip(action, -1.0, 1.0)
                    next_raw, reward, terminated, truncated, info = self.envs.step(action)
                    reward = reward.astype(np.float64)
                    done = terminated | truncated
                    if cfg.run.trajectories:
                        positions[step] = [
                            info["final_info"]["position"][i] if done[i] else kart.position
                            for i, kart in enumerate(self.karts)
                        ]
                        ends[step] = done
                    ep_return += reward
                    ep_length += 1
                    if truncated.any():
                        reward = reward + p.gamma * self._final_values(info, truncated)
                    rew_buf[step] = torch.from_numpy(reward.astype(np.float32))
                    end_buf[step] = torch.from_numpy(done.astype(np.float32))
                    for i in np.flatnonzero(done):
                        self._episode_end(info, i, ep_return[i], ep_length[i], stats)
                        ep_return[i], ep_length[i] = 0.0, 0
                    if interrupted():
                        break
                if interrupted():
                    self.progress, self.obs_rms = before
                    break
                rollout_time = time.perf_counter() - it_start

                # -- GAE -------------------------------------------------------------------
                with torch.no_grad():
                    last_norm = normalize_obs(self.obs_rms, p, next_raw)
                    last_value = self.policy.value(torch.from_numpy(last_norm))
                    advantages, returns = compute_gae(
                        rew_buf, val_buf, end_buf, last_value, p.gamma, p.gae_lambda
                    )

                # -- update ----------------------------------------------------------------
                update_start = time.perf_counter()
                losses = self.update(
                    obs_buf.reshape(S * E, obs_dim),
                    raw_buf.reshape(S * E, obs_dim),
                    act_buf.reshape((S * E, *act_shape)),
                    logp_buf.reshape(-1),
                    advantages.reshape(-1),
                    returns.reshape(-1),
                    val_buf.reshape(-1),
                    spk_buf.reshape(S * E, T, obs_dim).float() if spk_buf is not None else None,
                )
                update_time = time.perf_counter() - update_start

                record = self._log(stats, losses, rollout_time, update_time)
                if self.cfg.run.trajectories:
                    self._write_trajectories(positions, ends)
                if (
                    self.progress.iteration % cfg.run.checkpoint_every == 0
                    or self.progress.iteration == self.num_iterations
                ):
                    self.save()
                if on_iteration is not None:
                    on_iteration(record)
            if interrupted():
                self.save()
        finally:
            if self.writer is not None:
                self.writer.flush()
            self.interrupted_by = faults.consume()
            stack.close()
        self.interrupted = self.interrupted_by is not None
        return self.progress

    def update(
        self,
        b_obs: torch.Tensor,
        b_raw: torch.Tensor,
        b_actions: torch.Tensor,
        b_logprobs: torch.Tensor,
        b_advantages: torch.Tensor,
        b_returns: torch.Tensor,
        b_values: torch.Tensor,
        b_spikes: torch.Tensor | None,
    ) -> dict[str, float]:
        """PPO epochs over shuffled minibatches; returns the last epoch's mean losses."""
        p = self.cfg.ppo
        batch = b_obs.shape[0]
        mb_size = batch // p.num_minibatches
        rate_reg = self.cfg.snn.rate_reg if self.cfg.policy == "snn" else 0.0
        clipfracs: list[float] = []
        first_ratio_dev = float("nan")
        for _epoch in range(p.update_epochs):
            order = self.rng.permutation(batch)
            for start in range(0, mb_size * p.num_minibatches, mb_size):
                mb = torch.from_numpy(order[start : start + mb_size])
                out = self.policy(
                    b_obs[mb],
                    b_raw[mb],
                    action=b_actions[mb],
                    input_spikes=b_spikes[mb] if b_spikes is not None else None,
                )
                logratio = out.log_prob - b_logprobs[mb]
                ratio = logratio.exp()
                with torch.no_grad():
                    approx_kl = ((ratio - 1) - logratio).mean().item()
                    clipfracs.append(((ratio - 1.0).abs() > p.clip_coef).float().mean().item())
                    if math.isnan(first_ratio_dev):
                        first_ratio_dev = (ratio - 1.0).abs().max().item()
                adv = b_advantages[mb]
                if p.norm_adv:
                    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                pg_loss = torch.max(
                    -adv * ratio, -adv * ratio.clamp(1 - p.clip_coef, 1 + p.clip_coef)
                ).mean()
                if p.clip_vloss:
                    v_clipped = b_values[mb] + (out.value - b_values[mb]).clamp(
                        -p.clip_coef, p.clip_coef
                    )
                    v_loss = (
                        0.5
                        * torch.max(
                            (out.value - b_returns[mb]) ** 2, (v_clipped - b_returns[mb]) ** 2
                        ).mean()
                    )
                else:
                    v_loss = 0.5 * ((out.value - b_returns[mb]) ** 2).mean()
                entropy = out.entropy.mean()
                loss = pg_loss - self.ent_coef * entropy + p.vf_coef * v_loss
                if rate_reg > 0.0 and out.rates is not None:
                    loss = loss + rate_reg * out.rates.sum()
                self.optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(self.policy.parameters(), p.max_grad_norm)
                self.optimizer.step()
                self.policy.clamp_parameters()
            if p.target_kl is not None and approx_kl > p.target_kl:
                break
        y_pred, y_true = b_values.numpy(), b_returns.numpy()
        var_y = np.var(y_true)
        explained_var = float("nan") if var_y == 0 else float(1 - np.var(y_true - y_pred) / var_y)
        return {
            "losses/policy_loss": pg_loss.item(),
            "losses/value_loss": v_loss.item(),
            "losses/entropy": entropy.item(),
            "losses/approx_kl": approx_kl,
            "losses/clipfrac": float(np.mean(clipfracs)),
            "losses/explained_variance": explained_var,
            "losses/first_minibatch_max_ratio_deviation": first_ratio_dev,
        }

    # -- helpers -------------------------------------------------------------------------------

    def _final_values(self, info: dict[str, Any], truncated: np.ndarray) -> np.ndarray:
        """V(final observation) for truncated envs, 0 elsewhere."""
        values = np.zeros(truncated.shape[0])
        idx = np.flatnonzero(truncated)
        final = np.stack([info["final_obs"][i] for i in idx])
        norm = normalize_obs(self.obs_rms, self.cfg.ppo, final)
        with torch.no_grad():
            values[idx] = self.policy.value(torch.from_numpy(norm)).numpy()
        return values

    def _episode_end(
        self, info: dict[str, Any], i: int, ret: float, length: int, stats: IterationStats
    ) -> None:
        final = info["final_info"]
        finished = bool(final["lap_finished"][i])
        self.progress.episodes += 1
        stats.returns.append(float(ret))
        stats.lengths.append(int(length))
        if finished:
            stats.finishes += 1
            stats.lap_times.append(float(final["elapsed_time"][i]))
            self.progress.finishes += 1
            if self.progress.first_finish_step < 0:
                self.progress.first_finish_step = self.progress.global_step
        if bool(final["crashed"][i]):
            stats.crashes += 1

    def _log(
        self,
        stats: IterationStats,
        losses: dict[str, float],
        rollout_time: float,
        update_time: float,
    ) -> dict[str, Any]:
        steps = self.cfg.batch_size
        record: dict[str, Any] = {
            "iteration": self.progress.iteration,
            "global_step": self.progress.global_step,
            "charts/episodic_return": float(np.mean(stats.returns)) if stats.returns else None,
            "charts/episodic_length": float(np.mean(stats.lengths)) if stats.lengths else None,
            "charts/episodes": len(stats.returns),
            "charts/finishes": stats.finishes,
            "charts/crashes": stats.crashes,
            "charts/lap_time": float(np.mean(stats.lap_times)) if stats.lap_times else None,
            "charts/cumulative_finishes": self.progress.finishes,
            "charts/first_finish_step": self.progress.first_finish_step,
            "charts/learning_rate": self.optimizer.param_groups[0]["lr"],
            "charts/ent_coef": self.ent_coef,
            "charts/SPS": steps / (rollout_time + update_time),
            "charts/rollout_SPS": steps / rollout_time,
            "charts/update_seconds": update_time,
            **losses,
        }
        if stats.rates:
            rates = np.mean(stats.rates, axis=0)
            for k, r in enumerate(rates):
                record[f"snn/firing_rate_layer{k + 1}"] = float(r)
        with open(self.metrics_path, "a") as f:
            f.write(json.dumps(record) + "\n")
        if self.writer is not None:
            for key, value in record.items():
                if "/" in key and value is not None:
                    self.writer.add_scalar(key, value, self.progress.global_step)
        return record

    def _write_trajectories(self, positions: np.ndarray, ends: np.ndarray) -> None:
        path = self.run_dir / "trajectories" / f"iter_{self.progress.iteration:06d}.npz"
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(
                f,
                positions=positions,
                episode_end=ends,
                global_step=np.int64(self.progress.global_step),
            )

    def close(self) -> None:
        self.envs.close()
        if self.writer is not None:
            self.writer.close()
            self.writer = None
