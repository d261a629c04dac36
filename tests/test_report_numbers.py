"""The report's numbers read as numbers: break-even densities however small, a verdict that
says when no spike rate wins (or every one does), and totals in a table with sensible digits
instead of Python dictionaries."""

from __future__ import annotations

from typing import Any

from snnkart.report.document import _facts_rows, _verdict


def _comparison(density: float | None, fixed: float, ann: float) -> dict[str, Any]:
    return {"ann": "same_width", "snn_profile": "loihi1", "ann_profile": "horowitz45_fp32",
            "ratio": 2.5, "break_even": {"density": density, "fixed_pj": fixed, "ann_pj": ann}}  # fmt: skip


def _verdict_of(density: float | None, fixed: float = 1.0, ann: float = 2.0) -> str:
    report = {"ann": {"same_width": {"label": "ANN 64-64"}},
              "comparisons": [_comparison(density, fixed, ann)]}  # fmt: skip
    return _verdict(report)[0]


def test_a_small_break_even_density_keeps_its_digits() -> None:
    assert "wins below 0.0031x today's spikes" in _verdict_of(0.00314)
    assert "wins below 0.35x today's spikes" in _verdict_of(0.354)
    assert "0.00x" not in _verdict_of(0.001)


def test_without_a_break_even_density_the_verdict_says_which_way() -> None:
    assert "cannot win at any spike rate" in _verdict_of(None, fixed=3.0, ann=2.0)
    assert "wins at any spike rate" in _verdict_of(None, fixed=1.0, ann=2.0)


def test_totals_footprint_and_latency_are_rows_with_sensible_digits() -> None:
    snn = {
        "deployed": {"host_macs": 1664, "chip_synaptic_ops": 9109.454545454546, "spikes": 310.6676},
        "neurobench": {"effective_macs": 11072, "activation_sparsity": 0.6971435546875},
        "footprint": {"parameters": 6281, "parameter_bytes_fp32": 25124},
        "latency": {"ms_per_env_step": 0.7074531193176561, "backend": "nir-ref"},
    }
    rows = {(r[""], r["quantity"]): r["value"] for r in _facts_rows({"snn": snn})}
    assert rows[("as deployed, per inference", "host MACs")] == "1,664"
    assert rows[("as deployed, per inference", "chip synaptic ops")] == "9,109"
    assert rows[("as deployed, per inference", "spikes")] == "311"
    assert rows[("NeuroBench (first layer fed at every step)", "activation sparsity")] == "0.697"
    assert rows[("footprint", "weights and biases")] == "6,281"
    assert rows[("latency", "ms per env step")] == "0.707"
    assert rows[("latency", "backend")] == "nir-ref"


def _pair(chip: str, p: float, median: float, static: float) -> dict[str, Any]:
    spread = {"median": median, "p05": median / 2, "p95": median * 2}
    return {"ann": "run", "snn_profile": chip, "ann_profile": "arm", "ann_success_rate": 0.9,
            "ann_success": "measured: the float ANN", "uncertainty": {"p_snn_cheaper": p,
            "ratio": spread}, "static": {"ratio": static, "control_period_s": 1 / 60}}  # fmt: skip


def test_the_verdict_sentence_counts_the_pairs_and_names_the_best() -> None:
    """More likely than not cheaper means P > 0.5; the best pair has the highest P, then the
    lowest median; with static power the pairs below 1 are counted apart."""
    from snnkart.report.first_screen import sentence

    report = {"ann": {"run": {"label": "ANN run"}}, "snn": {"task": {"success_rate": 1.0}},
              "comparisons": [_pair("a", 0.5, 0.9, 2.0), _pair("b", 0.93, 0.6, 0.8),
                              _pair("c", 0.93, 0.4, 3.0)]}  # fmt: skip
    said = sentence(report)
    assert "cost less than the ANN run in 2 of 3 chip/target pairs" in said
    assert "on c against the ANN on arm (ANN success 90 %)" in said
    assert "a median 0.4x the ANN's energy (90 %: 0.2x-0.8x), P(SNN cheaper) 0.93" in said
    assert "16.7 ms control period it costs less in 1 of 3 (lowest ratio 0.8x)" in said
