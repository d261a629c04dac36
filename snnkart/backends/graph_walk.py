"""How snnkart walks a NIR graph before running it: the recurrent cycles (a neuron's own
synapse), the chain from the one Input to the Output, and an observation normalisation in front
of the first synapse. :mod:`snnkart.backends.network` builds the chain network on these."""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.errors import UnsupportedGraphError


def recurrent_synapses(graph: Any) -> dict[str, str]:
    """``{neuron: synapse}`` for every cycle ``neuron -> synapse -> neuron`` through an Affine
    or Linear whose only input and only output is that neuron (NIR's recurrence, as snnTorch's
    ``RLeaky`` export and snnkart's ``rsnn`` kind write it)."""
    import nir

    succ: dict[str, list[str]] = {}
    pred: dict[str, list[str]] = {}
    for src, dst in graph.edges:
        succ.setdefault(src, []).append(dst)
        pred.setdefault(dst, []).append(src)
    cycles = {}
    for name, node in graph.nodes.items():
        if not isinstance(node, (nir.Affine, nir.Linear)):
            continue
        ins, outs = pred.get(name, []), succ.get(name, [])
        if len(ins) == 1 and outs == ins and isinstance(graph.nodes[ins[0]], (nir.LIF, nir.IF)):
            cycles[ins[0]] = name
    return cycles


def chain_order(graph: Any, recurrent: set[str] | frozenset[str] = frozenset()) -> list[str]:
    """The node names from the one Input to the Output, checked to form a single chain of
    supported nodes; ``recurrent``: the synapses of cycles (:func:`recurrent_synapses`),
    which are not on the chain."""
    import nir

    nodes = {k: v for k, v in graph.nodes.items() if k not in recurrent}
    succ: dict[str, list[str]] = {}
    for src, dst in graph.edges:
        if src not in recurrent and dst not in recurrent:
            succ.setdefault(src, []).append(dst)
    supported = (
        nir.Input,
        nir.Output,
        nir.Affine,
        nir.Linear,
        nir.LIF,
        nir.IF,
        nir.CubaLIF,
        nir.LI,
        nir.Scale,
    )
    for name, node in nodes.items():
        if not isinstance(node, supported):
            raise UnsupportedGraphError(
                f"node {name!r} is a {type(node).__name__}; supported node types are "
                "Input, Output, Affine, Linear, LIF, IF, CubaLIF, LI (as the readout) and Scale "
                "(after the input)"
            )
    inputs = [k for k, n in nodes.items() if isinstance(n, nir.Input)]
    if len(inputs) != 1:
        raise UnsupportedGraphError(f"the graph must have exactly one Input node, found {inputs}")
    order = [inputs[0]]
    while True:
        nxt = succ.get(order[-1], [])
        if not nxt:
            break
        if len(nxt) > 1:
            raise UnsupportedGraphError(
                f"node {order[-1]!r} feeds {nxt}; only feed-forward chains are supported"
            )
        if nxt[0] in order:
            raise UnsupportedGraphError(
                f"recurrent edge {order[-1]!r} -> {nxt[0]!r}; a cycle runs only as a neuron's "
                "own recurrent synapse (neuron -> Affine/Linear -> the same neuron)"
            )
        order.append(nxt[0])
    if len(order) != len(nodes):
        missing = sorted(set(nodes) - set(order))
        raise UnsupportedGraphError(f"nodes {missing} are not on the chain from the input")
    if not isinstance(nodes[order[-1]], nir.Output):
        raise UnsupportedGraphError(f"the chain ends at {order[-1]!r}, not at an Output node")
    return order


def input_normalisation(graph: Any) -> str | None:
    """The name of the graph's input normalisation (a diagonal Affine after the input, or its
    Scale, that feeds the first synapse), or None."""
    import nir

    body = chain_order(graph, set(recurrent_synapses(graph).values()))[1:-1]
    if body and isinstance(graph.nodes[body[0]], nir.Scale):
        body = body[1:]
    return leading_normalisation(graph.nodes, body)


def leading_normalisation(nodes: dict[str, Any], body: list[str]) -> str | None:
    """:func:`input_normalisation` on a chain already walked: ``body``, the chain's nodes after
    the input (and its Scale) and before the output."""
    import nir

    if len(body) > 1 and _diagonal(nodes[body[0]]):
        if isinstance(nodes[body[1]], (nir.Affine, nir.Linear)):
            return str(body[0])
    return None


def _diagonal(node: Any) -> bool:
    """A square Affine with a diagonal weight (a per-input scale and offset)."""
    import nir

    if not isinstance(node, nir.Affine):
        return False
    w = np.asarray(node.weight)
    return w.ndim == 2 and w.shape[0] == w.shape[1] and not np.any(w - np.diag(np.diag(w)))
