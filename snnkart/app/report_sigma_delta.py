"""``snnkart report`` on a sigma-delta deployment: its counts per env step priced on every chip
profile (:func:`snnkart.energy.pricing.terms`), the schedule and update-rule what-ifs, the
joint 90 % intervals against the fair ANN baselines (the same shape on ``horowitz45_fp32_sram``
and ``horowitz45_int8``) and issue 34's goal, decided (:func:`snnkart.energy.goal.decide`).

The ANN baseline has the deployed network's shape: ``n_in -> sizes -> n_out``, as the report
builds it for a LIF policy. The host work is priced on ``--host-profile`` if given, else on the
baseline it is compared with (as :func:`snnkart.energy.goal.priced_policy` does).
"""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.report_record import StateNote, deploy_section
from snnkart.energy import goal
from snnkart.energy.counts import AnnCounts
from snnkart.energy.pricing import ann_terms, breakdown, terms, total
from snnkart.energy.profiles import Profile, load_profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.energy.sigma_delta_pricing import what_ifs
from snnkart.energy.uncertainty import method

KIND = "sigma-delta"
"""``report.json``'s ``kind`` for a sigma-delta deployment (a LIF report has no ``kind``)."""
BASELINES = tuple(name for name, _ in goal.BOUNDS)
"""The fair ANN baselines, memory-inclusive: fp32 + SRAM and int8 + SRAM."""
GOAL_CHIPS = (goal.PRIMARY, *goal.PROXIES)


def same_shape_ann(counts: SigmaDeltaCounts) -> AnnCounts:
    """The ANN with the deployed network's shape (its layers as ReLU MACs)."""
    widths = (counts.n_in, *counts.sizes, counts.n_out)
    return AnnCounts(
        widths, counts.action_mode, f"ANN {'-'.join(map(str, counts.sizes))} (same shape)"
    )


def layer_names(counts: SigmaDeltaCounts) -> list[str]:
    """Names of the per-layer counts: the input Delta, each SigmaDelta, the readout Sigma."""
    return [
        "input Delta (host)",
        *(f"SigmaDelta {i + 1}" for i in range(counts.depth)),
        "readout Sigma",
    ]


def _interval(p: goal.Priced, factor: float) -> dict[str, Any]:
    c = goal.check(p, factor)
    return {
        "baseline": p.baseline,
        "factor": factor,
        "ratio": c["ratio"],
        "snn_pj": c["snn_pj"],
        "ann_pj": c["ann_pj"],
        "within": c["holds"],
    }


def chip_pricing(
    counts: SigmaDeltaCounts, chip: Profile, baselines: list[Profile], host: Profile | None
) -> dict[str, Any]:
    """One chip: the terms (host work on ``host``, else on the first baseline), the what-ifs and
    the joint 90 % interval of the ratio against each baseline."""
    on = host or baselines[0]
    priced = terms(counts, chip, on)
    ann = same_shape_ann(counts)
    factors = dict(goal.BOUNDS)
    return {
        "chip": chip.name,
        "host_profile": on.name,
        "snn_pj": total(priced),
        "breakdown_pj": breakdown(priced),
        "terms": [t.as_dict() for t in priced],
        "what_ifs": what_ifs(counts, chip, on),
        "intervals": [
            _interval(goal.priced_policy(counts, chip, b, ann), factors[b.name]) for b in baselines
        ],
    }


def decide_goal(
    counts: SigmaDeltaCounts, sanafe_pj: dict[str, float] | None = None
) -> dict[str, Any]:
    """The goal's decision on loihi2 (loihi1 named as a proxy), against both baselines."""
    ann = same_shape_ann(counts)
    priced = [
        goal.priced_policy(counts, load_profile(c), load_profile(b), ann)
        for c in GOAL_CHIPS
        for b in BASELINES
    ]
    return goal.decide(priced, sanafe_pj)


def _sanafe(
    record: DeployRecord, counts: SigmaDeltaCounts, sanafe: bool
) -> tuple[dict[str, Any], dict[str, float] | None]:
    """The report's ``sanafe`` section and SANA-FE's energies (None unless ``sanafe``)."""
    if sanafe:
        from snnkart.app.sanafe_sigma_delta_report import sanafe_sd

        return sanafe_sd(record, counts, list(BASELINES))
    reason = "not asked for: run snnkart report with --sanafe (needs the sanafe extra)"
    return {"available": False, "reason": reason}, None


def _network(counts: SigmaDeltaCounts) -> dict[str, Any]:
    """The report's ``network``: the deployed shape, its rows and its message bits."""
    return {
        "n_in": counts.n_in,
        "sizes": list(counts.sizes),
        "n_out": counts.n_out,
        "rows": counts.rows,
        "num_message_bits": counts.num_message_bits,
        "input_bits": counts.input_bits,
        "action_mode": counts.action_mode,
    }


def _sigma_delta(counts: SigmaDeltaCounts) -> dict[str, Any]:
    """The report's ``sigma_delta``: the layers' names, the counts per env step, link and host."""
    return {
        "layers": layer_names(counts),
        "per_env_step": asdict(counts),
        "link_bits": list(counts.link_bits()),
        "host_ops": [vars(op) for op in counts.host()],
    }


def sd_report(
    record: DeployRecord,
    deploy_dir: Path,
    chips: list[Profile],
    host: Profile | None,
    success: tuple[float | None, bool | None],
    period_s: float,
    sanafe: bool = False,
) -> dict[str, Any]:
    """A sigma-delta deployment's report (module docstring), without the schema tag and the
    sweep (the caller adds them); ``success``: the task's success rate and whether it passes
    (both None: nothing to judge); ``period_s``: the control period. With ``sanafe``,
    SANA-FE's replay and its check of the goal."""
    counts = replace(SigmaDeltaCounts.of_deploy(record), period_s=period_s)
    rate, drives = success
    section, sanafe_pj = _sanafe(record, counts, sanafe)
    baselines = [load_profile(b) for b in BASELINES]
    ann = same_shape_ann(counts)
    s = record.summary
    steps = counts.env_steps / max(s.episodes, 1)
    return {
        "kind": KIND,
        "deploy": deploy_section(
            record, deploy_dir, record.summary.episodes, record.counts.env_steps
        ),
        "drives": drives,
        "network": _network(counts),
        "task": {
            "success_rate": rate,
            "mean_lap_time": s.mean_lap_time,
            "mean_return": s.mean_return,
            "episodes": s.episodes,
            "steps_per_episode": steps,
        },
        "sigma_delta": _sigma_delta(counts),
        "ann": {
            "same_shape": {
                "label": ann.label,
                "widths": list(ann.widths),
                "macs": ann.macs,
                "breakdown_pj": {b.name: breakdown(ann_terms(ann, b)) for b in baselines},
            }
        },
        "host_profile": host.name if host else "the baseline it is compared with",
        "profiles": {p.name: p.describe() for p in [*chips, *baselines, *([host] if host else [])]},
        "pricing": [chip_pricing(counts, c, baselines, host) for c in chips],
        "goal": decide_goal(counts, sanafe_pj),
        "uncertainty": method(),
        "sanafe": section,
    }


STATEFUL = (
    "membranes persist: the LIF state carries across env steps (manifest state_persists), "
    "zeroed only at an episode's start, so an action depends on the episode so far; each env "
    "step still runs T + L Lava steps, and the L fill/drain steps are priced with the T (they "
    "change the membranes the next env step starts from: the policy's computation, not a "
    "pipeline's idle steps)"
)
"""What the report says of a stateful LIF deployment (docs/stateful.md)."""


def stateful_note(record: DeployRecord) -> StateNote | None:
    """``{"state_persists": True, "note": ...}`` for a stateful LIF deployment (read from the
    manifest beside its NIR file), else None (a LIF report without a ``state`` key)."""
    from snnkart.contract.manifest import Manifest, manifest_path

    path = manifest_path(Path(record.nir_file))
    if not path.is_file() or not Manifest.read(path).state_persists:
        return None
    return {"state_persists": True, "rows_per_env_step": "T + L", "note": STATEFUL}
