"""Energy = count x price, term by term, with the provenance of every price; and how the SNN/ANN
ratio moves when a price or the firing density moves.

The SNN's energy per inference on a neuromorphic profile ``chip`` with its host work on a
digital profile ``host``::

    chip:  synaptic_op x synaptic ops + neuron_update x neuron updates + spike x spikes
           (the T logical steps, plus the Lava pipeline's fill and drain steps)
           + hop x spikes x tile hops (routing, from the placement of ``chip``)
           + io_bit x the bits over the host<->chip link (currents in, the last layer's spikes out)
    host:  mac, add, mult x the host operations (counts.host_ops), and its weights read from
           the host's memory array that holds the host's own weights (profiles.memory_row)

The ANN's on a digital profile: the same digital prices x its operations, its weights read from
the array that holds the ANN's weights. The ANN runs on the host the SNN's host work runs on,
so it has no link. Static power x the control period is a term of its own on each side
(:func:`static_terms`), apart from these dynamic energies.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import cast

from snnkart.contract.energy_record import DensityBreakEven
from snnkart.contract.report_record import SensitivityRow, Static, TermRecord
from snnkart.energy.activity import Counted
from snnkart.energy.counts import AnnCounts, HostOp, SnnCounts
from snnkart.energy.profiles import Price, Profile, memory_row
from snnkart.envs.constants import DT
from snnkart.errors import ProfileError

PARTS = (
    "synaptic ops",
    "neuron updates",
    "spikes",
    "routing",
    "host link",
    "host compute",
    "memory",
)
"""The dynamic energy's parts (memory: weight reads, priced by a memory-inclusive profile)."""
STATIC = "static"
"""The part of a static term: static power x the control period."""
CONTROL_PERIOD_S = DT
"""The env's control period in seconds (one inference per env step, 60 Hz)."""


@dataclass(frozen=True)
class Term:
    """One priced count: ``energy_pj = count * price_pj``, with the profile's figure it used."""

    part: str
    what: str
    count: float
    profile: str
    op: str
    price: Price

    @property
    def price_pj(self) -> float:
        return self.price.value

    @property
    def energy_pj(self) -> float:
        return self.count * self.price.value

    def as_dict(self) -> TermRecord:
        """The report's record of the term (``$defs/term``): the price flattened to its value
        and source."""
        return TermRecord(
            part=self.part,
            what=self.what,
            count=self.count,
            profile=self.profile,
            op=self.op,
            price_pj=self.price.value,
            source=self.price.source,
            energy_pj=self.energy_pj,
        )


def _term(part: str, what: str, count: float, profile: Profile, op: str) -> Term:
    return Term(part, what, count, profile.name, op, profile.prices[op])


def _digital(ops: Iterable[HostOp], profile: Profile, part: str, parameters: int) -> list[Term]:
    """Digital operations priced on ``profile``; weight reads as 64-bit reads from the array
    that holds this side's ``parameters`` weights at the profile's ``weight_bits``."""
    nbytes = profile.weight_bytes(parameters)
    row = memory_row(nbytes)
    terms = []
    for op in ops:
        if op.op != "weight_read":
            terms.append(_term(part, op.what, op.count, profile, op.op))
            continue
        reads = op.count * profile.weight_bits / 64
        what = (
            f"{op.what}: {op.count:g} x {profile.weight_bits} bits = {reads:g} 64-bit reads "
            f"from the array for {nbytes / 1000:.3g} kB of weights"
        )
        terms.append(_term("memory", what, reads, profile, row))
    return terms


def terms(counts: Counted, chip: Profile, host: Profile) -> list[Term]:
    """Any family's dynamic energy per inference, term by term: its chip activity priced on
    ``chip`` (with the prices the family derives from it), its host work on ``host``."""
    priced = counts.prices_for(chip)
    on_chip = [_term(a.part, a.what, a.count, priced, a.op) for a in counts.chip_activity(priced)]
    return on_chip + _digital(counts.host_work(), host, "host compute", counts.host_parameters)


def ann_terms(counts: AnnCounts, profile: Profile) -> list[Term]:
    """The ANN's dynamic energy per inference, term by term (all of it host work)."""
    return terms(counts, profile, profile)


def static_terms(profile: Profile, seconds: float, role: str) -> list[Term]:
    """``profile``'s static power over ``seconds`` (none where it is not published)."""
    if "static_power" not in profile.prices:
        return []
    what = f"{role}: static power x the control period ({1e3 * seconds:.3g} ms)"
    return [_term(STATIC, what, seconds, profile, "static_power")]


def not_published(*profiles: Profile) -> list[dict[str, str]]:
    """The optional prices these profiles have no figure for, and why."""
    seen = {p.name: p for p in profiles}
    return [
        {"profile": p.name, "op": op, "why": why}
        for p in seen.values()
        for op, why in p.not_published.items()
    ]


def total(terms: Iterable[Term]) -> float:
    return sum((t.energy_pj for t in terms), 0.0)


def breakdown(terms: Iterable[Term]) -> dict[str, float]:
    """Energy per part: every one of :data:`PARTS`, and any other part a term names (a
    sigma-delta inference's ``messages``)."""
    out = dict.fromkeys(PARTS, 0.0)
    for t in terms:
        out[t.part] = out.get(t.part, 0.0) + t.energy_pj
    return out


def with_price(profile: Profile, op: str, value: float) -> Profile:
    """``profile`` with one price replaced (the sensitivity analysis)."""
    prices = dict(profile.prices)
    prices[op] = replace(prices[op], value=value)
    return replace(profile, prices=prices)


@dataclass(frozen=True)
class Comparison:
    """The SNN on ``chip`` (host work on ``host``) against the ANN on ``digital``, one inference
    per control period (the SNN's counts': :attr:`SnnCounts.period_s`). When ``host`` and ``digital`` are the same profile, its
    prices are shared: a price moved on one side only is refused."""

    snn: SnnCounts
    ann: AnnCounts
    chip: Profile
    host: Profile
    digital: Profile

    @property
    def period_s(self) -> float:
        """The control period the static terms are taken over."""
        return self.snn.period_s

    def __post_init__(self) -> None:
        if self.host.name != self.digital.name:
            return
        for op, price in self.digital.prices.items():
            other = self.host.prices.get(op)
            if other != price:
                raise ProfileError(
                    f"{self.digital.name}.{op}: {price.value:g} pJ for the ANN but "
                    f"{'none' if other is None else f'{other.value:g} pJ'} for the SNN's host "
                    "work on the same profile; move a shared price on both sides together"
                )

    def energies(self) -> tuple[float, float]:
        """The SNN's and the ANN's dynamic energy per inference, pJ."""
        return (
            total(terms(self.snn, self.chip, self.host)),
            total(ann_terms(self.ann, self.digital)),
        )

    def ratio(self) -> float:
        e_snn, e_ann = self.energies()
        return e_snn / e_ann if e_ann > 0 else float("inf")

    def static_terms(self) -> tuple[list[Term], list[Term]]:
        """Static power x the control period: the SNN's (its chip and its host) and the ANN's
        (its host). Host static power adds alike to both sides, the chip's to the SNN's only."""
        snn = static_terms(self.chip, self.period_s, "chip")
        snn += static_terms(self.host, self.period_s, "SNN's host")
        return snn, static_terms(self.digital, self.period_s, "ANN's host")

    def with_static(self) -> Static:
        """The verdict with static power over the control period, the average power at the
        control rate, and the static figures that are not published (counted as 0)."""
        e_snn, e_ann = self.energies()
        s_terms, a_terms = self.static_terms()
        s_snn, s_ann = total(s_terms), total(a_terms)
        both = e_ann + s_ann
        return {
            "control_period_s": self.period_s,
            "snn_static_pj": s_snn,
            "ann_static_pj": s_ann,
            "snn_static_terms": [t.as_dict() for t in s_terms],
            "ann_static_terms": [t.as_dict() for t in a_terms],
            "ratio": (e_snn + s_snn) / both if both > 0 else None,
            "average_power_w": {
                "snn_dynamic": e_snn * 1e-12 / self.period_s,
                "snn_with_static": (e_snn + s_snn) * 1e-12 / self.period_s,
                "ann_dynamic": e_ann * 1e-12 / self.period_s,
                "ann_with_static": both * 1e-12 / self.period_s,
            },
            "not_published": [
                n
                for n in not_published(self.chip, self.host, self.digital)
                if n["op"] == "static_power"
            ],
            "note": "a static power that is not published counts as 0; the host's adds alike "
            "to both sides (the ANN runs on the SNN's host), pulling the ratio towards 1",
        }

    def _moved(self, side: str, op: str, value: float) -> Comparison:
        """This comparison with ``op`` at ``value`` on ``side`` (chip, host or digital); a
        price of the profile the host and the ANN share moves on both."""
        shared = self.host.name == self.digital.name and side != "chip"
        host = with_price(self.host, op, value) if side == "host" or shared else self.host
        digital = (
            with_price(self.digital, op, value) if side == "digital" or shared else self.digital
        )
        chip = with_price(self.chip, op, value) if side == "chip" else self.chip
        return replace(self, chip=chip, host=host, digital=digital)

    def sensitivity(self) -> list[SensitivityRow]:
        """The ratio with each dynamic price at its low and high end and at 0.1x and 10x its
        value (a price the host and the ANN share moved on both sides together)."""
        rows: list[SensitivityRow] = []
        shared = self.host.name == self.digital.name
        sides = ("chip", "digital") if shared else ("chip", "host", "digital")
        for side in sides:
            profile: Profile = getattr(self, side)
            for op, price in profile.prices.items():
                if op == "static_power":
                    continue  # not part of the dynamic ratio: see with_static
                ratios = {
                    name: self._moved(side, op, value).ratio()
                    for name, value in (
                        ("low", price.low),
                        ("high", price.high),
                        ("x0.1", price.value / 10),
                        ("x10", price.value * 10),
                    )
                }
                label = "host+digital" if shared and side == "digital" else side
                row = {"profile": profile.name, "side": label, "op": op, "ratio": self.ratio()}
                rows.append(
                    cast(SensitivityRow, row | {f"ratio_{k}": v for k, v in ratios.items()})
                )
        return rows

    def break_even(self) -> DensityBreakEven:
        """How sparse the SNN must be to match the ANN: its energy is a fixed part (neuron
        updates, the host link, host work) plus a part proportional to its spikes, so the
        break-even density (spikes relative to today's) solves ``fixed + d * variable = E_ann``."""
        e_ann = self.energies()[1]
        fixed = total(terms(self.snn.scaled(0.0), self.chip, self.host))
        variable = total(terms(self.snn, self.chip, self.host)) - fixed
        head = DensityBreakEven(
            ann_pj=e_ann, fixed_pj=fixed, per_density_pj=variable, density=None, reason=""
        )
        if fixed >= e_ann:
            reason = (
                "the clocked neuron updates, the host link and the host work alone cost at "
                "least as much as the ANN: no sparsity can break even"
            )
            return head | {"reason": reason}
        if variable <= 0:
            reason = (
                "the SNN's energy does not depend on its spikes here (no spikes, or spikes "
                "priced at 0), and it is below the ANN's"
            )
            return head | {"reason": reason}
        d = (e_ann - fixed) / variable
        return DensityBreakEven(
            ann_pj=e_ann,
            fixed_pj=fixed,
            per_density_pj=variable,
            density=d,
            firing_rates=[r * d for r in self.snn.firing_rates()],
            synops=d * sum(self.snn.synops),
            reason="the SNN uses less energy than the ANN below this density (spikes relative "
            "to the deployed policy's; pipeline fill/drain spikes scaled alike)",
        )
