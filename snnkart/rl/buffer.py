"""Rollout storage and generalised advantage estimation.

A rollout fills preallocated ``[steps, envs, ...]`` tensors (CleanRL's layout); the update
reads them flattened to ``[steps * envs, ...]``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import torch


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


@dataclass
class Batch:
    """A rollout flattened for the update: ``[steps * envs, ...]``."""

    obs: torch.Tensor
    raw: torch.Tensor
    actions: torch.Tensor
    logprobs: torch.Tensor
    advantages: torch.Tensor
    returns: torch.Tensor
    values: torch.Tensor
    spikes: torch.Tensor | None  # rate encoding: the input spike trains the actor saw
    previous: torch.Tensor | None = None  # sdnn: the previous env step's normalised observation

    def shuffled(self, order: np.ndarray) -> Batch:
        """The batch in ``order``: one gather per tensor and epoch, so that minibatches are
        contiguous slices (:meth:`rows`) instead of a gather per tensor and minibatch."""
        index = torch.from_numpy(order)
        return self._map(lambda v: v[index])

    def rows(self, start: int, stop: int) -> Batch:
        return self._map(lambda v: v[start:stop])

    def _map(self, f: Callable[[torch.Tensor], torch.Tensor]) -> Batch:
        fields = {k: None if v is None else f(v) for k, v in self.__dict__.items()}
        return Batch(**fields)  # type: ignore[arg-type]


@dataclass
class RolloutBuffer:
    """One iteration's transitions, ``[steps, envs, ...]``."""

    obs: torch.Tensor  # normalised observations (the actor's and critic's input)
    raw: torch.Tensor  # raw observations (the rate encoding's input)
    actions: torch.Tensor
    logprobs: torch.Tensor
    rewards: torch.Tensor  # with the time-limit bootstrap added
    ends: torch.Tensor  # 1 where the episode ended after the step
    values: torch.Tensor
    spikes: torch.Tensor | None
    previous: torch.Tensor | None = None
    """sdnn: each step's previous observation of its episode, normalised as ``obs`` is (the
    step's own at an episode's first step: no change); the message penalty's input."""

    @classmethod
    def allocate(
        cls,
        steps: int,
        envs: int,
        obs_dim: int,
        action_shape: tuple[int, ...],
        discrete: bool,
        snn_steps: int,
        rate: bool,
        previous: bool = False,
    ) -> RolloutBuffer:
        return cls(
            obs=torch.zeros(steps, envs, obs_dim),
            raw=torch.zeros(steps, envs, obs_dim),
            actions=torch.zeros(
                (steps, envs, *action_shape), dtype=torch.long if discrete else torch.float32
            ),
            logprobs=torch.zeros(steps, envs),
            rewards=torch.zeros(steps, envs),
            ends=torch.zeros(steps, envs),
            values=torch.zeros(steps, envs),
            spikes=(
                torch.zeros(steps, envs, snn_steps, obs_dim, dtype=torch.bool) if rate else None
            ),
            previous=torch.zeros(steps, envs, obs_dim) if previous else None,
        )

    def flat(self, advantages: torch.Tensor, returns: torch.Tensor) -> Batch:
        steps, envs, obs_dim = self.obs.shape
        n = steps * envs
        return Batch(
            obs=self.obs.reshape(n, obs_dim),
            raw=self.raw.reshape(n, obs_dim),
            actions=self.actions.reshape((n, *self.actions.shape[2:])),
            logprobs=self.logprobs.reshape(-1),
            advantages=advantages.reshape(-1),
            returns=returns.reshape(-1),
            values=self.values.reshape(-1),
            spikes=(
                self.spikes.reshape(n, *self.spikes.shape[2:]).float()
                if self.spikes is not None
                else None
            ),
            previous=None if self.previous is None else self.previous.reshape(n, obs_dim),
        )


@dataclass
class Sequences:
    """A stateful actor's rollout as env sequences: its state before the rollout's first step
    ``[envs, D]`` and ``starts`` ``[steps, envs]``, 1 where an episode began at that step
    (after the episode before ended; the state is zeroed there)."""

    state0: torch.Tensor
    starts: torch.Tensor

    @classmethod
    def of(cls, state0: torch.Tensor, ends: torch.Tensor) -> Sequences:
        starts = torch.zeros_like(ends)
        starts[1:] = ends[:-1]
        return cls(state0, starts)


def minibatches(
    b: Batch, n: int, rng: np.random.Generator, seq: Sequences | None = None
) -> Iterator[tuple[Batch, dict[str, torch.Tensor]]]:
    """One epoch's ``n`` minibatches and what the policy needs beside them: shuffled rows, or
    (``seq``, a stateful actor) whole env sequences, ``envs / n`` envs each, time-major, with
    their initial state and episode starts (as recurrent PPO implementations split a rollout)."""
    if seq is None:
        batch = b.obs.shape[0]
        size = batch // n
        epoch = b.shuffled(rng.permutation(batch))
        for start in range(0, size * n, size):
            yield epoch.rows(start, start + size), {}
        return
    steps, envs = seq.starts.shape
    per = envs // n
    order = rng.permutation(envs)
    for k in range(n):
        idx = order[k * per : (k + 1) * per]
        rows = (np.arange(steps)[:, None] * envs + idx[None, :]).reshape(-1)
        index = torch.from_numpy(idx)
        yield b.shuffled(rows), {"state": seq.state0[index], "starts": seq.starts[:, index]}
