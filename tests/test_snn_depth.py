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

from snnkart.backends.lava_sim import LavaSimPredictor
from snnkart.backends.reference import NIRReference
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.eval.deploy import make_policy_env
from snnkart.export.nir_export import export_nir
from snnkart.rl.config import ConfigError, load_config
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.trained import TorchPredictor, load_run

DEPTHS = {1: [48], 3: [40, 32, 24]}


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> dict[int, tuple[Path, Path]]:
    """A tiny grid SNN of each depth, its readout made to depend on the spikes (so actions
    vary), and its export."""
    base = tmp_path_factory.mktemp("depth")
    out = {}
    for depth, hidden in DEPTHS.items():
        run_dir = train_tiny(base / f"d{depth}", "grid", "snn", extra_sets=[f"snn.hidden={hidden}"])
        run = load_run(run_dir)
        assert isinstance(run.policy, SNNPolicy)
        with torch.no_grad():
            generator = torch.Generator().manual_seed(depth)
            readout = run.policy.snn.readout.weight
            readout.copy_(torch.randn(readout.shape, generator=generator))
        nir_path, _ = export_nir(run, base / f"d{depth}.nir")
        out[depth] = (run_dir, nir_path)
    return out


@pytest.mark.parametrize("depth", sorted(DEPTHS))
def test_export_writes_a_chain_of_that_depth(
    depth: int, exported: dict[int, tuple[Path, Path]]
) -> None:
    run_dir, nir_path = exported[depth]
    graph = nir.read(nir_path)
    hidden = DEPTHS[depth]
    lifs = [str(2 * i + 1) for i in range(depth)]
    affines = [str(2 * i) for i in range(depth + 1)]
    assert set(graph.nodes) == {"input", "output", *lifs, *affines}
    for name, size in zip(lifs, hidden, strict=True):
        assert isinstance(graph.nodes[name], nir.LIF) and graph.nodes[name].tau.shape == (size,)
    manifest = Manifest.read(manifest_path(nir_path))
    assert [layer.size for layer in manifest.layers] == hidden
    assert manifest.readout_node == str(2 * depth)
    run = load_run(run_dir)
    assert list(run.config.snn.hidden) == hidden
    assert len(run.policy.snn.lifs) == depth  # type: ignore[union-attr]


@pytest.mark.parametrize("depth", sorted(DEPTHS))
def test_reference_acts_as_the_torch_policy(
    depth: int, exported: dict[int, tuple[Path, Path]]
) -> None:
    run_dir, nir_path = exported[depth]
    run = load_run(run_dir)
    with torch.no_grad():  # the same readout as the export
        generator = torch.Generator().manual_seed(depth)
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
@pytest.mark.parametrize("depth", sorted(DEPTHS))
def test_lava_matches_the_reference_bit_for_bit(
    depth: int, exported: dict[int, tuple[Path, Path]]
) -> None:
    _, nir_path = exported[depth]
    reference = NIRReference(nir_path, "fixed")
    env = make_policy_env(reference.manifest, None, None)
    try:
        with LavaSimPredictor(nir_path, "fixed") as lava:
            obs, _ = env.reset(seed=11)
            for step in range(80):
                ref_window, ref_out = reference.step(obs)
                lava_window, lava_out = lava.step(obs)
                assert lava_window.raster.shape == (8 + depth - 1, sum(DEPTHS[depth]))
                np.testing.assert_array_equal(lava_window.raster, ref_window.raster, str(step))
                np.testing.assert_array_equal(lava_out, ref_out)
                obs, _, terminated, truncated, _ = env.step(reference.codec.decode(ref_out))
                if terminated or truncated:
                    obs, _ = env.reset(seed=12 + step)
            assert lava.counts.as_dict() == reference.counts.as_dict()
    finally:
        env.close()


@pytest.mark.parametrize("hidden", ["[]", "[8, 8, 8, 8]", "[8, 0]"])
def test_snn_hidden_takes_one_to_three_layers(hidden: str) -> None:
    with pytest.raises(ConfigError, match="1 to 3"):
        load_config(overrides={"policy": "snn"}, sets=[f"snn.hidden={hidden}"])
