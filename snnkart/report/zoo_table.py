"""A zoo study's table (``zoo-study.md`` and docs/zoo.md), rendered from its records alone."""

from __future__ import annotations

from typing import Any

from snnkart.report.zoo_record import NORMALISER, SNNKART_DEFAULTS, normalisable

LABELS = {
    "ann": "snnkart ANN",
    "snn": "snnkart SNN (LIF)",
    "sdnn": "snnkart sigma-delta",
    "sb3": "Stable-Baselines3 PPO",
}


def _opt(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def zoo_markdown(records: list[Any]) -> str:
    """One table per task: every policy's final return over seeds (each seed's mean over the
    evaluation episodes), IQM with its bootstrap interval, solved seeds, the score normalised
    between a random policy (0) and snnkart's ANN (1), training speed and wall time."""
    parts = []
    for r in records:
        seeds = sorted({run.seed for run in r.runs})
        head = (
            f"### {r.env}\n\n{r.name}: {r.data} data, seeds {seeds[0]}-{seeds[-1]} "
            f"({len(seeds)}), {r.steps:,} env steps each, scored on {r.eval_episodes} episodes "
            f"(seeds {r.eval_seed}+, deterministic) at commit {r.commit}. "
        )
        own = r.zoo == SNNKART_DEFAULTS
        head += f"PPO settings: {r.zoo['key']}" if own else f"RL Zoo settings: `{r.zoo['key']}`"
        if r.zoo.get("note"):
            head += f" ({r.zoo['note']})"
        head += f". Random policy: {r.random_return:.1f}."
        ann = next((s for s in r.scores if s.policy == NORMALISER), None)
        flat = ann is not None and not normalisable(ann.mean, r.random_return)
        if flat:
            head += " snnkart's ANN does not beat it, so no score is normalised (its scale is undefined)."
        if r.reward_threshold is not None:
            head += f" Solved: mean return >= {r.reward_threshold:g}."
        if r.zoo_score:
            head += f" The zoo's published score (context, not the baseline): {r.zoo_score}."
        rows = [
            "| policy | return (mean +- std over seeds) | IQM [95 % CI] | solved seeds | "
            "normalised (ANN = 1) | steps/s | wall (min) |",
            "|---|---|---|---|---|---|---|",
        ]
        for s in r.scores:
            solved = "-" if s.solved_seeds is None else f"{s.solved_seeds}/{len(s.returns)}"
            rows.append(
                f"| {LABELS.get(s.policy, s.policy)} | {s.mean:.1f} +- {s.std:.1f} | "
                f"{s.iqm:.1f} [{s.iqm_low:.1f}, {s.iqm_high:.1f}] | {solved} | "
                f"{_opt(None if flat else s.normalised, '.2f')} | {_opt(s.steps_per_s, ',.0f')} | "
                f"{_opt(s.wall_min, '.1f')} |"
            )
        deployed = [_deployed_line(d) for d in r.deployed]
        notes = [*deployed, *(f"- snnkart cannot express: {u}" for u in r.unexpressible)]
        parts.append("\n".join([head, "", *rows, "", *notes]).rstrip() + "\n")
    return "\n".join(parts)


def _deployed_line(d: Any) -> str:
    """One deployed seed: its return, parity, agreement with float32 torch, synaptic ops."""
    agree = d.float32_identical_action_fraction
    agreement = "" if agree is None else f", {agree:.1%} of actions as the float32 policy's"
    return (
        f"- {LABELS.get(d.policy, d.policy)}, seed {d.seed}, on lava-sim fixed "
        f"({d.summary.episodes} episodes): return {d.summary.mean_return:.1f}, "
        f"{d.mismatched_windows} of {d.env_steps} env steps differ from the numpy reference "
        f"(bit-exact: 0){agreement}, {d.synops_per_env_step:,.0f} synaptic operations per env "
        f"step{_energy(d.energy)}"
    )


def _g(x: float | None, scale: float = 1.0) -> str:
    return "-" if x is None else f"{x / scale:.3g}"


def _energy(e: Any) -> str:
    """A deployed seed's energy per decision against the same-width int8 ANN (a v1 record has
    none)."""
    if e is None:
        return ""
    s, a, r = e.snn_pj, e.ann_pj, e.ratio
    return (
        f"; dynamic energy per decision on {e.chip} {_g(s.median, 1e3)} nJ "
        f"[{_g(s.p05, 1e3)}, {_g(s.p95, 1e3)}] against {_g(a.median, 1e3)} nJ "
        f"[{_g(a.p05, 1e3)}, {_g(a.p95, 1e3)}] for the {e.ann} on {e.baseline}: "
        f"{_g(r.median)}x [{_g(r.p05)}, {_g(r.p95)}] (medians and 90 % intervals, every price "
        f"range sampled together; static power over the {1e3 * e.period_s:.3g} ms control "
        "period left out)"
    )
