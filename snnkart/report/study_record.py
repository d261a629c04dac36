"""``study.json``: what ``snnkart study`` trained, evaluated and deployed, per run and per cell
(track, env, policy, variant). :mod:`snnkart.app.study_run` writes it, :mod:`snnkart.report.study_document`
renders it. Versioned by the rule in :mod:`snnkart.contract.records`; records of early v1
studies (no variants, machine, evaluation backend or early stops) still load."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from snnkart.contract.deploy_record import StepCounts
from snnkart.contract.records import OMIT_NONE, Record, RecordKind, key, omit_if
from snnkart.envs.tracks import short_name
from snnkart.rl import kinds

STUDY = RecordKind("study", 4, rerun="snnkart study")
"""v2 (issue 31): the study's data kind, and per run the evaluation's mean lap time and counts
per env step, per cell the chip's synaptic operations; v1 files load without them. v3 (issue
34): a sigma-delta run's ``sigma_delta_counts``; v2 files load without them. v4 (issue 35):
the study's ``eval_tracks`` and ``eval_track_episodes``, and per run ``held_out`` (its
evaluation on each held-out track); v3 files load without them."""
SCHEMA_FILE = Path(__file__).with_name("study.schema.json")


def study_run_sets(
    sets: list[str],
    cells: dict[str, list[str]],
    variants: dict[str, list[str]],
    run: tuple[str, str, str, str],
) -> list[str]:
    """The settings a study gives the run ``(track, env, policy, variant)``, after its kind's:
    the study's ``sets``, the cell's (``env-policy``, then ``track/env-policy``), the variant's
    (a ``POLICY:NAME`` variant only for that policy). Planning a study and reading its record
    both ask this, so a figure's kind is the settings a run trained with."""
    track, env, policy, variant = run
    cell = f"{env}-{policy}"
    variant_sets = [
        s
        for name, vs in variants.items()
        if name.rpartition(":")[2] == variant and name.rpartition(":")[0] in ("", policy)
        for s in vs
    ]
    return [
        *sets,
        *cells.get(cell, []),
        *cells.get(f"{short_name(track)}/{cell}", []),
        *variant_sets,
    ]


@dataclass(frozen=True, kw_only=True)
class StudySettings:
    """The study config as it ran (:class:`snnkart.app.study_run.StudyConfig`, validated there)."""

    schema: str
    name: str
    data: str | None = field(default=None, metadata=OMIT_NONE)
    tracks: list[str]
    envs: list[str]
    policies: list[str]
    seeds: list[int]
    steps: int
    finishes: int
    eval_episodes: int
    deploy_episodes: int = 0
    eval_seed: int = 10_000
    eval_tracks: list[str] = field(default_factory=list)
    eval_track_episodes: int = 10
    sets: list[str] = field(default_factory=list)
    cells: dict[str, list[str]] = field(default_factory=dict)
    variants: dict[str, list[str]] = field(default_factory=dict)

    def run_sets(self, track: str, env: str, policy: str, variant: str) -> list[str]:
        """The study's own settings of one run (:func:`study_run_sets`)."""
        return study_run_sets(self.sets, self.cells, self.variants, (track, env, policy, variant))

    def run_label(self, track: str, env: str, policy: str, variant: str) -> str:
        """What the run is called in figures (:func:`snnkart.rl.kinds.run_label`), from the
        settings it was trained with."""
        from snnkart.rl.config import load_config

        sets = [*kinds.CONVERSIONS[policy].sets] if policy in kinds.CONVERSIONS else []
        cfg = load_config(
            overrides={"env": env, "policy": kinds.trained_as(policy), "track": track},
            sets=[*sets, *self.run_sets(track, env, policy, variant)],
        )
        return kinds.run_label(policy, cfg)

    @property
    def variant_names(self) -> list[str]:
        """The variants' names as runs carry them (a ``POLICY:NAME`` variant is ``NAME``), in
        order, once each; one unnamed variant outside an ablation."""
        names = [name.rpartition(":")[2] for name in self.variants]
        return list(dict.fromkeys(names)) or [""]


@dataclass(frozen=True)
class Curve:
    """Per training iteration: env steps, cumulative finishes, mean episodic return (None
    while no episode ended) and wall-clock seconds."""

    steps: list[int]
    finishes: list[int]
    returns: list[float | None] = field(metadata=key("return"))
    seconds: list[float] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class HeldOut:
    """A run's evaluation on one held-out track (the study's ``eval_tracks``): the track's
    short name, the ``eval_tracks`` entry it came from (a folder is one group), and what the
    seeded episodes gave, on the run's evaluation backend."""

    track: str
    group: str
    tuning_track: bool
    """A tuning track of the results protocol (docs/results.md): tables mark its results."""
    episodes: int
    success_rate: float
    mean_return: float
    crashes: int


@dataclass(frozen=True, kw_only=True)
class RunRecord:
    """One run of a study: how it trained and how its evaluation went."""

    name: str
    track: str
    env: str
    policy: str
    variant: str = ""
    seed: int
    status: str
    steps: int
    stopped_early: bool = False
    first_finish_step: int | None
    steps_to_finishes: int | None
    training_finishes: int
    training_episodes: int
    train_seconds: float
    eval_backend: str = ""
    eval_success_rate: float
    eval_mean_return: float
    eval_crashes: int
    eval_mean_lap_time: float | None = None
    eval_stood_still: int | None = None
    eval_spikes_per_step: float | None = None
    eval_counts_per_step: StepCounts | None = None
    sigma_delta_counts: dict[str, Any] | None = field(default=None, metadata=OMIT_NONE)
    """A sigma-delta run's evaluation counts per env step: ``dataclasses.asdict`` of
    :meth:`snnkart.energy.sigma_delta_counts.SigmaDeltaCounts.of_deploy` (what ``snnkart report --sweep``
    prices with ``sd_terms``)."""
    held_out: list[HeldOut] | None = field(default=None, metadata=OMIT_NONE)
    """The run on each held-out track, in ``eval_tracks`` order (None: the study has none)."""
    curve: Curve

    @property
    def cell(self) -> tuple[str, str, str, str]:
        """(track, env, policy, variant)."""
        return (self.track, self.env, self.policy, self.variant)


@dataclass(frozen=True)
class Spread:
    """Median, min and max over a cell's seeds (None: not reached), and how many reached it."""

    median: float | None
    min: float | None
    max: float | None
    reached: int
    of: int


@dataclass(frozen=True, kw_only=True)
class CellSummary:
    """A cell's runs summarised over seeds; an SNN cell also against the ANN of its track, env
    and variant (ANN steps / SNN steps to the finishes mark, in %)."""

    track: str
    env: str
    policy: str
    variant: str = ""
    seeds: list[int]
    first_finish_step: Spread
    steps_to_finishes: Spread
    eval_success_rate: Spread
    eval_spikes_per_step: Spread | None
    eval_synops_per_step: Spread | None = None
    train_seconds: Spread
    env_steps: int
    snn_pct_of_ann: float | None = field(
        default=None, metadata=omit_if(lambda cell: not kinds.compared_to_baseline(cell.policy))
    )


@dataclass(frozen=True, kw_only=True)
class DeployedRun:
    """A cell's median-seed SNN on lava-sim, beside its reference evaluation."""

    track: str
    env: str
    variant: str = ""
    run: str
    seed: int
    backend: str
    episodes: int
    success_rate: float
    bit_exact: bool
    env_steps: int
    reference_success_rate: float
    reference_episodes: int


@dataclass(frozen=True)
class WallClock:
    train_seconds: float
    eval_seconds: float
    runs: int
    runs_reused: int
    runs_set_aside: int = 0


@dataclass(frozen=True, kw_only=True)
class StudyRecord(Record):
    """``study.json`` (``snnkart/study/v1``): the study config as run, the piece of it
    (``only``), the env revision, the training code's digest, the machine (with the commit),
    the wall clock, and every cell, deployment and run."""

    KIND = STUDY

    schema: str
    study: StudySettings
    only: list[str] | None = None
    env_revision: int
    code: str
    machine: dict[str, str | int | None] | None = field(default=None, metadata=OMIT_NONE)
    wall_clock: WallClock
    env_steps: int
    cells: list[CellSummary]
    deployed: list[DeployedRun] = field(default_factory=list)
    runs: list[RunRecord]

    def tracks(self) -> list[str]:
        """The study's tracks that have runs in this record (all, unless it is a piece)."""
        return [t for t in self.study.tracks if any(r.track == t for r in self.runs)]
