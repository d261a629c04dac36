"""Predictors and the episode runner shared by ``snnkart eval`` and (later) ``snnkart deploy``.

A :class:`Predictor` maps one observation to one action and can be reset between episodes;
the torch ANN, the torch SNN, the NIR reference and Lava all implement it, so every backend is
scored by the same :func:`run_episodes`.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from snnkart import faults
from snnkart.io import write_json

EVAL_SCHEMA = "snnkart/eval/v1"


class Predictor(Protocol):
    def reset(self) -> None:
        """Forget any state before a new episode."""

    def predict(self, obs: np.ndarray) -> Any:
        """The action for one observation."""


@dataclass
class EpisodeResult:
    seed: int
    episode_return: float
    length: int
    finished: bool
    lap_time: float | None
    crashed: bool
    stood_still: bool
    timed_out: bool
    checkpoints_passed: int


@dataclass
class EvalSummary:
    episodes: int
    success_rate: float
    mean_return: float
    std_return: float
    mean_lap_time: float | None
    best_lap_time: float | None
    crashes: int
    stood_still: int
    timeouts: int

    @classmethod
    def of(cls, results: list[EpisodeResult]) -> EvalSummary:
        returns = [r.episode_return for r in results]
        laps = [r.lap_time for r in results if r.lap_time is not None]
        return cls(
            episodes=len(results),
            success_rate=sum(r.finished for r in results) / max(len(results), 1),
            mean_return=float(np.mean(returns)) if returns else float("nan"),
            std_return=float(np.std(returns)) if returns else float("nan"),
            mean_lap_time=statistics.fmean(laps) if laps else None,
            best_lap_time=min(laps) if laps else None,
            crashes=sum(r.crashed for r in results),
            stood_still=sum(r.stood_still for r in results),
            timeouts=sum(r.timed_out for r in results),
        )


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


def write_eval(
    path: Path, summary: EvalSummary, results: list[EpisodeResult], extra: dict[str, Any]
) -> dict[str, Any]:
    """Write the eval record to ``path`` (atomically) and return it."""
    record = {
        "schema": EVAL_SCHEMA,
        **extra,
        "summary": asdict(summary),
        "episodes": [asdict(r) for r in results],
    }
    write_json(path, record)
    return record
