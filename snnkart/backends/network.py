"""A NIR graph as a chain of spiking layers: what every snnkart backend executes.

Supported subset (anything else is refused with an error naming the node type):

    Input -> [Scale] -> [diagonal Affine] -> (Affine | Linear) -> (LIF | IF | CubaLIF) -> ...
             -> (Affine | Linear) -> [LI] -> Output   (or the last spiking layer -> Output)

A diagonal Affine before the first synapse (an observation normalisation, as snnkart's v4
exports write it: :mod:`snnkart.contract.obs_node`) is folded into that synapse here; a policy
opened with its manifest has it removed instead, and the host normalises.

NIR nodes are continuous-time; the chain is discretised with the recorded ``dt`` by forward
Euler, the convention of snntorch's exporter (snntorch writes tau = dt / (1 - beta), r = tau / dt):

    LIF:  v <- beta * v + gain * I + leak,   beta = 1 - dt/tau, gain = dt*r/tau, leak = dt*v_leak/tau
    IF:   v <- v + gain * I,                 gain = dt*r            (beta = 1)
    CubaLIF: i <- alpha * i + syn_gain * I,  alpha = 1 - dt/tau_syn, syn_gain = dt*w_in/tau_syn,
          then v <- beta * v + gain * i + leak with beta, gain, leak as LIF's from tau_mem
    spike = v > v_threshold (strict);  on spike v <- v_reset

``discretisation="exact"`` (exponential Euler, the convention of libraries that integrate each
decay exactly) uses ``beta = exp(-dt/tau)`` and ``gain = (1 - beta) r``, ``leak = (1 - beta)
v_leak`` (CubaLIF: ``alpha = exp(-dt/tau_syn)``, ``syn_gain = (1 - alpha) w_in``); at
``beta = 0.9`` the two differ by 0.5 % (0.9 against 0.905).

The readout is host-side: the mean spike rates of the T steps through the last Affine, or, with
an LI node (a non-spiking leaky integrator, the usual readout of spiking actors in other
libraries), ``v <- decay v + gain (W s[t] + b) + leak`` over the T steps from 0, read at the
last step. It is linear in the last layer's spikes, so every backend that matches those spikes
matches the readout.

For snntorch exports (``r = tau/dt``, ``v_leak = 0``; CubaLIF ``w_in = tau_syn/dt``) gain and
syn_gain are exactly 1 and leak exactly 0, and the update is ``v = beta v + I`` (Leaky), or
``i = alpha i + I; v = beta v + i`` (Synaptic), the trained neuron. The first layer's input current
``W1 x + b1`` is what the host computes (current encoding) or what a Dense synapse delivers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from snnkart.backends.graph_walk import chain_order as _chain_order
from snnkart.backends.graph_walk import leading_normalisation
from snnkart.backends.graph_walk import recurrent_synapses as _recurrent_synapses
from snnkart.errors import UnsupportedGraphError

DISCRETISATIONS = ("euler", "exact")


@dataclass(frozen=True)
class SpikingLayer:
    """``I = W s + b`` feeding a population of (L)IF neurons; per-neuron float64 parameters."""

    synapse: str  # NIR node name of the Affine/Linear
    neuron: str  # NIR node name of the LIF/IF
    weight: np.ndarray  # (n, m) float32 as stored
    bias: np.ndarray  # (n,) float32 (zeros for Linear)
    beta: np.ndarray  # (n,) float64
    gain: np.ndarray  # (n,)
    leak: np.ndarray  # (n,)
    threshold: np.ndarray  # (n,)
    v_reset: np.ndarray  # (n,)
    alpha: np.ndarray | None = None  # (n,) current decay of a CubaLIF; None: no current state
    syn_gain: np.ndarray | None = None  # (n,) CubaLIF input gain
    recurrent: np.ndarray | None = None  # (n, n) float32: the cycle neuron -> synapse -> neuron
    recurrent_node: str | None = None  # NIR node name of that synapse (Linear or Affine)

    @property
    def size(self) -> int:
        return int(self.weight.shape[0])

    @property
    def cuba(self) -> bool:
        """A current-based LIF (NIR CubaLIF): the input feeds a decaying current first."""
        return self.alpha is not None

    @property
    def plain(self) -> bool:
        """True when the update is exactly ``v = beta v + I`` (gain 1, no leak; for a CubaLIF
        also ``i = alpha i + I``)."""
        syn_plain = self.syn_gain is None or bool(np.all(self.syn_gain == 1.0))
        return bool(np.all(self.gain == 1.0) and np.all(self.leak == 0.0)) and syn_plain


@dataclass(frozen=True)
class LeakyReadout:
    """An LI node after the readout synapse: ``v <- decay v + gain I + leak`` (per output)."""

    node: str
    decay: np.ndarray
    gain: np.ndarray
    leak: np.ndarray


@dataclass(frozen=True)
class ChainNetwork:
    """Input scaling, spiking layers in order, and an optional linear readout of spike rates."""

    n_in: int
    input_scale: np.ndarray | None
    layers: tuple[SpikingLayer, ...]
    readout_weight: np.ndarray | None  # (n_out, n_last) float32
    readout_bias: np.ndarray | None
    readout_node: str | None
    readout_li: LeakyReadout | None = None

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(layer.size for layer in self.layers)

    @property
    def n_out(self) -> int:
        if self.readout_weight is None:
            return self.layers[-1].size
        return int(self.readout_weight.shape[0])

    @property
    def fan_out(self) -> tuple[int, ...]:
        """Synapses each spike of a layer drives (next layer, or the readout, and its own
        recurrent synapse)."""
        nxt = [layer.size for layer in self.layers[1:]]
        rec = [0 if layer.recurrent is None else layer.size for layer in self.layers]
        return tuple(a + b for a, b in zip((*nxt, self.n_out), rec, strict=True))

    @property
    def recurrent(self) -> bool:
        """Some layer feeds its own spikes back (a cycle in the NIR graph)."""
        return any(layer.recurrent is not None for layer in self.layers)


def _array(node: Any, name: str, field: str) -> np.ndarray:
    arr = np.asarray(getattr(node, field), dtype=np.float64)
    if not np.isfinite(arr).all():
        raise UnsupportedGraphError(f"node {name!r}: {field} contains NaN or infinite values")
    return arr


def _synapse(name: str, node: Any) -> tuple[np.ndarray, np.ndarray]:
    import nir

    weight = np.asarray(node.weight, dtype=np.float32)
    if weight.ndim != 2:
        raise UnsupportedGraphError(f"node {name!r}: weight must be a matrix, got {weight.shape}")
    if isinstance(node, nir.Affine):
        bias = np.asarray(node.bias, dtype=np.float32).reshape(-1)
    else:
        bias = np.zeros(weight.shape[0], dtype=np.float32)
    if bias.shape != (weight.shape[0],):
        raise UnsupportedGraphError(f"node {name!r}: bias shape {bias.shape} does not fit weight")
    if not (np.isfinite(weight).all() and np.isfinite(bias).all()):
        raise UnsupportedGraphError(f"node {name!r}: NaN or infinite weights")
    return weight, bias


def _decay(dt: float, tau: np.ndarray, discretisation: str) -> np.ndarray:
    return np.exp(-dt / tau) if discretisation == "exact" else 1.0 - dt / tau


def _input_gain(
    dt: float, tau: np.ndarray, decay: np.ndarray, k: np.ndarray, how: str
) -> np.ndarray:
    """The gain of an input through ``k`` (r or w_in): dt k / tau (Euler), (1 - decay) k."""
    return (1.0 - decay) * k if how == "exact" else dt * k / tau


def _neuron(
    name: str, node: Any, n: int, dt: float, discretisation: str = "euler"
) -> dict[str, np.ndarray]:
    import nir

    thr = _array(node, name, "v_threshold").reshape(-1)
    reset = _array(node, name, "v_reset").reshape(-1) if hasattr(node, "v_reset") else np.zeros(n)
    r = _array(node, name, "r").reshape(-1)
    params: dict[str, np.ndarray] = {}
    if isinstance(node, (nir.LIF, nir.CubaLIF)):
        tau = _positive(node, name, "tau" if isinstance(node, nir.LIF) else "tau_mem")
        v_leak = _array(node, name, "v_leak").reshape(-1)
        beta = _decay(dt, tau, discretisation)
        gain = _input_gain(dt, tau, beta, r, discretisation)
        leak = _input_gain(dt, tau, beta, v_leak, discretisation)
        if isinstance(node, nir.CubaLIF):
            tau_syn = _positive(node, name, "tau_syn")
            w_in = _array(node, name, "w_in").reshape(-1)
            params["alpha"] = _decay(dt, tau_syn, discretisation)
            params["syn_gain"] = _input_gain(dt, tau_syn, params["alpha"], w_in, discretisation)
    else:  # IF
        beta = np.ones(n)
        gain = dt * r
        leak = np.zeros(n)
    params.update(beta=beta, gain=gain, leak=leak, threshold=thr, v_reset=reset)
    params = _per_neuron(name, params, n, "synapse")
    params["leak"] = np.where(np.abs(params["leak"]) < 1e-12, 0.0, params["leak"])
    for key in ("beta", "alpha"):
        if key in params and (np.any(params[key] < 0) or np.any(params[key] > 1)):
            raise UnsupportedGraphError(
                f"node {name!r}: dt/tau outside [0, 1] (dt {dt}); the forward-Euler step is "
                "unstable"
            )
    return params


def _positive(node: Any, name: str, field: str) -> np.ndarray:
    tau = _array(node, name, field).reshape(-1)
    if np.any(tau <= 0):
        raise UnsupportedGraphError(f"node {name!r}: time constants must be positive ({field})")
    return tau


def chain_from_graph(graph: Any, dt: float, discretisation: str = "euler") -> ChainNetwork:
    """Convert a NIR graph to a :class:`ChainNetwork` with time step ``dt`` (s) by forward
    Euler or exponential Euler (``"exact"``), refusing anything outside the subset."""
    import nir

    if discretisation not in DISCRETISATIONS:
        raise UnsupportedGraphError(
            f"unknown discretisation {discretisation!r}; choose one of {DISCRETISATIONS}"
        )
    if not (np.isfinite(dt) and dt > 0):
        raise UnsupportedGraphError(f"the time step dt must be positive, got {dt}")

    nodes = graph.nodes
    cycles = _recurrent_synapses(graph)
    order = _chain_order(graph, set(cycles.values()))
    body = order[1:-1]
    n_in = int(np.prod(np.asarray(nodes[order[0]].input_type["input"])))
    scale = None
    if body and isinstance(nodes[body[0]], nir.Scale):
        scale = _array(nodes[body[0]], body[0], "scale").reshape(-1)
        body = body[1:]
    if leading_normalisation(nodes, body) is not None:
        nodes = {**nodes, body[1]: _folded(nodes[body[0]], nodes[body[1]])}
        body = body[1:]
    li = None
    if body and isinstance(nodes[body[-1]], nir.LI):
        li_name, body = body[-1], body[:-1]
        if not body or not isinstance(nodes[body[-1]], (nir.Affine, nir.Linear)):
            raise UnsupportedGraphError(
                f"LI node {li_name!r} must follow the readout synapse (Affine or Linear)"
            )
        n_out = int(np.asarray(nodes[body[-1]].weight).shape[0])
        li = _leaky_readout(li_name, nodes[li_name], n_out, dt, discretisation)
    layers, readout = _layers(nodes, body, n_in, dt, discretisation)
    layers = [_with_recurrence(layer, nodes, cycles) for layer in layers]
    if scale is not None and scale.shape not in ((1,), (n_in,)):
        raise UnsupportedGraphError(f"Scale after the input has shape {scale.shape}")
    return ChainNetwork(
        n_in=n_in,
        input_scale=scale,
        layers=tuple(layers),
        readout_weight=None if readout is None else readout[0],
        readout_bias=None if readout is None else readout[1],
        readout_node=None if readout is None else readout[2],
        readout_li=li,
    )


def _folded(first: Any, synapse: Any) -> Any:
    """``synapse`` after the diagonal Affine ``first``, as one Affine (float64)."""
    import nir

    d = np.diag(np.asarray(first.weight, dtype=np.float64))
    c = np.asarray(first.bias, dtype=np.float64).reshape(-1)
    w = np.asarray(synapse.weight, dtype=np.float64)
    b = np.asarray(getattr(synapse, "bias", np.zeros(w.shape[0])), dtype=np.float64).reshape(-1)
    return nir.Affine(weight=w * d, bias=w @ c + b)


def _leaky_readout(name: str, node: Any, n: int, dt: float, discretisation: str) -> LeakyReadout:
    tau = _positive(node, name, "tau")
    decay = _decay(dt, tau, discretisation)
    params = {
        "decay": decay,
        "gain": _input_gain(dt, tau, decay, _array(node, name, "r").reshape(-1), discretisation),
        "leak": _input_gain(
            dt, tau, decay, _array(node, name, "v_leak").reshape(-1), discretisation
        ),
    }
    return LeakyReadout(name, **_per_neuron(name, params, n, "readout synapse"))


def _per_neuron(
    name: str, params: dict[str, np.ndarray], n: int, before: str
) -> dict[str, np.ndarray]:
    """``params`` as ``(n,)`` vectors (a single value broadcast), or an error naming the one
    that does not fit the ``before`` node. snntorch writes r = tau/dt (and w_in = tau_syn/dt),
    so the input gains are 1 up to float32 rounding of the time constants: they are snapped."""
    out = {}
    for key, value in params.items():
        if value.shape == (1,):
            value = np.full(n, value[0])
        elif value.shape != (n,):
            raise UnsupportedGraphError(
                f"node {name!r}: {key} has shape {value.shape}, expected ({n},) to match the "
                f"{before} before it"
            )
        if key in ("gain", "syn_gain"):
            value = np.where(np.abs(value - 1.0) < 1e-6, 1.0, value)
        out[key] = value
    return out


def _with_recurrence(
    layer: SpikingLayer, nodes: dict[str, Any], cycles: dict[str, str]
) -> SpikingLayer:
    """``layer`` with the weights of its recurrent synapse, if it has one."""
    name = cycles.get(layer.neuron)
    if name is None:
        return layer
    weight, bias = _synapse(name, nodes[name])
    if weight.shape != (layer.size, layer.size):
        raise UnsupportedGraphError(
            f"recurrent synapse {name!r} of {layer.neuron!r} has shape {weight.shape}, not "
            f"{(layer.size, layer.size)}"
        )
    # An Affine's bias arrives every step whatever the spikes (snnTorch's RLeaky writes one):
    # it is the same current as a bias on the feed-forward synapse, so it is folded there.
    folded = (layer.bias.astype(np.float32) + bias).astype(np.float32)
    return replace(layer, bias=folded, recurrent=weight, recurrent_node=name)


def _layers(
    nodes: dict[str, Any], body: list[str], n_in: int, dt: float, discretisation: str
) -> tuple[list[SpikingLayer], tuple[np.ndarray, np.ndarray, str] | None]:
    """The spiking layers (synapse -> neuron pairs) and the readout synapse, if any."""
    import nir

    layers: list[SpikingLayer] = []
    readout: tuple[np.ndarray, np.ndarray, str] | None = None
    for i in range(0, len(body), 2):
        name, node = body[i], nodes[body[i]]
        if not isinstance(node, (nir.Affine, nir.Linear)):
            raise UnsupportedGraphError(
                f"node {name!r} ({type(node).__name__}) where a synapse (Affine or Linear) was "
                "expected; the chain must alternate synapse -> neuron"
            )
        weight, bias = _synapse(name, node)
        expected_in = layers[-1].size if layers else n_in
        if weight.shape[1] != expected_in:
            raise UnsupportedGraphError(
                f"node {name!r} takes {weight.shape[1]} inputs but receives {expected_in}"
            )
        if i + 1 == len(body):
            readout = (weight, bias, name)
            break
        neuron_name = body[i + 1]
        neuron = nodes[neuron_name]
        if not isinstance(neuron, (nir.LIF, nir.IF, nir.CubaLIF)):
            raise UnsupportedGraphError(
                f"node {neuron_name!r} ({type(neuron).__name__}) follows synapse {name!r}; "
                "expected LIF, IF or CubaLIF"
            )
        params = _neuron(neuron_name, neuron, weight.shape[0], dt, discretisation)
        layers.append(SpikingLayer(name, neuron_name, weight, bias, **params))  # type: ignore[arg-type]
    if not layers:
        raise UnsupportedGraphError("the graph has no spiking layer (LIF, IF or CubaLIF)")
    return layers, readout
