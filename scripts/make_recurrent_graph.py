"""Write the third-party recurrent NIR graph the tests run: ``tests/data/graphs/snntorch-rleaky.nir``.

    .venv/bin/python scripts/make_recurrent_graph.py

snnTorch 1.0 (``snntorch.export_nir.export_to_nir``) exports this network, seeded, untrained::

    Linear(6, 10) -> Leaky(beta 0.9) -> Linear(10, 8) -> RLeaky(beta 0.8, all-to-all) -> Linear(8, 3)

Beta and threshold are per-neuron vectors of equal values (a scalar breaks snnTorch 1.0's NIR
type inference). Every neuron resets to zero (``reset_mechanism="zero"``, ``reset_delay=False``: NIR has no subtractive
reset and no delayed one, so this is the setting whose export means what snnTorch simulates). snnTorch writes the ``RLeaky`` as a
``LIF`` node ``"3.lif"`` and an ``Affine`` ``"3.w_rec"`` (with its bias) in a cycle
``3.lif -> 3.w_rec -> 3.lif``. The script also stores snnTorch's own simulation of 40 steps of a
seeded input (``snntorch-rleaky.npz``: ``inputs``, and the spikes of both layers), which
``tests/test_kinds.py`` compares with snnkart's reference.
"""

from __future__ import annotations

from pathlib import Path

import nir
import numpy as np
import snntorch as snn
import torch
from snntorch.export_nir import export_to_nir

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "graphs"
STEPS = 40


def network() -> torch.nn.Sequential:
    torch.manual_seed(3)
    return torch.nn.Sequential(
        torch.nn.Linear(6, 10),
        snn.Leaky(
            beta=torch.full((10,), 0.9),
            threshold=torch.ones(10),
            reset_mechanism="zero",
            reset_delay=False,
            init_hidden=True,
        ),
        torch.nn.Linear(10, 8),
        snn.RLeaky(
            beta=torch.full((8,), 0.8),
            threshold=torch.ones(8),
            linear_features=8,
            reset_mechanism="zero",
            reset_delay=False,
            init_hidden=True,
        ),
        torch.nn.Linear(8, 3),
    )


def simulate(net: torch.nn.Sequential, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """snnTorch's own steps from zero state: the spikes of the Leaky and the RLeaky layer."""
    fc1, lif1, fc2, rlif, _ = net
    lif1.reset_hidden()
    rlif.reset_hidden()
    first, second = [], []
    with torch.no_grad():
        for x in torch.as_tensor(inputs, dtype=torch.float32):
            s1 = lif1(fc1(x[None]))
            s2 = rlif(fc2(s1))
            first.append(s1[0].numpy().copy())
            second.append(s2[0].numpy().copy())
    return np.array(first, dtype=bool), np.array(second, dtype=bool)


def main() -> None:
    net = network().eval()
    with torch.no_grad():
        graph = export_to_nir(net, torch.zeros(6))
    OUT.mkdir(parents=True, exist_ok=True)
    nir.write(OUT / "snntorch-rleaky.nir", graph)
    inputs = np.random.default_rng(5).uniform(0.0, 1.5, size=(STEPS, 6))
    first, second = simulate(network().eval(), inputs)
    np.savez(OUT / "snntorch-rleaky.npz", inputs=inputs, layer1=first, layer2=second)
    print(f"wrote {OUT / 'snntorch-rleaky.nir'}: nodes {sorted(graph.nodes)}")
    print(f"snnTorch's spikes: layer 1 {int(first.sum())}, layer 2 {int(second.sum())}")


if __name__ == "__main__":
    main()
