"""Write a built report: ``report.json``, ``report.md`` and one self-contained ``report.html``
(figures embedded as PNG data, no script or style fetched from anywhere)."""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from snnkart.contract.report_record import DeploySection, LifReport, lif_report
from snnkart.io import write_bytes, write_json, write_text
from snnkart.report import first_screen as first
from snnkart.report import sigma_delta_document as sd
from snnkart.report.document_figures import figures
from snnkart.report.ledger import ledger, price_rows
from snnkart.report.sanafe_page import TITLE as SANAFE_TITLE
from snnkart.report.sanafe_page import sanafe_lines, sanafe_rows
from snnkart.report.texts import (
    INCLUDES,
    LEAVES_OUT,
    REFERENCES,
    deployment,
    not_driving,
)

Block = dict[str, Any]
"""One piece of a section: ``{"kind": "p" | "warn" | "ul" | "table" | "details" | "figure", ...}``,
rendered alike to Markdown and to HTML."""
Section = tuple[str, list[Block]]


def _nj(pj: float) -> str:
    return f"{pj / 1000:.3g}"


def _uj(pj: float | None) -> str:
    return "-" if pj is None else f"{pj / 1e6:.3g}"


def _parity(deploy: DeploySection) -> str:
    """How the deployment's counts were cross-checked (deploy.json's parity)."""
    p = deploy.get("parity") or {}
    ref = p.get("same_arithmetic_reference")
    if not ref:
        return "The counts are the reference's own."
    return (
        f"Every env step's spike raster was checked against the {ref} reference: "
        f"{p.get('same_arithmetic_mismatched_windows')} of {p.get('env_steps')} differ."
    )


def headline(data: Mapping[str, object]) -> list[dict[str, str]]:
    """The energy table's rows: each SNN profile against each ANN on each digital profile,
    with both tasks; same-width ANN rows equal to the ANN run's are merged into them (a LIF
    report: ``report.json`` as read, or as built)."""
    report = lif_report(data)
    snn_task = report["snn"]["task"]
    rows = []
    for c in first.distinct(report):
        rows.append(
            {
                "SNN on": c["snn_profile"],
                "SNN nJ/inference": _nj(c["snn_pj"]),
                "ANN": report["ann"][c["ann"]]["label"],
                "ANN on": c["ann_profile"],
                "ANN nJ/inference": _nj(c["ann_pj"]),
                "SNN/ANN": f"{c['ratio']:.3g}" if c["ratio"] is not None else "-",
                "SNN µJ/episode": f"{c['snn_per_episode_pj'] / 1e6:.3g}",
                "ANN µJ/episode": _uj(c["ann_per_episode_pj"]),
                "SNN µJ/return": _uj(c["snn_per_return_pj"]),
                "ANN µJ/return": _uj(c["ann_per_return_pj"]),
                "SNN success": first.pct(snn_task["success_rate"]),
                "ANN success": first.ann_success(report, c),
            }
        )
    return rows


def _int8(report: LifReport) -> str:
    """What the int8 ANN did on the deployment's episodes, if it was run."""
    run = report["ann"].get("run")
    task = run["task"] if run else None
    q = task.get("int8") if task else None
    if not q:
        return ""
    agree = q["action_agreement"]
    return (
        f" The ANN run quantised to int8 (post-training, symmetric per tensor, calibrated "
        f"on {q['calibration']['observations']} observations of {q['calibration']['episodes']} "
        f"other episodes) was driven on the same episodes: success {first.pct(q['success_rate'])} "
        f"(measured), mean return {q['mean_return']:.2f}, "
        f"{'-' if agree is None else f'{agree:.1%}'} of its actions equal the float "
        "ANN's; the int8 profiles' rows carry its task."
    )


def _counts_rows(report: LifReport) -> list[dict[str, str]]:
    """Per layer: the policy's counts, the pipeline's fill/drain counts, and the neuron updates
    priced (both)."""
    per, sizes = report["snn"]["per_inference"], report["network"]["sizes"]
    extra = per["pipeline_overhead"]
    return [
        {
            "layer": f"{i + 1} ({n})",
            "spikes / inference": f"{per['spikes'][i]:.1f}",
            "firing rate": f"{100 * per['firing_rates'][i]:.1f} %",
            "synaptic ops (chip)": f"{per['synops_chip'][i]:.0f}",
            "neuron updates": f"{per['neuron_updates'][i]:.0f}",
            "fill/drain spikes": f"{extra['spikes'][i]:.2f}",
            "fill/drain synaptic ops": f"{extra['synops_chip'][i]:.0f}",
            "fill/drain neuron updates": f"{extra['neuron_updates'][i]:.0f}",
            "neuron updates priced": f"{per['neuron_updates'][i] + extra['neuron_updates'][i]:.0f}",
        }
        for i, n in enumerate(sizes)
    ]


FACT_GROUPS = (
    ("deployed", "as deployed, per inference"),
    ("neurobench", "NeuroBench (first layer fed at every step)"),
    ("footprint", "footprint"),
    ("latency", "latency"),
)
FACT_NAMES = {
    "parameters": "weights and biases",
    "parameter_bytes_fp32": "weight and bias bytes (fp32)",
    "host_macs": "host MACs",
    "effective_macs": "effective MACs",
    "effective_acs": "effective ACs",
    "ms_per_env_step": "ms per env step",
}


def _num(value: Any) -> str:
    """A count with thousands separators; any other number to 3 significant digits."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    if float(value).is_integer():
        return f"{int(value):,}"
    return f"{value:,.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def _facts_rows(report: LifReport) -> list[dict[str, str]]:
    """The SNN's deployed counts, NeuroBench's metrics, footprint and latency, one per row."""
    snn = report["snn"]
    facts: dict[str, Mapping[str, object]] = {
        "deployed": snn["deployed"],
        "neurobench": snn["neurobench"],
        "footprint": snn["footprint"],
        "latency": snn["latency"],
    }
    return [
        {"": group, "quantity": FACT_NAMES.get(key, key.replace("_", " ")), "value": _num(value)}
        for section, group in FACT_GROUPS
        for key, value in facts[section].items()
    ]


def _density(d: float) -> str:
    """A multiple of today's spikes, readable however small (0.0031x, not 0.00x)."""
    return f"{d:.2f}x" if d >= 0.1 else f"{d:.2g}x"


def _verdict(report: LifReport) -> list[str]:
    """One line per neuromorphic profile: the SNN's energy as a multiple of the primary ANN's on
    each digital profile, and the break-even spike density where there is one."""
    key = first.primary(report)
    label = report["ann"][key]["label"]
    lines = []
    for chip in dict.fromkeys(c["snn_profile"] for c in report["comparisons"]):
        parts = []
        for c in report["comparisons"]:
            if c["ann"] != key or c["snn_profile"] != chip or c["ratio"] is None:
                continue
            be = c["break_even"]
            density = be.get("density")
            if density is not None:
                note = f"wins below {_density(density)} today's spikes"
            elif be["fixed_pj"] >= be["ann_pj"]:
                note = "cannot win at any spike rate"
            else:  # its energy does not grow with its spikes and is below the ANN's
                note = "wins at any spike rate"
            parts.append(f"{first.times(c['ratio'])} the {label} on {c['ann_profile']} ({note})")
        lines.append(f"SNN on {chip}: " + "; ".join(parts) + ".")
    return lines


CAPTIONS = {
    "verdict": "Energy per inference, dynamic only: the SNN on each chip (its host work priced "
    "on the target) against the ANN on each digital target; each profile with the evidence "
    "grades of its prices.",
    "firing_rates": "Firing rate per layer over the deployed episodes.",
    "breakdown": "Energy per inference (log scale) and its parts, the SNN's host work priced on "
    "the first memory-inclusive target.",
    "sensitivity": "Secondary: the SNN/ANN ratio as one price at a time moves, and against "
    "spike density (the joint interval is the verdict's).",
    "tradeoff": "Accuracy against energy over a committed sparsity sweep (T, penalty, width): "
    "that study's runs, not this deployment.",
    "raster": "Spike raster and membrane traces of every layer for one env step, traced on the "
    "float32 reference of the deployed policy.",
}

REPORT_FILES = ("report.json", "report.md", "report.html", *(f"{name}.png" for name in CAPTIONS))
"""Every file :func:`write_report` may write."""


def _first_section(report: LifReport) -> list[Block]:
    """What the first screen holds: a warning if the SNN does not drive, the verdict sentence
    and its chart."""
    blocks: list[Block] = []
    if not report["drives"]:
        success = first.pct(report["snn"]["task"]["success_rate"])
        blocks.append(not_driving("the spiking policy", success, report))
    blocks.append({"kind": "p", "id": "verdict", "text": first.sentence(report)})
    blocks.append({"kind": "figure", "name": "verdict"})
    return blocks


def _deployment(report: LifReport) -> str:
    steps = report["network"]["num_steps"]
    return (
        f"{deployment(report, 'Network', f'T = {steps}')} "
        f"{_parity(report['deploy'])}{_int8(report)}"
        + (f" Stateful: {report['state']['note']}." if report.get("state") else "")
    )


def _pairs_section(report: LifReport) -> Section:
    """The verdict per pair: its table, what dynamic and static mean, and one line per chip."""
    return (
        "Verdict per pair",
        [
            {"kind": "table", "id": "pairs", "rows": first.pair_rows(report)},
            {
                "kind": "p",
                "text": f"Dynamic: the chip's and the host's operations only. With "
                "static: plus each side's published static power over the control period "
                f"({first.pairs(report)[0]['static']['note']}). Intervals: "
                f"{report['uncertainty']['rule']}.",
            },
            {"kind": "ul", "items": _verdict(report)},
        ],
    )


def sections(data: Mapping[str, object], figure_names: list[str]) -> list[Section]:
    """The page, in order (of either family's report); the first section (untitled) is the
    first screen."""
    if data.get("kind") == "sigma-delta":
        return sd.sections(dict(data), figure_names)
    report = lif_report(data)
    merged = first.merged_note(report)
    return [
        ("", _first_section(report)),
        _pairs_section(report),
        ("Deployment", [{"kind": "p", "text": _deployment(report)}]),
        (
            "Energy per inference and per episode, with the task",
            [
                {"kind": "table", "id": "headline", "rows": headline(report)},
                *([{"kind": "p", "text": merged}] if merged else []),
            ],
        ),
        (
            "Counts per inference (measured)",
            [{"kind": "table", "id": "counts", "rows": _counts_rows(report)}],
        ),
        (
            "Totals, footprint and latency",
            [{"kind": "table", "id": "facts", "rows": _facts_rows(report)}],
        ),
        (
            "Prices",
            [
                {
                    "kind": "details",
                    "summary": "Every price used: value, range, evidence tag, source",
                    "id": "prices",
                    "rows": price_rows(report),
                }
            ],
        ),
        (
            "Ledger: every term, count x price",
            [
                {"kind": "details", "summary": title, "id": f"ledger-{k}", "rows": rows}
                for k, (title, rows) in enumerate(ledger(report))
            ],
        ),
        ("Figures", [{"kind": "figure", "name": n} for n in figure_names if n != "verdict"]),
        (
            SANAFE_TITLE,
            [
                {"kind": "ul", "items": sanafe_lines(report)},
                {"kind": "table", "id": "sanafe", "rows": sanafe_rows(report)},
            ],
        ),
        ("What the estimate includes", [{"kind": "ul", "items": list(INCLUDES)}]),
        ("What it leaves out", [{"kind": "ul", "items": list(LEAVES_OUT)}]),
        ("References", [{"kind": "ul", "items": list(REFERENCES)}]),
    ]


def md_table(rows: list[dict[str, str]]) -> str:
    """``rows`` as a Markdown table (empty without rows)."""
    if not rows:
        return ""
    head = list(rows[0])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(r[h]).replace("|", "/") for h in head) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _md_block(block: Block) -> list[str]:
    kind = block["kind"]
    if kind == "warn":
        return [f"**{block['text']}**", ""]
    if kind == "p":
        return [block["text"], ""]
    if kind == "ul":
        return [*(f"- {x}" for x in block["items"]), ""]
    if kind == "table":
        return [md_table(block["rows"])] if block["rows"] else []
    if kind == "details":
        return [f"### {block['summary']}", "", md_table(block["rows"])]
    caption = block.get("caption") or CAPTIONS[block["name"]]
    return [f"![{caption}]({block['name']}.png)", ""]


def markdown(report: Mapping[str, object], figure_names: list[str]) -> str:
    out = ["# snnkart energy report", ""]
    for title, blocks in sections(report, figure_names):
        out += [f"## {title}", ""] if title else []
        for block in blocks:
            out += _md_block(block)
    return "\n".join(out)


def _html_table(rows: list[dict[str, str]], table_id: str) -> str:
    if not rows:
        return ""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in rows[0])
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in r.values()) + "</tr>"
        for r in rows
    )
    return f'<table id="{table_id}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def _html_block(block: Block, figs: dict[str, bytes]) -> str:
    kind = block["kind"]
    if kind in ("p", "warn"):
        ident = f' id="{block["id"]}"' if block.get("id") else ""
        cls = ' class="warn"' if kind == "warn" else ""
        return f"<p{ident}{cls}>{html.escape(block['text'])}</p>"
    if kind == "ul":
        return "<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in block["items"]) + "</ul>"
    if kind == "table":
        return _html_table(block["rows"], block["id"])
    if kind == "details":
        return (
            f"<details><summary>{html.escape(block['summary'])}</summary>"
            f"{_html_table(block['rows'], block['id'])}</details>"
        )
    name = block["name"]
    return (
        f'<figure id="fig-{name}"><img alt="{name}" src="data:image/png;base64,'
        f'{base64.b64encode(figs[name]).decode()}"><figcaption>{html.escape(block.get("caption") or CAPTIONS[name])}'
        "</figcaption></figure>"
    )


CSS = """body{font-family:sans-serif;max-width:1150px;margin:.6em auto;color:#222}
h1{margin:.2em 0;font-size:1.6em}#verdict{font-size:15px;line-height:1.35;margin:.3em 0}
table{border-collapse:collapse;margin:.5em 0;font-size:13px}td,th{border:1px solid #bbb;
padding:3px 6px;text-align:right}th{background:#eee}.warn{background:#fdd;border:2px solid #c00;
padding:.6em;font-weight:bold}figure{margin:.4em 0}img{max-width:100%}summary{cursor:pointer}
#prices td:last-child,#prices td:nth-child(2){text-align:left}"""


def html_page(report: Mapping[str, object], figs: dict[str, bytes]) -> str:
    body = []
    for title, blocks in sections(report, list(figs)):
        body += [f"<h2>{html.escape(title)}</h2>"] if title else []
        body += [_html_block(b, figs) for b in blocks]
    return (
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>snnkart energy report</title>"
        f"<style>{CSS}</style></head><body><h1>snnkart energy report</h1>{''.join(body)}"
        "</body></html>"
    )


def write_report(report: Mapping[str, object], out: Path, trace: Any = None) -> dict[str, Path]:
    """Write the report's files (either family's) into ``out``; return their paths."""
    figs = figures(dict(report), trace)
    report = {**report, "figures": sorted(f"{name}.png" for name in figs)}
    paths = {"json": out / "report.json", "md": out / "report.md", "html": out / "report.html"}
    write_json(paths["json"], report)
    for name, png in figs.items():
        write_bytes(out / f"{name}.png", png)
    write_text(paths["md"], markdown(report, list(figs)))
    write_text(paths["html"], html_page(report, figs))
    return paths
