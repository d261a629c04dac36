"""The report's figures, as PNG bytes (matplotlib, Agg: no display needed).

This package is the only place that imports matplotlib."""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any, TypedDict

import numpy as np

from snnkart.contract.report_record import SensitivityRow, SweepPoint

SD_PART_COLOURS = {"messages": "#bcbd22"}
"""A sigma-delta inference's part the LIF breakdown has not (its graded messages)."""
PART_COLOURS = {
    "synaptic ops": "#1f77b4",
    "neuron updates": "#ff7f0e",
    "spikes": "#2ca02c",
    "routing": "#17becf",
    "host link": "#e377c2",
    "host compute": "#9467bd",
    "memory": "#8c564b",
}


def _figure(width: float, height: float, ncols: int = 1, nrows: int = 1) -> tuple[Any, Any]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=(width, height), dpi=110, squeeze=False)


def _png(fig: Any, tight: bool = True) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    if tight:
        fig.tight_layout()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def firing_rates(rates: Sequence[float], sizes: Sequence[int]) -> bytes:
    fig, axes = _figure(5.5, 3.0)
    ax = axes[0][0]
    labels = [f"layer {i + 1}\n({n} neurons)" for i, n in enumerate(sizes)]
    bars = ax.bar(labels, [100 * r for r in rates], color="#1f77b4")
    ax.bar_label(bars, fmt="%.1f %%")
    ax.set_ylabel("spikes per neuron per SNN step (%)")
    ax.set_ylim(0, max(5.0, 130 * max(rates, default=0.0)))
    ax.set_title("Firing rate per layer (deployed episodes)")
    return _png(fig)


def breakdown(
    energies: dict[str, dict[str, float]], colours: dict[str, str] = PART_COLOURS
) -> bytes:
    """Left: energy per inference per (network, profile), log scale (an ``SNN ...`` label in
    red); right: its parts (%), one colour per part of ``colours``."""
    fig, axes = _figure(10.0, 0.45 * len(energies) + 1.6, ncols=2)
    left, right = axes[0]
    labels = list(energies)
    y = np.arange(len(labels))
    totals = [sum(parts.values()) for parts in energies.values()]
    left.barh(
        y,
        [t / 1000 for t in totals],
        color=["#d62728" if lab.startswith("SNN") else "#7f7f7f" for lab in labels],
    )
    left.set_xscale("log")
    left.set_xlim(right=12 * max(totals, default=1.0) / 1000)  # room for the value labels
    left.set_yticks(y, labels)
    left.invert_yaxis()
    left.set_xlabel("energy per inference (nJ, log scale)")
    for yi, t in zip(y, totals, strict=True):
        left.text(t / 1000, yi, f" {t / 1000:.3g}", va="center", fontsize=8)
    start = np.zeros(len(labels))
    for part, colour in colours.items():
        share = np.array(
            [
                100 * p.get(part, 0.0) / max(t, 1e-30)
                for p, t in zip(energies.values(), totals, strict=True)
            ]
        )
        right.barh(y, share, left=start, color=colour, label=part)
        start += share
    right.set_yticks(y, [""] * len(labels))
    right.invert_yaxis()
    right.set_xlim(0, 100)
    right.set_xlabel("share of the energy (%)")
    fig.legend(
        *right.get_legend_handles_labels(),
        fontsize=7,
        loc="lower center",
        ncol=len(colours),
        frameon=False,
    )  # below the bars, covering none
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return _png(fig, tight=False)


def _moves(row: SensitivityRow) -> bool:
    """Whether moving the price changes the ratio at all (a price whose count is 0 does not)."""
    values = {row["ratio"], row["ratio_x0.1"], row["ratio_x10"]}
    return max(values) > min(values) * (1 + 1e-9)


def sensitivity(
    rows: Sequence[SensitivityRow],
    curve: Sequence[tuple[float, float]],
    break_even: float | None,
    title: str,
) -> bytes:
    """Left: the SNN/ANN ratio as each price moves 0.1x-10x (light) and across its range (dark),
    the prices that do not move it named below; right: the ratio against the spike density,
    with the break-even point. ``title`` goes above both."""
    shown = [r for r in rows if _moves(r)]
    still = [f"{r['profile']}.{r['op']}" for r in rows if not _moves(r)]
    fig, axes = _figure(10.0, 0.38 * len(shown) + 2.6, ncols=2)
    left, right = axes[0]
    y = np.arange(len(shown))
    base = rows[0]["ratio"] if rows else 1.0
    for yi, row in zip(y, shown, strict=True):
        for (a, b), colour in (
            ((row["ratio_x0.1"], row["ratio_x10"]), "#aec7e8"),
            ((row["ratio_low"], row["ratio_high"]), "#1f77b4"),
        ):
            left.plot(
                sorted((a, b)),
                [yi, yi],
                color=colour,
                linewidth=6,
                marker="|",
                markersize=12,
                solid_capstyle="butt",
            )
    left.axvline(base, color="black", linewidth=1)
    left.axvline(1.0, color="#d62728", linestyle="--", linewidth=1)
    left.set_xscale("log")
    roles = {
        "chip": "SNN chip",
        "host": "SNN host",
        "digital": "ANN",
        "host+digital": "ANN + SNN host",
    }
    left.set_yticks(y, [f"{roles[r['side']]}: {r['profile']}.{r['op']}" for r in shown], fontsize=8)
    left.set_ylim(len(shown) - 0.5, -0.5)
    note = "\n(no effect: " + ", ".join(still) + ")" if still else ""
    left.set_xlabel(
        "SNN / ANN energy (log; < 1: SNN wins)\nlight: price 0.1x-10x, dark: its range" + note,
        fontsize=8,
    )
    _density_curve(right, curve, break_even)
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def _density_curve(ax: Any, curve: Sequence[tuple[float, float]], break_even: float | None) -> None:
    """The SNN/ANN ratio against the spike density, with the break-even point."""
    d, ratio = zip(*curve, strict=True)
    ax.plot(d, ratio, color="#1f77b4")
    ax.axhline(1.0, color="#d62728", linestyle="--", linewidth=1)
    ax.axvline(1.0, color="black", linewidth=1)
    if break_even is not None and break_even <= max(d):
        ax.axvline(break_even, color="#2ca02c", linewidth=1)
        shown = f"{break_even:.2f}" if break_even >= 0.1 else f"{break_even:.2g}"  # not 0.00
        ax.text(
            break_even, max(ratio), f" break-even {shown}x", color="#2ca02c", va="top", fontsize=8
        )
    elif break_even is None:
        ax.text(
            0.02,
            0.98,
            f"no break-even: with no spikes at all\nthe SNN still costs {ratio[0]:.2g}x the ANN",
            transform=ax.transAxes,
            va="top",
            fontsize=8,
            color="#d62728",
        )
    ax.set_ylim(bottom=0)
    ax.set_xlabel("spikes relative to the deployed policy's")
    ax.set_ylabel("SNN / ANN energy")


MARKERS = {
    "dense LIF": "o",
    "sparse LIF": "s",
    "stateful LIF": "D",
    "recurrent LIF": "P",
    "sigma-delta trained": "^",
    "ANN converted": "v",
}
"""One marker per policy kind of a sweep's runs (:meth:`snnkart.report.study_record.StudySettings.run_label`)."""


def tradeoff(
    points: Sequence[SweepPoint], ann_pj: dict[str, float], profile: str, title: str
) -> bytes:
    """Left: success rate against energy per inference (one dot per run of the sweep, its
    marker its policy kind, the ANN's energy as vertical lines); right: energy per inference
    against T (the ANN's as horizontal lines). ``title`` says whose runs these are."""
    fig, axes = _figure(10.0, 3.8, ncols=2)
    left, right = axes[0]
    names = sorted({p["point"] for p in points})
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    for k, name in enumerate(names):
        runs = [p for p in points if p["point"] == name]
        colour = cmap(k % 10)
        for kind in dict.fromkeys(r.get("kind", "dense LIF") for r in runs):
            mine = [r for r in runs if r.get("kind", "dense LIF") == kind]
            label = name if kind == "dense LIF" else f"{name} ({kind})"
            marker = MARKERS.get(kind, "o")
            left.scatter(
                [r["energy_pj"] / 1000 for r in mine],
                [100 * r["success_rate"] for r in mine],
                color=colour,
                label=label,
                s=22,
                marker=marker,
            )
            right.scatter(
                [r["num_steps"] for r in mine],
                [r["energy_pj"] / 1000 for r in mine],
                color=colour,
                s=22,
                marker=marker,
            )
    for (label, pj), style in zip(ann_pj.items(), ("--", ":", "-."), strict=False):
        left.axvline(pj / 1000, color="black", linestyle=style, linewidth=1, label=f"ANN {label}")
        right.axhline(pj / 1000, color="black", linestyle=style, linewidth=1)
    left.set_xscale("log")
    left.set_xlabel(f"SNN energy per inference on {profile} (nJ, log)")
    left.set_ylabel("success rate (%)")
    left.legend(fontsize=7, loc="lower left")
    right.set_yscale("log")
    right.set_xlabel("T (SNN steps per env step)")
    right.set_ylabel("energy per inference (nJ, log)")
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def raster(
    raster: np.ndarray,
    membranes: np.ndarray,
    sizes: Sequence[int],
    thresholds: Sequence[float],
    title: str,
) -> bytes:
    """Per layer: the spike raster (neuron against SNN step) and the membrane traces of a few
    neurons with the threshold."""
    n = len(sizes)
    fig, axes = _figure(10.0, 2.4 * n, ncols=2, nrows=n)
    offsets = np.cumsum((0, *sizes))
    T = raster.shape[0]
    for i in range(n):
        spikes = raster[:, offsets[i] : offsets[i + 1]]
        t, neuron = np.nonzero(spikes)
        ax = axes[i][0]
        ax.scatter(t, neuron, marker="|", s=40, color="black")
        ax.set_xlim(-0.5, T - 0.5)
        ax.set_xticks(range(T))
        ax.set_ylim(-0.5, sizes[i] - 0.5)
        ax.set_ylabel(f"layer {i + 1} neuron")
        ax.set_title(f"layer {i + 1}: {int(spikes.sum())} spikes in {T} steps", fontsize=9)
        v = membranes[:, offsets[i] : offsets[i + 1]]
        ax = axes[i][1]
        for j in _telling_neurons(spikes):
            ax.plot(range(T), v[:, j], marker=".", label=f"neuron {j}")
        ax.axhline(thresholds[i], color="#d62728", linestyle="--", linewidth=1, label="threshold")
        ax.set_xticks(range(T))
        low, high = ax.get_ylim()
        ax.set_ylim(low, high + 0.35 * (high - low))  # room for the legend
        ax.set_ylabel("membrane (before reset)")
        ax.legend(fontsize=6, ncol=5, loc="upper left")
    axes[-1][0].set_xlabel("SNN step")
    axes[-1][1].set_xlabel("SNN step")
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def _telling_neurons(spikes: np.ndarray, k: int = 4) -> list[int]:
    """Up to ``k`` neurons whose traces show the dynamics: ones that fire on some steps but not
    on all (nearest the middle first), then the busiest."""
    counts = spikes.sum(0)
    T = spikes.shape[0]
    partial = [
        int(j) for j in np.argsort(np.abs(counts - T / 2), kind="stable") if 0 < counts[j] < T
    ]
    busiest = [int(j) for j in np.argsort(-counts, kind="stable") if int(j) not in partial]
    return (partial + busiest)[:k]


class ChartRow(TypedDict):
    """One pair of the first screen's chart (:func:`verdict`): energies per inference in nJ as
    (point estimate, 5th, 95th percentile), the ANN's success on the target, P(SNN cheaper)."""

    label: str
    ann_success: str
    snn_nj: tuple[float, float, float]
    ann_nj: tuple[float, float, float]
    p: float


def verdict(rows: Sequence[ChartRow], legend: tuple[str, str]) -> bytes:
    """The first screen's chart: per pair, the SNN's and the ANN's energy per inference (point
    estimate, dot; 90 % interval of the joint sample, line), log scale, P(SNN cheaper) and the
    ANN's success at the right. Each row's ``snn_nj`` / ``ann_nj`` is (point, p05, p95) in nJ;
    ``legend`` names the two series."""
    fig, axes = _figure(10.5, 0.36 * len(rows) + 1.1)
    ax = axes[0][0]
    for k, row in enumerate(rows):
        for dy, nj, colour, name in (
            (-0.13, row["snn_nj"], "#d62728", legend[0]),
            (0.13, row["ann_nj"], "#555555", legend[1]),
        ):
            point, low, high = nj
            ax.plot([low, high], [k + dy] * 2, color=colour, linewidth=2.5, alpha=0.55)
            ax.plot(
                [point], [k + dy], "o", color=colour, markersize=4.5, label=name if k == 0 else None
            )
        ax.text(
            1.01,
            k,
            f"P(SNN cheaper) {row['p']:.2f}\nANN success {row['ann_success']}",
            transform=ax.get_yaxis_transform(),
            va="center",
            fontsize=7,
            color="#2ca02c" if row["p"] > 0.5 else "#222222",
        )
        if k:
            ax.axhline(k - 0.5, color="#dddddd", linewidth=0.8)
    ax.set_xscale("log")
    ax.set_yticks(range(len(rows)), [r["label"] for r in rows], fontsize=7)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlabel(
        "energy per inference, dynamic only (nJ, log): dot the estimate, line its 90 % "
        "interval (all prices sampled together)",
        fontsize=8,
    )
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", which="major", color="#eeeeee")
    ax.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False)
    return _png(fig)
