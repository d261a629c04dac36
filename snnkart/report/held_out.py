"""The held-out table of ``study.md``: every cell's success on the study's ``eval_tracks``
beside its own evaluation, for the question "does what was learnt carry to tracks not trained
on?". A folder of tracks is one column, each run's success averaged over its tracks."""

from __future__ import annotations

import statistics
from pathlib import Path

from snnkart.envs.tracks import short_name
from snnkart.report.study_record import HeldOut, RunRecord, StudyRecord


def group_label(group: str, tracks: list[HeldOut]) -> str:
    """A column's name: a folder's name with its count of tracks, or the track's short name;
    marked † when its tracks are tuning tracks."""
    name = f"{Path(group).name} ({len(tracks)} tracks)" if len(tracks) > 1 else tracks[0].track
    return f"{name} †" if any(h.tuning_track for h in tracks) else name


def run_success(run: RunRecord, group: str) -> float:
    """A run's success on a group: the mean over the group's tracks."""
    rates = [h.success_rate for h in run.held_out or [] if h.group == group]
    return sum(rates) / len(rates)


def _spread(values: list[float]) -> str:
    median = statistics.median(values)
    if len(values) == 1:
        return f"{100 * median:.0f} %"
    return f"{100 * median:.0f} % ({100 * min(values):.0f}–{100 * max(values):.0f})"


def held_out_lines(record: StudyRecord) -> list[str]:
    """The section (empty when the study has no held-out tracks)."""
    runs = [r for r in record.runs if r.held_out]
    if not runs:
        return []
    study = record.study
    groups = list(dict.fromkeys(h.group for h in runs[0].held_out or []))
    labels = [group_label(g, [h for h in runs[0].held_out or [] if h.group == g]) for g in groups]
    lines = [
        "## Held-out tracks",
        "",
        f"Success on the study's evaluation tracks: {study.eval_track_episodes} seeded "
        "episodes per track on each run's evaluation backend (a run trained on one of them "
        "meets its own track there); a folder's column is each run's mean over its tracks. "
        '"own track" is the run\'s evaluation on its training track '
        f"({study.eval_episodes} episodes; for `random`, tracks drawn from the evaluation "
        "seeds, never a reporting track). Medians over seeds with (min–max). † marks a tuning "
        "track (docs/results.md).",
        "",
        "| trained on | env | policy | own track | " + " | ".join(labels) + " |",
        "|---|---|---|---|" + "---|" * len(labels),
    ]
    cells: dict[tuple[str, str, str, str], list[RunRecord]] = {}
    for r in runs:
        cells.setdefault(r.cell, []).append(r)
    for (track, env, policy, variant), rs in cells.items():
        kind = f"{policy} · {variant}" if variant else policy
        own = _spread([r.eval_success_rate for r in rs])
        columns = [_spread([run_success(r, g) for r in rs]) for g in groups]
        lines.append(
            f"| {short_name(track)} | {env} | {kind} | {own} | " + " | ".join(columns) + " |"
        )
    return [*lines, ""]
