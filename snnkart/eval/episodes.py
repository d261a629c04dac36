"""Predictors and the episode runner shared by ``snnkart eval`` and (later) ``snnkart deploy``.

A :class:`Predictor` maps one observation to one action and can be reset between episodes;
the torch ANN, the torch SNN, the NIR reference and Lava all implement it, so every backend is
scored by the same :func:`run_episodes`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from snnkart import faults
from snnkart.contract.eval_record import EVAL_SCHEMA, EpisodeResult, EvalSummary


class Predictor(Protocol):
    def reset(self) -> None:
        """Forget any state before a new episode."""

    def predict(self, obs: np.ndarray) -> Any:
        """The action for one observation."""


def run_episodes(
    env: Any,
    predictor: Predictor,
    episodes: int,
    seed: int = 0,
    on_step: Callable[[Any], None] | None = None,
    on_episode: Callable[[EpisodeResult], None] | None = None,
) -> list[EpisodeResult]:
    """Run ``episodes`` episodes with seeds ``seed, seed+1, ...``; ``env`` is a gymnasium env."""
    results = []
    for k in range(episodes):
        predictor.reset()
        obs, info = env.reset(seed=seed + k)
        total, length = 0.0, 0
        while True:
            obs, reward, terminated, truncated, info = env.step(predictor.predict(obs))
            total += float(reward)
            length += 1
            if on_step is not None:
                on_step(env)
            faults.check()  # Ctrl-C/SIGTERM inside faults.caught() is taken here
            if terminated or truncated:
                break
        result = EpisodeResult(
            seed=seed + k,
            episode_return=total,
            length=length,
            finished=bool(info["lap_finished"]),
            lap_time=info["lap_time"],
            crashed=bool(info["crashed"]),
            stood_still=bool(info["stood_still"]),
            timed_out=bool(truncated),
            checkpoints_passed=int(info["checkpoint"]) + int(bool(info["lap_finished"])),
        )
        results.append(result)
        if on_episode is not None:
            on_episode(result)
    return results


__all__ = ["EVAL_SCHEMA", "EpisodeResult", "EvalSummary", "Predictor", "run_episodes"]
