"""Running observation normalisation: mean and variance kept while training, frozen with the
checkpoint (stored as plain tensors, see :meth:`RunningMeanStd.state`) and applied the way the
deployment contract does (:func:`snnkart.contract.encoding.normalise`); and the training
rewards' scaling (:class:`RewardScaling`), which a deployed policy never sees."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from snnkart.contract import encoding


@dataclass
class RunningMeanStd:
    """Running mean and variance of observations (parallel algorithm, float64)."""

    mean: np.ndarray
    var: np.ndarray
    count: float = 1e-4

    @classmethod
    def zeros(cls, dim: int) -> RunningMeanStd:
        return cls(np.zeros(dim), np.ones(dim))

    def update(self, batch: np.ndarray) -> None:
        b_mean, b_var, b_count = batch.mean(0), batch.var(0), batch.shape[0]
        delta = b_mean - self.mean
        total = self.count + b_count
        self.mean = self.mean + delta * b_count / total
        m2 = self.var * self.count + b_var * b_count + delta**2 * self.count * b_count / total
        self.var = m2 / total
        self.count = total

    def normalize(self, obs: np.ndarray, clip: float) -> np.ndarray:
        return encoding.normalise(obs, self.mean, encoding.obs_std(self.var), clip)

    def state(self) -> dict[str, torch.Tensor]:
        return {
            "mean": torch.as_tensor(self.mean),
            "var": torch.as_tensor(self.var),
            "count": torch.tensor(self.count, dtype=torch.float64),
        }

    @classmethod
    def from_state(cls, state: dict[str, torch.Tensor]) -> RunningMeanStd:
        return cls(state["mean"].numpy().copy(), state["var"].numpy().copy(), float(state["count"]))


@dataclass
class RewardScaling:
    """Stable-Baselines3's ``VecNormalize`` reward normalisation (``norm_reward``): every env
    keeps its discounted return ``R = gamma R + r`` (0 again after an episode ends), a running
    variance of those returns is updated each step, and the reward used for learning is
    ``clip(r / sqrt(var + 1e-8), +-clip)``. Values and advantages are then in these units."""

    gamma: float
    clip: float
    rms: RunningMeanStd
    returns: np.ndarray | None = None

    @classmethod
    def new(cls, gamma: float, clip: float) -> RewardScaling:
        return cls(gamma, clip, RunningMeanStd(np.zeros(()), np.ones(())))

    def __call__(self, reward: np.ndarray, done: np.ndarray) -> np.ndarray:
        """The scaled rewards of one vector step (``reward``, ``done``: one per env)."""
        if self.returns is None or self.returns.shape != reward.shape:
            self.returns = np.zeros_like(reward, dtype=np.float64)
        self.returns = self.returns * self.gamma + reward
        self.rms.update(self.returns)
        scaled = np.clip(reward / np.sqrt(self.rms.var + encoding.OBS_EPS), -self.clip, self.clip)
        self.returns[done] = 0.0
        return np.asarray(scaled, dtype=np.float64)
