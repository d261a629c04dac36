"""Issue 34's energy goal, decided: does a temporally sparse policy (sigma-delta, or stateful
LIF) cost at most half the memory-inclusive fp32 ANN and no more than the memory-inclusive int8
ANN, each with the whole 90 % interval on the winning side? And if not, which single term of
its energy is in the way?

The rule (:func:`decide`): on a chip, a bound ``policy <= factor x baseline`` holds when the
95th percentile of the policy/ANN ratio, every price range sampled together
(:func:`snnkart.energy.uncertainty.joint`), is at most ``factor``; the goal holds on the chip
when both bounds hold (:data:`BOUNDS`). It is decided on :data:`PRIMARY` (``loihi2``, the
only profile with graded messages); :data:`PROXIES` (``loihi1``) are decided alike and named
beside it. Dynamic energy decides; the chip's static power over the control period is shown
beside it (``static_pj``). SANA-FE's Loihi model gives one energy, no interval: there a bound holds when that
energy is at most ``factor`` x the baseline's 5th percentile (the baseline's whole interval on
the losing side). The goal holds when it holds on the primary chip and, where SANA-FE ran, on
SANA-FE's model too.

The term in the way (:func:`in_the_way`): on a chip where a bound fails, the part of the
policy's energy (synaptic ops, messages, neuron updates, host link, ...) whose removal alone
lowers the ratio's 95th percentile most, with its energy, the ratio with and without it, and
whether removing it alone would be enough.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from snnkart.contract.energy_record import (
    ChipGoal,
    Goal,
    GoalCheck,
    InTheWay,
    PartEnergy,
    SanafeCheck,
    SanafeGoal,
    Spread,
)
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.pricing import Term, ann_terms, static_terms, terms, total
from snnkart.energy.profiles import Profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.energy.uncertainty import SAMPLES, SEED, joint

FP32 = "horowitz45_fp32_sram"
INT8 = "horowitz45_int8"
BOUNDS = ((FP32, 0.5), (INT8, 1.0))
"""The goal's bounds: the baseline profile (memory-inclusive, the energy ruler's) and the
largest policy/ANN ratio allowed against it."""
PRIMARY = "loihi2"
PROXIES = ("loihi1",)


@dataclass(frozen=True)
class Priced:
    """A policy on ``chip`` against the ANN on ``baseline``: both sides' terms and the
    profiles they name (as :func:`joint` takes them: the chip with any derived prices)."""

    chip: str
    baseline: str
    snn: tuple[Term, ...]
    ann: tuple[Term, ...]
    profiles: tuple[Profile, ...]
    period_s: float  # the control period its static power is taken over (the policy's)


def _nj(x: float | None) -> str:
    return "-" if x is None else f"{x / 1e3:.3g} nJ"


def check(p: Priced, factor: float, samples: int = SAMPLES, seed: int = SEED) -> GoalCheck:
    """One bound on one chip: the ratio's median and 90 % interval, and whether its whole
    interval is at most ``factor``."""
    j = joint(p.snn, p.ann, p.profiles, samples, seed)
    top = j["ratio"]["p95"]
    return {
        "chip": p.chip,
        "baseline": p.baseline,
        "factor": factor,
        "ratio": j["ratio"],
        "snn_pj": j["snn_pj"],
        "ann_pj": j["ann_pj"],
        "holds": top is not None and top <= factor,
    }


def in_the_way(p: Priced, factor: float, samples: int = SAMPLES, seed: int = SEED) -> InTheWay:
    """The part of the policy's energy whose removal alone lowers the ratio's 95th percentile
    most (module docstring), with the numbers."""
    parts = list(dict.fromkeys(t.part for t in p.snn))
    rows: list[PartEnergy] = []
    for part in parts:
        kept = [t for t in p.snn if t.part != part]
        alone = [t for t in p.snn if t.part == part]
        without = joint(kept, p.ann, p.profiles, samples, seed)["ratio"]["p95"]
        energy = joint(alone, p.ann, p.profiles, samples, seed)["snn_pj"]
        rows.append({"part": part, "part_pj": energy, "ratio_p95_without": without})
    best = min(
        rows,
        key=lambda r: float("inf") if r["ratio_p95_without"] is None else r["ratio_p95_without"],
    )
    now = check(p, factor, samples, seed)
    without = best["ratio_p95_without"]
    clears = without is not None and without <= factor
    e = best["part_pj"]
    text = (
        f"on {p.chip}, {best['part']} is in the way: {_nj(e['median'])} (90 %: "
        f"{_nj(e['p05'])}-{_nj(e['p95'])}) of the policy's {_nj(now['snn_pj']['median'])}, "
        f"against {factor:g}x the {p.baseline} ANN's {_nj(now['ann_pj']['median'])}; the ratio's "
        f"90 % interval tops out at {now['ratio']['p95']:.3g}x, without {best['part']} at "
        f"{'-' if without is None else f'{without:.3g}x'} (needs <= {factor:g}x"
        f"{'' if clears else '; removing it alone is not enough'})"
    )
    return {
        **best,
        "chip": p.chip,
        "baseline": p.baseline,
        "factor": factor,
        "ratio_p95": now["ratio"]["p95"],
        "clears": clears,
        "text": text,
    }


def sanafe_check(snn_pj: float, ann_pj: Spread, baseline: str, factor: float) -> SanafeCheck:
    """One bound on SANA-FE's single energy ``snn_pj`` against the baseline's spread
    ``ann_pj`` (median, p05, p95): it holds when ``snn_pj <= factor x p05``."""
    low = ann_pj["p05"]
    return {
        "chip": "sanafe",
        "baseline": baseline,
        "factor": factor,
        "snn_pj": snn_pj,
        "ann_pj": ann_pj,
        "ratio_p95": snn_pj / low if low else None,
        "holds": low is not None and snn_pj <= factor * low,
    }


def _static(p: Priced, chip: str) -> float | None:
    """Beside the dynamic verdict: the chip's static power over one control period (pJ), or
    None where the profile publishes none."""
    profile = next(x for x in p.profiles if x.name == chip)
    terms = static_terms(profile, p.period_s, "chip")
    return total(terms) if terms else None


def _chip(priced: Sequence[Priced], chip: str, samples: int, seed: int) -> ChipGoal:
    by = {p.baseline: p for p in priced if p.chip == chip}
    missing = [b for b, _ in BOUNDS if b not in by]
    if missing:
        raise ValueError(
            f"the goal on {chip} needs the policy priced against {missing[0]}; price it there"
        )
    checks = [check(by[b], f, samples, seed) for b, f in BOUNDS]
    out: ChipGoal = {
        "chip": chip,
        "holds": all(c["holds"] for c in checks),
        "checks": checks,
        "in_the_way": None,
        "static_pj": _static(by[BOUNDS[0][0]], chip),
    }
    if not out["holds"]:
        worst = max(checks, key=lambda c: (c["ratio"]["p95"] or float("inf")) / c["factor"])
        out["in_the_way"] = in_the_way(by[worst["baseline"]], worst["factor"], samples, seed)
    return out


def decide(
    priced: Sequence[Priced],
    sanafe_pj: float | Mapping[str, float] | None = None,
    primary: str = PRIMARY,
    proxies: Sequence[str] = PROXIES,
    samples: int = SAMPLES,
    seed: int = SEED,
) -> dict[str, Any]:
    """The goal's verdict (module docstring) from the policy priced on ``primary`` and each of
    ``proxies`` against both baselines, and SANA-FE's energy per inference where it ran (its
    chip energy plus snnkart's host and link terms: one figure, or one per baseline where the
    host work is priced on the baseline's profile)."""
    main = _chip(priced, primary, samples, seed)
    named = [_chip(priced, chip, samples, seed) for chip in proxies]
    sanafe: SanafeGoal | None = None
    if sanafe_pj is not None:
        ann = {c["baseline"]: c["ann_pj"] for c in main["checks"]}
        per = sanafe_pj if isinstance(sanafe_pj, Mapping) else dict.fromkeys(ann, sanafe_pj)
        checks = [sanafe_check(per[b], ann[b], b, f) for b, f in BOUNDS]
        sanafe = {"holds": all(c["holds"] for c in checks), "checks": checks}
    holds = bool(main["holds"]) and (sanafe is None or bool(sanafe["holds"]))
    goal: Goal = {
        "rule": "policy/ANN ratio's 95th percentile <= 0.5 against the memory-inclusive fp32 "
        "ANN and <= 1 against the memory-inclusive int8 ANN (SANA-FE: its energy against the "
        "ANN's 5th percentile)",
        "primary": main,
        "proxies": named,
        "sanafe": sanafe,
        "holds": holds,
        "sanafe_run": sanafe is not None,
        "verdict": _verdict(main, named, sanafe, holds),
    }
    return dict(goal)  # a plain dict: snnkart.app.report_sigma_delta hands it on as one


def _verdict(main: ChipGoal, named: list[ChipGoal], sanafe: SanafeGoal | None, holds: bool) -> str:
    tops = ", ".join(f"{c['ratio']['p95']:.3g}x the {c['baseline']} ANN" for c in main["checks"])
    head = (
        f"the goal {'holds' if holds else 'does not hold'} on {main['chip']} "
        f"(the 90 % interval tops out at {tops})"
    )
    if main["in_the_way"]:
        head += f"; {main['in_the_way']['text']}"
    for chip in named:
        head += f"; proxy {chip['chip']}: {'holds' if chip['holds'] else 'does not hold'}"
    if sanafe is None:
        head += "; SANA-FE not run"
    else:
        head += f"; SANA-FE's Loihi model: {'holds' if sanafe['holds'] else 'does not hold'}"
    return head


def priced_policy(
    policy: SigmaDeltaCounts | SnnCounts, chip: Profile, baseline: Profile, ann: AnnCounts
) -> Priced:
    """A policy of any family (sigma-delta, LIF, stateful or not) priced by :func:`terms` on
    ``chip`` with its host work on ``baseline``, against ``ann`` on ``baseline`` (as the
    report prices a pair when no host profile is given)."""
    snn = terms(policy, chip, baseline)
    return Priced(
        chip.name,
        baseline.name,
        tuple(snn),
        tuple(ann_terms(ann, baseline)),
        (policy.prices_for(chip), baseline),
        policy.period_s,
    )
