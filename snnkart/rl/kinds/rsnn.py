"""``policy = "rsnn"``: a recurrent LIF actor. The stateful LIF actor (membranes carried across
env steps, docs/stateful.md) plus recurrent synapses: every spiking layer after the first feeds
its own spikes back into itself through an all-to-all Linear ``R_i`` (no bias), one Lava step
late, as a Dense from the layer's spikes to its own input does on Loihi.

One env step is ``W = T + L`` rows (L = K - 1 Dense stages) from the state the last one left::

    row r, layer 0:   I = W1 z + b1 (r < T; the host's current), 0 on the drain rows
    row r, layer i>0: I = W_{i+1} S_{i-1}[r - 1] + b_{i+1} + R_i S_i[r - 1]
    every layer:      U = beta U + I,  S = H(U - theta),  U = 0 where S      (snntorch Leaky)
    readout:          W_out mean(S_{K-1}[L .. L + T - 1]) + b_out

The state is ``[B, 2 sum(sizes)]``: every layer's membrane, then every layer's spikes of the
last row (zero at an episode's start). The first layer has no recurrent synapse: it is fed by
the host's current at the scale ``4096 / theta`` of Lava's fixed point (snnkart.backends.quantize),
which leaves no room for 8-bit recurrent weights beside it; the layers after it get their input
through a Dense whose weight scale covers the feed-forward and the recurrent weights together.
So the kind needs two spiking layers or more.

Exported to NIR with each recurrent synapse as a cycle: ``lif_i -> rec_i (Linear) -> lif_i``,
NIR's convention for recurrence (snnTorch's ``RLeaky`` export writes the same shape), which the
backends run with the recurrent Dense one step late.

The PPO update runs whole env sequences layer by layer (``snn.fused``, the default), each
recurrent layer in :class:`snnkart.rl.lif.FusedRecurrentLIF` (the recurrence inside the loop);
the rollout steps the rows one by one. Before that kernel the update stepped them too and
trained at ~42 env steps/s on grid (against ~3,000 for ``snn`` with ``snn.stateful``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from snnkart.errors import ExportError
from snnkart.rl.kinds.base import Kind, PolicySpace
from snnkart.rl.kinds.snn import KIND as SNN
from snnkart.rl.kinds.snn import spiking
from snnkart.rl.lif_nir import NIRGraph, lif_graph
from snnkart.rl.policies import ActorCritic, StatefulSNNPolicy
from snnkart.rl.stateful_config import stateful_problem


class RSNNConfig(BaseModel):
    """The recurrent synapses of a ``rsnn`` actor (the rest of it is the ``snn`` section)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    recurrent_gain: float = Field(
        0.5, ge=0.0, description="orthogonal initial gain of each recurrent weight matrix R_i"
    )


def recurrent_name(i: int) -> str:
    """The NIR node of layer ``i``'s recurrent synapse (layer i is node ``2i + 1``)."""
    return f"rec{2 * i + 1}"


class RecurrentLIFPolicy(StatefulSNNPolicy):
    """:class:`~snnkart.rl.policies.StatefulSNNPolicy` with recurrent synapses ``rec2 .. recK``
    (module docstring); ``forward`` takes ``state`` ``[B, D]`` or, with ``starts``, whole env
    sequences, as the stateful actor does."""

    kind = "rsnn"

    def __init__(self, *args: Any, recurrent_gain: float, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        sizes = tuple(self.cfg.hidden)
        recs = [nn.Linear(n, n, bias=False) for n in sizes[1:]]
        for rec in recs:
            nn.init.orthogonal_(rec.weight, recurrent_gain)
        self.recs = nn.ModuleList(recs)  # layer i >= 1's recurrent synapse is recs[i - 1]
        self.loops: list[nn.Linear] = recs

    def nir_graph(self) -> NIRGraph:
        """The feed-forward chain of :func:`~snnkart.rl.lif_nir.lif_graph` plus, per layer
        ``i >= 1``, the cycle ``lif -> rec (Linear) -> lif``."""
        import nir

        exported = lif_graph(self.snn)
        graph = exported.graph
        for i, (spec, rec) in enumerate(zip(exported.layers[1:], self.loops, strict=True), 1):
            weight = rec.weight.detach().numpy().astype(np.float32)
            if not np.isfinite(weight).all():
                raise ExportError(f"parameter recs.{i - 1}.weight contains NaN or infinite values")
            name = recurrent_name(i)
            graph.nodes[name] = nir.Linear(weight=weight)
            graph.edges += [(spec.node, name), (name, spec.node)]
        return NIRGraph(graph, exported.layers, exported.readout_node)


def build(cfg: Any, space: PolicySpace) -> ActorCritic:
    return spiking(RecurrentLIFPolicy, cfg, space, recurrent_gain=cfg.rsnn.recurrent_gain)


def check(cfg: Any) -> None:
    """The stateful actor's requirements, plus a second spiking layer (the first has no
    recurrent synapse: module docstring)."""
    stateful_problem(cfg)
    if len(cfg.snn.hidden) < 2:
        raise ValueError(
            "policy rsnn puts its recurrent synapses on the spiking layers after the first: "
            f"snn.hidden = {list(cfg.snn.hidden)} has one layer; give two or more, e.g. [64, 64]"
        )


KIND = Kind(
    name="rsnn",
    build=build,
    section=RSNNConfig,
    defaults=SNN.defaults,
    env_defaults=SNN.env_defaults,
    check=check,
    sections_used=("snn", "rsnn"),
    label=lambda cfg: "recurrent LIF",
)

__all__ = ["KIND", "RSNNConfig", "RecurrentLIFPolicy"]
