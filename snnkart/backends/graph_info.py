"""What a NIR graph is and where it runs: the facts behind ``snnkart nir info``.

For every node: its type, shapes and parameters (per-neuron vectors summarised by their
range); for the graph: its edges, parameter count, whether it is the chain the backends run
(:mod:`snnkart.backends.network`) and, per spiking node, what lava-sim cannot express
(:func:`snnkart.backends.quantize.lava_problems`). NIR graphs carry no time step; the decays a
chosen ``dt`` and discretisation imply are shown per layer, so a user can see whether they are
the ones the graph was trained with.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snnkart.backends.graph_walk import input_normalisation
from snnkart.backends.network import ChainNetwork, UnsupportedGraphError, chain_from_graph
from snnkart.backends.quantize import lava_problems

WEIGHT_FIELDS = ("weight", "bias")
"""The fields counted as weights and biases: what the energy report's footprint counts too;
every other field (time constants, resistances, thresholds, ...) is a neuron parameter."""
PARAMETER_FIELDS = (
    "weight",
    "bias",
    "scale",
    "tau",
    "tau_mem",
    "tau_syn",
    "r",
    "w_in",
    "v_leak",
    "v_threshold",
    "v_reset",
    "delay",
)


@dataclass
class NodeInfo:
    name: str
    kind: str
    input_shape: list[int] | None
    output_shape: list[int] | None
    parameters: dict[str, str]  # field -> summary ("shape [4]: 0.5 .. 2")
    count: int  # parameter values
    weights: int  # of them, weights and biases (WEIGHT_FIELDS)


@dataclass
class GraphInfo:
    nodes: list[NodeInfo]
    edges: list[tuple[str, str]]
    parameter_count: int  # every value: weight_count + neuron parameters
    weight_count: int  # weights and biases, as the energy report's footprint counts them
    dt: float | None  # the dt used to discretise (None: none given)
    dt_source: str  # where dt came from, or why there is none
    discretisation: str
    reference: str  # "supported" or why nir-ref cannot run it
    lava: dict[str, str] = field(default_factory=dict)  # node -> why lava-sim cannot run it
    layers: list[dict[str, Any]] = field(default_factory=list)  # per spiking layer, at dt
    state: str | None = None  # the manifest's state semantics, when the graph alone misleads
    recurrence: list[str] = field(default_factory=list)  # each cycle, and how it runs
    normalisation: str | None = None  # the input normalisation node (host-side, not counted)

    @property
    def lava_supported(self) -> bool:
        return self.reference == "supported" and not self.lava

    def as_dict(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        out["nodes"] = [n.__dict__ for n in self.nodes]
        out["edges"] = [list(e) for e in self.edges]
        out["lava_supported"] = self.lava_supported
        return out


def _shape(types: Any, key: str) -> list[int] | None:
    if not isinstance(types, dict) or key not in types:
        return None
    return [int(x) for x in np.asarray(types[key]).reshape(-1)]


def _summary(value: Any) -> tuple[str, int]:
    arr = np.asarray(value, dtype=np.float64)
    if arr.size == 0:
        return "empty", 0
    shape = "x".join(str(d) for d in arr.shape) or "scalar"
    finite = arr[np.isfinite(arr)]
    if finite.size < arr.size:
        return f"[{shape}] with {arr.size - finite.size} NaN/inf values", int(arr.size)
    lo, hi = float(finite.min()), float(finite.max())
    values = f"{lo:.6g}" if lo == hi else f"{lo:.6g} .. {hi:.6g}"
    return f"[{shape}] {values}", int(arr.size)


def _node(name: str, node: Any) -> NodeInfo:
    params, count, weights = {}, 0, 0
    for key in PARAMETER_FIELDS:
        if hasattr(node, key):
            params[key], n = _summary(getattr(node, key))
            count += n
            weights += n if key in WEIGHT_FIELDS else 0
    return NodeInfo(
        name,
        type(node).__name__,
        _shape(getattr(node, "input_type", None), "input"),
        _shape(getattr(node, "output_type", None), "output"),
        params,
        count,
        weights,
    )


def _layer_decays(chain: ChainNetwork) -> list[dict[str, Any]]:
    def value(arr: np.ndarray | None) -> float | list[float] | None:
        if arr is None:
            return None
        return float(arr[0]) if np.ptp(arr) == 0 else [float(arr.min()), float(arr.max())]

    return [
        {
            "synapse": layer.synapse,
            "neuron": layer.neuron,
            "size": layer.size,
            "beta": value(layer.beta),
            "alpha": value(layer.alpha),
            "gain": value(layer.gain),
            "syn_gain": value(layer.syn_gain),
            "leak": value(layer.leak),
            "threshold": value(layer.threshold),
        }
        for layer in chain.layers
    ]


def describe_graph(
    graph: Any, dt: float | None, dt_source: str, discretisation: str = "euler"
) -> GraphInfo:
    """The facts of ``graph``. Without ``dt`` only the structure is checked (node types, the
    chain, shapes, finite values, with a dt far below every time constant): whether a layer's
    gains fit Lava depends on dt, so lava-sim's checks and the per-layer decays need it."""
    nodes = [_node(name, graph.nodes[name]) for name in _flow_order(graph)]
    try:  # an observation normalisation runs on the host: not the network's parameters
        norm = input_normalisation(graph)
    except UnsupportedGraphError:
        norm = None
    counted = [n for n in nodes if n.name != norm]
    info = GraphInfo(
        nodes=nodes,
        edges=[(str(a), str(b)) for a, b in graph.edges],
        parameter_count=sum(n.count for n in counted),
        weight_count=sum(n.weights for n in counted),
        normalisation=norm,
        dt=dt,
        dt_source=dt_source,
        discretisation=discretisation,
        reference="supported",
    )
    try:
        chain = chain_from_graph(graph, dt if dt is not None else _tiny_dt(graph), discretisation)
    except UnsupportedGraphError as exc:
        info.reference = str(exc)
        return info
    info.recurrence = _recurrence(chain)
    if dt is None:
        info.lava = {"graph": "needs a time step (--dt) to check the decays and gains"}
        return info
    info.lava = dict(lava_problems(chain))
    info.layers = _layer_decays(chain)
    return info


def _recurrence(chain: ChainNetwork) -> list[str]:
    """Each cycle ``neuron -> synapse -> neuron`` of ``chain``, in words: what it means and how
    the backends run it."""
    return [
        f"{layer.neuron} -> {layer.recurrent_node} -> {layer.neuron}: a recurrent synapse "
        f"({layer.size}x{layer.size}); the layer's spikes of one step reach its own input at the "
        "next, summed with the feed-forward current (a bias on the cycle's synapse is folded "
        "into the feed-forward one: it arrives every step); lava-sim runs it as a Dense from "
        "the layer's spikes to its own input, the reference as the same one-step-late product"
        for layer in chain.layers
        if layer.recurrent is not None
    ]


def _flow_order(graph: Any) -> list[str]:
    """Node names from the inputs along the edges (breadth first), then any others."""
    import nir

    succ: dict[str, list[str]] = {}
    for src, dst in graph.edges:
        succ.setdefault(src, []).append(dst)
    order = [k for k, n in graph.nodes.items() if isinstance(n, nir.Input)]
    i = 0
    while i < len(order):
        order += [d for d in succ.get(order[i], []) if d not in order and d in graph.nodes]
        i += 1
    return order + [k for k in graph.nodes if k not in order]


def _tiny_dt(graph: Any) -> float:
    """A time step far below every time constant of the graph (for structural checks)."""
    taus = [
        float(np.min(np.asarray(getattr(node, key), dtype=np.float64)))
        for node in graph.nodes.values()
        for key in ("tau", "tau_mem", "tau_syn")
        if hasattr(node, key) and np.asarray(getattr(node, key)).size
    ]
    positive = [t for t in taus if np.isfinite(t) and t > 0]
    return min(positive, default=1.0) * 1e-6
