"""Sim-to-real imperfections of the robot: LIDAR noise, beam dropout and actuation delay.

Off by default (``env_config.sim2real`` unset): then nothing here draws a random number, so
an env without them is bit for bit what it was. With them, the noise and dropout come from the
env's own generator (seeded by ``reset(seed=...)``), and the delay holds each action back for
``action_delay_steps`` steps, the robot doing nothing (``IDLE_ACTION``, or a zero command) at
the start of an episode.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from snnkart.envs.config import Sim2RealConfig
from snnkart.envs.constants import PIXELS_PER_METRE


class Sim2Real:
    def __init__(self, cfg: Sim2RealConfig | None, action_space: Any, idle_action: int) -> None:
        self.cfg = cfg or Sim2RealConfig()
        shape = getattr(action_space, "shape", None)
        self.idle: Any = idle_action if not shape else np.zeros(shape, dtype=np.float32)
        self.queue: deque[Any] = deque()

    def reset(self) -> None:
        self.queue = deque([self.idle] * self.cfg.action_delay_steps)

    def act(self, action: Any) -> Any:
        """The action that takes effect this step."""
        if not self.cfg.action_delay_steps:
            return action
        self.queue.append(action)
        return self.queue.popleft()

    def sense(self, lidar: np.ndarray, range_px: float, rng: np.random.Generator) -> None:
        """Noise and dropout on the normalised ray distances, in place."""
        if self.cfg.lidar_noise_m > 0:
            sigma = self.cfg.lidar_noise_m * PIXELS_PER_METRE / range_px
            lidar += rng.normal(0.0, sigma, lidar.shape)
            np.clip(lidar, 0.0, 1.0, out=lidar)
        if self.cfg.beam_dropout > 0:
            lidar[rng.random(lidar.shape) < self.cfg.beam_dropout] = 1.0
