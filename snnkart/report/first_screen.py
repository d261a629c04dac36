"""The report's first screen: one sentence that answers "is the spiking policy worth it?" and
the data of the one chart beside it (energy per inference with its 90 % interval, the SNN on
each chip against the ANN on each digital target, both success rates, P(SNN cheaper) per pair),
every profile named with the evidence grades of its prices."""

from __future__ import annotations

from typing import Any


def primary(report: dict[str, Any]) -> str:
    """The ANN the verdict is about: the user's run where there is one, else the same widths."""
    return "run" if "run" in report["ann"] else "same_width"


def pairs(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The primary ANN's comparisons, one per (chip, digital target)."""
    key = primary(report)
    return [c for c in report["comparisons"] if c["ann"] == key]


def grade(report: dict[str, Any], profile: str) -> str:
    """The evidence tags of a profile's non-zero prices of dynamic energy (static power has a
    tag of its own in the price table), most frequent first."""
    prices = [p for op, p in report["profiles"][profile]["prices"].items() if op != "static_power"]
    tags = [p["tag"] for p in prices if p["pj"] > 0] or [p["tag"] for p in prices]
    return ", ".join(sorted(dict.fromkeys(tags), key=lambda t: -tags.count(t)))


def graded(report: dict[str, Any], profile: str) -> str:
    """A profile's name with its evidence grade: ``loihi1 [pre-silicon, derived]``."""
    return f"{profile} [{grade(report, profile)}]"


def pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def times(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x:,.0f}x" if x >= 100 else f"{x:.3g}x"


def ann_success(report: dict[str, Any], c: dict[str, Any]) -> str:
    """The ANN's success on a pair's target; an int8 datapath's is the int8 ANN's, measured."""
    if c.get("ann_success_rate") is None:
        return "not run"
    return pct(c["ann_success_rate"]) + (" (int8, measured)" if "int8" in c["ann_success"] else "")


def _p(c: dict[str, Any]) -> float:
    return float(c["uncertainty"]["p_snn_cheaper"])


def _best(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The pair most favourable to the SNN: highest P(SNN cheaper), then lowest ratio."""
    return min(rows, key=lambda c: (-_p(c), c["uncertainty"]["ratio"]["median"] or float("inf")))


def _interval(c: dict[str, Any]) -> str:
    r = c["uncertainty"]["ratio"]
    if r["median"] is None:
        return "undefined (the ANN costs 0 pJ)"
    return f"a median {times(r['median'])} the ANN's energy (90 %: {times(r['p05'])}-{times(r['p95'])})"


def sentence(report: dict[str, Any]) -> str:
    """The verdict in one sentence: dynamic energy only, then with static power."""
    rows = pairs(report)
    label = report["ann"][primary(report)]["label"]
    wins = sum(_p(c) > 0.5 for c in rows)
    best = _best(rows)
    with_static = [c["static"]["ratio"] for c in rows if c["static"]["ratio"] is not None]
    static_wins = sum(r < 1 for r in with_static)
    period = rows[0]["static"]["control_period_s"] * 1e3
    snn_ok = pct(report["snn"]["task"]["success_rate"])
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


def _unpublished(rows: list[dict[str, Any]]) -> str:
    """Whose static power the with-static count leaves at 0 (not published), said inline."""
    missing = sorted({n["profile"] for c in rows for n in c["static"].get("not_published", [])
                      if n["op"] == "static_power"})  # fmt: skip
    if not missing:
        return ""
    return f" (not published, so counted as 0, for {', '.join(missing)})"


def chart_rows(report: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per pair for the first-screen chart: both energies (nJ) as the point estimate
    and the 5th-95th percentile of the joint sample, the profiles with their grades, the ANN's
    success on the target, and P(SNN cheaper)."""
    rows = []
    for c in pairs(report):
        u = c["uncertainty"]
        rows.append({
            "label": f"SNN on {graded(report, c['snn_profile'])}\n"
                     f"vs ANN on {graded(report, c['ann_profile'])}",
            "ann_success": ann_success(report, c),
            "snn_nj": (c["snn_pj"] / 1e3, u["snn_pj"]["p05"] / 1e3, u["snn_pj"]["p95"] / 1e3),
            "ann_nj": (c["ann_pj"] / 1e3, u["ann_pj"]["p05"] / 1e3, u["ann_pj"]["p95"] / 1e3),
            "p": _p(c),
        })  # fmt: skip
    return rows


def chart_legend(report: dict[str, Any]) -> tuple[str, str]:
    """The chart's two series: the SNN with its success, the ANN with its label."""
    label = report["ann"][primary(report)]["label"]
    return (f"SNN (success {pct(report['snn']['task']['success_rate'])})",
            f"{label} (success at the right)")  # fmt: skip


def _nj(pj: float) -> str:
    return f"{pj / 1000:.3g}"


def pair_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """The verdict per pair: energies with their 90 % intervals, the ratio's median and
    interval, P(SNN cheaper), the ratio with static power, and both success rates."""
    snn_ok = pct(report["snn"]["task"]["success_rate"])
    rows = []
    for c in pairs(report):
        u, r = c["uncertainty"], c["uncertainty"]["ratio"]
        rows.append({
            "SNN on": graded(report, c["snn_profile"]),
            "ANN on": graded(report, c["ann_profile"]),
            "SNN nJ (90 %)": f"{_nj(c['snn_pj'])} ({_nj(u['snn_pj']['p05'])}-"
                             f"{_nj(u['snn_pj']['p95'])})",
            "ANN nJ (90 %)": f"{_nj(c['ann_pj'])} ({_nj(u['ann_pj']['p05'])}-"
                             f"{_nj(u['ann_pj']['p95'])})",
            "SNN/ANN median (90 %), dynamic": "-" if r["median"] is None else
            f"{times(r['median'])} ({times(r['p05'])}-{times(r['p95'])})",
            "P(SNN cheaper)": f"{_p(c):.2f}",
            "SNN/ANN with static": times(c["static"]["ratio"]),
            "SNN success": snn_ok,
            "ANN success": ann_success(report, c),
        })  # fmt: skip
    return rows


def merged_note(report: dict[str, Any]) -> str:
    """Which comparisons were dropped as duplicates of the primary ANN's (same energies)."""
    if primary(report) != "run":
        return ""
    run = {(c["snn_profile"], c["ann_profile"]): c for c in pairs(report)}
    same = [c for c in report["comparisons"] if c["ann"] == "same_width"
            and (c["snn_profile"], c["ann_profile"]) in run]  # fmt: skip
    equal = [c for c in same if c["ann_pj"] == run[(c["snn_profile"], c["ann_profile"])]["ann_pj"]]
    if not equal:
        return ""
    if len(equal) == len(same):
        return (f"The same-width ANN has the ANN run's widths: its {len(equal)} rows equal the "
                "run's and are merged into them (report.json keeps both).")  # fmt: skip
    return f"{len(equal)} same-width ANN rows equal the ANN run's and are merged into them."


def distinct(report: dict[str, Any]) -> list[dict[str, Any]]:
    """Every comparison but the same-width ANN's that equal the ANN run's."""
    if not merged_note(report):
        return list(report["comparisons"])
    run = {(c["snn_profile"], c["ann_profile"]): c["ann_pj"] for c in pairs(report)}
    return [c for c in report["comparisons"] if not (
        c["ann"] == "same_width" and run.get((c["snn_profile"], c["ann_profile"])) == c["ann_pj"]
    )]  # fmt: skip


def sd_sentence(report: dict[str, Any]) -> str:
    """A sigma-delta deployment's answer first (does issue 34's goal hold on the primary chip,
    with the ratios' 90 % intervals), then the term in the way, the proxies and SANA-FE: the
    goal's own verdict (:func:`snnkart.energy.goal.decide`)."""
    g = report["goal"]
    checks = "; ".join(
        f"{times(c['ratio']['median'])} the {c['baseline']} ANN (90 %: "
        f"{times(c['ratio']['p05'])}-{times(c['ratio']['p95'])}, needs <= {c['factor']:g}x)"
        for c in g["primary"]["checks"]
    )
    return (
        f"{'Yes' if g['holds'] else 'No'}: the sigma-delta policy (success "
        f"{pct(report['task']['success_rate'])}) {'meets' if g['holds'] else 'does not meet'} "
        f"the energy goal on {g['primary']['chip']}: dynamic energy per inference {checks}. "
        f"In words: {g['verdict']}."
    )
