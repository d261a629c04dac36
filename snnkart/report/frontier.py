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
``study.json`` and the profiles; nothing is typed by hand. The published page
(``docs/frontier.md``) is written from this summary by ``scripts/docs_blocks/frontier_blocks.py``.
"""

from __future__ import annotations

import statistics
from typing import Any, TypedDict

from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.goal import BOUNDS, PRIMARY, PROXIES, Priced, decide, priced_policy
from snnkart.energy.pricing import total
from snnkart.energy.profiles import Profile, load_profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.report.study_record import RunRecord, StudyRecord

KEEP = 0.95
"""A point keeps the accuracy at this fraction of the dense ANN's median success or more."""
HIDDEN = (64, 64)
"""The dense ANN's hidden widths (the study's ``ann`` cell: the ANN policy's default)."""


class Spread(TypedDict):
    """A policy/ANN ratio's median and 90 % interval (None where not finite)."""

    median: float | None
    p05: float | None
    p95: float | None


class InTheWay(TypedDict):
    """The term in the way of the goal on the goal's chip (:func:`snnkart.energy.goal.in_the_way`):
    its part and the sentence naming it."""

    part: str
    text: str


class FrontierPoint(TypedDict):
    """One point of the frontier: a policy kind and variant in one env, over its seeds."""

    env: str
    policy: str
    variant: str
    seeds: list[int]
    success: float
    success_min: float
    success_max: float
    keeps_accuracy: bool
    energy_nj: float
    median_energy_seed: int
    ratio_fp32: Spread
    ratio_int8: Spread
    energy_goal: bool
    proxy_holds: dict[str, bool]
    in_the_way: InTheWay | None
    goal: bool
    kind: str


class FrontierEnv(TypedDict):
    """One env of the frontier: the dense ANN's success, widths and energy per baseline (nJ),
    and the env's verdict (:func:`env_verdict`)."""

    ann_success: float | None
    ann_widths: list[int]
    ann_nj: dict[str, float]
    verdict: str


class Frontier(TypedDict):
    """The frontier of a study (:func:`frontier`)."""

    chip: str
    proxies: list[str]
    keep: float
    baselines: list[str]
    envs: dict[str, FrontierEnv]
    points: list[FrontierPoint]


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


def _priced(
    counts: SigmaDeltaCounts | SnnCounts, ann: AnnCounts, profiles: dict[str, Profile]
) -> list[Priced]:
    return [
        priced_policy(counts, profiles[chip], profiles[base], ann)
        for chip in (PRIMARY, *PROXIES)
        for base, _ in BOUNDS
    ]


def _energy_nj(
    counts: SigmaDeltaCounts | SnnCounts, ann: AnnCounts, profiles: dict[str, Profile]
) -> float:
    """Central energy per inference on the goal's chip (host work on the fp32 baseline), nJ."""
    p = priced_policy(counts, profiles[PRIMARY], profiles[BOUNDS[0][0]], ann)
    return total(p.snn) / 1e3


def _median_run(
    runs: list[RunRecord], ann: AnnCounts, profiles: dict[str, Profile]
) -> tuple[RunRecord, list[float]]:
    """The seed whose central energy is the median (of an even count, the lower middle), and
    every seed's energy."""
    energies = [_energy_nj(c, ann, profiles) for c in (_counts(r) for r in runs) if c]
    order = sorted(range(len(runs)), key=lambda i: (energies[i], runs[i].seed))
    return runs[order[(len(order) - 1) // 2]], energies


def _point(
    cell: tuple[str, str, str, str],
    runs: list[RunRecord],
    ann_success: float | None,
    ann: AnnCounts,
    profiles: dict[str, Profile],
) -> FrontierPoint:
    """The point of ``cell`` (env, policy, variant and its kind label) over its seeds."""
    env, policy, variant, kind = cell
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
        "env": env,
        "policy": policy,
        "variant": variant,
        "seeds": [r.seed for r in runs],
        "success": success,
        "success_min": min(r.eval_success_rate for r in runs),
        "success_max": max(r.eval_success_rate for r in runs),
        "keeps_accuracy": keeps,
        "energy_nj": statistics.median(energies),
        "median_energy_seed": chosen.seed,
        "ratio_fp32": ratios[BOUNDS[0][0]],
        "ratio_int8": ratios[BOUNDS[1][0]],
        "energy_goal": bool(main["holds"]),
        "proxy_holds": {c["chip"]: bool(c["holds"]) for c in verdict["proxies"]},
        "in_the_way": None if way is None else {"part": way["part"], "text": way["text"]},
        "goal": keeps and bool(main["holds"]),
        "kind": kind,
    }


def frontier(record: StudyRecord) -> Frontier:
    """Every priced point of the study, the dense ANN's success and the ANN baselines' energy
    per env, and the verdict per env (:func:`env_verdict`)."""
    profiles = {n: load_profile(n) for n in (PRIMARY, *PROXIES, *(b for b, _ in BOUNDS))}
    cells: dict[tuple[str, str, str], list[RunRecord]] = {}
    for r in record.runs:
        cells.setdefault((r.env, r.policy, r.variant), []).append(r)
    envs: dict[str, FrontierEnv] = {}
    points: list[FrontierPoint] = []
    for env in dict.fromkeys(r.env for r in record.runs):
        priced = [r for (e, _, _), rs in cells.items() if e == env for r in rs if _counts(r)]
        if not priced:
            continue
        counts = _counts(priced[0])
        assert counts is not None
        ann = _shape(counts)
        dense = cells.get((env, "ann", ""), [])
        ann_success = statistics.median(r.eval_success_rate for r in dense) if dense else None
        mine: list[FrontierPoint] = []
        for (e, policy, variant), runs in cells.items():
            if e == env and all(_counts(r) for r in runs):
                kind = record.study.run_label(runs[0].track, env, policy, variant)
                mine.append(_point((env, policy, variant, kind), runs, ann_success, ann, profiles))
        points += mine
        envs[env] = {
            "ann_success": ann_success,
            "ann_widths": list(ann.widths),
            "ann_nj": {b: total(_base_terms(ann, profiles[b])) / 1e3 for b, _ in BOUNDS},
            "verdict": env_verdict(env, mine, ann_success),
        }
    return {
        "chip": PRIMARY,
        "proxies": list(PROXIES),
        "keep": KEEP,
        "baselines": [b for b, _ in BOUNDS],
        "envs": envs,
        "points": points,
    }


def _base_terms(ann: AnnCounts, profile: Profile) -> list[Any]:
    from snnkart.energy.pricing import ann_terms

    return ann_terms(ann, profile)


def point_name(p: FrontierPoint) -> str:
    """The point's policy kind and variant, as the page names it."""
    return f"{p['policy']} {p['variant']}".strip()


def env_verdict(env: str, points: list[FrontierPoint], ann_success: float | None) -> str:
    """One sentence: the best point that reaches the goal, or how close the frontier comes and
    the single term in the way (``ann_success``: the dense ANN's median success)."""
    reach = sorted((p for p in points if p["goal"]), key=lambda p: p["energy_nj"])
    if reach:
        b = reach[0]
        return (
            f"{env}: the goal is reached by {point_name(b)} ({b['success']:.0%} success, "
            f"{b['energy_nj']:.3g} nJ per inference; its 90 % interval tops out at "
            f"{b['ratio_fp32']['p95']:.2g}x the fp32 ANN and {b['ratio_int8']['p95']:.2g}x "
            "the int8 ANN)."
        )
    keep = [p for p in points if p["keeps_accuracy"]] or points
    b = min(keep, key=lambda p: p["ratio_int8"]["p95"] or float("inf"))
    way = b["in_the_way"]["text"] if b["in_the_way"] else "none named"
    accuracy = (
        "keeps the accuracy"
        if b["keeps_accuracy"]
        else f"does not keep the accuracy ({b['success']:.0%} against the ANN's {ann_success:.0%})"
    )
    return (
        f"{env}: no point reaches the goal; the closest, {point_name(b)}, {accuracy} and "
        f"costs {b['energy_nj']:.3g} nJ per inference at central prices, its 90 % interval "
        f"up to {b['ratio_fp32']['p95']:.2g}x the fp32 ANN (goal 0.5) and "
        f"{b['ratio_int8']['p95']:.2g}x the int8 ANN (goal 1); in the way: {way}."
    )
