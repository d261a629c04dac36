"""Energy = count x price, term by term, with the provenance of every price; and how the SNN/ANN
ratio moves when a price or the firing density moves.

The SNN's energy per inference on a neuromorphic profile ``chip`` with its host work on a
digital profile ``host``::

    chip:  synaptic_op x synaptic ops + neuron_update x neuron updates + spike x spikes
           (the T logical steps, plus the Lava pipeline's fill and drain steps)
    host:  mac, add, mult and weight_read x the host operations (counts.host_ops)

The ANN's on a digital profile: the same four digital prices x its operations.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from typing import Any

from snnkart.energy.counts import AnnCounts, HostOp, SnnCounts
from snnkart.energy.profiles import Profile

PARTS = ("synaptic ops", "neuron updates", "spikes", "host compute", "memory")
"""The energy breakdown's parts (memory: weight reads priced by a memory-inclusive profile)."""


@dataclass(frozen=True)
class Term:
    """One priced count: ``energy_pj = count * price_pj``."""

    part: str
    what: str
    count: float
    profile: str
    op: str
    price_pj: float
    source: str

    @property
    def energy_pj(self) -> float:
        return self.count * self.price_pj

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), "energy_pj": self.energy_pj}


def _term(part: str, what: str, count: float, profile: Profile, op: str) -> Term:
    price = profile.prices[op]
    return Term(part, what, count, profile.name, op, price.value, price.source)


def _digital(ops: Iterable[HostOp], profile: Profile, part: str) -> list[Term]:
    return [
        _term("memory" if op.op == "weight_read" else part, op.what, op.count, profile, op.op)
        for op in ops
    ]


def snn_terms(counts: SnnCounts, chip: Profile, host: Profile) -> list[Term]:
    """The SNN's energy per inference, term by term."""
    terms = []
    for i, n in enumerate(counts.net.sizes):
        layer = f"layer {i + 1} ({n} neurons)"
        terms += [
            _term("synaptic ops", f"{layer}: spikes x fan-out", counts.synops[i], chip, "synaptic_op"),
            _term("neuron updates", f"{layer}: N x T", counts.neuron_updates[i], chip, "neuron_update"),
            _term("spikes", f"{layer}: spikes", counts.spikes[i], chip, "spike"),
        ]  # fmt: skip
        if counts.overhead_neuron_updates[i] or counts.overhead_spikes[i]:
            terms += [
                _term("synaptic ops", f"{layer}: pipeline fill/drain", counts.overhead_synops[i], chip, "synaptic_op"),
                _term("neuron updates", f"{layer}: pipeline fill/drain", counts.overhead_neuron_updates[i], chip, "neuron_update"),
                _term("spikes", f"{layer}: pipeline fill/drain", counts.overhead_spikes[i], chip, "spike"),
            ]  # fmt: skip
    return terms + _digital(counts.host, host, "host compute")


def ann_terms(counts: AnnCounts, profile: Profile) -> list[Term]:
    return _digital(counts.ops(), profile, "host compute")


def total(terms: Iterable[Term]) -> float:
    return sum(t.energy_pj for t in terms)


def breakdown(terms: Iterable[Term]) -> dict[str, float]:
    out = dict.fromkeys(PARTS, 0.0)
    for t in terms:
        out[t.part] += t.energy_pj
    return out


def with_price(profile: Profile, op: str, value: float) -> Profile:
    """``profile`` with one price replaced (the sensitivity analysis)."""
    prices = dict(profile.prices)
    prices[op] = replace(prices[op], value=value)
    return replace(profile, prices=prices)


@dataclass(frozen=True)
class Comparison:
    """The SNN on ``chip`` (host work on ``host``) against the ANN on ``digital``."""

    snn: SnnCounts
    ann: AnnCounts
    chip: Profile
    host: Profile
    digital: Profile

    def energies(self) -> tuple[float, float]:
        return (
            total(snn_terms(self.snn, self.chip, self.host)),
            total(ann_terms(self.ann, self.digital)),
        )

    def ratio(self) -> float:
        e_snn, e_ann = self.energies()
        return e_snn / e_ann if e_ann > 0 else float("inf")

    def sensitivity(self) -> list[dict[str, Any]]:
        """The ratio with each price at its low and high end and at 0.1x and 10x its value."""
        rows = []
        for side in ("chip", "host", "digital"):
            profile: Profile = getattr(self, side)
            for op, price in profile.prices.items():
                ratios = {}
                for name, value in (("low", price.low), ("high", price.high),
                                    ("x0.1", price.value / 10), ("x10", price.value * 10)):  # fmt: skip
                    moved = with_price(profile, op, value)
                    ratios[name] = replace(
                        self,
                        chip=moved if side == "chip" else self.chip,
                        host=moved if side == "host" else self.host,
                        digital=moved if side == "digital" else self.digital,
                    ).ratio()
                rows.append({"profile": profile.name, "side": side, "op": op, "ratio": self.ratio(),
                             **{f"ratio_{k}": v for k, v in ratios.items()}})  # fmt: skip
        return rows

    def break_even(self) -> dict[str, Any]:
        """How sparse the SNN must be to match the ANN: its energy is a fixed part (neuron
        updates, host work) plus a part proportional to its spikes, so the break-even density
        (spikes relative to today's) solves ``fixed + d * variable = E_ann``."""
        e_ann = self.energies()[1]
        fixed = total(snn_terms(self.snn.scaled(0.0), self.chip, self.host))
        variable = total(snn_terms(self.snn, self.chip, self.host)) - fixed
        out: dict[str, Any] = {"ann_pj": e_ann, "fixed_pj": fixed, "per_density_pj": variable}
        if fixed >= e_ann:
            out.update(density=None, reason="the clocked neuron updates and the host work alone "
                       "cost at least as much as the ANN: no sparsity can break even")  # fmt: skip
            return out
        if variable <= 0:
            out.update(density=None, reason="the SNN's energy does not depend on its spikes "
                       "here (no spikes, or spikes priced at 0), and it is below the ANN's")  # fmt: skip
            return out
        d = (e_ann - fixed) / variable
        out.update(
            density=d,
            firing_rates=[r * d for r in self.snn.firing_rates()],
            synops=d * sum(self.snn.synops),
            reason="the SNN uses less energy than the ANN below this density (spikes relative to "
            "the deployed policy's; pipeline fill/drain spikes scaled alike)",
        )
        return out
