"""The records a study is made of, shared by :mod:`snnkart.app.study_run` (planning, training) and
:mod:`snnkart.app.study_eval` (evaluation): the study config and one planned run."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, field_validator

from snnkart.app.launch import RunSpec
from snnkart.app.protocol import DataKind
from snnkart.envs.tracks import short_name
from snnkart.errors import UsageError
from snnkart.rl import kinds

STUDY_SCHEMA = "snnkart/study-config/v1"


class StudyConfig(BaseModel):
    """What a study trains: every track x env x policy (a cell) for every seed."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_: str = Field(STUDY_SCHEMA, alias="schema")
    name: str = "study"
    data: DataKind = Field(description="tuning or reporting data (docs/results.md)")
    tracks: list[str] = Field(["small_S"], min_length=1, description="built-in names or files")
    envs: list[str] = Field(["grid", "gazebo", "steer"], min_length=1)
    policies: list[str] = Field(
        ["ann", "snn"],
        min_length=1,
        description="registered kinds (snnkart.rl.kinds) or conversions: "
        + kinds.study_choices_help(),
    )
    seeds: list[int] = Field([1, 2, 3, 4, 5], min_length=1)
    steps: int = Field(300_000, ge=1, description="env steps per run (the cap)")
    finishes: int = Field(300, ge=1, description="report the step at this many finishes")
    eval_episodes: int = Field(50, ge=1)
    deploy_episodes: int = Field(
        5, ge=0, description="episodes of each SNN cell's median seed on lava-sim (0: none)"
    )
    eval_seed: int = 10_000
    eval_tracks: list[str] = Field(
        default_factory=list,
        description="held-out tracks every run is also evaluated on: built-in names, track "
        "files, or folders of track files (a folder is one group, its tracks averaged)",
    )
    eval_track_episodes: int = Field(10, ge=1, description="seeded episodes per held-out track")
    sets: list[str] = Field(default_factory=list, description="KEY=VALUE for every run")
    cells: dict[str, list[str]] = Field(
        default_factory=dict,
        description='KEY=VALUE per cell: "env-policy" or "track/env-policy" -> settings',
    )
    variants: dict[str, list[str]] = Field(
        default_factory=dict,
        description="an ablation: every cell once per named variant (its KEY=VALUE settings); "
        "a name 'POLICY:NAME' applies to that policy kind's cells only",
    )

    @field_validator("envs")
    @classmethod
    def _kart_envs(cls, envs: list[str]) -> list[str]:
        from snnkart.envs.resolve import resolve_env

        for name in envs:
            if not resolve_env(name).kart:
                raise ValueError(
                    f"{name!r} is not a kart env: this study is track x env x policy on the kart "
                    f"envs (finished laps); a study of a gymnasium env is a zoo study config "
                    f'(schema = "snnkart/zoo-study-config/v1", env = "{name}", settings = '
                    '"snnkart" for snnkart\'s defaults or "zoo" for the RL Zoo\'s tuned settings; '
                    "see studies/zoo/)"
                )
        return envs

    @field_validator("policies")
    @classmethod
    def _known_policies(cls, policies: list[str]) -> list[str]:
        for name in policies:
            kinds.study_policy(name)
        return policies

    @field_validator("variants")
    @classmethod
    def _variant_names(cls, variants: dict[str, list[str]]) -> dict[str, list[str]]:
        for name in variants:
            if not re.fullmatch(r"([a-z-]+:)?[A-Za-z0-9_.]+", name):
                raise ValueError(
                    f"variant name {name!r}: use letters, digits, '_' and '.', after an "
                    "optional 'POLICY:' that restricts it to that policy kind"
                )
        return variants


@dataclass(frozen=True)
class Run:
    track: str
    env: str
    policy: str
    seed: int
    spec: RunSpec
    variant: str = ""

    @property
    def cell_label(self) -> str:
        return f"{short_name(self.track)}/{self.env}-{self.policy}"

    @property
    def label(self) -> str:
        """``TRACK/ENV-POLICY`` (``:VARIANT`` in an ablation), what ``--only`` matches."""
        return f"{self.cell_label}:{self.variant}" if self.variant else self.cell_label


def held_out_tracks(groups: list[str]) -> list[tuple[str, str]]:
    """The held-out tracks of ``eval_tracks`` entries as (group, track): a folder gives each
    of its ``*.toml`` files (sorted), anything else itself."""
    out = []
    for group in groups:
        folder = Path(group)
        if folder.is_dir():
            files = sorted(folder.glob("*.toml"))
            if not files:
                raise UsageError(f"eval_tracks: the folder {group} holds no *.toml track file")
            out += [(group, str(f)) for f in files]
        else:
            out.append((group, group))
    return out
