"""The report's first screen: one sentence that answers "is the spiking policy worth it?" and
the data of the one chart beside it (energy per inference with its 90 % interval, the SNN on
each chip against the ANN on each digital target, both success rates, P(SNN cheaper) per pair),
every profile named with the evidence grades of its prices."""

from __future__ import annotations

from collections.abc import Mapping

from snnkart.contract.energy_record import Spread
from snnkart.contract.report_record import ComparisonRow, lif_report, sd_report
from snnkart.report.plots import ChartRow


def primary(report: Mapping[str, object]) -> str:
    """The ANN the verdict is about: the user's run where there is one, else the same widths."""
    return "run" if "run" in lif_report(report)["ann"] else "same_width"


def pairs(report: Mapping[str, object]) -> list[ComparisonRow]:
    """The primary ANN's comparisons, one per (chip, digital target)."""
    key = primary(report)
    return [c for c in lif_report(report)["comparisons"] if c["ann"] == key]


def grade(report: Mapping[str, object], profile: str) -> str:
    """The evidence tags of a profile's non-zero prices of dynamic energy (static power has a
    tag of its own in the price table), most frequent first."""
    priced = lif_report(report)["profiles"][profile]["prices"]
    prices = [p for op, p in priced.items() if op != "static_power"]
    tags = [p["tag"] for p in prices if p["pj"] > 0] or [p["tag"] for p in prices]
    return ", ".join(sorted(dict.fromkeys(tags), key=lambda t: -tags.count(t)))


def graded(report: Mapping[str, object], profile: str) -> str:
    """A profile's name with its evidence grade: ``loihi1 [pre-silicon, derived]``."""
    return f"{profile} [{grade(report, profile)}]"


def pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def times(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x:,.0f}x" if x >= 100 else f"{x:.3g}x"


def ann_success(report: Mapping[str, object], c: ComparisonRow) -> str:
    """The ANN's success on a pair's target; an int8 datapath's is the int8 ANN's, measured."""
    if c.get("ann_success_rate") is None:
        return "not run"
    return pct(c["ann_success_rate"]) + (" (int8, measured)" if "int8" in c["ann_success"] else "")


def _p(c: ComparisonRow) -> float:
    return float(c["uncertainty"]["p_snn_cheaper"])


def _best(rows: list[ComparisonRow]) -> ComparisonRow:
    """The pair most favourable to the SNN: highest P(SNN cheaper), then lowest ratio."""
    return min(rows, key=lambda c: (-_p(c), c["uncertainty"]["ratio"]["median"] or float("inf")))


def _interval(c: ComparisonRow) -> str:
    r = c["uncertainty"]["ratio"]
    if r["median"] is None:
        return "undefined (the ANN costs 0 pJ)"
    return f"a median {times(r['median'])} the ANN's energy (90 %: {times(r['p05'])}-{times(r['p95'])})"


def sentence(report: Mapping[str, object]) -> str:
    """The verdict in one sentence: dynamic energy only, then with static power."""
    rows, lif = pairs(report), lif_report(report)
    label = lif["ann"][primary(report)]["label"]
    wins = sum(_p(c) > 0.5 for c in rows)
    best = _best(rows)
    with_static = [c["static"]["ratio"] for c in rows if c["static"]["ratio"] is not None]
    static_wins = sum(r < 1 for r in with_static)
    period = rows[0]["static"]["control_period_s"] * 1e3
    snn_ok = pct(lif["snn"]["task"]["success_rate"])
    ann_said = ann_success(report, best)
    ann_said = "the ANN was not run" if ann_said == "not run" else f"ANN success {ann_said}"
    return (
        f"Dynamic energy only, the SNN (success {snn_ok}) is more likely than not to cost less "
        f"than the {label} in {wins} of {len(rows)} chip/target pairs; in its best pair, on "
        f"{best['snn_profile']} against the ANN on {best['ann_profile']} ({ann_said}), it "
        f"costs {_interval(best)}, P(SNN cheaper) "
        f"{_p(best):.2f}; "
        f"with static power over the {period:.1f} ms control period{_unpublished(rows)} it "
        f"costs less in {static_wins} of {len(with_static)}"
        + (f" (lowest ratio {times(min(with_static))})." if with_static else ".")
    )


def _unpublished(rows: list[ComparisonRow]) -> str:
    """Whose static power the with-static count leaves at 0 (not published), said inline."""
    missing = sorted(
        {
            n["profile"]
            for c in rows
            for n in c["static"].get("not_published", [])
            if n["op"] == "static_power"
        }
    )
    if not missing:
        return ""
    return f" (not published, so counted as 0, for {', '.join(missing)})"


def chart_rows(report: Mapping[str, object]) -> list[ChartRow]:
    """One row per pair for the first-screen chart: both energies (nJ) as the point estimate
    and the 5th-95th percentile of the joint sample, the profiles with their grades, the ANN's
    success on the target, and P(SNN cheaper)."""
    rows: list[ChartRow] = []
    for c in pairs(report):
        u = c["uncertainty"]
        rows.append(
            {
                "label": f"SNN on {graded(report, c['snn_profile'])}\n"
                f"vs ANN on {graded(report, c['ann_profile'])}",
                "ann_success": ann_success(report, c),
                "snn_nj": _nj_point(c["snn_pj"], u["snn_pj"]),
                "ann_nj": _nj_point(c["ann_pj"], u["ann_pj"]),
                "p": _p(c),
            }
        )
    return rows


def chart_legend(report: Mapping[str, object]) -> tuple[str, str]:
    """The chart's two series: the SNN with its success, the ANN with its label."""
    lif = lif_report(report)
    label = lif["ann"][primary(report)]["label"]
    return (
        f"SNN (success {pct(lif['snn']['task']['success_rate'])})",
        f"{label} (success at the right)",
    )


def _band(energy: Spread) -> tuple[float, float]:
    """An energy's 5th and 95th percentile, pJ: finite, as every energy is (only a ratio over
    an ANN priced at 0 pJ is not)."""
    low, high = energy["p05"], energy["p95"]
    assert low is not None and high is not None, "an energy's percentiles are finite"
    return low, high


def _nj_point(pj: float, energy: Spread) -> tuple[float, float, float]:
    """An energy and its 90 % interval in nJ, as the chart draws them."""
    low, high = _band(energy)
    return pj / 1e3, low / 1e3, high / 1e3


def _nj(pj: float) -> str:
    return f"{pj / 1000:.3g}"


def _nj_band(pj: float, energy: Spread) -> str:
    """An energy with its 90 % interval, nJ: ``1.2 (0.9-1.6)``."""
    low, high = _band(energy)
    return f"{_nj(pj)} ({_nj(low)}-{_nj(high)})"


def pair_rows(report: Mapping[str, object]) -> list[dict[str, str]]:
    """The verdict per pair: energies with their 90 % intervals, the ratio's median and
    interval, P(SNN cheaper), the ratio with static power, and both success rates."""
    snn_ok = pct(lif_report(report)["snn"]["task"]["success_rate"])
    rows = []
    for c in pairs(report):
        u, r = c["uncertainty"], c["uncertainty"]["ratio"]
        rows.append(
            {
                "SNN on": graded(report, c["snn_profile"]),
                "ANN on": graded(report, c["ann_profile"]),
                "SNN nJ (90 %)": _nj_band(c["snn_pj"], u["snn_pj"]),
                "ANN nJ (90 %)": _nj_band(c["ann_pj"], u["ann_pj"]),
                "SNN/ANN median (90 %), dynamic": "-"
                if r["median"] is None
                else f"{times(r['median'])} ({times(r['p05'])}-{times(r['p95'])})",
                "P(SNN cheaper)": f"{_p(c):.2f}",
                "SNN/ANN with static": times(c["static"]["ratio"]),
                "SNN success": snn_ok,
                "ANN success": ann_success(report, c),
            }
        )
    return rows


def merged_note(report: Mapping[str, object]) -> str:
    """Which comparisons were dropped as duplicates of the primary ANN's (same energies)."""
    if primary(report) != "run":
        return ""
    run = {(c["snn_profile"], c["ann_profile"]): c for c in pairs(report)}
    same = [
        c
        for c in lif_report(report)["comparisons"]
        if c["ann"] == "same_width" and (c["snn_profile"], c["ann_profile"]) in run
    ]
    equal = [c for c in same if c["ann_pj"] == run[(c["snn_profile"], c["ann_profile"])]["ann_pj"]]
    if not equal:
        return ""
    if len(equal) == len(same):
        return (
            f"The same-width ANN has the ANN run's widths: its {len(equal)} rows equal the "
            "run's and are merged into them (report.json keeps both)."
        )
    return f"{len(equal)} same-width ANN rows equal the ANN run's and are merged into them."


def distinct(report: Mapping[str, object]) -> list[ComparisonRow]:
    """Every comparison but the same-width ANN's that equal the ANN run's."""
    comparisons = lif_report(report)["comparisons"]
    if not merged_note(report):
        return list(comparisons)
    run = {(c["snn_profile"], c["ann_profile"]): c["ann_pj"] for c in pairs(report)}
    return [
        c
        for c in comparisons
        if not (
            c["ann"] == "same_width"
            and run.get((c["snn_profile"], c["ann_profile"])) == c["ann_pj"]
        )
    ]


def sd_sentence(report: Mapping[str, object]) -> str:
    """A sigma-delta deployment's answer first (does issue 34's goal hold on the primary chip,
    with the ratios' 90 % intervals), then the term in the way, the proxies and SANA-FE: the
    goal's own verdict (:func:`snnkart.energy.goal.decide`)."""
    sd = sd_report(report)
    g = sd["goal"]
    checks = "; ".join(
        f"{times(c['ratio']['median'])} the {c['baseline']} ANN (90 %: "
        f"{times(c['ratio']['p05'])}-{times(c['ratio']['p95'])}, needs <= {c['factor']:g}x)"
        for c in g["primary"]["checks"]
    )
    return (
        f"{'Yes' if g['holds'] else 'No'}: the sigma-delta policy (success "
        f"{pct(sd['task']['success_rate'])}) {'meets' if g['holds'] else 'does not meet'} "
        f"the energy goal on {g['primary']['chip']}: dynamic energy per inference {checks}. "
        f"In words: {g['verdict']}."
    )
