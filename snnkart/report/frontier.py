"""The temporal-sparsity frontier (issue 34): every point of a frontier study (a policy kind and
variant in one env, over its seeds) with its success and its energy per inference on the chips,
against the fair ANN baselines, and the goal decided per point and per env.

A point **keeps the accuracy** when the median success of its seeds (50 seeded episodes each,
fixed point on the numpy reference, bit-exact with Lava) is at least 95 % of the dense ANN's
(the ``ann`` cell of the same env: tanh, 64-64, torch). Its **energy** is priced from the
counts of its median-energy seed with :func:`snnkart.energy.goal.priced_policy` on ``loihi2``
(the goal's chip) and ``loihi1`` (a named proxy), against the memory-inclusive fp32 and the int8
ANN of the env's shape (``n_in``-64-64-``n_out``); :func:`snnkart.energy.goal.decide` says
whether the whole 90 % interval is on the winning side and, if not, names the term in the way.
A point **reaches the goal** when it does both. Every number is computed here from
``study.json`` and the profiles; nothing is typed by hand.
"""

from __future__ import annotations

import statistics
from typing import Any

import numpy as np

from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.goal import BOUNDS, PRIMARY, PROXIES, decide, priced_policy
from snnkart.energy.pricing import total
from snnkart.energy.profiles import Profile, load_profile
from snnkart.energy.sd_counts import SigmaDeltaCounts
from snnkart.report.study_record import RunRecord, StudyRecord

KEEP = 0.95
"""A point keeps the accuracy at this fraction of the dense ANN's median success or more."""
HIDDEN = (64, 64)
"""The dense ANN's hidden widths (the study's ``ann`` cell: the ANN policy's default)."""


def _counts(run: RunRecord) -> SigmaDeltaCounts | SnnCounts | None:
    if run.sigma_delta_counts is not None:
        return SigmaDeltaCounts.from_dict(run.sigma_delta_counts)
    if run.eval_counts_per_step is not None:
        return SnnCounts.of_sweep(run.eval_counts_per_step)
    return None


def _shape(counts: SigmaDeltaCounts | SnnCounts) -> AnnCounts:
    """The dense ANN of the env the counts come from: its inputs, 64-64, its outputs."""
    if isinstance(counts, SigmaDeltaCounts):
        return AnnCounts((counts.n_in, *HIDDEN, counts.n_out), counts.action_mode)
    net = counts.net
    n_in = net.n_in // (net.population or 1)
    return AnnCounts((n_in, *HIDDEN, net.n_out), net.action_mode)


def _priced(counts: SigmaDeltaCounts | SnnCounts, ann: AnnCounts,
            profiles: dict[str, Profile]) -> list[Any]:  # fmt: skip
    return [priced_policy(counts, profiles[chip], profiles[base], ann)
            for chip in (PRIMARY, *PROXIES) for base, _ in BOUNDS]  # fmt: skip


def _energy_nj(
    counts: SigmaDeltaCounts | SnnCounts, ann: AnnCounts, profiles: dict[str, Profile]
) -> float:
    """Central energy per inference on the goal's chip (host work on the fp32 baseline), nJ."""
    p = priced_policy(counts, profiles[PRIMARY], profiles[BOUNDS[0][0]], ann)
    return total(p.snn) / 1e3


def _median_run(runs: list[RunRecord], ann: AnnCounts,
                profiles: dict[str, Profile]) -> tuple[RunRecord, list[float]]:  # fmt: skip
    """The seed whose central energy is the median (of an even count, the lower middle), and
    every seed's energy."""
    energies = [_energy_nj(c, ann, profiles) for c in (_counts(r) for r in runs) if c]
    order = sorted(range(len(runs)), key=lambda i: (energies[i], runs[i].seed))
    return runs[order[(len(order) - 1) // 2]], energies


def _point(env: str, policy: str, variant: str, runs: list[RunRecord], ann_success: float | None,
           ann: AnnCounts, profiles: dict[str, Profile]) -> dict[str, Any]:  # fmt: skip
    success = statistics.median(r.eval_success_rate for r in runs)
    keeps = ann_success is not None and success >= KEEP * ann_success
    chosen, energies = _median_run(runs, ann, profiles)
    counts = _counts(chosen)
    assert counts is not None
    verdict = decide(_priced(counts, ann, profiles))
    main = verdict["primary"]
    ratios = {c["baseline"]: c["ratio"] for c in main["checks"]}
    way = main["in_the_way"]
    return {
        "env": env, "policy": policy, "variant": variant, "seeds": [r.seed for r in runs],
        "success": success, "success_min": min(r.eval_success_rate for r in runs),
        "success_max": max(r.eval_success_rate for r in runs), "keeps_accuracy": keeps,
        "energy_nj": statistics.median(energies), "median_energy_seed": chosen.seed,
        "ratio_fp32": ratios[BOUNDS[0][0]], "ratio_int8": ratios[BOUNDS[1][0]],
        "energy_goal": bool(main["holds"]),
        "proxy_holds": {c["chip"]: bool(c["holds"]) for c in verdict["proxies"]},
        "in_the_way": None if way is None else {k: way[k] for k in ("part", "text")},
        "goal": keeps and bool(main["holds"]),
    }  # fmt: skip


def frontier(record: StudyRecord) -> dict[str, Any]:
    """Every priced point of the study, the dense ANN's success and the ANN baselines' energy
    per env, and the verdict per env (:func:`env_verdict`)."""
    profiles = {n: load_profile(n) for n in (PRIMARY, *PROXIES, *(b for b, _ in BOUNDS))}
    cells: dict[tuple[str, str, str], list[RunRecord]] = {}
    for r in record.runs:
        cells.setdefault((r.env, r.policy, r.variant), []).append(r)
    envs: dict[str, Any] = {}
    points = []
    for env in dict.fromkeys(r.env for r in record.runs):
        priced = [r for (e, _, _), rs in cells.items() if e == env for r in rs if _counts(r)]
        if not priced:
            continue
        counts = _counts(priced[0])
        assert counts is not None
        ann = _shape(counts)
        dense = cells.get((env, "ann", ""), [])
        ann_success = statistics.median(r.eval_success_rate for r in dense) if dense else None
        envs[env] = {"ann_success": ann_success, "ann_widths": list(ann.widths),
                     "ann_nj": {b: total(_base_terms(ann, profiles[b])) / 1e3
                                for b, _ in BOUNDS}}  # fmt: skip
        for (e, policy, variant), runs in cells.items():
            if e == env and all(_counts(r) for r in runs):
                kind = record.study.run_label(runs[0].track, env, policy, variant)
                points.append({**_point(env, policy, variant, runs, ann_success, ann, profiles),
                               "kind": kind})  # fmt: skip
    for env, info in envs.items():
        info["verdict"] = env_verdict(env, [p for p in points if p["env"] == env], info)
    return {"chip": PRIMARY, "proxies": list(PROXIES), "keep": KEEP,
            "baselines": [b for b, _ in BOUNDS], "envs": envs, "points": points}  # fmt: skip


def _base_terms(ann: AnnCounts, profile: Profile) -> list[Any]:
    from snnkart.energy.pricing import ann_terms

    return ann_terms(ann, profile)


def _name(p: dict[str, Any]) -> str:
    return f"{p['policy']} {p['variant']}".strip()


def env_verdict(env: str, points: list[dict[str, Any]], info: dict[str, Any]) -> str:
    """One sentence: the best point that reaches the goal, or how close the frontier comes and
    the single term in the way."""
    reach = sorted((p for p in points if p["goal"]), key=lambda p: p["energy_nj"])
    if reach:
        b = reach[0]
        return (f"{env}: the goal is reached by {_name(b)} ({b['success']:.0%} success, "
                f"{b['energy_nj']:.3g} nJ per inference; its 90 % interval tops out at "
                f"{b['ratio_fp32']['p95']:.2g}x the fp32 ANN and {b['ratio_int8']['p95']:.2g}x "
                "the int8 ANN).")  # fmt: skip
    keep = [p for p in points if p["keeps_accuracy"]] or points
    b = min(keep, key=lambda p: p["ratio_int8"]["p95"] or float("inf"))
    way = b["in_the_way"]["text"] if b["in_the_way"] else "none named"
    accuracy = ("keeps the accuracy" if b["keeps_accuracy"] else
                f"does not keep the accuracy ({b['success']:.0%} against the ANN's "
                f"{info['ann_success']:.0%})")  # fmt: skip
    return (f"{env}: no point reaches the goal; the closest, {_name(b)}, {accuracy} and costs "
            f"{b['energy_nj']:.3g} nJ per inference at central prices, its 90 % interval up to "
            f"{b['ratio_fp32']['p95']:.2g}x the fp32 ANN (goal 0.5) and "
            f"{b['ratio_int8']['p95']:.2g}x the int8 ANN (goal 1); in the way: {way}.")  # fmt: skip


KIND_MARKERS = {"ANN converted": ("v", "ANN converted"),
                "sigma-delta trained": ("^", "sigma-delta trained"),
                "stateful LIF": ("s", "stateful LIF"), "recurrent LIF": ("P", "recurrent LIF"),
                "dense LIF": ("o", "LIF (dense, sparse)"),
                "sparse LIF": ("o", "LIF (dense, sparse)")}  # fmt: skip
"""The figure's marker and legend per kind label (:meth:`StudySettings.run_label`); dense and
sparse LIF share one."""


def _kind(p: dict[str, Any]) -> tuple[str, str]:
    return KIND_MARKERS.get(p["kind"], ("o", p["kind"]))


def _row(p: dict[str, Any]) -> list[str]:
    way = p["in_the_way"]["part"] if p["in_the_way"] else "-"
    return [_name(p), f"{p['success']:.0%} ({p['success_min']:.0%}-{p['success_max']:.0%})",
            f"{p['energy_nj']:.3g}", f"{p['ratio_fp32']['median']:.2g} ({p['ratio_fp32']['p95']:.2g})",
            f"{p['ratio_int8']['median']:.2g} ({p['ratio_int8']['p95']:.2g})",
            "yes" if p["keeps_accuracy"] else "no", "yes" if p["goal"] else "no", way]  # fmt: skip


def frontier_block(summary: dict[str, Any], source: str, begin: str, end: str,
                   commit: str) -> str:  # fmt: skip
    """The docs' generated block: where it comes from, then per env the dense ANN, a table of
    the points and the verdict sentence."""
    head = ["point", "success (seeds' range)", f"nJ on {summary['chip']}",
            "x fp32 ANN, median (p95)", "x int8 ANN, median (p95)", "keeps accuracy", "goal",
            "in the way"]  # fmt: skip
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


def frontier_figure(summary: dict[str, Any]) -> bytes:
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
                ax.scatter([p["energy_nj"] for p in pts], [p["success"] for p in pts],
                           marker=marker, s=46, label=label, zorder=3)  # fmt: skip
        for base, style in zip(summary["baselines"], ("--", ":"), strict=True):
            ax.axvline(info["ann_nj"][base], color="grey", ls=style, lw=1,
                       label=f"ANN, {base}")  # fmt: skip
        if info["ann_success"] is not None:
            ax.axhline(KEEP * info["ann_success"], color="black", lw=0.6,
                       label=f"{KEEP:.0%} of the ANN's success")  # fmt: skip
        ax.set_xscale("log")
        ax.set_title(env)
        ax.set_xlabel(f"energy per inference on {summary['chip']} (nJ, central)")
        ax.set_ylim(-0.03, 1.03)
    axes[0].set_ylabel("success (median of seeds)")
    axes[-1].legend(fontsize=7, loc="best")
    fig.tight_layout()
    return bytes(_png(fig))


def verdicts_block(summary: dict[str, Any], source: str, begin: str, end: str) -> str:
    """The README's generated block: the verdict per env, one sentence each."""
    lines = "\n".join(f"- {info['verdict']}" for info in summary["envs"].values())
    return "\n\n".join([begin.format(source=source), lines, end])
