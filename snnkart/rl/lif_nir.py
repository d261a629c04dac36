"""A LIF actor as a NIR graph (through snntorch's exporter): what
:meth:`snnkart.rl.policies.SNNPolicy.nir_graph` returns to :mod:`snnkart.export.nir_export`.

Sharp edges of snntorch 1.0 / nir 1.0.8 handled here (found by experiment when the export was
written; docs/deployment.md states the contract): a scalar beta or threshold breaks NIR type
inference, so each layer's shared value is written as a per-neuron vector of equal values; the
sample input has no batch dimension; ``reset_mechanism`` is not exported (NIR LIF resets to
``v_reset``), so only reset-to-zero networks are accepted. What a Lava target cannot run is
refused with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from snnkart.contract.manifest import LayerSpec
from snnkart.errors import ExportError


@dataclass(frozen=True)
class NIRGraph:
    """A spiking actor's exported graph: the graph, each spiking layer's node and parameters,
    and the readout's node (the manifest records both)."""

    graph: Any
    layers: tuple[LayerSpec, ...]
    readout_node: str


NIR_DT = 1e-4
"""snntorch's export convention: tau = NIR_DT / (1 - beta), r = tau / NIR_DT."""


def _leaky(size: int, beta: float, threshold: float) -> torch.nn.Module:
    import snntorch as snn

    return snn.Leaky(
        beta=torch.full((size,), beta),
        threshold=torch.full((size,), threshold),
        reset_mechanism="zero",
        reset_delay=False,
        init_hidden=True,
    )


def _synaptic(size: int, alpha: float, beta: float, threshold: float) -> torch.nn.Module:
    import snntorch as snn

    return snn.Synaptic(
        alpha=torch.full((size,), alpha),
        beta=torch.full((size,), beta),
        threshold=torch.full((size,), threshold),
        reset_mechanism="zero",
        reset_delay=False,
        init_hidden=True,
    )


def _neuron_module(spec: LayerSpec) -> torch.nn.Module:
    """The snntorch module whose export is this layer's NIR node (LIF or CubaLIF)."""
    if spec.alpha is None:
        return _leaky(spec.size, spec.beta, spec.threshold)
    return _synaptic(spec.size, spec.alpha, spec.beta, spec.threshold)


def check_exportable(actor: Any) -> None:
    """Refuse what Lava's LIF cannot run: subtractive reset, non-uniform decay or threshold
    (``actor``: a :class:`~snnkart.rl.spiking.SpikingActor`)."""
    for i, lif in enumerate(actor.lifs, start=1):
        name = f"lif{i}"
        # The buffer, not the string attribute, is what forward() uses and a state dict sets.
        if int(lif.reset_mechanism_val) != 1:
            mechanism = {0: "subtract", 1: "zero", 2: "none"}.get(int(lif.reset_mechanism_val))
            raise ExportError(
                f"{name} uses reset_mechanism={mechanism!r}; Lava's LIF can only reset "
                "the membrane to zero (NIR v_reset = 0); retrain with reset to zero"
            )
        beta = lif.beta.detach().reshape(-1)
        thr = lif.threshold.detach().reshape(-1)
        alpha = getattr(lif, "alpha", beta).detach().reshape(-1)  # Synaptic's current decay
        if not all(torch.all(x == x[0]) for x in (beta, thr, alpha)):
            raise ExportError(
                f"{name} has per-neuron decay or threshold values; Lava's LIF has one decay, "
                "one current decay and one threshold per population"
            )
        if not 0.0 <= float(alpha[0].clamp(0, 1)) < 1.0:
            raise ExportError(
                f"{name} has alpha = {float(alpha[0])}; the current decay must be < 1 (alpha = 1 "
                "is an infinite NIR tau_syn)"
            )
        b = float(beta[0].clamp(0, 1))
        if not 0.0 <= b < 1.0:
            raise ExportError(
                f"{name} has beta = {b}; beta must be < 1 (beta = 1 is an infinite NIR time "
                "constant)"
            )
    for pname, p in actor.named_parameters():
        if not torch.isfinite(p).all():
            raise ExportError(f"parameter {pname} contains NaN or infinite values")


def lif_graph(actor: Any) -> NIRGraph:
    """The feed-forward LIF actor as the chain input -> fc1 -> lif1 -> ... -> readout -> output
    (nodes ``"0"``, ``"1"``, ..., ``"2K"``), checked to round-trip the trained parameters."""
    from snntorch.export_nir import export_to_nir

    check_exportable(actor)
    layers = _layer_specs(actor)
    modules: list[torch.nn.Module] = []
    for fc, spec in zip(actor.fcs, layers, strict=True):
        modules += [fc, _neuron_module(spec)]
    net = torch.nn.Sequential(*modules, actor.readout).eval()
    with torch.no_grad():
        graph = export_to_nir(net, torch.zeros(actor.fcs[0].in_features))
    readout = str(2 * len(layers))
    _check_graph(graph, layers, readout_node=readout)
    return NIRGraph(graph, layers, readout)


def _layer_specs(actor: Any) -> tuple[LayerSpec, ...]:
    """Each spiking layer's NIR node name (``2i - 1`` in the exported chain), size, decay and
    threshold, and a Synaptic layer's current decay (one per population, as Lava's LIF has)."""
    return tuple(
        LayerSpec(
            str(2 * i + 1),
            fc.out_features,
            float(lif.beta.detach().reshape(-1)[0].clamp(0, 1)),
            float(lif.threshold.detach().reshape(-1)[0]),
            float(lif.alpha.detach().reshape(-1)[0].clamp(0, 1)) if hasattr(lif, "alpha") else None,
        )
        for i, (fc, lif) in enumerate(zip(actor.fcs, actor.lifs, strict=True))
    )


def _check_graph(graph: Any, layers: tuple[LayerSpec, ...], readout_node: str) -> None:
    """The exported graph must be the expected chain with reset-to-zero LIF (or CubaLIF)
    vectors whose time constants give back the trained decays."""
    import nir

    expected: dict[str, type | tuple[type, ...]] = {
        "input": nir.Input,
        "output": nir.Output,
        readout_node: nir.Affine,
    }
    for spec in layers:
        expected[spec.node] = nir.LIF if spec.alpha is None else nir.CubaLIF
        expected[str(int(spec.node) - 1)] = (nir.Affine, nir.Linear)  # Linear: no bias
    for name, kind in expected.items():
        node = graph.nodes.get(name)
        if not isinstance(node, kind):
            raise ExportError(f"unexpected NIR graph from snntorch: node {name!r} is {node!r}")
    for spec in layers:
        name, size, beta, th = spec.node, spec.size, spec.beta, spec.threshold
        node = graph.nodes[name]
        tau = node.tau if spec.alpha is None else node.tau_mem
        if tau.shape != (size,) or not np.all(node.v_reset == 0):
            raise ExportError(f"NIR LIF {name}: expected {size} neurons resetting to 0")
        beta_back = 1.0 - NIR_DT / tau
        if not np.allclose(beta_back, beta, rtol=0, atol=1e-6) or not np.all(
            node.v_threshold == th
        ):
            raise ExportError(f"NIR LIF {name}: time constants or thresholds do not round-trip")
        if spec.alpha is not None and not np.allclose(
            1.0 - NIR_DT / node.tau_syn, spec.alpha, rtol=0, atol=1e-6
        ):
            raise ExportError(f"NIR CubaLIF {name}: current time constants do not round-trip")
        if not math.isfinite(float(np.max(tau))):
            raise ExportError(f"NIR LIF {name}: infinite time constant (beta = 1)")
