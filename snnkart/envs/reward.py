"""The terms of one step's reward, and the stand-still watch that can end an episode.

The reward of a step is the sum of its terms, in the order :func:`step_terms` writes them
(then any env-specific term, such as steer's steering penalty); ``info["reward_terms"]``
reports each under its name.
"""

from __future__ import annotations

import math

from snnkart.envs.config import RewardConfig
from snnkart.envs.constants import PIXELS_PER_METRE


def step_terms(
    rw: RewardConfig,
    *,
    progress_px: float,
    turn: float,
    passed: int,
    finished: bool,
    crashed: bool,
    stood_still: bool,
    stalled: bool = False,
    impact_m_s: float = 0.0,
) -> dict[str, float]:
    """This step's reward terms. ``progress_px``: how much nearer the next checkpoint line the
    kart came along the track; ``turn``: the rise of the cosine between its heading and the way
    there; ``passed``: checkpoints passed in order this step; ``stalled``: the kart has not come
    nearer the next checkpoint for more than ``stall_grace_steps`` (:class:`Stall`);
    ``impact_m_s``: the speed at which a crashing kart entered the step. Finishing pays no
    progress or heading for the last step."""
    return {
        "progress": 0.0 if finished else rw.progress * progress_px / PIXELS_PER_METRE,
        "heading": 0.0 if finished else rw.heading * turn,
        "checkpoint": rw.checkpoint * passed,
        "finish": rw.finish if finished else 0.0,
        "time": -rw.time,
        "wall": -(rw.wall + rw.wall_per_m_s * impact_m_s) if crashed else 0.0,
        "stand_still": -rw.stand_still if stood_still else 0.0,
        "stall": -rw.stall if stalled else 0.0,
    }


class StandStill:
    """How many steps the kart has stayed within ``radius`` (px) of one spot: hovering back
    and forth counts as standing still, and the count restarts where the kart leaves the
    circle."""

    def __init__(self, radius: float) -> None:
        self.radius = radius
        self.restart(0.0, 0.0)

    def restart(self, x: float, y: float) -> None:
        self.anchor = (x, y)
        self.steps = 0

    def update(self, x: float, y: float) -> int:
        """Count this step at ``(x, y)``; return the steps spent standing still."""
        if math.hypot(x - self.anchor[0], y - self.anchor[1]) > self.radius:
            self.restart(x, y)
        else:
            self.steps += 1
        return self.steps


class Stall:
    """Steps since the kart last came nearer the next checkpoint, along the track, than it had
    been before (by more than 1 px). Wandering, hovering and standing still all count; a new
    next checkpoint starts the count again."""

    def __init__(self) -> None:
        self.checkpoint, self.best, self.steps = -1, math.inf, 0

    def update(self, checkpoint: int, distance: float) -> int:
        """Count this step at ``distance`` (px, NaN where undefined) from ``checkpoint``."""
        if checkpoint != self.checkpoint:
            self.checkpoint, self.best, self.steps = checkpoint, distance, 0
        elif distance < self.best - 1.0:
            self.best, self.steps = distance, 0
        else:
            self.steps += 1
        return self.steps
