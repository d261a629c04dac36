"""A sigma-delta inference priced term by term on a tiny count set, by hand: graded synaptic
events and messages (their derived payload range on a graded and on a binary chip), neuron
updates by the profile's rule (clocked or active), the link's bits, the host's work, the
one-step schedule's what-if, the joint uncertainty over the derived ranges, the break-even
in message density; and the profile rules themselves."""

from __future__ import annotations

from typing import Any

import pytest

from snnkart.energy.graded import graded_op
from snnkart.energy.pricing import Term, breakdown, total
from snnkart.energy.pricing import terms as price_terms
from snnkart.energy.profiles import load_profile, parse_profile
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.energy.sigma_delta_pricing import break_even_density, what_ifs, with_rule
from snnkart.energy.uncertainty import joint
from snnkart.errors import ProfileError, ReportError

# 2 inputs -> Delta -> Dense(3) -> SigmaDelta(3) -> Dense(2) -> Sigma(2); held: L + 2 = 3 rows.
# Per env step: the Delta sends 1 message (4-bit payload) into 3 neurons, the hidden layer 2
# (8-bit) into 2; every chip neuron sits through 3 rows, 2 hidden and 2 Sigma neurons active.
TINY: dict[str, Any] = {
    "n_in": 2, "sizes": [3], "n_out": 2, "num_message_bits": 8, "input_bits": 4, "rows": 3,
    "messages": [1, 2, 0], "payload_bits": [4, 16, 0], "synaptic_events": [3, 4, 0],
    "updates_clocked": [6, 9, 6], "updates_active": [1, 2, 2],
}  # fmt: skip


@pytest.fixture
def tiny() -> SigmaDeltaCounts:
    return SigmaDeltaCounts.from_dict(TINY)


def _part(terms: list[Term], part: str) -> float:
    return breakdown(terms)[part]


def test_graded_synaptic_events_and_messages_on_a_graded_chip(tiny: SigmaDeltaCounts) -> None:
    chip, host = load_profile("loihi2"), load_profile("horowitz45_int8")
    terms = price_terms(tiny, chip, host)
    # (3 + 4) events x 4.2 pJ; messages: 2 hidden messages x the spike's 0 pJ
    assert _part(terms, "synaptic ops") == pytest.approx(7 * 4.2)
    assert [t.count for t in terms if t.part == "messages"] == [2.0]
    graded = tiny.prices_for(chip)
    # an 8-bit payload is one 8-bit word: the range is the synaptic op's own
    synop = graded.prices[graded_op("synop", 8)]
    assert (synop.low, synop.value, synop.high) == (0.067, 4.2, 6.8)
    assert synop.tag == "derived" and "no graded synop energy is published" in synop.source


def test_a_binary_chip_derives_the_payload_range_per_bit(tiny: SigmaDeltaCounts) -> None:
    chip = load_profile("loihi1")
    terms = price_terms(tiny, chip, load_profile("horowitz45_int8"))
    assert _part(terms, "synaptic ops") == pytest.approx(7 * 23.6)
    assert _part(terms, "messages") == pytest.approx(2 * 1.7)
    graded = tiny.prices_for(chip)
    # up to one spike and one accumulate per payload bit: 4 bits in, 8 bits hidden
    assert graded.prices[graded_op("synop", 4)].high == pytest.approx(35.5 * 4)
    assert graded.prices[graded_op("synop", 8)].high == pytest.approx(35.5 * 8)
    assert graded.prices[graded_op("message", 8)].high == pytest.approx(180.3 * 8)
    assert graded.prices[graded_op("hop", 8)].high == pytest.approx(4.2 * 8)
    event_ops = [t.op for t in terms if t.part == "synaptic ops"]
    assert event_ops == [graded_op("synop", 4), graded_op("synop", 8)]


def test_a_clocked_chip_updates_every_neuron_at_every_row(tiny: SigmaDeltaCounts) -> None:
    chip, host = load_profile("loihi1"), load_profile("horowitz45_int8")
    assert chip.rule("neuron_updates").value == "clocked"
    # hidden 3 x 3 rows + Sigma 2 x 3 rows (the host's Delta is not a chip neuron) x 81 pJ
    assert _part(price_terms(tiny, chip, host), "neuron updates") == pytest.approx(15 * 81.0)
    active = with_rule(chip, "neuron_updates", "active", "test")
    assert _part(price_terms(tiny, active, host), "neuron updates") == pytest.approx(4 * 81.0)


def test_an_active_chip_pays_only_for_active_neurons(tiny: SigmaDeltaCounts) -> None:
    chip = load_profile("truenorth")
    assert chip.rule("neuron_updates").value == "active"
    terms = [t for t in price_terms(tiny, chip, load_profile("horowitz45_int8"))
             if t.part == "neuron updates"]  # fmt: skip
    assert [t.count for t in terms] == [2.0, 2.0]
    assert "active" in terms[0].what


def test_the_link_carries_input_messages_with_addresses_and_the_readout(
    tiny: SigmaDeltaCounts,
) -> None:
    # in: 4 payload bits + 1 address bit (2 inputs); out: 2 Sigma values x 24 bits (fixed)
    assert tiny.link_bits() == (5.0, 48.0)
    terms = price_terms(tiny, load_profile("loihi2"), load_profile("horowitz45_int8"))
    assert _part(terms, "host link") == pytest.approx(53 * 20.3)


def test_the_host_work_is_the_delta_and_the_readout(tiny: SigmaDeltaCounts) -> None:
    terms = price_terms(tiny, load_profile("loihi2"), load_profile("horowitz45_int8"))
    host = [t for t in terms if t.part == "host compute"]
    adds = sum(t.count for t in host if t.op == "add")
    mults = sum(t.count for t in host if t.op == "mult")
    # adds: normalisation 3 x 2, Delta 2 x 2 + 2 + 2, readout bias 2, argmax 1; mults: 2 + 2 + 2
    assert (adds, mults) == (17, 6)
    # memory: the readout's 2 int8 biases = 2 x 8 / 64 reads of the 8 KB array (10 pJ)
    assert _part(terms, "memory") == pytest.approx(2 * 8 / 64 * 10.0)
    assert _part(terms, "host compute") == pytest.approx(17 * 0.1 + 6 * 0.2)


def test_the_one_step_schedule_divides_the_clocked_updates_by_the_rows(
    tiny: SigmaDeltaCounts,
) -> None:
    one = tiny.one_step_schedule()
    assert one.updates_clocked == (2.0, 3.0, 2.0) and one.rows == 1
    assert one.messages == tiny.messages and one.synaptic_events == tiny.synaptic_events
    w = what_ifs(tiny, load_profile("loihi1"), load_profile("horowitz45_int8"))
    assert w["as_priced_pj"] == w["held_clocked_pj"]
    assert w["held_clocked_pj"] - w["one_step_clocked_pj"] == pytest.approx((15 - 5) * 81.0)
    assert w["held_clocked_pj"] - w["held_active_pj"] == pytest.approx((15 - 4) * 81.0)
    assert w["clocked_updates"] == {"held": 15.0, "one_step": 5.0}


def test_the_joint_uncertainty_samples_the_derived_ranges(tiny: SigmaDeltaCounts) -> None:
    chip, host = load_profile("loihi1"), load_profile("horowitz45_int8")
    graded = tiny.prices_for(chip)
    terms = price_terms(tiny, chip, host)
    events = [t for t in terms if t.part == "synaptic ops"]
    j = joint(events, terms, (graded, host), samples=2000)
    # 3 events at 23.6-142 pJ, 4 at 23.6-284 pJ: the spread covers more than the low end
    assert 7 * 23.6 <= j["snn_pj"]["p05"] < j["snn_pj"]["p95"] <= 3 * 142 + 4 * 284
    assert j["snn_pj"]["p95"] > 3 * 35.5 + 4 * 35.5  # beyond the binary synaptic op's range


def test_break_even_density_keeps_the_clocked_updates_fixed(tiny: SigmaDeltaCounts) -> None:
    chip, host = load_profile("loihi1"), load_profile("horowitz45_int8")
    now = total(price_terms(tiny, chip, host))
    fixed = total(price_terms(tiny.scaled(0.0), chip, host))
    assert now - fixed == pytest.approx(7 * 23.6 + 2 * 1.7 + 5 * 20.3)
    out = break_even_density(tiny, chip, host, budget_pj=fixed + (now - fixed) / 2)
    assert out["density"] == pytest.approx(0.5)
    assert break_even_density(tiny, chip, host, budget_pj=fixed / 2)["density"] is None


def test_counts_from_a_plain_dict_and_refused_when_inconsistent() -> None:
    without_sigma = {**TINY, **{k: TINY[k][:2] for k in ("messages", "payload_bits",
                                                         "synaptic_events")}}  # fmt: skip
    assert SigmaDeltaCounts.from_dict(without_sigma).messages == (1.0, 2.0, 0.0)
    for bad, fragment in (({"messages": [1]}, "messages has 1 entries"),
                          ({"updates_active": [1, 10, 2]}, "more active updates"),
                          ({"colour": 1}, "unknown key 'colour'"),
                          ({"precision": "int3"}, "unknown precision")):  # fmt: skip
        with pytest.raises((ReportError, ValueError), match=fragment):
            SigmaDeltaCounts.from_dict({**TINY, **bad})


def test_profile_rules_parse_default_and_refuse() -> None:
    text = _builtin("loihi1")
    assert parse_profile(text, "t").rule("messages").value == "binary"
    spin = load_profile("spinnaker2").rule("neuron_updates")
    assert (spin.value, spin.tag) == ("clocked", "assumed")  # no rule stated: the costlier
    for edit, fragment in (
        (lambda t: t.replace('value = "clocked"', 'value = "lazy"'), "'lazy' is not one of"),
        (lambda t: t + '\n[rules.colour]\nvalue = "x"\n', "rules.colour: unknown rule"),
        (
            lambda t: t.replace('value = "binary"\ntag = "derived"\n', 'value = "binary"\n'),
            "give exactly source, tag, value",
        ),
    ):
        with pytest.raises(ProfileError, match=fragment):
            parse_profile(edit(text), "t")
    digital = _builtin("horowitz45_int8") + '\n[rules.messages]\nvalue = "binary"\n'
    with pytest.raises(ProfileError, match="only a neuromorphic profile states rules"):
        parse_profile(digital, "t")


def _builtin(name: str) -> str:
    from importlib import resources

    return resources.files("snnkart.energy.builtin").joinpath(f"{name}.toml").read_text("utf-8")
