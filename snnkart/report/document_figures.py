"""The energy report's figures (:func:`figures`), drawn from a built report as PNG bytes: a LIF
deployment's verdict, firing rates, breakdown, sensitivity and raster, or a sigma-delta
deployment's own (:mod:`snnkart.report.sigma_delta_document`), with the sweep's trade-off."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snnkart.report import first_screen as first
from snnkart.report import plots
from snnkart.report import sigma_delta_document as sd


def figures(report: dict[str, Any], trace: Any) -> dict[str, bytes]:
    """The report's figures by name, as PNG bytes (the raster only with a ``trace``)."""
    if report.get("kind") == "sigma-delta":
        figs = sd.figures(report)
        if report.get("sweep"):
            sw = report["sweep"]
            figs["tradeoff"] = plots.tradeoff(
                sw["points"], sw["ann_64_64_pj"], sw["profile"], _sweep_title(sw)
            )
        return figs
    snn, net, d = report["snn"], report["network"], report["deploy"]
    figs = {
        "verdict": plots.verdict(first.chart_rows(report), first.chart_legend(report)),
        "firing_rates": plots.firing_rates(snn["per_inference"]["firing_rates"], net["sizes"]),
    }
    sens = report["sensitivity"][0]
    target = sens["ann_profile"]  # the fair baseline: the first memory-inclusive target
    energies: dict[str, dict[str, float]] = {}
    for c in first.pairs(report):
        if c["ann_profile"] == target:
            energies[f"SNN on {c['snn_profile']} (host on {target})"] = c["snn_breakdown_pj"]
    for c in first.pairs(report):
        energies.setdefault(f"ANN on {c['ann_profile']}", c["ann_breakdown_pj"])
    figs["breakdown"] = plots.breakdown(energies)
    main = next(
        c
        for c in report["comparisons"]
        if c["snn_profile"] == sens["snn_profile"]
        and c["ann_profile"] == target
        and c["ann"] == "same_width"
    )
    be = main["break_even"]
    fixed, var, ann_pj = be["fixed_pj"], be["per_density_pj"], be["ann_pj"]
    curve = [(x / 20, (fixed + x / 20 * var) / ann_pj) for x in range(41)]
    title = (
        f"One price at a time: SNN on {sens['snn_profile']} vs same-width ANN on {target} "
        f"(ratio {main['ratio']:.3g}x)"
    )
    figs["sensitivity"] = plots.sensitivity(sens["rows"], curve, be.get("density"), title)
    if report.get("sweep"):
        sw = report["sweep"]
        figs["tradeoff"] = plots.tradeoff(
            sw["points"], sw["ann_64_64_pj"], sw["profile"], _sweep_title(sw)
        )
    if trace is not None:
        figs["raster"] = plots.raster(
            trace.raster,
            trace.membranes,
            trace.sizes,
            trace.thresholds,
            f"env step {trace.env_step} of the episode of seed {trace.seed}, traced on the "
            f"float32 reference (the deployment ran {d['backend']}, {d['precision']}); action "
            f"{trace.action}",
        )
    return figs


def _sweep_title(sweep: dict[str, Any]) -> str:
    """The trade-off figure's title: which sweep, at which commit, priced on which profile."""
    commit = f" at commit {sweep['commit']}" if sweep.get("commit") else ""
    return (
        f"Not this deployment: the runs of the sweep {Path(sweep['file']).name}{commit} "
        f"({sweep['env']}), priced on {sweep['profile']}"
    )
