"""NIR graphs from outside snnkart: foreign LIF, IF and two-layer graphs against hand-written
loops, foreign chains of one and three layers on Lava bit for bit, unsupported nodes refused."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

from typing import Any

import nir
import numpy as np
import pytest
from deploy_helpers import DT, nir_graph, plain_chain_graph, snntorch_lif

from snnkart.backends.base import split_window
from snnkart.backends.lava_params import lava_spec
from snnkart.backends.lava_sim import LavaWorker
from snnkart.backends.network import UnsupportedGraphError, chain_from_graph
from snnkart.backends.quantize import (
    check_lava_compatible,
    quantize,
)
from snnkart.backends.reference import ChainSimulator

# -- a NIR graph from outside snnkart ----------------------------------------------------------


def _foreign_lif_graph() -> tuple[nir.NIRGraph, dict[str, np.ndarray]]:
    rng = np.random.default_rng(3)
    p = {
        "w1": rng.normal(0.0, 1.0, (4, 3)).astype(np.float32),
        "b1": np.array([0.5, -0.25, 0.75, 0.0], dtype=np.float32),
        "tau": np.array([4e-3, 4e-3, 2e-3, 8e-3]),  # beta 0.75, 0.75, 0.5, 0.875
        "r": np.array([8.0, 4.0, 2.0, 8.0]),  # gain dt r / tau: 2, 1, 1, 1
        "thr": np.array([1.0, 0.5, 2.0, 0.8]),
        "w2": rng.normal(0.0, 1.0, (2, 4)).astype(np.float32),
        "b2": np.array([0.1, -0.1], dtype=np.float32),
    }
    graph = nir_graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "fc": nir.Affine(weight=p["w1"], bias=p["b1"]),
            "lif": nir.LIF(
                tau=p["tau"],
                r=p["r"],
                v_leak=np.zeros(4),
                v_threshold=p["thr"],
                v_reset=np.zeros(4),
            ),
            "ro": nir.Affine(weight=p["w2"], bias=p["b2"]),
            "out": nir.Output(output_type={"output": np.array([2])}),
        },
        [("in", "fc"), ("fc", "lif"), ("lif", "ro"), ("ro", "out")],
    )
    return graph, p


def _hand_loop(
    current: np.ndarray, beta: np.ndarray, gain: np.ndarray, thr: np.ndarray, reset: np.ndarray
) -> tuple[np.ndarray, float]:
    """v <- beta v + gain I; spike if v > thr; then v <- reset. Returns the spikes and the
    smallest |v - thr| seen (how far the test's values stay from a rounding-sensitive tie)."""
    v = np.zeros(current.shape[1])
    out = np.zeros(current.shape, dtype=bool)
    margin = np.inf
    for t in range(current.shape[0]):
        v = beta * v + gain * current[t]
        margin = min(margin, float(np.min(np.abs(v - thr))))
        out[t] = v > thr
        v = np.where(out[t], reset, v)
    return out, margin


def test_foreign_lif_graph_runs_like_a_hand_written_loop() -> None:
    graph, p = _foreign_lif_graph()
    chain = chain_from_graph(graph, DT)
    assert chain.n_in == 3 and chain.sizes == (4,) and chain.n_out == 2
    assert chain.fan_out == (2,) and chain.readout_node == "ro"
    (layer,) = chain.layers
    assert (layer.synapse, layer.neuron) == ("fc", "lif")
    np.testing.assert_allclose(layer.beta, [0.75, 0.75, 0.5, 0.875])
    np.testing.assert_allclose(layer.gain, [2.0, 1.0, 1.0, 1.0])
    assert not layer.plain
    assert chain.readout_weight is not None and chain.readout_bias is not None
    np.testing.assert_array_equal(chain.readout_weight, p["w2"])
    np.testing.assert_array_equal(chain.readout_bias, p["b2"])

    T = 12
    x = np.array([0.8, -0.3, 0.5], dtype=np.float32)
    current = np.broadcast_to(p["w1"] @ x + p["b1"], (T, 4)).astype(np.float32)
    current = current * np.linspace(0.5, 1.5, T, dtype=np.float32)[:, None]  # varying in time
    expected, margin = _hand_loop(
        current.astype(np.float64), 1 - DT / p["tau"], DT * p["r"] / p["tau"], p["thr"], np.zeros(4)
    )
    assert margin > 1e-4, "the hand-chosen values come too close to the threshold"
    assert 0 < expected.sum() < expected.size  # some spikes, some silence
    raster = ChainSimulator(chain, T, "float32").window(current)
    assert raster.shape == (T, 4) and raster.dtype == bool
    np.testing.assert_array_equal(raster, expected)
    window = split_window(raster, chain.sizes, T)
    np.testing.assert_array_equal(window.last_counts, expected.sum(axis=0))


def test_foreign_if_graph_with_nonzero_reset() -> None:
    w = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -0.5], [0.3, 0.3, 0.3], [-1.0, 2.0, 0.0]], np.float32)
    r = np.array([500.0, 1000.0, 250.0, 1000.0])  # gain dt r: 0.5, 1, 0.25, 1
    thr = np.array([1.0, 1.5, 0.35, 2.0])
    reset = np.array([0.0, 0.25, -0.5, 0.5])
    graph = nir_graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "lin": nir.Linear(weight=w),
            "if": nir.IF(r=r, v_threshold=thr, v_reset=reset),
            "out": nir.Output(output_type={"output": np.array([4])}),
        },
        [("in", "lin"), ("lin", "if"), ("if", "out")],
    )
    chain = chain_from_graph(graph, DT)
    assert chain.readout_weight is None and chain.n_out == 4 and chain.fan_out == (4,)
    np.testing.assert_array_equal(chain.layers[0].beta, np.ones(4))
    np.testing.assert_array_equal(chain.layers[0].bias, np.zeros(4))
    T = 10
    x = np.array([0.7, 0.9, 0.4], dtype=np.float32)
    current = np.broadcast_to(w @ x, (T, 4)).astype(np.float32)
    expected, margin = _hand_loop(current.astype(np.float64), np.ones(4), DT * r, thr, reset)
    assert margin > 1e-4
    assert 0 < expected.sum() < expected.size
    np.testing.assert_array_equal(ChainSimulator(chain, T, "float32").window(current), expected)
    with pytest.raises(UnsupportedGraphError, match="'if'"):
        check_lava_compatible(chain)  # v_reset != 0 (and gain != 1) has no Lava mapping


def test_foreign_two_layer_graph_float32_and_lava_pipeline_agree() -> None:
    """A plain (snntorch-style) 2-layer graph: the float32 window, a hand loop and the float64
    Lava pipeline give the same logical spikes; layer 2 sees layer 1's spikes of the same step."""
    rng = np.random.default_rng(11)
    w1 = rng.normal(0.0, 1.0, (5, 3)).astype(np.float32)
    w2 = rng.normal(0.0, 0.8, (4, 5)).astype(np.float32)
    b2 = np.array([0.3, -0.2, 0.1, 0.45], dtype=np.float32)
    tau = 4e-3  # beta 0.75
    graph = nir_graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "a": nir.Affine(weight=w1, bias=np.zeros(5, np.float32)),
            "n1": snntorch_lif(5, tau, 1.0),
            "b": nir.Affine(weight=w2, bias=b2),
            "n2": snntorch_lif(4, tau, 0.5),
            "out": nir.Output(output_type={"output": np.array([4])}),
        },
        [("in", "a"), ("a", "n1"), ("n1", "b"), ("b", "n2"), ("n2", "out")],
    )
    chain = chain_from_graph(graph, DT)
    assert chain.sizes == (5, 4) and all(layer.plain for layer in chain.layers)
    check_lava_compatible(chain)
    T = 10
    x = np.array([1.2, -0.4, 0.9], dtype=np.float32)
    current = np.ascontiguousarray(np.broadcast_to(w1 @ x, (T, 5)), dtype=np.float32)
    # hand loop, float64
    v1, v2 = np.zeros(5), np.zeros(4)
    expected = np.zeros((T, 9), dtype=bool)
    margin = np.inf
    for t in range(T):
        v1 = 0.75 * v1 + current[t]
        margin = min(margin, float(np.min(np.abs(v1 - 1.0))))
        s1 = v1 > 1.0
        v1[s1] = 0.0
        v2 = 0.75 * v2 + w2.astype(np.float64) @ s1 + b2
        margin = min(margin, float(np.min(np.abs(v2 - 0.5))))
        s2 = v2 > 0.5
        v2[s2] = 0.0
        expected[t] = np.concatenate([s1, s2])
    assert margin > 1e-4
    assert 0 < expected[:, 5:].sum() < expected[:, 5:].size
    np.testing.assert_array_equal(ChainSimulator(chain, T, "float32").window(current), expected)
    lava64 = ChainSimulator(chain, T, "float64")
    for _ in range(3):  # the pipeline's state carries across windows; each window starts fresh
        raster = lava64.window(current.astype(np.float64))
        assert raster.shape == (T + 1, 9)
        np.testing.assert_array_equal(split_window(raster, chain.sizes, T).logical, expected)


@pytest.mark.lava
@pytest.mark.timeout(120)
@pytest.mark.parametrize("precision", ["float", "fixed"])
@pytest.mark.parametrize("sizes", [(24,), (20, 16, 12)], ids=["1-layer", "3-layer"])
def test_lava_runs_foreign_chains_of_one_and_three_layers_bit_exact(
    sizes: tuple[int, ...], precision: str
) -> None:
    """Graphs of 1 and 3 LIF layers written with the ``nir`` package (training makes 2): Lava's
    LIF and Dense processes give the same-arithmetic reference's raster, window after window,
    with the pipeline depth (T + L rows) that the number of layers implies."""
    chain = chain_from_graph(plain_chain_graph(sizes, n_in=6, seed=len(sizes)), DT)
    assert chain.sizes == sizes
    T, L = 8, len(sizes) - 1
    fixed = quantize(chain) if precision == "fixed" else None
    reference = ChainSimulator(chain, T, "float64" if fixed is None else "fixed", fixed)
    float32 = ChainSimulator(chain, T, "float32")
    rng = np.random.default_rng(5)
    first = chain.layers[0]
    windows, logical_flips, spikes = 25, 0, np.zeros(len(sizes), dtype=np.int64)
    worker = LavaWorker(lava_spec(chain, T, "float64" if fixed is None else "fixed", fixed))
    try:
        for _ in range(windows):
            x = rng.normal(0.0, 1.0, (T, chain.n_in))  # a different input at every SNN step
            current = x @ first.weight.astype(np.float64).T + first.bias
            sent = current if fixed is None else fixed.host_current(current)
            raster = worker.window(np.ascontiguousarray(sent))
            expected = reference.window(sent)
            assert raster.shape == (T + L, sum(sizes))
            np.testing.assert_array_equal(raster, expected)
            window = split_window(raster, sizes, T)
            spikes += window.spikes
            # the pipeline computes the policy's steps: its logical spikes are those of the
            # unpipelined float32 chain (torch's order), up to rare rounding or quantisation flips
            own = float32.window(current.astype(np.float32))
            logical_flips += int((window.logical != own).sum())
    finally:
        worker.close()
    neuron_steps = windows * T * sum(sizes)
    assert logical_flips <= (0.001 if fixed is None else 0.03) * neuron_steps, logical_flips
    # not trivial: every layer fires, none saturates
    assert np.all(spikes > 0.05 * windows * T * np.asarray(sizes)), spikes
    assert np.all(spikes < 0.9 * windows * T * np.asarray(sizes)), spikes


@pytest.mark.parametrize("kind", ["CubaLI", "Delay"])
def test_foreign_graph_with_unsupported_node_is_refused(kind: str) -> None:
    nodes: dict[str, Any] = {
        "in": nir.Input(input_type={"input": np.array([3])}),
        "fc": nir.Affine(weight=np.ones((4, 3), np.float32), bias=np.zeros(4, np.float32)),
        "out": nir.Output(output_type={"output": np.array([4])}),
    }
    if kind == "CubaLI":  # a non-spiking readout
        nodes["odd"] = nir.CubaLI(
            tau_syn=np.full(4, 2e-3), tau_mem=np.full(4, 4e-3), r=np.full(4, 4.0),
            v_leak=np.zeros(4),
        )  # fmt: skip
        edges = [("in", "fc"), ("fc", "odd"), ("odd", "out")]
    else:
        nodes["odd"] = nir.Delay(delay=np.full(3, 2e-3))
        nodes["lif"] = nir.LIF(
            tau=np.full(4, 4e-3), r=np.full(4, 4.0), v_leak=np.zeros(4), v_threshold=np.ones(4)
        )
        edges = [("in", "odd"), ("odd", "fc"), ("fc", "lif"), ("lif", "out")]
    with pytest.raises(UnsupportedGraphError) as info:
        chain_from_graph(nir_graph(nodes, edges), DT)
    assert kind in str(info.value) and "'odd'" in str(info.value)
