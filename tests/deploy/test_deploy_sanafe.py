"""SANA-FE's LIF runs Lava's fixed-point pipeline bit for bit: a foreign chain of three layers,
fed a host current that changes at every SNN step, gives in SANA-FE (chained, and replayed
layer by layer) every spike of the fixed-point reference, fill and drain rows included.

Needs the ``sanafe`` extra; skips as optional without it."""

from __future__ import annotations

import numpy as np
import pytest
from deploy_helpers import DT, plain_chain_graph

from snnkart.app.sanafe_report import network_job
from snnkart.backends.network import chain_from_graph
from snnkart.backends.quantize import quantize
from snnkart.backends.reference import ChainSimulator
from snnkart.contract.deploy_inputs import DeployInputs
from snnkart.energy.sanafe_model import run_sanafe, sanafe_python


def test_sanafe_reproduces_a_three_layer_fixed_point_chain() -> None:
    python = sanafe_python()
    if python is None:
        pytest.skip("optional: SANA-FE is not installed (pip install 'snnkart[sanafe]')")
    sizes, T, windows = (20, 16, 12), 8, 40
    chain = chain_from_graph(plain_chain_graph(sizes, n_in=6, seed=3), DT)
    fixed = quantize(chain)
    reference = ChainSimulator(chain, T, "fixed", fixed)
    rng = np.random.default_rng(5)
    first = chain.layers[0]
    currents, rasters = [], []
    for _ in range(windows):
        x = rng.normal(0.0, 1.0, (T, chain.n_in))  # a different input at every SNN step
        current = fixed.host_current(x @ first.weight.astype(np.float64).T + first.bias)
        currents.append(current.astype(np.int32))
        rasters.append(reference.window(current))
    inputs = DeployInputs(
        current=np.stack(currents), raster=np.stack(rasters), episode_starts=np.array([0]),
        sizes=sizes, num_steps=T, depth=len(sizes) - 1, first_seed=0, arithmetic="fixed",
        backend="nir-ref",
    )  # fmt: skip
    job, arrays = network_job(chain, fixed, inputs)
    result = run_sanafe(job, arrays, python)
    recorded = inputs.layer_spikes()
    assert all(n > 0.05 * windows * (T + 2) * size for n, size in zip(recorded, sizes, strict=True))
    for mode in ("replay", "chain"):
        run = result[mode]
        assert run["lif_spikes"] == recorded, mode
        assert run["lif_mismatched_logical_neuron_steps"] == [0, 0, 0], mode
    assert result["replay"]["replayed_spikes"] == [*recorded[:2], 0]
