"""Issue 34's goal decided by hand: the bounds against the fp32 and int8 baselines with the
whole 90 % interval on the winning side, the term in the way, the proxies, SANA-FE's single
energy against the baseline's interval."""

from __future__ import annotations

from pathlib import Path

import pytest

from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.goal import FP32, INT8, Priced, decide, priced_policy
from snnkart.energy.pricing import Term
from snnkart.energy.profiles import Price, Profile, load_profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts


def _profile(name: str, kind: str, **ranges: tuple[float, float, float]) -> Profile:
    prices = {op: Price(v, lo, hi, "pJ", "assumed", "test") for op, (v, lo, hi) in ranges.items()}
    return Profile(name, name, kind, "", "", prices, "test")


def _term(part: str, count: float, profile: Profile, op: str) -> Term:
    return Term(part, part, count, profile.name, op, profile.prices[op])


def _priced(chip: str, synops: float, updates: float, ann: dict[str, float],
            update_range: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> list[Priced]:  # fmt: skip
    """A policy of ``synops`` synaptic ops and ``updates`` neuron updates (1 pJ each, the
    updates over ``update_range``) against each baseline's ANN of ``ann[baseline]`` MACs."""
    c = _profile(chip, "neuromorphic", synaptic_op=(1.0, 1.0, 1.0), neuron_update=update_range)
    d = _profile("digital", "digital", mac=(1.0, 1.0, 1.0))
    snn = (_term("synaptic ops", synops, c, "synaptic_op"),
           _term("neuron updates", updates, c, "neuron_update"))  # fmt: skip
    return [Priced(chip, b, snn, (_term("host compute", macs, d, "mac"),), (c, d), 1 / 60)
            for b, macs in ann.items()]  # fmt: skip


def test_the_goal_holds_when_both_bounds_hold_on_loihi2() -> None:
    out = decide(_priced("loihi2", 10, 30, {FP32: 100, INT8: 80}), proxies=(), samples=200)
    assert out["holds"] and out["primary"]["in_the_way"] is None
    assert [c["ratio"]["p95"] for c in out["primary"]["checks"]] == pytest.approx([0.4, 0.5])
    assert "SANA-FE not run" in out["verdict"]


def test_the_term_in_the_way_is_named_with_numbers() -> None:
    # 10 + 60 = 70 pJ: 0.7x the fp32 ANN's 100 (> 0.5), 0.875x the int8 ANN's 80 (<= 1)
    out = decide(_priced("loihi2", 10, 60, {FP32: 100, INT8: 80}), proxies=(), samples=200)
    assert not out["holds"]
    fp32, int8 = out["primary"]["checks"]
    assert (fp32["holds"], int8["holds"]) == (False, True)
    way = out["primary"]["in_the_way"]
    assert (way["part"], way["baseline"], way["factor"]) == ("neuron updates", FP32, 0.5)
    assert way["ratio_p95"] == pytest.approx(0.7)
    assert way["ratio_p95_without"] == pytest.approx(0.1) and way["clears"]
    assert way["part_pj"]["median"] == pytest.approx(60.0)
    assert "neuron updates is in the way: 0.06 nJ" in out["verdict"]


def test_the_whole_interval_must_be_on_the_winning_side() -> None:
    # updates 30 x 0.5-1.5 pJ + 10: 25-55 pJ, median 40: 0.4x the fp32 ANN, the top 0.55x
    priced = _priced("loihi2", 10, 30, {FP32: 100, INT8: 100}, update_range=(1.0, 0.5, 1.5))
    out = decide(priced, proxies=(), samples=4000)
    fp32 = out["primary"]["checks"][0]
    assert fp32["ratio"]["median"] == pytest.approx(0.4, abs=0.01)
    assert fp32["ratio"]["p95"] == pytest.approx(0.535, abs=0.01)
    assert not fp32["holds"] and not out["holds"]


def test_proxies_are_named_but_do_not_decide() -> None:
    priced = [*_priced("loihi2", 10, 30, {FP32: 100, INT8: 80}),
              *_priced("loihi1", 10, 300, {FP32: 100, INT8: 80})]  # fmt: skip
    out = decide(priced, samples=200)
    assert out["holds"] and [p["chip"] for p in out["proxies"]] == ["loihi1"]
    assert not out["proxies"][0]["holds"] and "proxy loihi1: does not hold" in out["verdict"]
    with pytest.raises(ValueError, match="needs the policy priced against horowitz45_int8"):
        decide(priced[:1], proxies=(), samples=10)


def test_sanafe_is_checked_against_the_baselines_whole_interval() -> None:
    priced = _priced("loihi2", 10, 30, {FP32: 100, INT8: 80})
    assert decide(priced, sanafe_pj=50.0, proxies=(), samples=200)["holds"]  # 0.5 x 100
    out = decide(priced, sanafe_pj=60.0, proxies=(), samples=200)
    assert out["primary"]["holds"] and not out["sanafe"]["holds"] and not out["holds"]
    assert out["sanafe"]["checks"][0]["ratio_p95"] == pytest.approx(0.6)


def test_sanafe_takes_one_energy_per_baseline() -> None:
    priced = _priced("loihi2", 10, 30, {FP32: 100, INT8: 80})
    out = decide(priced, sanafe_pj={FP32: 50.0, INT8: 81.0}, proxies=(), samples=200)
    assert [c["holds"] for c in out["sanafe"]["checks"]] == [True, False]


def test_a_sigma_delta_and_a_lif_policy_are_decided_on_the_real_profiles() -> None:

    record = Path(__file__).parent / "data/records/deploy-nir-ref-fixed.json"  # 21-64-64-5, T 8
    tiny = {"n_in": 2, "sizes": [3], "n_out": 2, "num_message_bits": 8, "input_bits": 4,
            "rows": 3, "messages": [1, 2, 0], "payload_bits": [4, 16, 0],
            "synaptic_events": [3, 4, 0], "updates_clocked": [6, 9, 6],
            "updates_active": [1, 2, 2]}  # fmt: skip
    ann = AnnCounts((2, 3, 2))
    baselines = [load_profile(FP32), load_profile(INT8)]
    for policy in (
        SigmaDeltaCounts.from_dict(tiny),
        SnnCounts.of_deploy(DeployRecord.read(record)),
    ):
        priced = [priced_policy(policy, load_profile(c), b, ann)
                  for c in ("loihi2", "loihi1") for b in baselines]  # fmt: skip
        out = decide(priced, samples=500)
        assert not out["holds"]  # both cost more than this 2-3-2 ANN
        way = out["primary"]["in_the_way"]
        assert way["part"] in {t.part for t in priced[0].snn}
        assert way["ratio_p95_without"] < way["ratio_p95"]


def test_static_power_is_shown_beside_the_dynamic_verdict() -> None:
    tiny = SigmaDeltaCounts.from_dict({
        "n_in": 2, "sizes": [3], "n_out": 2, "num_message_bits": 8, "input_bits": 4, "rows": 3,
        "messages": [1, 2, 0], "payload_bits": [4, 16, 0], "synaptic_events": [3, 4, 0],
        "updates_clocked": [6, 9, 6], "updates_active": [1, 2, 2]})  # fmt: skip
    priced = [priced_policy(tiny, load_profile("loihi2"), load_profile(b), AnnCounts((2, 3, 2)))
              for b in (FP32, INT8)]  # fmt: skip
    out = decide(priced, proxies=(), samples=100)
    # loihi2: 0.232 W measured x 1/60 s = 3.87 mJ, not part of the dynamic verdict
    assert out["primary"]["static_pj"] == pytest.approx(0.232e12 / 60)
    assert out["primary"]["checks"][0]["snn_pj"]["median"] < 1e6
