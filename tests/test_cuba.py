"""Current-based LIF (NIR CubaLIF, snntorch Synaptic) in the chain, the reference's three
arithmetics and the quantisation; its Lava parity is in ``test_snn_depth.py``."""

from __future__ import annotations

from typing import Any

import nir
import numpy as np
import pytest

from snnkart.backends.lava_params import lava_layers
from snnkart.backends.network import ChainNetwork, UnsupportedGraphError, chain_from_graph
from snnkart.backends.quantize import UV_MAX, quantize
from snnkart.backends.reference import ChainSimulator

DT = 1e-3


def _cuba(n: int, tau_syn: np.ndarray, tau_mem: np.ndarray, **kw: np.ndarray) -> nir.CubaLIF:
    """As snntorch exports it unless overridden: r = tau_mem/dt, w_in = tau_syn/dt, reset 0."""
    params = {
        "r": tau_mem / DT,
        "w_in": tau_syn / DT,
        "v_leak": np.zeros(n),
        "v_threshold": np.ones(n),
        "v_reset": np.zeros(n),
        **kw,
    }
    return nir.CubaLIF(tau_syn=tau_syn, tau_mem=tau_mem, **params)


def _graph(
    w1: np.ndarray, cuba: nir.CubaLIF, w2: np.ndarray, lif: nir.NIRNode, b2: float = 0.1
) -> nir.NIRGraph:
    n_in, n2 = w1.shape[1], w2.shape[0]
    return nir.NIRGraph(
        nodes={
            "in": nir.Input(input_type={"input": np.array([n_in])}),
            "fc1": nir.Linear(weight=w1),
            "cuba": cuba,
            "fc2": nir.Affine(weight=w2, bias=np.full(n2, b2, np.float32)),
            "lif": lif,
            "out": nir.Output(output_type={"output": np.array([n2])}),
        },
        edges=[("in", "fc1"), ("fc1", "cuba"), ("cuba", "fc2"), ("fc2", "lif"), ("lif", "out")],
    )


def _lif(n: int, tau: float) -> nir.LIF:
    return nir.LIF(
        tau=np.full(n, tau), r=np.full(n, tau / DT), v_leak=np.zeros(n),
        v_threshold=np.ones(n), v_reset=np.zeros(n),
    )  # fmt: skip


def _hand(
    current: np.ndarray, alpha: Any, syn_gain: Any, beta: Any, gain: Any,
    w2: np.ndarray, b2: float, beta2: float,
) -> np.ndarray:  # fmt: skip
    """i <- alpha i + syn_gain I; v <- beta v + gain i; spike if v > 1, reset to 0; then a
    plain LIF layer fed by the spikes through (w2, b2); returns both layers' spikes."""
    T, n1 = current.shape
    i = np.zeros(n1)
    v = np.zeros(n1)
    v2 = np.zeros(w2.shape[0])
    out = np.zeros((T, n1 + w2.shape[0]), dtype=bool)
    for t in range(T):
        i = alpha * i + syn_gain * current[t]
        v = beta * v + gain * i
        s = v > 1.0
        v[s] = 0.0
        v2 = beta2 * v2 + w2 @ s + b2
        s2 = v2 > 1.0
        v2[s2] = 0.0
        out[t] = np.concatenate([s, s2])
    return out


def test_a_cubalif_graph_runs_like_a_hand_written_loop() -> None:
    tau_syn = np.array([2e-3, 4e-3, 5e-3])  # alpha 0.5, 0.75, 0.8
    tau_mem = np.array([10e-3, 4e-3, 20e-3])  # beta 0.9, 0.75, 0.95
    w_in = np.array([2.0, 8.0, 5.0])  # syn_gain dt w_in / tau_syn: 1, 2, 1
    cuba = _cuba(3, tau_syn, tau_mem, w_in=w_in)
    w1 = np.array([[0.5, 0.1], [0.2, -0.3], [0.05, 0.4]], np.float32)
    w2 = np.array([[1.5, -0.5, 0.7]], np.float32)
    chain = chain_from_graph(_graph(w1, cuba, w2, _lif(1, 5e-3)), DT)
    first = chain.layers[0]
    assert first.cuba and not chain.layers[1].cuba
    np.testing.assert_allclose(first.alpha, [0.5, 0.75, 0.8])
    np.testing.assert_allclose(first.syn_gain, [1.0, 2.0, 1.0])
    assert not first.plain  # a syn_gain of 2

    T = 16
    x = np.array([0.9, 0.4], np.float32)
    current = np.broadcast_to(w1 @ x, (T, 3)).astype(np.float32)
    expected = _hand(current.astype(np.float64), first.alpha, first.syn_gain, first.beta,
                     first.gain, w2.astype(np.float64), 0.1, 0.8)  # fmt: skip
    assert 0 < expected.sum() < expected.size
    # a LIF of the same tau_mem (no current state) spikes differently: the current matters
    no_current = _hand(current.astype(np.float64), 0.0, 1.0, first.beta, first.gain,
                       w2.astype(np.float64), 0.1, 0.8)  # fmt: skip
    assert not np.array_equal(expected, no_current)
    raster = ChainSimulator(chain, T, "float32").window(current)
    np.testing.assert_array_equal(raster, expected)


def _snntorch_chain(alpha: float, beta: float = 0.9, second_cuba: bool = False) -> ChainNetwork:
    """A CubaLIF layer (6) and a LIF layer (3), or a second CubaLIF of the same decays."""
    n1, n2 = 6, 3
    rng = np.random.default_rng(5)
    w1 = rng.normal(0.0, 1.0, (n1, 4)).astype(np.float32)
    w2 = rng.normal(0.0, 1.0, (n2, n1)).astype(np.float32)
    tau_syn, tau_mem = DT / (1 - alpha), DT / (1 - beta)
    cuba = _cuba(n1, np.full(n1, tau_syn), np.full(n1, tau_mem))
    if second_cuba:  # no bias into a CubaLIF behind a Dense: Lava could not run it
        second = _cuba(n2, np.full(n2, tau_syn), np.full(n2, tau_mem))
        return chain_from_graph(_graph(w1, cuba, w2, second, b2=0.0), DT)
    return chain_from_graph(_graph(w1, cuba, w2, _lif(n2, tau_mem)), DT)


def test_lava_gets_the_current_decay() -> None:
    chain = _snntorch_chain(alpha=0.8)
    floats = lava_layers(chain, "float64")
    assert floats[0].du == pytest.approx(0.2) and floats[1].du == 1.0  # 1: no current state
    fixed = quantize(chain)
    assert fixed.layers[0].du == 818 and fixed.layers[1].du == 4095  # Lava adds 1 (ds_offset)
    assert fixed.layers[0].effective_alpha == pytest.approx(0.8, abs=1e-4)
    assert fixed.layers[1].effective_alpha == 0.0
    assert fixed.describe()[0]["effective_alpha"] == fixed.layers[0].effective_alpha
    assert "effective_alpha" not in fixed.describe()[1]  # a LIF: as before


@pytest.mark.parametrize("alpha", [0.5, 0.95, 0.999])
def test_a_slow_current_stays_inside_24_bits(alpha: float) -> None:
    """The current sums up to 1 / (1 - alpha) inputs: the host's clip and the Dense scale keep
    u inside 24 bits, so a strong input fires every step instead of wrapping around."""
    chain = _snntorch_chain(alpha, second_cuba=True)
    fixed = quantize(chain)
    first = fixed.layers[0]
    assert first.input_max * 64 / (1 - first.effective_alpha) < UV_MAX
    assert first.vth < first.input_max  # a clipped strong current still crosses the threshold
    dense = fixed.layers[1]
    assert dense.weight is not None and dense.du == first.du
    summed = np.abs(dense.weight).sum(axis=1).max()  # every input spiking at once
    assert summed <= dense.input_max and summed * 64 / (1 - dense.effective_alpha) < UV_MAX
    sim = ChainSimulator(chain, 40, "fixed", fixed)
    strong = np.full((40, 6), 1e6)
    raster = sim.window(fixed.host_current(strong))
    assert raster[:40, :6].all()  # the host layer fires at every step, never wraps
    assert all(np.abs(u).max() < UV_MAX for u in sim.u)


def test_lava_refuses_per_neuron_current_decays() -> None:
    n1 = 6
    chain = _snntorch_chain(0.5)
    graph = _graph(
        np.ones((n1, 4), np.float32),
        _cuba(n1, np.linspace(1.5e-3, 3e-3, n1), np.full(n1, 1e-2)),
        np.ones((3, n1), np.float32),
        _lif(3, 1e-2),
    )
    per_neuron = chain_from_graph(graph, DT)
    assert chain.layers[0].cuba
    with pytest.raises(UnsupportedGraphError, match=r"'cuba'.*non-uniform current decay"):
        quantize(per_neuron)
    with pytest.raises(UnsupportedGraphError, match=r"'cuba'.*non-uniform current decay"):
        ChainSimulator(per_neuron, 8, "float64")


def test_lava_refuses_a_bias_into_a_cubalif_behind_a_dense() -> None:
    """NIR's Affine bias feeds a CubaLIF's decaying current; Lava adds its bias to the voltage."""
    n1, n2 = 6, 3
    cuba1 = _cuba(n1, np.full(n1, 2e-3), np.full(n1, 1e-2))
    cuba2 = _cuba(n2, np.full(n2, 2e-3), np.full(n2, 1e-2))
    graph = _graph(np.ones((n1, 4), np.float32), cuba1, np.ones((n2, n1), np.float32), cuba2)
    graph.nodes["cuba2"] = graph.nodes.pop("lif")
    graph.edges[:] = [(a, "cuba2" if b == "lif" else b) for a, b in graph.edges]
    graph.edges[:] = [("cuba2" if a == "lif" else a, b) for a, b in graph.edges]
    chain = chain_from_graph(graph, DT)
    with pytest.raises(UnsupportedGraphError, match=r"'cuba2': the bias of 'fc2' feeds"):
        quantize(chain)
    ChainSimulator(chain, 8, "float32").window(np.ones((8, n1), np.float32))  # runs on nir-ref
