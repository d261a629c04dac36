"""A study's numbers per cell: medians and spreads over seeds, and the SNN against the ANN.

A run that never reached a mark (a first finish, N finishes) counts as later than every run
that did: medians are taken with it as infinity and shown as ">cap" when they land there.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from typing import Any

from snnkart.report.study_record import CellSummary, RunRecord, Spread
from snnkart.rl import kinds

ORIGINAL = {
    # kart-simulator's headline table (one run per cell, as quoted in issue 17):
    # first finish and step at 300 finishes, ANN and SNN, and ANN steps / SNN steps to 300.
    "grid": {
        "ann_first": 141_000,
        "snn_first": 175_000,
        "ann_300": 402_000,
        "snn_300": 406_000,
        "snn_pct_of_ann": 99.0,
    },
    "gazebo": {
        "ann_first": 82_000,
        "snn_first": 22_000,
        "ann_300": 431_000,
        "snn_300": 507_000,
        "snn_pct_of_ann": 85.0,
    },
    "steer": {
        "ann_first": 156_000,
        "snn_first": 441_000,
        "ann_300": 724_000,
        "snn_300": 957_000,
        "snn_pct_of_ann": 75.7,
    },
}


def spread(values: list[float | None]) -> Spread:
    """Median, min and max over seeds; None (never reached) counts as infinity."""
    finite = [v for v in values if v is not None]
    as_inf = [math.inf if v is None else float(v) for v in values]
    median = statistics.median(as_inf) if as_inf else math.inf
    return Spread(
        median=None if math.isinf(median) else median,
        min=min(finite) if finite else None,
        max=None if len(finite) < len(values) else (max(finite) if finite else None),
        reached=len(finite),
        of=len(values),
    )


def summarise(records: list[RunRecord], study: Any) -> list[CellSummary]:
    """One entry per cell (track, env, policy, variant), with the SNN against the ANN of the
    same track, env and variant."""
    cells: dict[tuple[str, str, str, str], list[RunRecord]] = {}
    for r in records:
        cells.setdefault(r.cell, []).append(r)
    out = []
    for (track, env, policy, variant), rs in cells.items():
        spikes = [r.eval_spikes_per_step for r in rs]
        synops = [
            None if r.eval_counts_per_step is None else r.eval_counts_per_step.chip_synops
            for r in rs
        ]
        out.append(
            CellSummary(
                track=track,
                env=env,
                policy=policy,
                variant=variant,
                seeds=[r.seed for r in rs],
                first_finish_step=spread([r.first_finish_step for r in rs]),
                steps_to_finishes=spread([r.steps_to_finishes for r in rs]),
                eval_success_rate=spread([r.eval_success_rate for r in rs]),
                eval_spikes_per_step=spread(spikes) if None not in spikes else None,
                eval_synops_per_step=spread(synops) if None not in synops else None,
                train_seconds=spread([r.train_seconds for r in rs]),
                env_steps=sum(r.steps for r in rs),
            )
        )
    for i, entry in enumerate(out):
        if kinds.compared_to_baseline(entry.policy):
            ann = next(
                (
                    e
                    for e in out
                    if e.policy == kinds.BASELINE
                    and (e.track, e.env, e.variant) == (entry.track, entry.env, entry.variant)
                ),
                None,
            )
            out[i] = dataclasses.replace(entry, snn_pct_of_ann=pct_of_ann(ann, entry))
    return out


def pct_of_ann(ann: CellSummary | None, snn: CellSummary) -> float | None:
    """ANN median steps to N finishes / SNN median steps to N finishes, in %; None when either
    median did not get there."""
    if ann is None:
        return None
    a, s = ann.steps_to_finishes.median, snn.steps_to_finishes.median
    return None if a is None or s is None else 100.0 * a / s
