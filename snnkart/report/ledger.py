"""The report's price table (every price of every profile used, with its range, evidence tag and
source) and its per-term ledger (count x price = energy, for each pair of the verdict)."""

from __future__ import annotations

from collections.abc import Mapping

from snnkart.contract.report_record import lif_report
from snnkart.report.first_screen import pairs


def _value(op: str, pj: float) -> str:
    """A price in its unit: static power in W (stored as pJ/s), every other price in pJ."""
    return f"{pj / 1e12:.3g} W" if op == "static_power" else f"{pj:.3g} pJ"


def price_rows(report: Mapping[str, object]) -> list[dict[str, str]]:
    """Every price of every profile the report used, then what is not published."""
    rows = []
    for name, p in lif_report(report)["profiles"].items():
        for op, price in p["prices"].items():
            rows.append(
                {
                    "profile": name,
                    "op": op,
                    "value": _value(op, price["pj"]),
                    "low-high": f"{_value(op, price['low_pj'])} - {_value(op, price['high_pj'])}",
                    "tag": price["tag"],
                    "source": price["source"],
                }
            )
        for op, why in p["not_published"].items():
            rows.append(
                {
                    "profile": name,
                    "op": op,
                    "value": "not published",
                    "low-high": "-",
                    "tag": "-",
                    "source": why,
                }
            )
    return rows


def ledger(report: Mapping[str, object]) -> list[tuple[str, list[dict[str, str]]]]:
    """For each pair of the verdict, every term of both sides: count x price (with its evidence
    tag) = energy."""
    out = []
    tag = {
        (name, op): price["tag"]
        for name, p in lif_report(report)["profiles"].items()
        for op, price in p["prices"].items()
    }
    for c in pairs(report):
        rows = []
        for side, terms in (
            ("SNN", c["snn_terms"]),
            ("ANN", c["ann_terms"]),
            ("SNN static", c["static"]["snn_static_terms"]),
            ("ANN static", c["static"]["ann_static_terms"]),
        ):
            rows += [
                {
                    "side": side,
                    "part": t["part"],
                    "what": t["what"],
                    "count": f"{t['count']:.4g}",
                    "price": f"{t['profile']}.{t['op']} = {_value(t['op'], t['price_pj'])}",
                    "tag": tag[(t["profile"], t["op"])],
                    "energy pJ": f"{t['energy_pj']:.4g}",
                }
                for t in terms
            ]
        title = (
            f"{c['snn_profile']} (host on {c['host_profile']}) vs ANN on "
            f"{c['ann_profile']}: {c['snn_pj']:.4g} pJ against {c['ann_pj']:.4g} pJ"
        )
        out.append((title, rows))
    return out
