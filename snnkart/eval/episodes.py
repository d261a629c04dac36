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
        result = _result(seed + k, total, length, bool(truncated), info)
        results.append(result)
        if on_episode is not None:
            on_episode(result)
    return results


def _result(seed: int, total: float, length: int, truncated: bool, info: dict) -> EpisodeResult:
    """The episode's result; a kart env's info says how the lap went, any other env's not."""
    if "lap_finished" not in info:
        return EpisodeResult(seed, total, length, None, None, None, None, truncated, None)
    return EpisodeResult(
        seed=seed,
        episode_return=total,
        length=length,
        finished=bool(info["lap_finished"]),
        lap_time=info["lap_time"],
        crashed=bool(info["crashed"]),
        stood_still=bool(info["stood_still"]),
        timed_out=truncated,
        checkpoints_passed=int(info["checkpoint"]) + int(bool(info["lap_finished"])),
    )


def describe_returns(summary: EvalSummary) -> str:
    """Any gymnasium env's summary in words: return, NeuroBench's risk, solved or not."""
    words = f"return {summary.mean_return:.2f} +- {summary.std_return:.2f}"
    if summary.risk is not None:
        words += f", risk {summary.risk:.2f} (worst 5 %)"
    if summary.solved is not None:
        verdict = "solved" if summary.solved else "not solved"
        words += f", {verdict} (threshold {summary.reward_threshold:g})"
    return words + f", time-outs {summary.timeouts}"


__all__ = [
    "EVAL_SCHEMA",
    "EpisodeResult",
    "EvalSummary",
    "Predictor",
    "describe_returns",
    "run_episodes",
]
