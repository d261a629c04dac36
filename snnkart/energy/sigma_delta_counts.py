"""A sigma-delta policy's counts per inference (one env step), as its deployment records them,
and the host work around the chip.

The chain (docs/sigma-delta.md) is ``obs -> Delta -> Dense_1 -> SigmaDelta_1 -> ... ->
Dense_{L+1} -> Sigma -> readout``. Every per-layer count is a mean per env step over the
``L + 2`` layers in that order:

- index 0, the input **Delta**: host work (the observation's change, sent when it reaches the
  input threshold); its messages cross the host->chip link into Dense_1 on the chip;
- indices 1..L, the **SigmaDelta** layers: chip neurons that send graded messages;
- index L + 1, the readout **Sigma**: chip neurons that accumulate, read by the host once per
  env step (they send no message on the chip).

Per layer: ``messages`` sent, their ``payload_bits``, ``synaptic_events`` (messages x fan-out
of the Dense they enter), ``updates_clocked`` (layer size x ``rows``, the Lava steps per env
step: ``L + 2`` under the held schedule) and ``updates_active`` (neurons that received a
non-zero input or sent a message).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.link import word_bits
from snnkart.energy.activity import Activity
from snnkart.energy.counts import HostOp, placement
from snnkart.energy.graded import graded_op, with_graded_prices
from snnkart.energy.profiles import Profile
from snnkart.envs.constants import DT
from snnkart.errors import ReportError

PER_LAYER = ("messages", "payload_bits", "synaptic_events", "updates_clocked", "updates_active")
"""The counts given per layer (Delta, SigmaDelta..., Sigma), each a mean per env step."""


@dataclass(frozen=True)
class SigmaDeltaCounts:
    """A sigma-delta deployment's counts per env step (module docstring), with the network's
    shape: ``n_in`` inputs, hidden ``sizes``, ``n_out`` readout neurons, ``num_message_bits``
    per hidden message, ``input_bits`` per input message, ``rows`` Lava steps per env step,
    ``precision`` of the deployment (the readout's word over the link)."""

    n_in: int
    sizes: tuple[int, ...]
    n_out: int
    num_message_bits: int
    input_bits: int
    rows: int
    messages: tuple[float, ...]
    payload_bits: tuple[float, ...]
    synaptic_events: tuple[float, ...]
    updates_clocked: tuple[float, ...]
    updates_active: tuple[float, ...]
    precision: str = "fixed"
    action_mode: str = "discrete"
    env_steps: int = 1
    period_s: float = DT  # the control period (:attr:`SnnCounts.period_s`)

    def __post_init__(self) -> None:
        n = len(self.sizes) + 2
        for name in PER_LAYER:
            values = getattr(self, name)
            if len(values) != n:
                raise ReportError(
                    f"sigma-delta counts: {name} has {len(values)} entries for {n} layers "
                    "(input Delta, each SigmaDelta, readout Sigma); record one per layer"
                )
            if any(v < 0 for v in values):
                raise ReportError(f"sigma-delta counts: {name} has a negative count {values}")
        if self.rows < 1 or min(self.sizes, default=0) < 1 or self.n_in < 1 or self.n_out < 1:
            raise ReportError(
                f"sigma-delta counts: rows {self.rows}, n_in {self.n_in}, sizes {self.sizes}, "
                f"n_out {self.n_out}: every one must be at least 1"
            )
        over = [
            i
            for i, (a, c) in enumerate(zip(self.updates_active, self.updates_clocked, strict=True))
            if a > c
        ]
        if over:
            raise ReportError(
                f"sigma-delta counts: layer {over[0]} has more active updates than clocked ones; "
                "an active neuron is one of the clocked"
            )
        word_bits(self.precision)  # refuses an unknown precision

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SigmaDeltaCounts:
        """From a plain dict with this class's field names (per-layer lists of means per env
        step); a per-layer list that leaves out the Sigma (``L + 1`` entries) gets a 0 for it."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ReportError(
                f"sigma-delta counts: unknown key {unknown[0]!r}; use {sorted(known)}"
            )
        missing = sorted(
            k
            for k in known - set(data)
            if k not in ("precision", "action_mode", "env_steps", "period_s")
        )
        if missing:
            raise ReportError(f"sigma-delta counts: {missing[0]!r} missing")
        values = dict(data)
        values["sizes"] = tuple(int(n) for n in data["sizes"])
        for name in PER_LAYER:
            v = [float(x) for x in data[name]]
            values[name] = tuple([*v, 0.0] if len(v) == len(values["sizes"]) + 1 else v)
        return cls(**values)

    @classmethod
    def of_deploy(cls, record: DeployRecord) -> SigmaDeltaCounts:
        """A sigma-delta deployment's counts (``counts.sigma_delta`` totals) as means per env
        step, with its network's shape, precision and action mode. ``input_bits`` is
        ``num_message_bits``: the deploy record's manifest summary does not keep the manifest's
        ``input_bits`` (the integer range of the input, 8), and the deployed input Delta sends
        its messages at ``num_message_bits`` as every layer (its ``payload_bits`` are messages x
        ``num_message_bits``), so that is what crosses the link."""
        sd = record.counts.sigma_delta
        if sd is None:
            raise ReportError(
                f"{record.nir_file}: a LIF deployment has no sigma-delta counts; price it with "
                "SnnCounts.of_deploy (snnkart report does)"
            )
        n = max(record.counts.env_steps, 1)
        net = record.network
        per_layer: dict[str, Any] = {k: tuple(v / n for v in getattr(sd, k)) for k in PER_LAYER}
        return cls(
            n_in=net.n_in,
            sizes=tuple(net.sizes),
            n_out=net.n_out,
            num_message_bits=sd.num_message_bits,
            input_bits=sd.num_message_bits,
            rows=sd.rows_per_env_step,
            **per_layer,
            precision=record.precision,
            action_mode=record.manifest.action_mode,
            env_steps=record.counts.env_steps,
        )

    @property
    def depth(self) -> int:
        """L: the hidden SigmaDelta layers."""
        return len(self.sizes)

    @property
    def chip_sizes(self) -> tuple[int, ...]:
        """The chip's neuron groups: each SigmaDelta layer, then the readout Sigma."""
        return (*self.sizes, self.n_out)

    @property
    def message_bits(self) -> tuple[int, ...]:
        """Payload bits of one message per sending layer (Delta, SigmaDelta...; Sigma sends
        none on the chip: 0)."""
        return (self.input_bits, *([self.num_message_bits] * self.depth), 0)

    @property
    def host_parameters(self) -> int:
        """What the host reads from memory: the readout's biases (every weight is on the chip)."""
        return self.n_out

    def link_bits(self) -> tuple[float, float]:
        """``(host_to_chip, chip_to_host)`` bits per env step: each input message's payload and
        its address (``ceil(log2 n_in)`` bits: which input changed), and the readout Sigma's
        ``n_out`` values of one word each, read once per env step."""
        address = math.ceil(math.log2(self.n_in)) if self.n_in > 1 else 0
        bits_in = self.payload_bits[0] + self.messages[0] * address
        return bits_in, float(self.n_out * word_bits(self.precision))

    def host_work(self) -> list[HostOp]:
        return self.host()

    def prices_for(self, chip: Profile) -> Profile:
        """``chip`` with the derived graded prices of these payload widths
        (:mod:`snnkart.energy.graded`)."""
        return with_graded_prices(chip, self.message_bits)

    def chip_activity(self, chip: Profile) -> list[Activity]:
        """Graded synaptic events into each Dense, each SigmaDelta's graded messages, the
        updates the chip performs (``rules.neuron_updates``), routing and the link; ``chip``
        must carry the graded prices (:meth:`prices_for`)."""
        items = []
        for i, bits in enumerate(self.message_bits[:-1]):
            sender = "input Delta (host)" if i == 0 else f"SigmaDelta {i}"
            what = (
                f"{sender} -> {self.chip_sizes[i]}: messages x fan-out "
                f"({bits}-bit payload x weight)"
            )
            items.append(
                Activity("synaptic ops", what, self.synaptic_events[i], graded_op("synop", bits))
            )
            if i:
                items.append(
                    Activity(
                        "messages",
                        f"{sender}: graded messages ({bits}-bit)",
                        self.messages[i],
                        graded_op("message", bits),
                    )
                )
        return items + self._updates(chip) + self._routing(chip) + self._link(chip)

    def _updates(self, chip: Profile) -> list[Activity]:
        clocked = chip.rule("neuron_updates").value == "clocked"
        source = self.updates_clocked if clocked else self.updates_active
        items = []
        for i, n in enumerate(self.chip_sizes, start=1):
            name = f"SigmaDelta {i}" if i <= self.depth else "readout Sigma"
            what = (
                f"{name} ({n} neurons): N x {self.rows} rows (clocked)"
                if clocked
                else f"{name} ({n} neurons): active neurons (active)"
            )
            items.append(Activity("neuron updates", what, source[i], "neuron_update"))
        return items

    def _routing(self, chip: Profile) -> list[Activity]:
        where = placement(self.chip_sizes, chip)
        if "hop" not in chip.prices or where is None:
            return []
        op = graded_op("hop", self.num_message_bits)
        return [
            Activity(
                "routing",
                f"SigmaDelta {i}: messages x {hops:g} tile hops",
                self.messages[i] * hops,
                op,
            )
            for i, hops in enumerate(where.hops_per_spike[:-1], start=1)
        ]

    def _link(self, chip: Profile) -> list[Activity]:
        if "io_bit" not in chip.prices:
            return []
        bits_in, bits_out = self.link_bits()
        return [
            Activity(
                "host link", "in: input messages x (payload + address bits)", bits_in, "io_bit"
            ),
            Activity(
                "host link",
                f"out: the Sigma's {self.n_out} values, once per env step",
                bits_out,
                "io_bit",
            ),
        ]

    def host(self) -> list[HostOp]:
        """The host's work per env step: the observation's normalisation (as the ANN's), its
        integers, the input Delta, the readout and the action's decoding."""
        n_in, n_out = self.n_in, self.n_out
        compares = n_out - 1 if self.action_mode == "discrete" else 2 * n_out
        return [
            HostOp("normalisation: obs - mean, clip to +-c", "add", 3 * n_in),
            HostOp("normalisation: / std", "mult", n_in),
            HostOp("input integers: z / input_scale, rounded", "mult", n_in),
            HostOp("input Delta: a - act + residue", "add", 2 * n_in),
            HostOp("input Delta: |delta| >= vth", "add", n_in),
            HostOp("input Delta: residue = delta - sent", "add", n_in),
            HostOp("readout: sigma x out_scale", "mult", n_out),
            HostOp("readout: + b", "add", n_out),
            HostOp("readout: bias reads", "weight_read", n_out),
            HostOp("decoding: argmax or clip", "add", compares),
        ]

    def one_step_schedule(self) -> SigmaDeltaCounts:
        """What the 1-Lava-step-per-env-step schedule would count (the action lagging by
        ``L + 1`` env steps; docs/sigma-delta.md): the same messages and synaptic events, the
        clocked updates of one row instead of ``rows``, the same active updates (a layer
        receives one delivery per env step under either schedule)."""
        clocked = tuple(c / self.rows for c in self.updates_clocked)
        active = tuple(min(a, c) for a, c in zip(self.updates_active, clocked, strict=True))
        return replace(self, rows=1, updates_clocked=clocked, updates_active=active)

    def scaled(self, density: float) -> SigmaDeltaCounts:
        """``density`` times the messages (and so their payload, their synaptic events and the
        active updates: each is one per message or per delivery), the clocked updates as they are."""

        def s(v: tuple[float, ...]) -> tuple[float, ...]:
            return tuple(density * x for x in v)

        active = tuple(
            min(density * a, c)
            for a, c in zip(self.updates_active, self.updates_clocked, strict=True)
        )
        return replace(
            self,
            messages=s(self.messages),
            payload_bits=s(self.payload_bits),
            synaptic_events=s(self.synaptic_events),
            updates_active=active,
        )
