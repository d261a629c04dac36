"""The verdict's joint uncertainty and the break-even in T and width: a seeded sample is
reproducible, a shared price is drawn once for both sides, the distribution follows the
high/low rule, and the break-even in T and in width matches a hand computation."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from snnkart.app.report import build_report
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.break_even import break_even_steps, break_even_width, rescaled
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.pricing import Comparison, Term, ann_terms, terms
from snnkart.energy.profiles import Price, Profile, load_profile
from snnkart.energy.uncertainty import Draw, distribution, joint, sample_prices

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "tests/data/records/deploy-nir-ref-fixed.json"


def _tiny() -> SnnCounts:
    """3 inputs -> 4 -> 2 spiking -> 2 actions, T = 2, one Dense delay; per env step layer 1
    fires 3 spikes (6 synaptic ops), layer 2 one; the pipeline's fill/drain step adds 4 + 2
    neuron updates, one spike and 2 synaptic ops."""
    data = json.loads(RECORD.read_text())
    data.update({
        "precision": "float64",
        "manifest": {"num_steps": 2, "encoding": "current", "action_mode": "discrete"},
        "network": {"n_in": 3, "sizes": [4, 2], "n_out": 2, "readout": True, "input_scale": False},
        "counts": {"env_steps": 2, "spikes": [6, 2], "synops": [12, 4], "neuron_updates": [16, 8],
                   "pipeline_overhead": {"spikes": [2, 0], "synops": [4, 0],
                                         "neuron_updates": [8, 4]}},
        "episodes": [],
    })  # fmt: skip
    return SnnCounts.of_deploy(DeployRecord.from_json(json.dumps(data)))


def _priced(profile: Profile, name: str, **ranges: tuple[float, float]) -> Profile:
    """``profile`` renamed, every price fixed at 0 except ``op=(low, high)`` (value = low)."""
    prices = {op: dataclasses.replace(p, value=0.0, low=0.0, high=0.0)
              for op, p in profile.prices.items()}  # fmt: skip
    for op, (low, high) in ranges.items():
        prices[op] = dataclasses.replace(prices[op], value=low, low=low, high=high)
    return dataclasses.replace(profile, name=name, prices=prices)


def _memory_op(ann: AnnCounts, digital: Profile) -> str:
    """The operation a digital profile prices the ANN's weight reads with."""
    return next(t.op for t in ann_terms(ann, digital) if t.part == "memory")


def _realistic() -> tuple[list[Term], list[Term], tuple[Profile, ...]]:
    snn = SnnCounts.of_deploy(DeployRecord.read(RECORD))
    net = snn.net
    ann = AnnCounts((net.obs_dim, *net.sizes, net.n_out), net.action_mode)
    chip, dig = load_profile("loihi2"), load_profile("horowitz45_fp32_sram")
    return terms(snn, chip, dig), ann_terms(ann, dig), (chip, dig)


def test_a_seeded_sample_is_reproducible_and_another_seed_is_close() -> None:
    snn, ann, profiles = _realistic()
    first = joint(snn, ann, profiles, seed=7)
    assert joint(snn, ann, profiles, seed=7) == first  # every number, to the last digit
    other = joint(snn, ann, profiles, seed=8)
    assert other["ratio"] != first["ratio"]
    assert first["ratio"]["p05"] < first["ratio"]["median"] < first["ratio"]["p95"]
    for key in ("p05", "median", "p95"):  # 10,000 samples: within a few per cent
        assert other["ratio"][key] == pytest.approx(first["ratio"][key], rel=0.05)
    assert other["p_snn_cheaper"] == pytest.approx(first["p_snn_cheaper"], abs=0.03)


def test_a_shared_price_is_drawn_once_for_both_sides() -> None:
    """Only the memory read is uncertain and both energies are proportional to it: drawn once
    (one quantile of each side's range, the SNN host's 5-50 pJ and the ANN's 10-100 pJ on
    another profile of the same technology), the ratio is one number; drawn apart, it spreads."""
    snn = _tiny()
    ann = AnnCounts((3, 4, 2, 2))
    base = load_profile("horowitz45_fp32_sram")
    read = _memory_op(ann, base)
    chip = _priced(load_profile("truenorth"), "free-chip")
    host = _priced(base, "host45", **{read: (5.0, 50.0)})
    dig = _priced(base, "ann45", **{read: (10.0, 100.0)})
    s_terms, a_terms = terms(snn, chip, host), ann_terms(ann, dig)
    reads_snn = sum(t.count for t in s_terms if t.op == read)
    reads_ann = sum(t.count for t in a_terms if t.op == read)
    out = joint(s_terms, a_terms, (chip, host, dig))
    expected = reads_snn / (2 * reads_ann)  # the ANN's read is twice the host's at every quantile
    for key in ("p05", "median", "p95"):
        assert out["ratio"][key] == pytest.approx(expected, rel=1e-12)
    assert out["shared"] == [f"on-chip SRAM read, {base.technology}"]
    assert out["snn_pj"]["p95"] > 3 * out["snn_pj"]["p05"]  # the energies themselves do move
    # one at a time, the shared read moves on both sides at once: the ratio does not move
    [row] = out["one_at_a_time"]
    assert row["prices"] == [f"host45.{read}", f"ann45.{read}"]
    assert row["sides"] == ["SNN", "ANN"]
    assert (row["ratio_low"], row["ratio_high"]) == pytest.approx((expected, expected), rel=1e-12)
    # the ANN on another technology: its read is a quantity of its own, and the ratio spreads
    apart = joint(s_terms, a_terms, (chip, host, dataclasses.replace(dig, technology="28 nm")))
    assert apart["ratio"]["p95"] > 2 * apart["ratio"]["p05"] and apart["shared"] == []
    # moving the ANN's range moves nothing on the SNN's side
    wider = dataclasses.replace(dig, prices={**dig.prices, read: dataclasses.replace(
        dig.prices[read], high=400.0)})  # fmt: skip
    assert joint(s_terms, a_terms, (chip, host, wider))["snn_pj"] == out["snn_pj"]


def _price(low: float, high: float) -> Price:
    return Price(low, low, high, "pJ", "assumed", "test")


def test_log_uniform_above_a_decade_uniform_below() -> None:
    assert distribution(_price(1.0, 10.0)) == "uniform"  # exactly a decade: uniform
    assert distribution(_price(1.0, 10.5)) == "log-uniform"
    assert distribution(_price(0.0, 50.0)) == "uniform"  # a range from 0 cannot be log-uniform
    assert distribution(_price(3.0, 3.0)) == "fixed"
    draws = [Draw("p", "log", 1.0, 0.1, 1000.0, "log-uniform", "a"),
             Draw("p", "lin", 1.0, 0.0, 1000.0, "uniform", "b")]  # fmt: skip
    x = sample_prices(draws, 20_000, seed=1)
    assert x.shape == (20_000, 2) and x.min() >= 0.0 and x.max() <= 1000.0
    # log-uniform: the median is the geometric mean, each decade holds a quarter
    assert np.median(x[:, 0]) == pytest.approx(10.0, rel=0.05)
    assert np.mean(x[:, 0] < 1.0) == pytest.approx(0.25, abs=0.02)
    assert np.median(x[:, 1]) == pytest.approx(500.0, rel=0.05)


def _linear(chip_prices: dict[str, tuple[float, float]], mac: float, ann: AnnCounts) -> Comparison:
    """The tiny SNN on a chip priced only at ``chip_prices``, its host work free, against
    ``ann`` whose MACs alone cost ``mac`` pJ."""
    base = load_profile("horowitz45_fp32")
    chip = _priced(load_profile("loihi1"), "chip", **chip_prices)
    return Comparison(
        _tiny(), ann, chip, _priced(base, "free"), _priced(base, "macs", mac=(mac, mac))
    )


def test_break_even_in_t_against_a_hand_computation() -> None:
    # per inference at T: neuron updates (4 + 2) x T + (4 + 2) x 1 fill/drain step at 1 pJ;
    # synaptic ops 3 x T (layer 1: 3/8 spikes per neuron and step x 4 neurons x fan-out 2)
    # + 2 fill/drain at 2 pJ: E_snn = 12 T + 10. The ANN 3-4-2-2: 24 MACs at 5 pJ = 120 pJ.
    cmp = _linear({"neuron_update": (1.0, 1.0), "synaptic_op": (2.0, 2.0)}, 5.0,
                  AnnCounts((3, 4, 2, 2)))  # fmt: skip
    for steps in (1, 2, 7):
        assert rescaled(cmp.snn, num_steps=steps).neuron_updates == (4.0 * steps, 2.0 * steps)
        e_snn, e_ann = dataclasses.replace(cmp, snn=rescaled(cmp.snn, num_steps=steps)).energies()
        assert (e_snn, e_ann) == pytest.approx((12 * steps + 10, 120.0))
    be = break_even_steps(cmp)
    assert be["largest"] == 9 and be["num_steps"] == pytest.approx(110 / 12)
    assert be["today"] == 2 and be["ratio_at"]["2"] == pytest.approx(34 / 120)
    # an ANN of 12 pJ costs less than the SNN at T = 1 (22 pJ): no T breaks even
    cheap = break_even_steps(
        dataclasses.replace(cmp, digital=_priced(cmp.digital, "m", mac=(0.5, 0.5)))
    )
    assert cheap["num_steps"] is None and "no T breaks even" in cheap["reason"]


def test_break_even_in_width_against_a_hand_computation() -> None:
    # width W: layers (W, n2 = round(W / 2)), the ANN 3-W-n2-2. Only synaptic ops cost on the
    # chip (2 pJ): (3 x T/2 ... ) = 6 W/4 n2/2 + 2 fill/drain x W/4 n2/2 = W n2 synaptic ops,
    # E_snn = 2 W n2; the ANN's MACs at 1 pJ: 3 W + W n2 + 2 n2. With n2 = W/2 they are equal at
    # W = 8 (64 pJ each); the SNN costs less below (W = 7: n2 = 4, 56 < 57 pJ).
    cmp = _linear({"synaptic_op": (2.0, 2.0)}, 1.0, AnnCounts((3, 4, 2, 2)))
    be = break_even_width(cmp)
    assert be["cheaper"] == [{"from": 1, "to": 7}] and be["crossings"] == [pytest.approx(8.0)]
    assert be["today"] == 4 and be["ratio_at"]["8"] == pytest.approx(1.0)
    assert "from 1 to 7" in be["reason"]
    # a synaptic op cheaper than a MAC: the SNN costs less at every width scanned
    wins = break_even_width(
        dataclasses.replace(cmp, chip=_priced(cmp.chip, "c", synaptic_op=(0.5, 0.5)))
    )
    assert wins["cheaper"] == [{"from": 1, "to": None}] and wins["crossings"] == []
    # clocked neuron updates only (4 pJ): E_snn = 4 x (W + n2) x (T + 1) = 12 (W + n2), linear,
    # against the ANN's quadratic MACs: equal at W = 28 (n2 = 14: 504 pJ each), the SNN costs
    # less from W = 29 (n2 = 14: 516 < 521 pJ) up
    clocked = _linear({"neuron_update": (4.0, 4.0)}, 1.0, AnnCounts((3, 4, 2, 2)))
    late = break_even_width(clocked)
    assert late["cheaper"] == [{"from": 29, "to": None}] and late["crossings"] == [
        pytest.approx(28.0)
    ]
    assert "from 29 up" in late["reason"]


def _terms(rows: list[dict[str, Any]]) -> list[Term]:
    """The report's term records as terms again (each price as the figure it was priced at)."""
    return [
        Term(r["part"], r["what"], r["count"], r["profile"], r["op"], _as_priced(r)) for r in rows
    ]


def _as_priced(row: dict[str, Any]) -> Price:
    value = row["price_pj"]
    return Price(value, value, value, "pJ", "as priced", row["source"])


def test_the_report_carries_each_pairs_interval_and_break_even() -> None:
    report = build_report(RECORD, None, None)
    assert (
        report["uncertainty"]["samples"] == 10_000
        and "log-uniform" in report["uncertainty"]["rule"]
    )
    profiles = [load_profile(name) for name in report["profiles"]]
    for c in report["comparisons"]:
        u = c["uncertainty"]  # recomputed from the report's own terms: the same numbers
        assert joint(_terms(c["snn_terms"]), _terms(c["ann_terms"]), profiles) == u
        r = u["ratio"]
        assert r["p05"] <= r["median"] <= r["p95"] and 0.0 <= u["p_snn_cheaper"] <= 1.0
        assert {"density", "num_steps", "width"} <= set(c["break_even"])
    assert report["sensitivity"] and report["sensitivity"][0]["rows"]  # the tornado stays
    json.dumps(report, allow_nan=False)


def test_an_ann_priced_at_zero_gives_undefined_ratios_not_a_traceback() -> None:
    snn = _tiny()
    ann = AnnCounts((3, 4, 2, 2))
    free = _priced(load_profile("horowitz45_fp32"), "free")
    chip = _priced(load_profile("loihi2"), "chip", synaptic_op=(1.0, 100.0))
    cmp = Comparison(snn, ann, chip, free, free)
    out = joint(terms(snn, chip, free), ann_terms(ann, free), (chip, free))
    assert out["ratio"] == {"median": None, "p05": None, "p95": None}
    assert out["p_snn_cheaper"] == 0.0 and out["ann_pj"]["p95"] == 0.0
    steps, width = break_even_steps(cmp), break_even_width(cmp)
    assert steps["num_steps"] is None and "undefined multiple" in steps["reason"]
    assert width["cheaper"] == [] and set(width["ratio_at"].values()) == {None}
    json.dumps([out, steps, width], allow_nan=False)


def test_rescaled_counts_keep_todays_firing_rates_and_recount_the_host() -> None:
    snn = SnnCounts.of_deploy(DeployRecord.read(RECORD))  # 64-64, T = 8, fixed point
    net = snn.net
    small = rescaled(snn, num_steps=4, sizes=(32, 16))
    assert small.firing_rates() == pytest.approx(snn.firing_rates())
    assert small.neuron_updates == (32 * 4, 16 * 4)
    assert small.overhead_neuron_updates == (32.0, 16.0)  # one fill/drain step, whatever T
    # layer 1's synaptic ops: its spikes x the new fan-out (16)
    assert small.synops[0] == pytest.approx(small.spikes[0] * 16) and small.synops[1] == 0
    host = {op: sum(h.count for h in small.host if h.op == op) for op in ("mac", "mult")}
    # first layer n_in x 32, readout 16 x n_out | /std n_in, fixed-point scaling 32, /T 16
    assert host == {"mac": net.n_in * 32 + 16 * net.n_out, "mult": net.n_in + 32 + 16}
