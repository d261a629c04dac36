"""The report page's SANA-FE section: the second chip model's figures from ``report.json``'s
``sanafe`` entry (:mod:`snnkart.app.sanafe_report`), as lines and a table for the Markdown
and the HTML alike."""

from __future__ import annotations

from collections.abc import Mapping

from snnkart.contract.report_record import lif_report
from snnkart.contract.sanafe_record import SanafeSection

TITLE = "Second chip model: SANA-FE (Loihi)"


def _nj(pj: float | None) -> str:
    return "-" if pj is None else f"{pj / 1000:.3g}"


def _section(report: Mapping[str, object]) -> SanafeSection:
    return lif_report(report).get("sanafe") or {"available": False}


def sanafe_lines(report: Mapping[str, object]) -> list[str]:
    """What SANA-FE found, or why it did not run and how to add it."""
    s = _section(report)
    if not s.get("available"):
        return [f"SANA-FE did not run: {s.get('reason', 'no sanafe entry in report.json')}."]
    e, lat, check = s["per_inference"]["energy_pj"], s["latency"], s["lif_check"]
    spikes = s["spikes_per_layer"]
    same = spikes["deploy_json"] == spikes["inputs_npz"] == spikes["sanafe_lif_replay"]
    flagged = [r["term"] for r in s["versus_snnkart_loihi1"] if r["over_2x"]]
    return [
        f"{s['model']}, driven layer by layer with the deployment's recorded inputs "
        f"({s['run']['env_steps']} env steps, {s['run']['mapping']}): "
        f"{_nj(e['total'])} nJ per inference (synapse {_nj(e['synapse'])}, soma "
        f"{_nj(e['soma'])}, network {_nj(e['network'])}); dynamic energy only.",
        "Spikes per layer: SANA-FE's equal deploy.json's."
        if same
        else f"Spikes per layer differ: deploy.json {spikes['deploy_json']}, SANA-FE "
        f"{spikes['sanafe_lif_replay']}.",
        f"SANA-FE's own LIF, driven by layer 0's current only ({check['env_steps']} env steps, "
        f"{check['arithmetic']}): "
        + (
            "reproduces every recorded spike."
            if check["reproduces"]
            else f"{check['mismatched_logical_neuron_steps']} neuron-steps per layer differ "
            "(SANA-FE truncates v to 1/64 of a unit, keeps the current u unrounded and never "
            "reset, and has no 24-bit wrap-around); the replay above uses the recorded spikes."
        ),
        f"On-chip latency per inference: {lat['on_chip_s_per_inference'] * 1e6:.1f} µs for "
        f"{lat['steps_per_inference']} time steps, {lat['fraction_of_control_period']:.2%} of "
        f"the {lat['control_period_s'] * 1e3:.1f} ms control period ({lat['from']}).",
        "More than 2x apart from snnkart's Loihi 1 estimate: "
        + (", ".join(flagged) if flagged else "none")
        + " (SANA-FE is calibrated on measured Loihi energy; Davies' Table 2 is pre-silicon).",
    ]


def sanafe_rows(report: Mapping[str, object]) -> list[dict[str, str]]:
    """SANA-FE against snnkart's Loihi 1 estimate, term by term (none when it did not run)."""
    s = _section(report)
    if not s.get("available"):
        return []
    return [
        {
            "term": r["term"],
            "snnkart loihi1 nJ": _nj(r["snnkart_pj"]),
            "SANA-FE nJ": _nj(r["sanafe_pj"]),
            "SANA-FE / snnkart": "-"
            if r["ratio_sanafe_to_snnkart"] is None
            else f"{r['ratio_sanafe_to_snnkart']:.3g}x" + (" (>2x)" if r["over_2x"] else ""),
            "prices": r["why"],
        }
        for r in s["versus_snnkart_loihi1"]
    ]
