"""Operation counts per inference (one env step): the spiking policy's, measured in a deployment,
and an ANN's, from its layer widths.

The SNN's counts split where the work runs:

- **on the chip**: synaptic operations (spikes x fan-out, between spiking layers), neuron
  updates (every neuron at every SNN step: clocked) and spikes, for the policy's T logical
  steps, and apart from them the Lava pipeline's fill and drain steps (``overhead``);
- **on the host** (priced as digital operations): the observation's normalisation, the first
  layer's input current ``W1 z + b1`` (once per env step, current encoding), the readout
  ``Wr (counts / T) + br`` from the last layer's spike counts, and the action's decoding.

The last layer's spikes leave the chip for the host's readout; the deployment's counts list
them with the readout's fan-out, which is host work, so they are not chip synaptic operations.
What crosses the host<->chip link per inference (the T x n1 input currents in, the last layer's
spike flags out) is ``link_bits`` (:mod:`snnkart.contract.link`, the rule the backends count by).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from snnkart.contract.deploy_record import Counts, DeployRecord, StepCounts
from snnkart.contract.link import link_bits
from snnkart.energy.activity import Activity, HostOp
from snnkart.energy.network import Network, host_ops
from snnkart.energy.placement import Placement
from snnkart.energy.profiles import Profile
from snnkart.envs.constants import DT
from snnkart.errors import ReportError


def placement(sizes: tuple[int, ...], chip: Profile) -> Placement | None:
    """Layers of ``sizes`` neurons placed on ``chip`` (None for a chip without placement)."""
    if not chip.neurons_per_core:
        return None
    return Placement.of(sizes, chip.neurons_per_core, chip.cores_per_tile)


def _link(net: Network, precision: str) -> tuple[float, float]:
    bits_in, bits_out = link_bits(net.num_steps, net.sizes[0], net.sizes[-1], precision)
    return float(bits_in), float(bits_out)


@dataclass(frozen=True)
class SnnCounts:
    """The spiking policy's counts per inference, averaged over a deployment's env steps."""

    net: Network
    env_steps: int
    episodes: int
    spikes: tuple[float, ...]  # per layer
    synops: tuple[float, ...]  # per layer, to the next spiking layer (0 for the last)
    neuron_updates: tuple[float, ...]  # per layer, the T logical steps
    overhead_spikes: tuple[float, ...]  # the pipeline's fill and drain steps
    overhead_synops: tuple[float, ...]
    overhead_neuron_updates: tuple[float, ...]
    host: tuple[HostOp, ...] = field(default=())
    link_bits: tuple[float, float] = (0.0, 0.0)
    """Bits over the host<->chip link per inference, in and out (:mod:`snnkart.contract.link`)."""
    period_s: float = DT
    """The control period: one inference per env step (a kart env's 1/60 s; a gymnasium env's
    1/render_fps, or the report's --control-hz)."""

    @classmethod
    def of_deploy(cls, record: DeployRecord) -> SnnCounts:
        """A deployment's counts, per env step (its episodes, or one if it lists none)."""
        return cls.measured(
            Network.of_deploy(record), record.counts, len(record.episodes) or 1, record.precision
        )

    @classmethod
    def measured(cls, net: Network, c: Counts, episodes: int, precision: str) -> SnnCounts:
        """Counts measured over ``c.env_steps`` env steps of ``episodes`` episodes, per step,
        of a deployment in ``precision`` (``fixed``, ``float``, ``float32``, ``float64``)."""
        fixed_point = precision == "fixed"
        n = c.env_steps
        if n < 1:
            raise ReportError("the deployment ran no env step; deploy at least one episode")
        over = c.pipeline_overhead
        L = len(net.sizes)

        def per_step(values: list[int] | None, chip_only: bool = False) -> tuple[float, ...]:
            vals = [float(v) / n for v in (values or [0] * L)]
            if chip_only:
                vals[-1] = 0.0  # the last layer's fan-out is the host's readout
            return tuple(vals)

        return cls(
            net=net,
            env_steps=n,
            episodes=episodes,
            spikes=per_step(c.spikes),
            synops=per_step(c.synops, chip_only=True),
            neuron_updates=per_step(c.neuron_updates),
            overhead_spikes=per_step(over.spikes if over else None),
            overhead_synops=per_step(over.synops if over else None, chip_only=True),
            overhead_neuron_updates=per_step(over.neuron_updates if over else None),
            host=tuple(host_ops(net, fixed_point=fixed_point)),
            link_bits=_link(net, precision),
        )

    @classmethod
    def of_sweep(cls, run: StepCounts) -> SnnCounts:
        """A study run's counts per env step (``eval_counts_per_step`` in ``study.json``)."""
        net = Network.of_shape(
            run.network, run.sizes, run.num_steps, run.encoding, run.population, run.action_mode
        )

        def chip(values: list[float]) -> tuple[float, ...]:
            return (*values[:-1], 0.0)  # the last layer's fan-out is the host's readout

        return cls(
            net=net,
            env_steps=run.env_steps,
            episodes=1,
            spikes=tuple(run.spikes_per_step),
            synops=chip(run.synops_per_step),
            neuron_updates=tuple(run.neuron_updates_per_step),
            overhead_spikes=tuple(run.overhead_spikes_per_step),
            overhead_synops=chip(run.overhead_synops_per_step),
            overhead_neuron_updates=tuple(run.overhead_neuron_updates_per_step),
            host=tuple(host_ops(net, fixed_point=run.precision == "fixed")),
            link_bits=_link(net, run.precision),
        )

    def scaled(self, density: float) -> SnnCounts:
        """The same policy with ``density`` times its spikes (and so its synaptic ops)."""

        def s(v: tuple[float, ...]) -> tuple[float, ...]:
            return tuple(density * x for x in v)

        return SnnCounts(
            self.net,
            self.env_steps,
            self.episodes,
            s(self.spikes),
            s(self.synops),
            self.neuron_updates,
            s(self.overhead_spikes),
            s(self.overhead_synops),
            self.overhead_neuron_updates,
            self.host,
            self.link_bits,
        )

    @property
    def host_parameters(self) -> int:
        return self.net.host_parameters

    def host_work(self) -> tuple[HostOp, ...]:
        return self.host

    def prices_for(self, chip: Profile) -> Profile:
        return chip  # binary spikes: the chip's own prices

    def chip_activity(self, chip: Profile) -> list[Activity]:
        """Per layer: synaptic ops (spikes x fan-out), neuron updates (N x T) and spikes, and
        apart from them the pipeline's fill/drain; routing between placed layers; the link."""
        items = []
        for i, n in enumerate(self.net.sizes):
            layer = f"layer {i + 1} ({n} neurons)"
            items += [
                Activity(
                    "synaptic ops", f"{layer}: spikes x fan-out", self.synops[i], "synaptic_op"
                ),
                Activity(
                    "neuron updates", f"{layer}: N x T", self.neuron_updates[i], "neuron_update"
                ),
                Activity("spikes", f"{layer}: spikes", self.spikes[i], "spike"),
            ]
            if self.overhead_neuron_updates[i] or self.overhead_spikes[i]:
                fill = f"{layer}: pipeline fill/drain"
                items += [
                    Activity("synaptic ops", fill, self.overhead_synops[i], "synaptic_op"),
                    Activity(
                        "neuron updates", fill, self.overhead_neuron_updates[i], "neuron_update"
                    ),
                    Activity("spikes", fill, self.overhead_spikes[i], "spike"),
                ]
        return items + self._routing(chip) + self._link(chip)

    def _routing(self, chip: Profile) -> list[Activity]:
        where = placement(self.net.sizes, chip)
        if "hop" not in chip.prices or where is None:
            return []
        items = []
        for i, hops in enumerate(where.hops_per_spike[:-1]):
            spikes = self.spikes[i] + self.overhead_spikes[i]
            what = (
                f"layer {i + 1} -> {i + 2}: spikes x {hops:g} tile hops "
                f"({where.cores[i]} -> {where.cores[i + 1]} cores)"
            )
            items.append(Activity("routing", what, spikes * hops, "hop"))
        return items

    def _link(self, chip: Profile) -> list[Activity]:
        if "io_bit" not in chip.prices:
            return []
        (bits_in, bits_out), sizes = self.link_bits, self.net.sizes
        return [
            Activity("host link", f"in: T x {sizes[0]} input currents", bits_in, "io_bit"),
            Activity("host link", f"out: T x {sizes[-1]} output spike flags", bits_out, "io_bit"),
        ]

    @property
    def steps_per_episode(self) -> float:
        return self.env_steps / self.episodes

    def firing_rates(self) -> list[float]:
        """Spikes per neuron per SNN step, per layer."""
        T = self.net.num_steps
        return [s / (n * T) for s, n in zip(self.spikes, self.net.sizes, strict=True)]

    def neurobench(self) -> dict[str, float]:
        """NeuroBench's counts per inference (Yik et al. 2025; snn-nir-lava.md §3.4), as its
        SynapticOperations would count the snntorch policy: a layer is AC when all its inputs
        are in {-1, 0, 1}, else MAC; the first layer is fed at every one of the T steps (real
        values: MACs; rate-coded spikes: ACs, counted densely as input spikes are not
        recorded); the readout takes real-valued rates (MACs, once); ``dense_ops`` sets every
        input to 1. Biases are not counted. Activation sparsity: neuron-steps without a spike.
        :meth:`deployed` gives what the deployment actually computes."""
        net, T = self.net, self.net.num_steps
        first = T * net.n_in * net.sizes[0]
        readout = net.sizes[-1] * net.n_out if net.readout else 0
        rate = net.encoding == "rate"
        return {
            "effective_macs": (0 if rate else first) + readout,
            "effective_acs": (first if rate else 0) + sum(self.synops),
            "dense_ops": first + T * net.chip_synapses + readout,
            "activation_sparsity": 1.0 - sum(self.spikes) / (net.neurons * T),
        }

    def deployed(self) -> dict[str, float]:
        """What the deployment computes per inference: the host's MACs (the first layer once
        per env step with current encoding, the readout), the chip's synaptic operations
        (ACs), its neuron updates, and the pipeline's extra neuron updates."""
        return {
            "host_macs": sum(op.count for op in self.host if op.op == "mac"),
            "chip_synaptic_ops": sum(self.synops) + sum(self.overhead_synops),
            "chip_neuron_updates": sum(self.neuron_updates) + sum(self.overhead_neuron_updates),
            "spikes": sum(self.spikes) + sum(self.overhead_spikes),
        }

    def footprint(self) -> dict[str, int]:
        """Parameters and state: the parameter count and its bytes at fp32 (NeuroBench's
        footprint), the chip's weights at 8 bits as Lava's fixed point stores them, and the
        neuron state (current and voltage per neuron)."""
        net = self.net
        return {
            "parameters": net.parameters,
            "parameter_bytes_fp32": 4 * net.parameters,
            "host_parameters": net.host_parameters,
            "chip_weight_bytes_int8": net.chip_synapses,
            "state_variables": 2 * net.neurons,
        }


@dataclass(frozen=True)
class AnnCounts:
    """An MLP actor's counts per inference: ``widths`` = (n_in, hidden..., n_out)."""

    widths: tuple[int, ...]
    action_mode: str = "discrete"
    label: str = ""

    @property
    def macs(self) -> int:
        return sum(a * b for a, b in zip(self.widths, self.widths[1:], strict=False))

    @property
    def parameters(self) -> int:
        return self.macs + sum(self.widths[1:])

    host_parameters = parameters

    def host_work(self) -> list[HostOp]:
        return self.ops()

    def prices_for(self, chip: Profile) -> Profile:
        return chip

    def chip_activity(self, chip: Profile) -> list[Activity]:
        return []  # an ANN runs on the host alone

    def ops(self) -> list[HostOp]:
        """Everything per inference, as digital operations (the same normalisation and
        decoding as the SNN's host side, so neither side is spared them)."""
        n_in, n_out = self.widths[0], self.widths[-1]
        compares = n_out - 1 if self.action_mode == "discrete" else 2 * n_out
        return [
            HostOp("normalisation: obs - mean, clip to +-c", "add", 3 * n_in),
            HostOp("normalisation: / std", "mult", n_in),
            HostOp("layers: W x", "mac", self.macs),
            HostOp("layers: + b", "add", sum(self.widths[1:])),
            HostOp("weight and bias reads", "weight_read", self.parameters),
            HostOp("decoding: argmax or clip", "add", compares),
        ]

    def neurobench(self) -> dict[str, float]:
        return {"effective_macs": self.macs, "effective_acs": 0, "dense_ops": self.macs}

    def footprint(self) -> dict[str, int]:
        return {
            "parameters": self.parameters,
            "parameter_bytes_fp32": 4 * self.parameters,
            "state_variables": 0,
        }
