"""The frontier's page (``docs/frontier.md``) and the README's verdicts: the generated blocks
and the figure, written from the frontier's summary (:func:`snnkart.report.frontier.frontier`,
priced from the committed ``study.json``), never typed by hand."""

from __future__ import annotations

import numpy as np

from snnkart.report.frontier import KEEP, Frontier, FrontierPoint, point_name

KIND_MARKERS = {
    "ANN converted": ("v", "ANN converted"),
    "sigma-delta trained": ("^", "sigma-delta trained"),
    "stateful LIF": ("s", "stateful LIF"),
    "recurrent LIF": ("P", "recurrent LIF"),
    "dense LIF": ("o", "LIF (dense, sparse)"),
    "sparse LIF": ("o", "LIF (dense, sparse)"),
}
"""The figure's marker and legend per kind label (:meth:`StudySettings.run_label`); dense and
sparse LIF share one."""


def _kind(p: FrontierPoint) -> tuple[str, str]:
    return KIND_MARKERS.get(p["kind"], ("o", p["kind"]))


def _row(p: FrontierPoint) -> list[str]:
    way = p["in_the_way"]["part"] if p["in_the_way"] else "-"
    fp32, int8 = p["ratio_fp32"], p["ratio_int8"]
    return [
        point_name(p),
        f"{p['success']:.0%} ({p['success_min']:.0%}-{p['success_max']:.0%})",
        f"{p['energy_nj']:.3g}",
        f"{fp32['median']:.2g} ({fp32['p95']:.2g})",
        f"{int8['median']:.2g} ({int8['p95']:.2g})",
        "yes" if p["keeps_accuracy"] else "no",
        "yes" if p["goal"] else "no",
        way,
    ]


def frontier_block(summary: Frontier, source: str, begin: str, end: str, commit: str) -> str:
    """The docs' generated block: where it comes from, then per env the dense ANN, a table of
    the points and the verdict sentence."""
    head = [
        "point",
        "success (seeds' range)",
        f"nJ on {summary['chip']}",
        "x fp32 ANN, median (p95)",
        "x int8 ANN, median (p95)",
        "keeps accuracy",
        "goal",
        "in the way",
    ]
    parts = [begin.format(source=source), f"Rendered from `{source}` (commit {commit})."]
    for env, info in summary["envs"].items():
        ann = info["ann_nj"]
        fp32, int8 = (ann[b] for b in summary["baselines"])
        parts.append(
            f"**{env}** — dense ANN {'-'.join(map(str, info['ann_widths']))}: "
            f"{info['ann_success']:.0%} success; {fp32:.3g} nJ (fp32 + SRAM), "
            f"{int8:.3g} nJ (int8) per inference."
        )
        rows = [_row(p) for p in summary["points"] if p["env"] == env]
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        parts.append("\n".join(lines))
    parts.append("\n".join(f"- {info['verdict']}" for info in summary["envs"].values()))
    parts.append(end)
    return "\n\n".join(parts)


def frontier_figure(summary: Frontier) -> bytes:
    """Success against energy per inference on the goal's chip, one panel per env: a marker
    per point (its kind), the ANN baselines' energy as vertical lines and 95 % of the dense
    ANN's success as a horizontal one. PNG bytes."""
    from snnkart.report.plots import _figure, _png

    envs = list(summary["envs"])
    fig, axes = _figure(4.2 * len(envs), 3.8, ncols=len(envs))
    axes = list(np.atleast_1d(axes).ravel())
    for ax, env in zip(axes, envs, strict=True):
        info = summary["envs"][env]
        mine = [p for p in summary["points"] if p["env"] == env]
        for marker, label in dict.fromkeys([*KIND_MARKERS.values(), *map(_kind, mine)]):
            pts = [p for p in mine if _kind(p) == (marker, label)]
            if pts:
                ax.scatter(
                    [p["energy_nj"] for p in pts],
                    [p["success"] for p in pts],
                    marker=marker,
                    s=46,
                    label=label,
                    zorder=3,
                )
        for base, style in zip(summary["baselines"], ("--", ":"), strict=True):
            ax.axvline(info["ann_nj"][base], color="grey", ls=style, lw=1, label=f"ANN, {base}")
        if info["ann_success"] is not None:
            ax.axhline(
                KEEP * info["ann_success"],
                color="black",
                lw=0.6,
                label=f"{KEEP:.0%} of the ANN's success",
            )
        ax.set_xscale("log")
        ax.set_title(env)
        ax.set_xlabel(f"energy per inference on {summary['chip']} (nJ, central)")
        ax.set_ylim(-0.03, 1.03)
    axes[0].set_ylabel("success (median of seeds)")
    axes[-1].legend(fontsize=7, loc="best")
    fig.tight_layout()
    return bytes(_png(fig))


def verdicts_block(summary: Frontier, source: str, begin: str, end: str) -> str:
    """The README's generated block: the verdict per env, one sentence each."""
    lines = "\n".join(f"- {info['verdict']}" for info in summary["envs"].values())
    return "\n\n".join([begin.format(source=source), lines, end])
