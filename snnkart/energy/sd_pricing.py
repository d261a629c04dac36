"""A sigma-delta inference priced on a chip profile (its host work on a digital one), term by
term, with the provenance of every price, and the schedule and update-rule what-ifs.

    chip:  graded message x messages of each SigmaDelta layer
           + graded synaptic op x synaptic events (the input Delta's, each SigmaDelta's, into
             the readout Sigma's Dense too: a graded event is a multiply-accumulate)
           + neuron_update x the updates the chip performs: every neuron at every row (the
             profile's rules.neuron_updates = clocked) or only the active ones (active)
           + graded hop x messages x tile hops (where the chip prices hops)
           + io_bit x the bits over the host<->chip link
    host:  the normalisation, the input Delta, the readout (SigmaDeltaCounts.host)

**No profile publishes the energy of a graded message or a graded synaptic event.** Both are
derived from the chip's own price of a (binary) spike and synaptic op, for a payload of ``b``
bits, as ``k x price`` with ``k`` from 1 (the payload rides in the message at no extra cost)
up to the number of the chip's native units the payload takes: ``ceil(b / 8)`` 8-bit words on
a chip with graded messages (Loihi 2, whose per-op prices derive from totals over 8-bit
operations), ``b`` one-bit spikes (and ``b`` accumulates, bit-serially) on a chip that carries
binary spikes only (every other profile: an emulation). The central value is ``k = 1``. These
derived prices are added to the chip profile under their own names (``graded_message_<b>b``,
``graded_synop_<b>b``, ``graded_hop_<b>b``), so the joint uncertainty samples their ranges.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from snnkart.energy.placement import Placement
from snnkart.energy.pricing import Term, _digital, total
from snnkart.energy.profiles import Price, Profile, Rule
from snnkart.energy.sd_counts import SigmaDeltaCounts

WORD_BITS = 8
"""The payload unit of a chip with graded messages: Loihi 2's per-op prices derive from
Hala Point's totals over 8-bit operations (>15 TOPS/W, 8-bit; snn-nir-lava.md §3.2)."""
GRADED = {"message": "spike", "synop": "synaptic_op", "hop": "hop"}
"""Each graded price and the chip's binary price it is derived from."""


def payload_units(chip: Profile, bits: int) -> int:
    """How many of ``chip``'s native units a payload of ``bits`` takes at the most: 8-bit
    words on a chip with graded messages, single bits on a binary one."""
    if chip.rule("messages").value == "graded":
        return max(1, math.ceil(bits / WORD_BITS))
    return max(1, bits)


def graded_op(kind: str, bits: int) -> str:
    """The name of the derived price of a graded ``kind`` (message, synop, hop) of ``bits``."""
    return f"graded_{kind}_{bits}b"


def graded_price(chip: Profile, kind: str, bits: int) -> Price:
    """The derived price of one graded ``kind`` with a ``bits`` payload (module docstring)."""
    base = chip.prices[GRADED[kind]]
    k = payload_units(chip, bits)
    rule = chip.rule("messages")
    unit = f"{WORD_BITS}-bit words" if rule.value == "graded" else "one-bit spikes"
    source = (
        f"no graded {kind} energy is published for {chip.name}; derived from its "
        f"{GRADED[kind]} ({base.value:g} pJ, {base.low:g}-{base.high:g}; {base.tag}) x k, "
        f"k = 1 (the payload free) to {k} (a {bits}-bit payload as {k} {unit}; "
        f"rules.messages = {rule.value}: {rule.source})"
    )
    return Price(base.value, base.low, base.high * k, "pJ", "derived", source)


def with_graded_prices(chip: Profile, counts: SigmaDeltaCounts) -> Profile:
    """``chip`` with the derived graded prices ``counts`` needs (its payload widths)."""
    prices = dict(chip.prices)
    for bits in sorted({b for b in counts.message_bits if b}):
        for kind in GRADED:
            if GRADED[kind] in chip.prices:
                prices[graded_op(kind, bits)] = graded_price(chip, kind, bits)
    return replace(chip, prices=prices)


def _term(part: str, what: str, count: float, profile: Profile, op: str) -> Term:
    price = profile.prices[op]
    return Term(part, what, count, profile.name, op, price.value, price.source)


def _updates(counts: SigmaDeltaCounts, chip: Profile) -> list[Term]:
    rule = chip.rule("neuron_updates").value
    source = counts.updates_clocked if rule == "clocked" else counts.updates_active
    terms = []
    for i, n in enumerate(counts.chip_sizes, start=1):
        name = f"SigmaDelta {i}" if i <= counts.depth else "readout Sigma"
        what = (f"{name} ({n} neurons): N x {counts.rows} rows (clocked)" if rule == "clocked"
                else f"{name} ({n} neurons): active neurons (active)")  # fmt: skip
        terms.append(_term("neuron updates", what, source[i], chip, "neuron_update"))
    return terms


def chip_terms(counts: SigmaDeltaCounts, chip: Profile) -> list[Term]:
    """The chip's terms; ``chip`` must carry the graded prices (:func:`with_graded_prices`)."""
    terms = []
    for i, bits in enumerate(counts.message_bits[:-1]):
        into = counts.chip_sizes[i]
        sender = "input Delta (host)" if i == 0 else f"SigmaDelta {i}"
        terms.append(_term("synaptic ops", f"{sender} -> {into}: messages x fan-out "
                           f"({bits}-bit payload x weight)", counts.synaptic_events[i], chip,
                           graded_op("synop", bits)))  # fmt: skip
        if i:
            terms.append(_term("messages", f"{sender}: graded messages ({bits}-bit)",
                               counts.messages[i], chip, graded_op("message", bits)))  # fmt: skip
    terms += _updates(counts, chip)
    if "hop" in chip.prices and chip.neurons_per_core:
        where = Placement.of(counts.chip_sizes, chip.neurons_per_core, chip.cores_per_tile)
        for i, hops in enumerate(where.hops_per_spike[:-1], start=1):
            what = f"SigmaDelta {i}: messages x {hops:g} tile hops"
            op = graded_op("hop", counts.num_message_bits)
            terms.append(_term("routing", what, counts.messages[i] * hops, chip, op))
    if "io_bit" in chip.prices:
        bits_in, bits_out = counts.link_bits()
        terms += [
            _term("host link", "in: input messages x (payload + address bits)", bits_in, chip,
                  "io_bit"),
            _term("host link", f"out: the Sigma's {counts.n_out} values, once per env step",
                  bits_out, chip, "io_bit"),
        ]  # fmt: skip
    return terms


def sd_terms(counts: SigmaDeltaCounts, chip: Profile, host: Profile) -> list[Term]:
    """A sigma-delta inference's dynamic energy, term by term (``chip`` as loaded: its graded
    prices are added here; price the uncertainty on :func:`with_graded_prices` of it)."""
    graded = with_graded_prices(chip, counts)
    return chip_terms(counts, graded) + _digital(
        counts.host(), host, "host compute", counts.host_parameters
    )


def with_rule(chip: Profile, name: str, value: str, why: str) -> Profile:
    """``chip`` with one rule set (a what-if)."""
    return replace(chip, rules={**chip.rules, name: Rule(value, "assumed", why)})


def what_ifs(counts: SigmaDeltaCounts, chip: Profile, host: Profile) -> dict[str, Any]:
    """The energy per inference (pJ) as priced, and under each other schedule and update rule:
    held (``rows`` Lava steps per env step) or one step per env step, clocked or active."""
    one = counts.one_step_schedule()
    clocked = with_rule(chip, "neuron_updates", "clocked", "what-if")
    active = with_rule(chip, "neuron_updates", "active", "what-if")
    return {
        "rule": chip.rule("neuron_updates").as_dict(),
        "rows": counts.rows,
        "as_priced_pj": total(sd_terms(counts, chip, host)),
        "held_clocked_pj": total(sd_terms(counts, clocked, host)),
        "held_active_pj": total(sd_terms(counts, active, host)),
        "one_step_clocked_pj": total(sd_terms(one, clocked, host)),
        "clocked_updates": {
            "held": sum(counts.updates_clocked[1:]),
            "one_step": sum(one.updates_clocked[1:]),
        },
        "note": "one step per env step: the action lags the observation by L + 1 env steps "
        "(docs/sigma-delta.md, the held-schedule decision); the same messages and synaptic events",
    }


def break_even_density(counts: SigmaDeltaCounts, chip: Profile, host: Profile,
                       budget_pj: float) -> dict[str, Any]:  # fmt: skip
    """The message density (relative to today's) at which the inference costs ``budget_pj``:
    its energy is a fixed part (clocked updates, the link's readout, host work) plus a part
    proportional to the messages, so ``fixed + d x variable = budget``."""
    fixed = total(sd_terms(counts.scaled(0.0), chip, host))
    variable = total(sd_terms(counts, chip, host)) - fixed
    out: dict[str, Any] = {"budget_pj": budget_pj, "fixed_pj": fixed, "per_density_pj": variable}
    if fixed >= budget_pj:
        return {**out, "density": None, "reason": "the parts that do not depend on the messages "
                "alone cost at least the budget: no sparsity reaches it"}  # fmt: skip
    if variable <= 0:
        return {**out, "density": None, "reason": "the energy does not depend on the messages "
                "here, and it is within the budget"}  # fmt: skip
    return {**out, "density": (budget_pj - fixed) / variable,
            "reason": "below this density (messages relative to the deployment's) the "
            "inference costs less than the budget"}  # fmt: skip
