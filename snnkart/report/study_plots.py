"""A study's figures: per track, cumulative finishes and mean episodic return against training
steps, small multiples: one panel per cell of the table (env, or env · variant in an ablation)
with the ANN and the SNN in two colours, shared axes, one legend above the panels and a caption
below them; PNG and SVG. Drawn from the same :class:`StudyRecord` as ``study.md`` (nothing else
feeds them), each seed's line tagged with its run's name (the SVG's ``id``)."""

from __future__ import annotations

import textwrap
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.report.study_record import RunRecord, StudyRecord
from snnkart.rl import kinds

PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")
"""The study policies' colours, in the kinds registry's order (its kinds, then its
conversions): ann blue, snn red, sdnn green, rsnn orange, ann-sd purple."""


def colour(policy: str) -> str:
    """``policy``'s colour: its place among the registered study policies, in :data:`PALETTE`."""
    order = [*kinds.REGISTRY, *kinds.CONVERSIONS]
    return PALETTE[order.index(policy) % len(PALETTE)]


KEYS = {"finishes": "cumulative laps finished", "return": "mean episodic return"}
"""The figures per track: the curve's key and its axis label."""
NCOLS = 3
"""Panels per row: three stay readable at GitHub's page width."""
PANEL_IN = (3.2, 2.3)
"""A panel's width and height in inches (110 dpi)."""
CAPTION = (
    "Thick line: the median over the cell's seeds, band: their min–max, both drawn only while "
    "every seed is still training. Thin lines: each seed to its end; a dot: the run stopped "
    "early because it had learned (the study's stop rule). After the first early stop the "
    "median of the seeds left would be a median of the slow ones (a cumulative count would "
    "seem to fall), so the median and the band end there."
)
"""Why a median band ends where it does; under every figure and beside it in ``study.md``."""


def cell_label(env: str, variant: str) -> str:
    """A cell's name in the table's first column and above its panel."""
    return f"{env} · {variant}" if variant else env


def panels(record: StudyRecord, track: str) -> list[tuple[str, str]]:
    """The (env, variant) cells of ``track`` that have runs, in the table's order."""
    have = {(r.env, r.variant) for r in record.runs if r.track == track}
    return [(e, v) for e in record.study.envs for v in record.study.variant_names if (e, v) in have]


def plot_names(track: str) -> list[str]:
    """The files :func:`write_plots` writes for ``track``, PNG before SVG per figure."""
    return [_name(track, key, suffix) for key in KEYS for suffix in ("png", "svg")]


def _name(track: str, key: str, suffix: str) -> str:
    return f"{Path(track).stem}-{key}.{suffix}"


def record_commit(record: StudyRecord) -> str:
    """The commit the record was made at, or a phrase saying it names none."""
    commit = record.machine.get("commit") if record.machine else None
    return str(commit) if commit else "not recorded"


def _band(ax: Any, runs: list[RunRecord], key: str, colour: str, label: str) -> None:
    """Every seed as a thin line (its ``gid`` the run's name), and the median and min-max band
    over seeds while every seed is still training. A run stopped early (the study's ``stop``
    rule: it had learned) ends in a dot; after the first such stop the median of the seeds
    left would be a median of the slow ones (a cumulative count would seem to fall), so it is
    not drawn (:data:`CAPTION` says so under the figure)."""
    field = "returns" if key == "return" else key  # the curve's JSON key is "return"
    curves = [
        (
            np.asarray(r.curve.steps, dtype=float),
            np.asarray([np.nan if v is None else v for v in getattr(r.curve, field)], dtype=float),
        )
        for r in runs
    ]
    full = min(len(x) for x, _ in curves)
    steps = curves[0][0][:full]
    ys = np.stack([y[:full] for _, y in curves])
    with warnings.catch_warnings():  # iterations in which no seed ended an episode: a gap
        warnings.simplefilter("ignore", RuntimeWarning)
        median, low, high = (np.nanmedian(ys, axis=0), np.nanmin(ys, axis=0), np.nanmax(ys, axis=0))
    ax.plot(steps, median, color=colour, lw=2, label=f"{label} (median of {len(runs)})")
    ax.fill_between(steps, low, high, color=colour, alpha=0.15)
    for r, (x, y) in zip(runs, curves, strict=True):
        ax.plot(x, y, color=colour, lw=0.6, alpha=0.45, gid=r.name)
        if r.stopped_early:
            ax.plot(x[-1:], y[-1:], "o", color=colour, ms=3.5)
    ax.xaxis.set_major_formatter(_thousands)


def _thousands(x: float, _: Any = None) -> str:
    """A step count on an axis: ``150k``; below a thousand as it is (a short test study)."""
    return f"{x / 1000:.0f}k" if abs(x) >= 1000 else f"{x:.0f}"


def _legend_handles(record: StudyRecord, key: str) -> list[Any]:
    """The figure's one legend: a colour per policy, a seed's line, the early stop's dot and,
    for finishes, the study's mark."""
    from matplotlib.lines import Line2D

    grey = "#555555"
    handles = [
        Line2D([], [], color=colour(p), lw=2, label=f"{p.upper()}: median, min–max band")
        for p in record.study.policies
        if any(r.policy == p for r in record.runs)
    ]
    handles += [
        Line2D([], [], color=grey, lw=0.6, label="one seed"),
        Line2D([], [], color=grey, ls="", marker="o", ms=3.5, label="stopped early: learned"),
    ]
    if key == "finishes":
        handles.append(
            Line2D([], [], color="grey", lw=0.8, ls=":", label=f"{record.study.finishes} finishes")
        )
    return handles


def _panel(ax: Any, record: StudyRecord, cell: tuple[str, str, str], key: str) -> None:
    """One cell's panel: its ANN and SNN runs, each policy in its colour."""
    track, env, variant = cell
    for policy in record.study.policies:
        runs = [r for r in record.runs if r.cell == (track, env, policy, variant)]
        if runs:
            _band(ax, runs, key, colour(policy), policy.upper())
    if key == "finishes":
        ax.axhline(record.study.finishes, color="grey", lw=0.8, ls=":")
    ax.set_title(cell_label(env, variant), fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(color="#eeeeee", lw=0.6)


def _title(record: StudyRecord, track: str, key: str) -> str:
    """The study's name, the track (unless the name says it), the curve and the commit."""
    stem, name = Path(track).stem, record.study.name
    where = name if stem in name else f"{name}, {stem}"
    return f"{where}: {KEYS[key]} (record at commit {record_commit(record)})"


def figure(record: StudyRecord, track: str, key: str) -> Any:
    """The figure of ``key`` (a key of :data:`KEYS`) on ``track``: a grid of panels, one per
    cell, shared axes; above them the title (with the record's commit) and the one legend,
    below them :data:`CAPTION`. Laid out in inches, so no text overlaps a panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = panels(record, track)
    ncols = min(len(cells), NCOLS)
    nrows = -(-len(cells) // ncols)
    width = max(PANEL_IN[0] * ncols + 0.9, 6.5)
    handles = _legend_handles(record, key)
    per_row = len(handles) if width > 9 else 3
    title = textwrap.fill(_title(record, track, key), width=int(12 * width))
    caption = textwrap.fill(CAPTION, width=int(15 * width))
    line = 0.2  # inches per line of 8-10 pt text
    head = 0.1 + line * (title.count("\n") + 1)
    top = head + line * -(-len(handles) // per_row) + 0.3  # title, legend, a panel's title
    bottom = 0.15 + 0.16 * (caption.count("\n") + 1) + 0.6  # caption, axis label, ticks
    height = PANEL_IN[1] * nrows + 0.45 * (nrows - 1) + top + bottom
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(width, height), dpi=110, sharex=True, sharey=True, squeeze=False
    )
    fig.subplots_adjust(
        left=0.75 / width,
        right=1 - 0.15 / width,
        top=1 - top / height,
        bottom=bottom / height,
        wspace=0.25 / PANEL_IN[0],
        hspace=0.45 / PANEL_IN[1],
    )
    for ax, (env, variant) in zip(axes.flat, cells, strict=False):
        _panel(ax, record, (track, env, variant), key)
    for k in range(len(cells), nrows * ncols):  # an empty slot: the panel above shows the steps
        axes.flat[k].remove()
        axes.flat[k - ncols].tick_params(labelbottom=True)
    fig.text(0.5, 1 - 0.1 / height, title, ha="center", va="top", fontsize=10)
    fig.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, 1 - head / height),
        ncol=per_row,
        fontsize=8,
        frameon=False,
        borderaxespad=0,
    )
    fig.text(0.5 / width, 0.15 / height, caption, va="bottom", fontsize=8)
    fig.text(0.5, (bottom - 0.3) / height, "training env steps", ha="center", va="top", fontsize=9)
    fig.text(
        0.12 / width,
        (bottom + (height - top - bottom) / 2) / height,
        KEYS[key],
        rotation=90,
        va="center",
        fontsize=9,
    )
    return fig


def write_plots(record: StudyRecord, out: Path) -> list[Path]:
    """Per track, the :func:`figure` of each key as PNG and SVG, named by :func:`plot_names`.
    Returns the files written."""
    import matplotlib.pyplot as plt

    written = []
    for track in record.tracks():
        for key in KEYS:
            fig = figure(record, track, key)
            for suffix in ("png", "svg"):
                path = out / _name(track, key, suffix)
                fig.savefig(path, format=suffix)
                written.append(path)
            plt.close(fig)
    return written
