"""Spiking actors of 1 to 3 layers (``snn.hidden``): they train, export to a NIR chain of that
depth, the numpy reference acts as the torch policy, and Lava matches the reference bit for bit.
Two layers are tested everywhere else; these are the other depths."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from pathlib import Path

import nir
import numpy as np
import pytest
import torch
from tiny_runs import train_tiny

from snnkart.backends.reference import NIRReference
from snnkart.backends.registry import open_backend
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.eval.closed_loop import make_policy_env
from snnkart.export.nir_export import export_nir
from snnkart.rl.config import ConfigError, load_config
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.trained import TorchPredictor, load_run

# Each case: hidden layer sizes and extra settings. "cuba2" is a current-based LIF network
# (snntorch Synaptic, exported as NIR CubaLIF) with a current decay that fixed point cannot
# hold exactly (du = 818: effective alpha 0.80005).
CASES: dict[str, tuple[list[int], list[str]]] = {
    "lif1": ([48], []),
    "lif3": ([40, 32, 24], []),
    "cuba2": ([40, 32], ["snn.neuron=cuba", "snn.alpha=0.8"]),
}
DEPTHS = {name: hidden for name, (hidden, _) in CASES.items()}
SEEDS = {"lif1": 1, "lif3": 3, "cuba2": 2}  # readout weights that make actions vary


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    """A tiny grid SNN of each case, its readout made to depend on the spikes (so actions
    vary), and its export."""
    base = tmp_path_factory.mktemp("depth")
    out = {}
    for depth, (hidden, extra) in CASES.items():
        sets = [f"snn.hidden={hidden}", *extra]
        run_dir = train_tiny(base / f"d{depth}", "grid", "snn", extra_sets=sets)
        run = load_run(run_dir)
        assert isinstance(run.policy, SNNPolicy)
        with torch.no_grad():
            generator = torch.Generator().manual_seed(SEEDS[depth])
            readout = run.policy.snn.readout.weight
            readout.copy_(torch.randn(readout.shape, generator=generator))
        nir_path, _ = export_nir(run, base / f"d{depth}.nir")
        out[depth] = (run_dir, nir_path)
    return out


@pytest.mark.parametrize("depth", sorted(DEPTHS))
def test_export_writes_a_chain_of_that_depth(
    depth: str, exported: dict[str, tuple[Path, Path]]
) -> None:
    run_dir, nir_path = exported[depth]
    graph = nir.read(nir_path)
    hidden = DEPTHS[depth]
    n = len(hidden)
    lifs = [str(2 * i + 1) for i in range(n)]
    affines = [str(2 * i) for i in range(n + 1)]
    assert set(graph.nodes) == {"input", "normalise", "output", *lifs, *affines}
    manifest = Manifest.read(manifest_path(nir_path))
    cuba = depth.startswith("cuba")
    for name, size, spec in zip(lifs, hidden, manifest.layers, strict=True):
        node = graph.nodes[name]
        if cuba:  # snntorch's dt: tau = dt / (1 - decay)
            assert isinstance(node, nir.CubaLIF) and node.tau_syn.shape == (size,)
            np.testing.assert_allclose(1 - 1e-4 / node.tau_syn, 0.8, atol=1e-6)
            assert spec.alpha == pytest.approx(0.8)
        else:
            assert isinstance(node, nir.LIF) and node.tau.shape == (size,)
            assert spec.alpha is None
    assert [layer.size for layer in manifest.layers] == hidden
    assert manifest.readout_node == str(2 * n)
    run = load_run(run_dir)
    assert list(run.config.snn.hidden) == hidden
    assert len(run.policy.snn.lifs) == n  # type: ignore[union-attr]


@pytest.mark.parametrize("depth", sorted(DEPTHS))
def test_reference_acts_as_the_torch_policy(
    depth: str, exported: dict[str, tuple[Path, Path]]
) -> None:
    run_dir, nir_path = exported[depth]
    run = load_run(run_dir)
    with torch.no_grad():  # the same readout as the export
        generator = torch.Generator().manual_seed(SEEDS[depth])
        readout = run.policy.snn.readout.weight  # type: ignore[union-attr]
        readout.copy_(torch.randn(readout.shape, generator=generator))
    torch_policy, reference = TorchPredictor(run), NIRReference(nir_path, "float32")
    env = make_policy_env(reference.manifest, None, None)
    same = steps = 0
    actions = set()
    try:
        obs, _ = env.reset(seed=3)
        while steps < 150:
            action = reference.predict(obs)
            same += action == torch_policy.predict(obs)
            actions.add(action)
            obs, _, terminated, truncated, _ = env.step(action)
            steps += 1
            if terminated or truncated:
                obs, _ = env.reset(seed=3 + steps)
    finally:
        env.close()
    assert len(actions) >= 2, actions
    assert same >= 0.99 * steps, (same, steps)
    assert np.all(reference.counts.spikes > 0)


@pytest.mark.lava
@pytest.mark.timeout(120)
@pytest.mark.parametrize(
    ("depth", "arithmetic"), [(d, "fixed") for d in sorted(DEPTHS)] + [("cuba2", "float")]
)
def test_lava_matches_the_reference_bit_for_bit(
    depth: str, arithmetic: str, exported: dict[str, tuple[Path, Path]]
) -> None:
    _, nir_path = exported[depth]
    reference = NIRReference(nir_path, "fixed" if arithmetic == "fixed" else "float64")
    env = make_policy_env(reference.manifest, None, None)
    n = len(DEPTHS[depth])
    try:
        with open_backend(nir_path, "lava-sim", arithmetic) as lava:
            obs, _ = env.reset(seed=11)
            for step in range(80):
                ref_window, ref_out = reference.step(obs)
                lava_window, lava_out = lava.step(obs)
                assert lava_window.raster.shape == (8 + n - 1, sum(DEPTHS[depth]))
                np.testing.assert_array_equal(lava_window.raster, ref_window.raster, str(step))
                np.testing.assert_array_equal(lava_out, ref_out)
                obs, _, terminated, truncated, _ = env.step(reference.codec.decode(ref_out))
                if terminated or truncated:
                    obs, _ = env.reset(seed=12 + step)
            assert lava.counts.as_dict() == reference.counts.as_dict()
    finally:
        env.close()
    assert reference.counts.spikes.sum() > 0


@pytest.mark.parametrize("hidden", ["[]", "[8, 8, 8, 8]", "[8, 0]"])
def test_snn_hidden_takes_one_to_three_layers(hidden: str) -> None:
    with pytest.raises(ConfigError, match="1 to 3"):
        load_config(overrides={"policy": "snn"}, sets=[f"snn.hidden={hidden}"])
