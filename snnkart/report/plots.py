"""The report's figures, as PNG bytes (matplotlib, Agg: no display needed).

This package is the only place that imports matplotlib."""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

import numpy as np

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


def _png(fig: Any) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
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


def breakdown(energies: dict[str, dict[str, float]]) -> bytes:
    """Left: energy per inference per (network, profile), log scale; right: its parts (%)."""
    fig, axes = _figure(10.0, 0.45 * len(energies) + 1.6, ncols=2)
    left, right = axes[0]
    labels = list(energies)
    y = np.arange(len(labels))
    totals = [sum(parts.values()) for parts in energies.values()]
    left.barh(y, [t / 1000 for t in totals], color=["#d62728" if lab.startswith("SNN") else
                                                  "#7f7f7f" for lab in labels])  # fmt: skip
    left.set_xscale("log")
    left.set_yticks(y, labels)
    left.invert_yaxis()
    left.set_xlabel("energy per inference (nJ, log scale)")
    for yi, t in zip(y, totals, strict=True):
        left.text(t / 1000, yi, f" {t / 1000:.3g}", va="center", fontsize=8)
    start = np.zeros(len(labels))
    for part, colour in PART_COLOURS.items():
        share = np.array([100 * p.get(part, 0.0) / max(t, 1e-30)
                          for p, t in zip(energies.values(), totals, strict=True)])  # fmt: skip
        right.barh(y, share, left=start, color=colour, label=part)
        start += share
    right.set_yticks(y, [""] * len(labels))
    right.invert_yaxis()
    right.set_xlim(0, 100)
    right.set_xlabel("share of the energy (%)")
    right.legend(fontsize=7, loc="lower right", framealpha=0.9)
    return _png(fig)


def sensitivity(rows: Sequence[dict[str, Any]], curve: Sequence[tuple[float, float]],
                break_even: float | None, title: str) -> bytes:  # fmt: skip
    """Left: the SNN/ANN ratio as each price moves 0.1x-10x (bar) and across its range (dark);
    right: the ratio against the spike density, with the break-even point."""
    fig, axes = _figure(10.0, 0.35 * len(rows) + 1.8, ncols=2)
    left, right = axes[0]
    y = np.arange(len(rows))
    base = rows[0]["ratio"] if rows else 1.0
    for yi, row in zip(y, rows, strict=True):
        lo, hi = sorted((row["ratio_x0.1"], row["ratio_x10"]))
        left.plot([lo, hi], [yi, yi], color="#aec7e8", linewidth=6, solid_capstyle="butt")
        rlo, rhi = sorted((row["ratio_low"], row["ratio_high"]))
        left.plot([rlo, rhi], [yi, yi], color="#1f77b4", linewidth=6, solid_capstyle="butt")
    left.axvline(base, color="black", linewidth=1)
    left.axvline(1.0, color="#d62728", linestyle="--", linewidth=1)
    left.set_xscale("log")
    roles = {"chip": "SNN chip", "host": "SNN host", "digital": "ANN",
             "host+digital": "ANN + SNN host"}  # fmt: skip
    left.set_yticks(
        y, [f"{roles[r['side']]} ({r['profile']}): {r['op']}" for r in rows], fontsize=8
    )
    left.invert_yaxis()
    left.set_xlabel("SNN / ANN energy (log; < 1: SNN wins)\nlight: price 0.1x-10x, dark: its range")
    d, ratio = zip(*curve, strict=True)
    right.plot(d, ratio, color="#1f77b4")
    right.axhline(1.0, color="#d62728", linestyle="--", linewidth=1)
    right.axvline(1.0, color="black", linewidth=1)
    if break_even is not None and break_even <= max(d):
        right.axvline(break_even, color="#2ca02c", linewidth=1)
        shown = f"{break_even:.2f}" if break_even >= 0.1 else f"{break_even:.2g}"  # not 0.00
        right.text(break_even, max(ratio), f" break-even {shown}x", color="#2ca02c",
                   va="top", fontsize=8)  # fmt: skip
    elif break_even is None:
        right.text(0.02, 0.98, f"no break-even: with no spikes at all\nthe SNN still costs "
                   f"{ratio[0]:.2g}x the ANN",
                   transform=right.transAxes, va="top", fontsize=8, color="#d62728")  # fmt: skip
    right.set_ylim(bottom=0)
    right.set_xlabel("spikes relative to the deployed policy's")
    right.set_ylabel("SNN / ANN energy")
    right.set_title(title, fontsize=9)
    return _png(fig)


def tradeoff(points: Sequence[dict[str, Any]], ann_pj: dict[str, float], profile: str) -> bytes:
    """Left: success rate against energy per inference (one dot per run of the sweep, the
    ANN's energy as vertical lines); right: energy per inference against T."""
    fig, axes = _figure(10.0, 3.8, ncols=2)
    left, right = axes[0]
    names = sorted({p["point"] for p in points})
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    for k, name in enumerate(names):
        runs = [p for p in points if p["point"] == name]
        colour = cmap(k % 10)
        left.scatter([r["energy_pj"] / 1000 for r in runs], [100 * r["success_rate"] for r in runs],
                     color=colour, label=name, s=22)  # fmt: skip
        right.scatter([r["num_steps"] for r in runs], [r["energy_pj"] / 1000 for r in runs],
                      color=colour, s=22)  # fmt: skip
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
    return _png(fig)


def raster(raster: np.ndarray, membranes: np.ndarray, sizes: Sequence[int],
           thresholds: Sequence[float], title: str) -> bytes:  # fmt: skip
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
    partial = [int(j) for j in np.argsort(np.abs(counts - T / 2), kind="stable")
               if 0 < counts[j] < T]  # fmt: skip
    busiest = [int(j) for j in np.argsort(-counts, kind="stable") if int(j) not in partial]
    return (partial + busiest)[:k]
