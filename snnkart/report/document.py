"""Write a built report: ``report.json``, ``report.md`` and one self-contained ``report.html``
(figures embedded as PNG data, no script or style fetched from anywhere)."""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

from snnkart.io import write_bytes, write_json, write_text
from snnkart.report import plots
from snnkart.report.sanafe_page import TITLE as SANAFE_TITLE
from snnkart.report.sanafe_page import sanafe_lines, sanafe_rows

INCLUDES = (
    "Chip: synaptic operations (spikes x fan-out between spiking layers), neuron updates (every "
    "neuron at every SNN step, as Loihi clocks them), spikes; the Lava pipeline's fill and drain "
    "steps (L per action) are priced too; routing: spikes x the tile hops of the layers' "
    "placement (each layer on cores of its own) where the chip prices a hop.",
    "Host link: the bits the deployment sends per action (T x n1 input currents in, the last "
    "layer's T x n spike flags out), priced per bit where a figure or bound exists.",
    "Host, priced as digital operations on the host profile: observation normalisation, the "
    "first layer's input current W1 z + b1 (once per action), the readout from spike counts, "
    "the decoding, and reading those weights from the memory array that holds the host's own "
    "weights (Horowitz's 8 KB / 32 KB / 1 MB SRAM rows, DRAM beyond).",
    "ANN: the same normalisation and decoding, every layer's multiply-accumulates and biases, "
    "and one read per weight from the array that holds the ANN's own weights. The ANN runs on "
    "the host, so it has no link.",
    "Static power x the control period (one action per env step, 60 Hz), a term of its own on "
    "each side, where a figure is published; report.json gives the verdict with and without it "
    "and the average power at the control rate.",
)
LEAVES_OUT = (
    "No power was measured: Lava's CPU simulator has no power model; every number is a count "
    "from the deployment times a published, derived or assumed per-operation price.",
    "Loihi 1's per-operation energies are pre-silicon simulations, the synaptic one a minimum "
    "(Davies et al. 2018; SANA-FE's silicon-calibrated figures are the high ends); Loihi 2 has "
    "no published per-operation figures: its ranges are derived from Hala Point's totals.",
    "Technology nodes differ (Loihi 14 nm and Intel 4, Horowitz's digital figures 45 nm): the "
    "ratios compare published figures, not equal processes.",
    "Static power is not published for the digital targets (the host's static power would add "
    "alike to both sides), nor for SpiNNaker; TrueNorth's figure is all-in and includes it. "
    "The ANN's activation functions (tanh) are not priced.",
    "Weight reuse across inferences and caches are not modelled; memory-inclusive profiles "
    "read every weight once per inference.",
)
REFERENCES = (
    "Davies et al., Loihi: a neuromorphic manycore processor with on-chip learning, IEEE Micro "
    "38(1):82-99, 2018 (Table 2, pre-silicon).",
    "Horowitz, Computing's energy problem (and what we can do about it), ISSCC 2014.",
    "Merolla et al., Science 2014 (TrueNorth: 26 pJ per synaptic event, measured, all-in).",
    "Höppner et al., arXiv 1903.08941, 2019 (SpiNNaker 2 prototype), as encoded by "
    "KerasSpiking's ModelEnergy.",
    "Yik et al., The NeuroBench framework ..., Nat. Commun. 16:1545, 2025.",
    "Dampfhoffer et al., Are SNNs really more energy-efficient than ANNs?, IEEE TETCI 7(3), 2023.",
    "Yan et al., Reconsidering the energy efficiency of SNN inference, arXiv 2409.08290.",
    "Intel/Sandia, Hala Point (1,152 Loihi 2), press release, April 2024.",
    "Boyle et al., SANA-FE, IEEE TCAD 44(8):3165-3178, 2025 (Loihi figures calibrated on silicon).",
    "Degnan et al. 2015 (ARM-class processor, 0.9 nJ per operation), as encoded by "
    "KerasSpiking's ModelEnergy.",
    "Paredes-Vallés et al., Science Robotics 2024 (Loihi idle power); lava-dl's PilotNet "
    "benchmarks on Loihi 2 (static power).",
)


def _nj(pj: float) -> str:
    return f"{pj / 1000:.3g}"


def _uj(pj: float | None) -> str:
    return "-" if pj is None else f"{pj / 1e6:.3g}"


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def _host(name: str) -> str:
    return name if name.startswith("the ") else f"`{name}`"


def _parity(deploy: dict[str, Any]) -> str:
    """How the deployment's counts were cross-checked (deploy.json's parity)."""
    p = deploy.get("parity") or {}
    ref = p.get("same_arithmetic_reference")
    if not ref:
        return "The counts are the reference's own."
    return (f"Every env step's spike raster was checked against the {ref} reference: "
            f"{p.get('same_arithmetic_mismatched_windows')} of {p.get('env_steps')} differ.")  # fmt: skip


def headline(report: dict[str, Any]) -> list[dict[str, str]]:
    """The main table's rows: each SNN profile against each ANN profile, with both tasks."""
    snn_task = report["snn"]["task"]
    rows = []
    for c in report["comparisons"]:
        ann = report["ann"][c["ann"]]
        task = ann["task"]
        rows.append({
            "SNN on": c["snn_profile"], "SNN nJ/inference": _nj(c["snn_pj"]),
            "ANN": ann["label"], "ANN on": c["ann_profile"], "ANN nJ/inference": _nj(c["ann_pj"]),
            "SNN/ANN": f"{c['ratio']:.3g}" if c["ratio"] is not None else "-",
            "SNN µJ/episode": f"{c['snn_per_episode_pj'] / 1e6:.3g}",
            "ANN µJ/episode": _uj(c["ann_per_episode_pj"]),
            "SNN µJ/return": _uj(c["snn_per_return_pj"]),
            "ANN µJ/return": _uj(c["ann_per_return_pj"]),
            "SNN success": _pct(snn_task["success_rate"]),
            "ANN success": _ann_success(c, task),
        })  # fmt: skip
    return rows


def _ann_success(row: dict[str, Any], task: dict[str, Any] | None) -> str:
    """The ANN's success on the row's profile; an int8 datapath's is the int8 ANN's, measured."""
    if row.get("ann_success_rate") is None:
        return _pct(task["success_rate"]) if task else "not run"
    measured = "int8" in row.get("ann_success", "")
    return _pct(row["ann_success_rate"]) + (" (int8, measured)" if measured else "")


def _int8(report: dict[str, Any]) -> str:
    """What the int8 ANN did on the deployment's episodes, if it was run."""
    run = report["ann"].get("run")
    q = (run.get("task") or {}).get("int8") if run else None
    if not q:
        return ""
    agree = q["action_agreement"]
    return (f" The ANN run quantised to int8 (post-training, symmetric per tensor, calibrated "
            f"on {q['calibration']['observations']} observations of {q['calibration']['episodes']} "
            f"other episodes) was driven on the same episodes: success {_pct(q['success_rate'])} "
            f"(measured), mean return {q['mean_return']:.2f}, "
            f"{'-' if agree is None else f'{agree:.1%}'} of its actions equal the float "
            "ANN's; the int8 profiles' rows carry its task.")  # fmt: skip


def _figures(report: dict[str, Any], trace: Any) -> dict[str, bytes]:
    snn, net = report["snn"], report["network"]
    figs = {"firing_rates": plots.firing_rates(snn["per_inference"]["firing_rates"], net["sizes"])}
    primary = "run" if "run" in report["ann"] else "same_width"
    energies: dict[str, dict[str, float]] = {}
    for c in report["comparisons"]:
        if c["ann"] == primary:
            energies[f"SNN on {c['snn_profile']}"] = c["snn_breakdown_pj"]
            energies[f"ANN on {c['ann_profile']}"] = c["ann_breakdown_pj"]
    figs["breakdown"] = plots.breakdown(energies)
    sens = report["sensitivity"][0]
    main = next(c for c in report["comparisons"] if c["snn_profile"] == sens["snn_profile"]
                and c["ann_profile"] == sens["ann_profile"] and c["ann"] == "same_width")  # fmt: skip
    be = main["break_even"]
    fixed, var, ann_pj = be["fixed_pj"], be["per_density_pj"], be["ann_pj"]
    curve = [(d / 20, (fixed + d / 20 * var) / ann_pj) for d in range(41)]
    title = f"SNN on {sens['snn_profile']} vs same-width ANN on {sens['ann_profile']}"
    figs["sensitivity"] = plots.sensitivity(sens["rows"], curve, be.get("density"), title)
    if report.get("sweep"):
        sw = report["sweep"]
        figs["tradeoff"] = plots.tradeoff(sw["points"], sw["ann_64_64_pj"], sw["profile"])
    if trace is not None:
        figs["raster"] = plots.raster(
            trace.raster, trace.membranes, trace.sizes, trace.thresholds,
            f"env step {trace.env_step} of the episode of seed {trace.seed} "
            f"(float32 reference; action {trace.action})",
        )  # fmt: skip
    return figs


def _md_table(rows: list[dict[str, str]]) -> str:
    if not rows:
        return ""
    head = list(rows[0])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(r[h]) for h in head) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _counts_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    snn, net = report["snn"], report["network"]
    per = snn["per_inference"]
    rows = [
        {"layer": f"{i + 1} ({n})", "spikes / inference": f"{per['spikes'][i]:.1f}",
         "firing rate": f"{100 * per['firing_rates'][i]:.1f} %",
         "synaptic ops (chip)": f"{per['synops_chip'][i]:.0f}",
         "neuron updates": f"{per['neuron_updates'][i]:.0f}"}
        for i, n in enumerate(net["sizes"])
    ]  # fmt: skip
    return rows


FACT_GROUPS = (
    ("deployed", "as deployed, per inference"),
    ("neurobench", "NeuroBench (first layer fed at every step)"),
    ("footprint", "footprint"),
    ("latency", "latency"),
)
FACT_NAMES = {"parameters": "weights and biases", "parameter_bytes_fp32": "weight and bias "
              "bytes (fp32)", "host_macs": "host MACs", "effective_macs": "effective MACs",
              "effective_acs": "effective ACs", "ms_per_env_step": "ms per env step"}  # fmt: skip


def _num(value: Any) -> str:
    """A count with thousands separators; any other number to 3 significant digits."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    if float(value).is_integer():
        return f"{int(value):,}"
    return f"{value:,.0f}" if abs(value) >= 1000 else f"{value:.3g}"


def _facts_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """The SNN's deployed counts, NeuroBench's metrics, footprint and latency, one per row."""
    snn = report["snn"]
    return [
        {"": group, "quantity": FACT_NAMES.get(key, key.replace("_", " ")), "value": _num(value)}
        for section, group in FACT_GROUPS
        for key, value in snn[section].items()
    ]


def _density(d: float) -> str:
    """A multiple of today's spikes, readable however small (0.0031x, not 0.00x)."""
    return f"{d:.2f}x" if d >= 0.1 else f"{d:.2g}x"


def _times(ratio: float) -> str:
    return f"{ratio:,.0f}x" if ratio >= 100 else f"{ratio:.3g}x"


def _verdict(report: dict[str, Any]) -> list[str]:
    """One line per neuromorphic profile: the SNN's energy as a multiple of the primary ANN's on
    each digital profile, and the break-even spike density where there is one."""
    primary = "run" if "run" in report["ann"] else "same_width"
    label = report["ann"][primary]["label"]
    lines = []
    for chip in dict.fromkeys(c["snn_profile"] for c in report["comparisons"]):
        parts = []
        for c in report["comparisons"]:
            if c["ann"] != primary or c["snn_profile"] != chip or c["ratio"] is None:
                continue
            be = c["break_even"]
            if be.get("density") is not None:
                note = f"wins below {_density(be['density'])} today's spikes"
            elif be["fixed_pj"] >= be["ann_pj"]:
                note = "cannot win at any spike rate"
            else:  # its energy does not grow with its spikes and is below the ANN's
                note = "wins at any spike rate"
            parts.append(f"{_times(c['ratio'])} the {label} on {c['ann_profile']} ({note})")
        lines.append(f"SNN on {chip}: " + "; ".join(parts) + ".")
    return lines


def markdown(report: dict[str, Any], figure_names: list[str]) -> str:
    d, snn = report["deploy"], report["snn"]
    out = ["# snnkart energy report", ""]
    if not report["drives"]:
        out += [f"**WARNING: the spiking policy does not drive: success "
                f"{_pct(snn['task']['success_rate'])} (< 80 %). The energy numbers below describe "
                "a policy that fails its task; they are not a result.**", ""]  # fmt: skip
    out += [
        f"Deployment: `{d['file']}` ({d['backend']}, {d['precision']}), {d['env']}/{d['track']}, "
        f"{d['episodes']} episodes, {d['env_steps']} env steps (inferences). "
        f"Network {report['network']['n_in']} -> {report['network']['sizes']} -> "
        f"{report['network']['n_out']}, T = {report['network']['num_steps']}. "
        f"Host work priced on {_host(report['host_profile'])}. {_parity(d)}{_int8(report)}", "",
        "## Verdict", "", *[f"- {line}" for line in _verdict(report)], "",
        "## Energy per inference and per episode, with the task", "", _md_table(headline(report)),
        "## Counts per inference (measured)", "", _md_table(_counts_rows(report)),
        "## Totals, footprint and latency", "", _md_table(_facts_rows(report)),
        f"## {SANAFE_TITLE}", "", *[f"- {x}" for x in sanafe_lines(report)], "",
        _md_table(sanafe_rows(report)),
        "## What the estimate includes", "", *[f"- {x}" for x in INCLUDES], "",
        "## What it leaves out", "", *[f"- {x}" for x in LEAVES_OUT], "",
        "## References", "", *[f"- {x}" for x in REFERENCES], "",
        "Figures: " + ", ".join(f"`{n}.png`" for n in figure_names), "",
    ]  # fmt: skip
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


CSS = """body{font-family:sans-serif;max-width:1150px;margin:1em auto;color:#222}
table{border-collapse:collapse;margin:.5em 0;font-size:13px}td,th{border:1px solid #bbb;
padding:3px 6px;text-align:right}th{background:#eee}.warn{background:#fdd;border:2px solid #c00;
padding:.6em;font-weight:bold}figure{margin:1em 0}img{max-width:100%}"""
CAPTIONS = {
    "firing_rates": "Firing rate per layer over the deployed episodes.",
    "breakdown": "Energy per inference (log scale) and its parts.",
    "sensitivity": "Sensitivity: the SNN/ANN ratio as each price moves, and against spike density.",
    "tradeoff": "Accuracy against energy over the committed sparsity sweep (T, penalty, width).",
    "raster": "Spike raster and membrane traces of every layer for one env step.",
}

REPORT_FILES = ("report.json", "report.md", "report.html", *(f"{name}.png" for name in CAPTIONS))
"""Every file :func:`write_report` may write."""


def html_page(report: dict[str, Any], figs: dict[str, bytes]) -> str:
    md_sections = markdown(report, list(figs))
    warn = "" if report["drives"] else (
        f'<p class="warn">The spiking policy does not drive: success '
        f'{_pct(report["snn"]["task"]["success_rate"])} (&lt; 80 %). The energy numbers below '
        "describe a policy that fails its task; they are not a result.</p>"
    )  # fmt: skip
    figures = "".join(
        f'<figure id="fig-{name}"><img alt="{name}" src="data:image/png;base64,'
        f'{base64.b64encode(png).decode()}"><figcaption>{html.escape(CAPTIONS[name])}'
        "</figcaption></figure>"
        for name, png in figs.items()
    )
    lists = {
        title: "<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in items) + "</ul>"
        for title, items in (("Verdict", _verdict(report)), ("What the estimate includes", INCLUDES),
                             ("What it leaves out", LEAVES_OUT), ("References", REFERENCES),
                             (SANAFE_TITLE, sanafe_lines(report)))
    }  # fmt: skip
    intro = md_sections.split("\n## ")[0].split("\n", 2)[-1]
    intro = html.escape(intro.replace("**", "").replace("`", "").strip())
    return (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>snnkart energy report</title>"
        f"<style>{CSS}</style></head><body><h1>snnkart energy report</h1>{warn}<p>{intro}</p>"
        f"<h2>Verdict</h2>{lists['Verdict']}"
        f"<h2>Energy per inference and per episode, with the task</h2>"
        f"{_html_table(headline(report), 'headline')}"
        f"<h2>Counts per inference (measured)</h2>{_html_table(_counts_rows(report), 'counts')}"
        f"<h2>Totals, footprint and latency</h2>{_html_table(_facts_rows(report), 'facts')}"
        f"<h2>Figures</h2>{figures}"
        f"<h2>{SANAFE_TITLE}</h2>{lists[SANAFE_TITLE]}{_html_table(sanafe_rows(report), 'sanafe')}"
        f"<h2>What the estimate includes</h2>{lists['What the estimate includes']}"
        f"<h2>What it leaves out</h2>{lists['What it leaves out']}"
        f"<h2>References</h2>{lists['References']}</body></html>"
    )


def write_report(report: dict[str, Any], out: Path, trace: Any = None) -> dict[str, Path]:
    """Write the report's files into ``out``; return their paths."""
    figs = _figures(report, trace)
    report = {**report, "figures": sorted(f"{name}.png" for name in figs)}
    paths = {"json": out / "report.json", "md": out / "report.md", "html": out / "report.html"}
    write_json(paths["json"], report)
    for name, png in figs.items():
        write_bytes(out / f"{name}.png", png)
    write_text(paths["md"], markdown(report, list(figs)))
    write_text(paths["html"], html_page(report, figs))
    return paths
