"""``zoo-study.json``: what a zoo study (:mod:`snnkart.app.zoo_study`) trained, scored and
deployed, and its statistics over seeds (mean, std, IQM with a stratified-bootstrap interval, as
rliable computes them; the score normalised between a random policy and snnkart's ANN).
Versioned by the rule in :mod:`snnkart.contract.records`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from snnkart.contract.eval_record import EvalSummary
from snnkart.contract.records import OMIT_NONE, Record, RecordKind

ZOO_STUDY = RecordKind("zoo-study", 2, rerun="snnkart study")
"""v2: a deployed seed's ``energy`` (a v1 file loads without it)."""
SNNKART_DEFAULTS: dict[str, str | None] = {
    "key": "snnkart's defaults",
    "source": "snnkart.rl.config (the study's sets on top)",
    "note": None,
}
"""The ``zoo`` entry of a study on snnkart's own settings (``settings = "snnkart"``), where a
zoo study names the zoo's entry."""
BOOTSTRAP = 2000
"""Resamples of the runs for the IQM's interval."""


@dataclass(frozen=True)
class ZooRun:
    """One trained run and its evaluation."""

    policy: str
    seed: int
    run_dir: str
    global_step: int
    wall_s: float | None  # None: trained before a resume (the part timed is in steps_per_s)
    steps_per_s: float | None
    summary: EvalSummary


@dataclass(frozen=True)
class Sampled:
    """A sampled energy or ratio: its median and 5th-95th percentile (None: not finite)."""

    median: float | None
    p05: float | None
    p95: float | None


@dataclass(frozen=True)
class ZooEnergy:
    """A deployed seed's dynamic energy per decision on ``chip`` against the ANN of the same
    widths in int8 on ``baseline`` (both sides priced from the same profiles, every price range
    sampled together: median and 90 % interval). Static power is left out (``period_s`` is the
    control period it would be taken over)."""

    chip: str
    baseline: str
    ann: str  # the ANN's label (its widths)
    snn_pj: Sampled
    ann_pj: Sampled
    ratio: Sampled  # policy / ANN
    period_s: float


@dataclass(frozen=True)
class ZooDeploy:
    """One seed of a spiking kind exported to NIR and run closed loop on Lava's simulated
    Loihi in fixed point, every env step checked against the numpy reference."""

    policy: str
    seed: int
    deploy_dir: str
    summary: EvalSummary
    env_steps: int
    mismatched_windows: int  # bit-exact: 0
    mismatched_actions: int
    float32_identical_action_fraction: float | None  # against the torch-order float32 policy
    synops_per_env_step: float  # summed over layers (sigma-delta: synaptic events)
    ms_per_env_step: float
    energy: ZooEnergy | None = field(default=None, metadata=OMIT_NONE)  # None: a v1 file


@dataclass(frozen=True)
class PolicyScore:
    """One policy's final returns over seeds (each the mean over the evaluation episodes)."""

    policy: str
    returns: list[float]
    mean: float
    std: float  # over seeds, ddof 0
    iqm: float
    iqm_low: float  # 95 % stratified-bootstrap interval of the IQM (over seeds)
    iqm_high: float
    normalised: float | None  # (mean - random) / (ANN mean - random): 1 is the ANN; None
    # where the ANN does not beat the random policy (the scale is then undefined)
    solved_seeds: int | None  # seeds whose mean return reaches the reward threshold
    steps_per_s: float | None  # median over seeds
    wall_min: float | None  # median over seeds


@dataclass(frozen=True)
class ZooStudyRecord(Record):
    """``zoo-study.json`` (``snnkart/zoo-study/v2``)."""

    KIND = ZOO_STUDY

    schema: str
    name: str
    data: str
    env: str
    steps: int
    eval_episodes: int
    eval_seed: int
    zoo: dict[str, str | None]
    unexpressible: list[str]
    reward_threshold: float | None
    random_return: float
    runs: list[ZooRun]
    scores: list[PolicyScore]
    deployed: list[ZooDeploy]
    commit: str  # the snnkart commit the study ran at ("-dirty": with uncommitted changes)
    machine: dict[str, str]
    zoo_score: str | None = field(default=None, metadata=OMIT_NONE)
    zoo_score_source: str | None = field(default=None, metadata=OMIT_NONE)


def iqm(scores: np.ndarray) -> float:
    """The interquartile mean: the mean of the middle half (scipy's ``trim_mean(x, 0.25)``,
    which rliable uses: ``int(0.25 n)`` cut from each end)."""
    s = np.sort(np.asarray(scores, dtype=np.float64))
    cut = int(0.25 * s.size)
    return float(np.mean(s[cut : s.size - cut]))


def bootstrap_iqm(scores: list[float], seed: int = 0) -> tuple[float, float]:
    """The 95 % percentile interval of the IQM over ``BOOTSTRAP`` resamples of the runs."""
    rng = np.random.default_rng(seed)
    x = np.asarray(scores, dtype=np.float64)
    draws = [iqm(rng.choice(x, size=x.size, replace=True)) for _ in range(BOOTSTRAP)]
    low, high = np.percentile(draws, [2.5, 97.5])
    return float(low), float(high)


NORMALISER = "ann"
"""The study row whose mean return is 1 on the normalised scale (snnkart's ANN; a study role,
not a kind switch: the zoo study's rows also include Stable-Baselines3)."""


def normalisable(ann_mean: float | None, floor: float) -> bool:
    """Whether scores normalise between the random policy (0) and snnkart's ANN (1): only where
    the ANN beats the random policy; otherwise the scale is undefined (its sign flips)."""
    return ann_mean is not None and ann_mean > floor


def scores(runs: list[ZooRun], floor: float, threshold: float | None) -> list[PolicyScore]:
    """Per policy, in the order run: its returns over seeds summarised."""
    by: dict[str, list[ZooRun]] = {}
    for run in runs:
        by.setdefault(run.policy, []).append(run)
    ann = by.get(NORMALISER)
    ann_mean = float(np.mean([r.summary.mean_return for r in ann])) if ann else None
    out = []
    for policy, group in by.items():
        returns = [r.summary.mean_return for r in group]
        mean = float(np.mean(returns))
        low, high = bootstrap_iqm(returns)
        rates = [r.steps_per_s for r in group if r.steps_per_s is not None]
        walls = [r.wall_s / 60 for r in group if r.wall_s is not None]
        out.append(
            PolicyScore(
                policy=policy,
                returns=returns,
                mean=mean,
                std=float(np.std(returns)),
                iqm=iqm(np.asarray(returns)),
                iqm_low=low,
                iqm_high=high,
                normalised=(mean - floor) / (ann_mean - floor)
                if ann_mean is not None and normalisable(ann_mean, floor)
                else None,
                solved_seeds=None if threshold is None else sum(x >= threshold for x in returns),
                steps_per_s=float(np.median(rates)) if rates else None,
                wall_min=float(np.median(walls)) if walls else None,
            )
        )
    return out
