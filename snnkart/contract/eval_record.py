"""``eval.json``: what ``snnkart eval`` measured of a torch policy on seeded episodes, and the
per-episode results and summary that every evaluation (``eval.json``, ``deploy.json``, a
study's) shares. Versioned by the rule in :mod:`snnkart.contract.records`."""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from snnkart.contract.records import Record, RecordKind

EVAL = RecordKind("eval", 1, rerun="snnkart eval")
EVAL_SCHEMA = EVAL.tag
SCHEMA_FILE = Path(__file__).with_name("eval.schema.json")


@dataclass
class EpisodeResult:
    """One seeded episode: its return, length and how it ended."""

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
    """Episodes summarised: success rate, returns, lap times and how they ended."""

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


@dataclass(frozen=True)
class EvalRecord(Record):
    """``eval.json`` (``snnkart/eval/v1``): the run and checkpoint evaluated, the track it ran
    on (and the one it was trained on), the first seed, the summary and every episode."""

    KIND = EVAL

    schema: str
    run: str
    checkpoint: str
    global_step: int | None
    policy: str
    env: str
    track: str
    track_given: str
    track_source: str
    track_sha256: str
    trained_track: dict[str, str]
    track_override: bool
    first_seed: int
    summary: EvalSummary
    episodes: list[EpisodeResult] = field(default_factory=list)
