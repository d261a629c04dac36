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
from snnkart.energy.placement import Placement
from snnkart.energy.profiles import Profile
from snnkart.errors import ReportError


def placement(sizes: tuple[int, ...], chip: Profile) -> Placement | None:
    """Layers of ``sizes`` neurons placed on ``chip`` (None for a chip without placement)."""
    if not chip.neurons_per_core:
        return None
    return Placement.of(sizes, chip.neurons_per_core, chip.cores_per_tile)


@dataclass(frozen=True)
class Network:
    """The deployed network's shape: inputs, spiking layer sizes, outputs, T."""

    n_in: int
    sizes: tuple[int, ...]
    n_out: int
    num_steps: int
    encoding: str = "current"
    population: int = 0
    """Population encoding: receptive fields per observation value (``n_in`` is their sum)."""
    readout: bool = True
    input_scale: bool = False
    action_mode: str = "discrete"

    @classmethod
    def of_deploy(cls, record: DeployRecord) -> Network:
        """The network a deployment ran: its shape, T, encoding and action decoding."""
        net, manifest = record.network, record.manifest
        return cls(
            n_in=net.n_in,
            sizes=tuple(net.sizes),
            n_out=net.n_out,
            num_steps=manifest.num_steps,
            encoding=manifest.encoding,
            population=manifest.population or 0,
            readout=net.readout,
            input_scale=net.input_scale,
            action_mode=manifest.action_mode,
        )

    def __post_init__(self) -> None:
        if (self.encoding == "population") != (self.population > 0):
            raise ReportError(
                f"a {self.encoding} encoding with population {self.population}: the deploy "
                "record is inconsistent (written by an older snnkart?); run snnkart deploy again"
            )

    @property
    def obs_dim(self) -> int:
        """Observation values per inference (the graph's inputs, or their receptive fields)."""
        return self.n_in // self.population if self.population else self.n_in

    @property
    def depth(self) -> int:
        """L: Dense delays between the spiking layers."""
        return len(self.sizes) - 1

    @property
    def neurons(self) -> int:
        return sum(self.sizes)

    @property
    def chip_synapses(self) -> int:
        return sum(a * b for a, b in zip(self.sizes, self.sizes[1:], strict=False))

    @property
    def parameters(self) -> int:
        """Weights and biases: first layer (host), the chip's layers, readout (host)."""
        return self.host_parameters + self.chip_synapses + sum(self.sizes[1:])

    @property
    def host_parameters(self) -> int:
        """The weights and biases the host keeps and reads: the first layer's and the readout's."""
        n1, last = self.sizes[0], self.sizes[-1]
        readout = (last * self.n_out + self.n_out) if self.readout else 0
        return self.n_in * n1 + n1 + readout


def host_ops(net: Network, fixed_point: bool = False) -> list[HostOp]:
    """The SNN's host-side work per inference (per env step)."""
    n_in, n1, last, n_out, T = net.n_in, net.sizes[0], net.sizes[-1], net.n_out, net.num_steps
    ops: list[HostOp] = []
    if net.encoding == "rate":
        ops += [
            HostOp("rate encoding: (obs - low) / (high - low), clipped", "add", 3 * n_in),
            HostOp("rate encoding: (obs - low) / (high - low)", "mult", n_in),
            HostOp("rate encoding: compare a random number per input and step", "add", T * n_in),
            HostOp("first layer: input spikes x W1, dense upper bound", "add", T * n_in * n1),
            HostOp("first layer: bias per step", "add", T * n1),
            HostOp("first layer: weight reads, dense upper bound", "weight_read", T * (n_in * n1 + n1)),
        ]  # fmt: skip
    else:
        if net.encoding == "population":
            n_obs = net.obs_dim
            ops += [
                HostOp("population encoding: (obs - low) / (high - low), clipped", "add", 3 * n_obs),
                HostOp("population encoding: (obs - low) / (high - low)", "mult", n_obs),
                HostOp("population encoding: x01 - centre", "add", n_in),
                HostOp("population encoding: x (P - 1), square, x -1/2", "mult", 3 * n_in),
                HostOp("population encoding: exp, priced as one mult (a table lookup)", "mult", n_in),
            ]  # fmt: skip
        else:
            ops += [
                HostOp("normalisation: obs - mean, clip to +-c", "add", 3 * n_in),
                HostOp("normalisation: / std", "mult", n_in),
            ]
        ops += [
            HostOp("first layer: W1 z, once per env step", "mac", n_in * n1),
            HostOp("first layer: + b1", "add", n1),
            HostOp("first layer: weight and bias reads", "weight_read", n_in * n1 + n1),
        ]
        if net.input_scale:
            ops.append(HostOp("input scale", "mult", n_in))
    if fixed_point:
        scaled = T * n1 if net.encoding == "rate" else n1
        ops.append(HostOp("fixed point: scale the current to integers", "mult", scaled))
    if net.readout:
        ops += [
            HostOp("readout: spike counts / T", "mult", last),
            HostOp("readout: Wr rates", "mac", n_out * last),
            HostOp("readout: + br", "add", n_out),
            HostOp("readout: weight and bias reads", "weight_read", n_out * last + n_out),
        ]
    compares = n_out - 1 if net.action_mode == "discrete" else 2 * n_out
    ops.append(HostOp("decoding: argmax or clip", "add", compares))
    return ops


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
        shape = run.network
        net = Network(
            n_in=shape.n_in, sizes=tuple(run.sizes), n_out=shape.n_out,
            num_steps=run.num_steps, encoding=run.encoding, population=run.population or 0,
            readout=shape.readout, input_scale=shape.input_scale, action_mode=run.action_mode,
        )  # fmt: skip

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
            self.net, self.env_steps, self.episodes, s(self.spikes), s(self.synops),
            self.neuron_updates, s(self.overhead_spikes), s(self.overhead_synops),
            self.overhead_neuron_updates, self.host, self.link_bits,
        )  # fmt: skip

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
                Activity("synaptic ops", f"{layer}: spikes x fan-out", self.synops[i], "synaptic_op"),
                Activity("neuron updates", f"{layer}: N x T", self.neuron_updates[i], "neuron_update"),
                Activity("spikes", f"{layer}: spikes", self.spikes[i], "spike"),
            ]  # fmt: skip
            if self.overhead_neuron_updates[i] or self.overhead_spikes[i]:
                fill = f"{layer}: pipeline fill/drain"
                items += [
                    Activity("synaptic ops", fill, self.overhead_synops[i], "synaptic_op"),
                    Activity("neuron updates", fill, self.overhead_neuron_updates[i], "neuron_update"),
                    Activity("spikes", fill, self.overhead_spikes[i], "spike"),
                ]  # fmt: skip
        return items + self._routing(chip) + self._link(chip)

    def _routing(self, chip: Profile) -> list[Activity]:
        where = placement(self.net.sizes, chip)
        if "hop" not in chip.prices or where is None:
            return []
        items = []
        for i, hops in enumerate(where.hops_per_spike[:-1]):
            spikes = self.spikes[i] + self.overhead_spikes[i]
            what = (f"layer {i + 1} -> {i + 2}: spikes x {hops:g} tile hops "
                    f"({where.cores[i]} -> {where.cores[i + 1]} cores)")  # fmt: skip
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
        return {"parameters": self.parameters, "parameter_bytes_fp32": 4 * self.parameters,
                "state_variables": 0}  # fmt: skip
