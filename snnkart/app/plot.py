"""``snnkart plot raster``: the spike raster and membrane traces of every layer for one env step
of a deployed policy."""

from __future__ import annotations

from pathlib import Path

from snnkart.app.reporter import Reporter


def run_plot_raster(
    nir_file: Path, step: int, seed: int, track: str | None, out: Path, reporter: Reporter
) -> Path:
    from snnkart.backends.loading import load_chain
    from snnkart.eval.trace import trace_step
    from snnkart.io import write_bytes
    from snnkart.report import plots

    load_chain(nir_file)  # a clear error for a missing or bad file
    trace = trace_step(nir_file, step, seed, track)
    png = plots.raster(
        trace.raster,
        trace.membranes,
        trace.sizes,
        trace.thresholds,
        f"{nir_file.name}: env step {step} of the episode of seed {seed} "
        f"(float32 reference; action {trace.action})",
    )
    write_bytes(out, png)
    spikes = trace.raster.sum(0)
    per_layer = []
    start = 0
    for n in trace.sizes:
        per_layer.append(int(spikes[start : start + n].sum()))
        start += n
    reporter.message(f"spikes per layer at env step {step}: {per_layer}; raster written to {out}")
    return out
