"""The page of a sigma-delta deployment's report (``kind: "sigma-delta"``,
:mod:`snnkart.app.report_sigma_delta`): the goal's answer first, then per chip the energy, the ratios'
90 % intervals against the fair ANN baselines and the what-ifs, the counts per layer and every
term. Rendered to Markdown and HTML by :mod:`snnkart.report.document`."""

from __future__ import annotations

from typing import Any

from snnkart.report import first_screen as first
from snnkart.report import plots
from snnkart.report.texts import deployment, not_driving

Block = dict[str, Any]
Section = tuple[str, list[Block]]

CAPTIONS = {
    "breakdown": "Energy per inference (log scale) and its parts: the sigma-delta policy on each "
    "chip (host work priced on the baseline it is compared with) and the same-shape ANN on "
    "the fair baselines (fp32 + SRAM, int8 + SRAM).",
}


def figures(report: dict[str, Any]) -> dict[str, bytes]:
    """The sigma-delta page's figures (the sweep's is added by the caller)."""
    energies = {
        f"SNN sigma-delta on {p['chip']} (host on {p['host_profile']})": p["breakdown_pj"]
        for p in report["pricing"]
    }
    for name, parts in report["ann"]["same_shape"]["breakdown_pj"].items():
        energies[f"ANN on {name}"] = parts
    return {"breakdown": plots.breakdown(energies, {**plots.PART_COLOURS, **plots.SD_PART_COLOURS})}


def _nj(pj: float | None) -> str:
    return "-" if pj is None else f"{pj / 1e3:.3g} nJ"


def _ratio(c: dict[str, Any]) -> str:
    r = c["ratio"]
    return (
        f"{first.times(r['median'])} (90 %: {first.times(r['p05'])}-{first.times(r['p95'])})"
        f" {'<=' if c['within'] else '>'} {c['factor']:g}x"
    )


def chip_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """Per chip: energy per inference as priced, the ratio against each baseline, the what-ifs."""
    rows = []
    for p in report["pricing"]:
        w = p["what_ifs"]
        row = {
            "chip": p["chip"],
            "updates rule": w["rule"]["value"],
            "energy / inference": _nj(p["snn_pj"]),
        }
        for c in p["intervals"]:
            row[f"vs {c['baseline']}"] = _ratio(c)
        row |= {
            "held, clocked": _nj(w["held_clocked_pj"]),
            "held, active": _nj(w["held_active_pj"]),
            "one step, clocked": _nj(w["one_step_clocked_pj"]),
        }
        rows.append(row)
    return rows


def layer_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """Per layer, per env step (measured): messages, payload bits, synaptic events, clocked and
    active updates."""
    c = report["sigma_delta"]["per_env_step"]
    sizes = [c["n_in"], *c["sizes"], c["n_out"]]
    return [
        {
            "layer": name,
            "neurons": str(n),
            "messages": f"{c['messages'][i]:.3g}",
            "payload bits": f"{c['payload_bits'][i]:.4g}",
            "synaptic events": f"{c['synaptic_events'][i]:.4g}",
            "updates clocked": f"{c['updates_clocked'][i]:.4g}",
            "updates active": f"{c['updates_active'][i]:.4g}",
        }
        for i, (name, n) in enumerate(zip(report["sigma_delta"]["layers"], sizes, strict=True))
    ]


def goal_lines(report: dict[str, Any]) -> list[str]:
    """The goal: its rule, each chip's checks, the term in the way, SANA-FE."""
    g = report["goal"]
    lines = [f"Rule: {g['rule']}."]
    for chip in [g["primary"], *g["proxies"]]:
        role = "primary" if chip is g["primary"] else "proxy"
        checks = "; ".join(
            f"vs {c['baseline']}: 95th percentile {first.times(c['ratio']['p95'])}"
            f" (needs <= {c['factor']:g}x)"
            for c in chip["checks"]
        )
        lines.append(
            f"{chip['chip']} ({role}): {'holds' if chip['holds'] else 'does not hold'}; {checks}"
        )
        if chip["in_the_way"]:
            lines.append(f"In the way: {chip['in_the_way']['text']}.")
    if g["sanafe"] is None:
        return [*lines, "SANA-FE: not run (snnkart report --sanafe)."]
    checks = "; ".join(
        f"{_nj(c['snn_pj'])} against {c['factor']:g}x the {c['baseline']} ANN's "
        f"5th percentile {_nj(c['ann_pj']['p05'])}"
        for c in g["sanafe"]["checks"]
    )
    return [
        *lines,
        f"SANA-FE's Loihi model (chip + host and link): "
        f"{'holds' if g['sanafe']['holds'] else 'does not hold'}; {checks}.",
    ]


def _deployment(report: dict[str, Any]) -> str:
    net = report["network"]
    schedule = (
        f"{net['rows']} Lava steps per env step (the held schedule), "
        f"{net['num_message_bits']}-bit messages"
    )
    baseline = report["ann"]["same_shape"]["label"]
    return f"{deployment(report, 'Sigma-delta network', schedule)} Baseline: the {baseline}."


def sections(report: dict[str, Any], figure_names: list[str]) -> list[Section]:
    """The sigma-delta page, in order; the first section (untitled) is the first screen."""
    first_screen: list[Block] = []
    if not report["drives"]:
        success = first.pct(report["task"]["success_rate"])
        first_screen.append(not_driving("the sigma-delta policy", success, report))
    first_screen.append({"kind": "p", "id": "verdict", "text": first.sd_sentence(report)})
    return [
        ("", first_screen),
        ("The goal, decided", [{"kind": "ul", "items": goal_lines(report)}]),
        (
            "Per chip: energy per inference, ratios and what-ifs",
            [
                {"kind": "table", "id": "chips", "rows": chip_rows(report)},
                {
                    "kind": "p",
                    "text": f"Intervals: {report['uncertainty']['rule']}. What-ifs: "
                    f"{report['pricing'][0]['what_ifs']['note']}.",
                },
            ],
        ),
        ("Deployment", [{"kind": "p", "text": _deployment(report)}]),
        (
            "Counts per layer, per env step (measured)",
            [{"kind": "table", "id": "layers", "rows": layer_rows(report)}],
        ),
        (
            "Ledger: every term, count x price",
            [
                {
                    "kind": "details",
                    "summary": f"sigma-delta on {p['chip']}",
                    "id": f"ledger-{k}",
                    "rows": [
                        {
                            "part": t["part"],
                            "what": t["what"],
                            "count": f"{t['count']:.4g}",
                            "price": f"{t['price_pj']:g} pJ ({t['op']})",
                            "energy": f"{t['energy_pj']:.4g} pJ",
                        }
                        for t in p["terms"]
                    ],
                }
                for k, p in enumerate(report["pricing"])
            ],
        ),
        (
            "Figures",
            [
                {"kind": "figure", "name": n, **({"caption": CAPTIONS[n]} if n in CAPTIONS else {})}
                for n in figure_names
            ],
        ),
    ]
