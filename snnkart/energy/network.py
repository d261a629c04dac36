"""The deployed spiking network's shape (:class:`Network`) and the host's work for it per
inference (:func:`host_ops`): the observation's encoding, the first layer's input current, the
readout and the action's decoding, priced as digital operations (:mod:`snnkart.energy.counts`
says where each part of the work runs)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from snnkart.contract.deploy_record import DeployRecord, NetworkShape
from snnkart.energy.activity import HostOp
from snnkart.errors import ReportError


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
    def of_shape(
        cls,
        shape: NetworkShape,
        sizes: Sequence[int],
        num_steps: int,
        encoding: str,
        population: int | None,
        action_mode: str,
    ) -> Network:
        """The network of a deployed ``shape`` with these spiking layer sizes, T, encoding
        (and population) and action decoding."""
        return cls(
            n_in=shape.n_in,
            sizes=tuple(sizes),
            n_out=shape.n_out,
            num_steps=num_steps,
            encoding=encoding,
            population=population or 0,
            readout=shape.readout,
            input_scale=shape.input_scale,
            action_mode=action_mode,
        )

    @classmethod
    def of_deploy(cls, record: DeployRecord) -> Network:
        """The network a deployment ran: its shape, T, encoding and action decoding."""
        net, manifest = record.network, record.manifest
        return cls.of_shape(
            net,
            net.sizes,
            manifest.num_steps,
            manifest.encoding,
            manifest.population,
            manifest.action_mode,
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
            HostOp(
                "first layer: weight reads, dense upper bound", "weight_read", T * (n_in * n1 + n1)
            ),
        ]
    else:
        if net.encoding == "population":
            n_obs = net.obs_dim
            ops += [
                HostOp(
                    "population encoding: (obs - low) / (high - low), clipped", "add", 3 * n_obs
                ),
                HostOp("population encoding: (obs - low) / (high - low)", "mult", n_obs),
                HostOp("population encoding: x01 - centre", "add", n_in),
                HostOp("population encoding: x (P - 1), square, x -1/2", "mult", 3 * n_in),
                HostOp(
                    "population encoding: exp, priced as one mult (a table lookup)", "mult", n_in
                ),
            ]
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
