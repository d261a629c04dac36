"""``eval.json``: what ``snnkart eval`` measured of a torch policy on seeded episodes, and the
per-episode results and summary that every evaluation (``eval.json``, ``deploy.json``, a
study's) shares. Versioned by the rule in :mod:`snnkart.contract.records`."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from snnkart.contract.records import OMIT_NONE, Record, RecordKind, omit_if
from snnkart.errors import EnvError

EVAL = RecordKind("eval", 2, rerun="snnkart eval")
"""v2 (issue 45): any gymnasium env: the kart-only keys (track, laps, crashes) are left out
for one, and the summary gains NeuroBench's ``risk`` and the env's ``reward_threshold`` with
``solved``; v1 files load without them."""
KART_ONLY = OMIT_NONE
"""Field metadata of a kart-only key: left out of the records of any other env (None)."""


def _not_kart(summary: EvalSummary) -> bool:
    return summary.crashes is None


EVAL_SCHEMA = EVAL.tag
SCHEMA_FILE = Path(__file__).with_name("eval.schema.json")


@dataclass
class EpisodeResult:
    """One seeded episode: its return, length and how it ended (``timed_out``: truncated by
    the time limit; the lap, crash and checkpoint keys only in a kart env)."""

    seed: int
    episode_return: float
    length: int
    finished: bool | None = field(metadata=KART_ONLY)
    lap_time: float | None = field(metadata=omit_if(lambda r: r.finished is None))
    crashed: bool | None = field(metadata=KART_ONLY)
    stood_still: bool | None = field(metadata=KART_ONLY)
    timed_out: bool
    checkpoints_passed: int | None = field(metadata=KART_ONLY)


@dataclass
class EvalSummary:
    """Episodes summarised: returns (mean, std over episodes, NeuroBench's risk), how they
    ended, and in a kart env the success rate (finished laps), lap times and crashes; with the
    env's ``reward_threshold``, whether the mean return reaches it (``solved``)."""

    episodes: int
    success_rate: float | None = field(metadata=KART_ONLY)
    mean_return: float
    std_return: float
    mean_lap_time: float | None = field(metadata=omit_if(_not_kart))
    best_lap_time: float | None = field(metadata=omit_if(_not_kart))
    crashes: int | None = field(metadata=KART_ONLY)
    stood_still: int | None = field(metadata=KART_ONLY)
    timeouts: int
    risk: float | None = field(default=None, metadata=OMIT_NONE)
    """NeuroBench's risk: the mean return of the worst 5 % of episodes (at least 20 episodes,
    :func:`snnkart.contract.neurobench.reward_score`)."""
    reward_threshold: float | None = field(default=None, metadata=OMIT_NONE)
    solved: bool | None = field(default=None, metadata=OMIT_NONE)

    @property
    def laps(self) -> float:
        """The share of finished laps (a kart env's; any other env has none to count)."""
        if self.success_rate is None:
            raise EnvError(_KART_ONLY.format("a finished-lap rate"))
        return self.success_rate

    @property
    def crash_count(self) -> int:
        """The crashed episodes (a kart env's)."""
        if self.crashes is None:
            raise EnvError(_KART_ONLY.format("crashes"))
        return self.crashes

    @classmethod
    def of(cls, results: list[EpisodeResult], reward_threshold: float | None = None) -> EvalSummary:
        returns = [r.episode_return for r in results]
        laps = [r.lap_time for r in results if r.lap_time is not None]
        kart = any(r.finished is not None for r in results) or not results
        mean = float(np.mean(returns)) if returns else float("nan")
        return cls(
            episodes=len(results),
            success_rate=sum(bool(r.finished) for r in results) / max(len(results), 1)
            if kart
            else None,
            mean_return=mean,
            std_return=float(np.std(returns)) if returns else float("nan"),
            mean_lap_time=statistics.fmean(laps) if laps else None,
            best_lap_time=min(laps) if laps else None,
            crashes=sum(bool(r.crashed) for r in results) if kart else None,
            stood_still=sum(bool(r.stood_still) for r in results) if kart else None,
            timeouts=sum(r.timed_out for r in results),
            risk=_risk(returns),
            reward_threshold=reward_threshold,
            solved=None if reward_threshold is None else bool(mean >= reward_threshold),
        )


def success_share(results: Sequence[EpisodeResult], reward_threshold: float | None) -> float | None:
    """The share of ``results`` that did the task: a kart env's finished laps; a gymnasium
    env's episodes whose return reaches ``reward_threshold`` (None without one: nothing
    judges the task)."""
    if any(r.finished is not None for r in results):
        return sum(bool(r.finished) for r in results) / len(results)
    if reward_threshold is None or not results:
        return None
    return sum(r.episode_return >= reward_threshold for r in results) / len(results)


_KART_ONLY = "{} is a kart env's measure; this evaluation ran on a gymnasium env (use its returns)"


def _risk(returns: list[float]) -> float | None:
    """NeuroBench's risk of these returns, None below its 20 episodes (where it is NaN)."""
    from snnkart.contract.neurobench import reward_score

    risk = reward_score(returns).risk if returns else float("nan")
    return None if math.isnan(risk) else float(risk)


@dataclass(frozen=True)
class TrackFields:
    """The track a policy ran on, how it was named, and the track it was trained on, as eval
    and deploy records state them."""

    track: str | None = field(metadata=KART_ONLY)
    track_given: str | None = field(metadata=KART_ONLY)
    track_source: str | None = field(metadata=KART_ONLY)
    # "--track", "run" (trained on), "embedded" (in the manifest), "name"
    track_sha256: str | None = field(metadata=KART_ONLY)
    trained_track: dict[str, str] | None = field(metadata=KART_ONLY)
    track_override: bool | None = field(metadata=KART_ONLY)

    @classmethod
    def none(cls) -> TrackFields:
        """Any gymnasium env's: no track."""
        return cls(None, None, None, None, None, None)


@dataclass(frozen=True)
class EvalRecord(Record, TrackFields):
    """``eval.json`` (``snnkart/eval/v2``): the track it ran on (and the one it was trained on:
    :class:`TrackFields`), the run and checkpoint evaluated, the first seed, the summary and
    every episode."""

    KIND = EVAL

    schema: str
    run: str
    checkpoint: str
    global_step: int | None
    policy: str
    env: str
    first_seed: int
    summary: EvalSummary
    episodes: list[EpisodeResult] = field(default_factory=list)
