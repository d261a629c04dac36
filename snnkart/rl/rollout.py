"""Collecting experience: the vector env, observation normalisation and episode bookkeeping.

gymnasium 1.x vector envs run in ``SAME_STEP`` autoreset mode, so every stored transition is a
real one (no training on a reset step); the terminal observation comes from
``info["final_obs"]``. Time-limit truncation is bootstrapped: ``r_t += gamma * V(final_obs)``,
then the episode is cut for GAE. Termination (finish, crash, standing still) is not.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypedDict, cast

import gymnasium as gym
import numpy as np
import torch

from snnkart.envs.base import KartEnv
from snnkart.envs.tracks import Track
from snnkart.rl.buffer import RolloutBuffer, Sequences
from snnkart.rl.config import PPOConfig, TrainConfig
from snnkart.rl.normalise import RewardScaling, RunningMeanStd
from snnkart.rl.policies import ActorCritic


class EpisodeEndInfo(gym.Wrapper):  # type: ignore[type-arg]
    """Pass on only what training reads, and only at episode ends.

    The vector env merges every info key of every env on every step; the kart envs report a
    dozen keys (a nested dict among them), which cost more than the env step itself.
    """

    KEYS = ("lap_finished", "crashed", "elapsed_time", "position")

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated or truncated:
            return obs, reward, terminated, truncated, {k: info[k] for k in self.KEYS}
        return obs, reward, terminated, truncated, {}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, object]]:
        obs, _ = self.env.reset(**kwargs)
        return obs, {}


class EpisodeEnd(gym.Wrapper):  # type: ignore[type-arg]
    """A gymnasium env's steps without their info: training reads none of it (the return and
    length it counts itself), and a vector env merging every key costs time."""

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, _ = self.env.step(action)
        return obs, reward, terminated, truncated, {}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, object]]:
        obs, _ = self.env.reset(**kwargs)
        return obs, {}


KART_CHARTS = (
    "charts/finishes",
    "charts/crashes",
    "charts/lap_time",
    "charts/cumulative_finishes",
    "charts/first_finish_step",
)
"""The metrics of a kart env's laps (None for any other env)."""


def normalize_obs(rms: RunningMeanStd, ppo: PPOConfig, raw: np.ndarray) -> np.ndarray:
    """The float32 observation the critic and the ANN actor see (the policy's input)."""
    if ppo.norm_obs:
        return rms.normalize(raw, ppo.clip_obs)
    return np.asarray(raw, dtype=np.float32)


class ProgressState(TypedDict):
    """:class:`Progress` as checkpoints store it (``state["progress"]``, and in the metadata)."""

    global_step: int
    iteration: int
    episodes: int
    finishes: int
    first_finish_step: int
    stop_mark: int
    stop_streak: int
    eval_mark: int


class TrainResult(ProgressState):
    """What a run's training ended with (:func:`snnkart.rl.ppo.train`): its counters, and
    whether it was interrupted or stopped early by the ``stop`` rule."""

    interrupted: bool
    stopped_early: bool


@dataclass
class Progress:
    """Counters that survive a resume."""

    global_step: int = 0
    iteration: int = 0
    episodes: int = 0
    finishes: int = 0
    first_finish_step: int = -1
    stop_mark: int = 0
    """How many multiples of ``stop.every`` the early-stop checks have handled."""
    stop_streak: int = 0
    """Early-stop checks in a row at or above ``stop.success``."""
    eval_mark: int = 0
    """How many multiples of ``eval.every_steps`` the periodic evaluations have handled."""

    def state(self) -> ProgressState:
        return cast(ProgressState, dict(self.__dict__))  # its fields, in order


@dataclass
class IterationStats:
    """What one iteration's finished episodes and spiking layers did."""

    returns: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    finishes: int = 0
    crashes: int = 0
    lap_times: list[float] = field(default_factory=list)
    kind: dict[str, list[np.ndarray]] = field(default_factory=dict)
    """What the policy's kind records per step (:meth:`ActorCritic.rollout_stats`: ``rates``,
    a spiking actor's mean firing rate per layer; ``messages``, a sigma-delta actor's share of
    neurons whose integer changed), by name."""


class RewardState(TypedDict, total=False):
    """A checkpoint's ``reward_rms``: ``ppo.norm_reward``'s running return variance."""

    reward_rms: dict[str, torch.Tensor]


class Rollout:
    """The training envs and what carries over between rollouts: the next observation and
    the running return and length of every env's episode."""

    def __init__(self, cfg: TrainConfig, track: Track | None) -> None:
        """``track``: a kart env's (None: a gymnasium env, which has none)."""
        self.cfg, self.ppo = cfg, cfg.ppo
        wrap = EpisodeEndInfo if track is not None else EpisodeEnd
        self.envs = gym.vector.SyncVectorEnv(
            [lambda: wrap(cfg.make_env(track=track))] * cfg.ppo.num_envs,
            autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
        )
        self.karts: list[KartEnv] = (
            [e.unwrapped for e in self.envs.envs] if track is not None else []  # type: ignore[misc]
        )
        for kart in self.karts:
            kart.start_spread = cfg.ppo.start_spread
        steps, envs = cfg.ppo.rollout_steps, cfg.ppo.num_envs
        # trajectories: poses after each step (an episode's terminal pose where it ended), the
        # reset pose of the episode begun after a step that ended one, every env's pose before
        # the rollout's first step, and whether that pose began an episode (a fresh reset)
        self.positions = np.zeros((steps, envs, 2), dtype=np.float32)
        self.ends = np.zeros((steps, envs), dtype=bool)
        self.reset_positions = np.zeros((steps, envs, 2), dtype=np.float32)
        self.first_positions = np.zeros((envs, 2), dtype=np.float32)
        self.fresh = np.zeros(envs, dtype=bool)
        self.episode_start = np.zeros(envs, dtype=bool)
        self.actor_state: torch.Tensor | None = None  # a stateful actor's, per env
        self.start_state: torch.Tensor | None = None  # ... before the last rollout
        self.reward_scaling = (
            RewardScaling.new(cfg.ppo.gamma, cfg.ppo.clip_reward) if cfg.ppo.norm_reward else None
        )

    def reward_scaling_state(self) -> RewardState:
        """``reward_rms`` (the return variance) for a checkpoint when ``ppo.norm_reward`` is on."""
        scaling = self.reward_scaling
        return {} if scaling is None else {"reward_rms": scaling.rms.state()}

    def restore_reward_scaling(self, state: Mapping[str, Any]) -> None:
        """Take the return variance back from a checkpoint's ``state`` (where it has one)."""
        if self.reward_scaling is not None and "reward_rms" in state:
            self.reward_scaling.rms = RunningMeanStd.from_state(state["reward_rms"])

    def reset(self, seed: int) -> None:
        self.next_raw, _ = self.envs.reset(seed=seed)
        self.previous_raw = np.array(self.next_raw, copy=True)  # no change at a first step
        self.ep_return = np.zeros(self.ppo.num_envs)
        self.ep_length = np.zeros(self.ppo.num_envs, dtype=np.int64)
        self.fresh[:] = True
        self.actor_state = None  # every env starts an episode: zero state
        if self.reward_scaling is not None:
            self.reward_scaling.returns = None  # ... and a discounted return from zero

    def collect(
        self,
        policy: ActorCritic,
        obs_rms: RunningMeanStd,
        buf: RolloutBuffer,
        progress: Progress,
        stats: IterationStats,
        interrupted: Callable[[], bool],
    ) -> bool:
        """Fill ``buf`` with one rollout; False if it was cut short by an interrupt."""
        p, E = self.ppo, self.ppo.num_envs
        self.positions[:] = 0.0
        self.ends[:] = False
        self.reset_positions[:] = 0.0
        if self.karts:
            self.first_positions[:] = [kart.position for kart in self.karts]
        self.episode_start[:], self.fresh[:] = self.fresh, False
        if policy.carries_state and self.actor_state is None:
            self.actor_state = policy.initial_state(E)
        self.start_state = self.actor_state
        extra: dict[str, torch.Tensor] = {}
        for step in range(p.rollout_steps):
            progress.global_step += E
            if p.norm_obs:
                obs_rms.update(self.next_raw)
            obs_t = torch.from_numpy(normalize_obs(obs_rms, p, self.next_raw))
            raw_t = torch.from_numpy(np.asarray(self.next_raw, dtype=np.float32))
            if self.actor_state is not None:  # a stateful actor acts from its state
                extra = {"state": self.actor_state}
            with torch.no_grad():
                out = policy(obs_t, raw_t, **extra)
            buf.obs[step], buf.raw[step] = obs_t, raw_t
            buf.actions[step], buf.logprobs[step], buf.values[step] = (
                out.action,
                out.log_prob,
                out.value,
            )
            if buf.spikes is not None and out.input_spikes is not None:
                buf.spikes[step] = out.input_spikes.bool()
            previous = None
            if buf.previous is not None:
                previous = torch.from_numpy(normalize_obs(obs_rms, p, self.previous_raw))
                buf.previous[step] = previous
            for name, value in policy.rollout_stats(out, obs_t, previous).items():
                stats.kind.setdefault(name, []).append(value)
            current = self.next_raw
            self._step(step, out.action.numpy(), policy, obs_rms, buf, progress, stats)
            done = buf.ends[step].numpy()[:, None] > 0
            self.previous_raw = np.where(done, self.next_raw, current)
            if out.state is not None:  # an episode that ended starts the next from zero
                self.actor_state = out.state * (1.0 - buf.ends[step]).unsqueeze(-1)
            if interrupted():
                return False
        return True

    def _step(
        self,
        step: int,
        action: np.ndarray,
        policy: ActorCritic,
        obs_rms: RunningMeanStd,
        buf: RolloutBuffer,
        progress: Progress,
        stats: IterationStats,
    ) -> None:
        if not policy.discrete:
            action = np.clip(action, -1.0, 1.0)
        self.next_raw, reward, terminated, truncated, info = self.envs.step(action)
        reward = reward.astype(np.float64)
        done = terminated | truncated
        if self.cfg.run.trajectories and self.karts:
            self.positions[step] = [
                info["final_info"]["position"][i] if done[i] else kart.position
                for i, kart in enumerate(self.karts)
            ]
            self.ends[step] = done
            for i in np.flatnonzero(done):  # autoreset in the same step: already the next start
                self.reset_positions[step, i] = self.karts[i].position
        self.ep_return += reward
        self.ep_length += 1
        if self.reward_scaling is not None:  # learning sees scaled rewards, the stats raw ones
            reward = self.reward_scaling(reward, done)
        if truncated.any():
            final = self.final_values(policy, obs_rms, info["final_obs"], truncated)
            reward = reward + self.ppo.gamma * final
        buf.rewards[step] = torch.from_numpy(reward.astype(np.float32))
        buf.ends[step] = torch.from_numpy(done.astype(np.float32))
        for i in np.flatnonzero(done):
            self._episode_end(info.get("final_info", {}), i, progress, stats)

    def sequences(self, buf: RolloutBuffer) -> Sequences | None:
        """The last rollout as env sequences (a stateful actor's), else None."""
        if self.start_state is None:
            return None
        return Sequences.of(self.start_state, buf.ends)

    def trajectory(self) -> dict[str, np.ndarray]:
        """The last rollout's kart poses (px), as ``trajectories/iter_NNNNNN.npz`` stores them:
        ``positions`` and ``episode_end`` ``[steps, envs]``, ``reset_positions`` (where an
        episode ended, the next one's reset pose), ``first_positions`` (before step 0) and
        ``episode_start`` (that pose is a reset pose: the first rollout after a (re)start)."""
        return {
            "positions": self.positions,
            "episode_end": self.ends,
            "reset_positions": self.reset_positions,
            "first_positions": self.first_positions,
            "episode_start": self.episode_start,
        }

    def final_values(
        self,
        policy: ActorCritic,
        obs_rms: RunningMeanStd,
        final_obs: np.ndarray,
        truncated: np.ndarray,
    ) -> np.ndarray:
        """V(final observation) for truncated envs, 0 elsewhere (the time-limit bootstrap);
        ``final_obs``: the vector env's ``info["final_obs"]``."""
        values = np.zeros(truncated.shape[0])
        idx = np.flatnonzero(truncated)
        final = np.stack([final_obs[i] for i in idx])
        norm = normalize_obs(obs_rms, self.ppo, final)
        with torch.no_grad():
            values[idx] = policy.value(torch.from_numpy(norm)).numpy()
        return values

    def last_value(self, policy: ActorCritic, obs_rms: RunningMeanStd) -> torch.Tensor:
        """V of the observation after the rollout's last step."""
        with torch.no_grad():
            last_norm = normalize_obs(obs_rms, self.ppo, self.next_raw)
            return policy.value(torch.from_numpy(last_norm))

    def _episode_end(
        self, final: Mapping[str, np.ndarray], i: int, progress: Progress, stats: IterationStats
    ) -> None:
        """Env ``i``'s episode ended; ``final``: the vector env's ``info["final_info"]``."""
        finished = bool(final["lap_finished"][i]) if "lap_finished" in final else False
        progress.episodes += 1
        stats.returns.append(float(self.ep_return[i]))
        stats.lengths.append(int(self.ep_length[i]))
        if finished:
            stats.finishes += 1
            stats.lap_times.append(float(final["elapsed_time"][i]))
            progress.finishes += 1
            if progress.first_finish_step < 0:
                progress.first_finish_step = progress.global_step
        if "crashed" in final and bool(final["crashed"][i]):
            stats.crashes += 1
        self.ep_return[i], self.ep_length[i] = 0.0, 0

    def close(self) -> None:
        self.envs.close()
