"""Export -> ``nir.read`` -> snntorch's ``import_from_nir``: the imported network, given the
env's raw observations (the graph's first node normalises them: contract/obs_node.py), acts as
the trained policy does on normalised ones, LIF and CubaLIF alike, once its neurons are reset before each env step
(snntorch's importer builds ``init_hidden`` neurons that keep their state across calls and
ignore the state argument)."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from pathlib import Path

import nir
import numpy as np
import pytest
import snntorch.utils
import torch
from snntorch.import_nir import import_from_nir
from tiny_runs import train_tiny

from snnkart.backends.reference import NIRReference
from snnkart.contract.obs_node import raw_clip
from snnkart.eval.closed_loop import make_policy_env
from snnkart.export.nir_export import export_nir
from snnkart.rl.trained import TorchPredictor, load_run


def _imported_logits(net: torch.nn.Module, z: np.ndarray, T: int, reset: bool) -> np.ndarray:
    if reset:
        snntorch.utils.reset(net)
    outs, state = [], None
    with torch.no_grad():
        for _ in range(T):
            out, state = net(torch.from_numpy(z.astype(np.float32)), state)
            outs.append(out)
    return torch.stack(outs).mean(0).numpy()


@pytest.mark.parametrize("neuron", ["lif", "cuba"])
def test_snntorch_imports_the_export_and_acts_as_the_trained_policy(
    tmp_path: Path, neuron: str
) -> None:
    run_dir = train_tiny(tmp_path / "run", "steer", "snn", extra_sets=[f"snn.neuron={neuron}"])
    run = load_run(run_dir)
    with torch.no_grad():  # a readout that depends on the spikes, so actions vary
        w = run.policy.snn.readout.weight  # type: ignore[union-attr]
        w.copy_(torch.randn(w.shape, generator=torch.Generator().manual_seed(2)))
    path, _ = export_nir(run, tmp_path / "policy.nir")
    net = import_from_nir(nir.read(path))
    reference, policy = NIRReference(path, "float32"), TorchPredictor(run)
    m = reference.manifest
    T = m.num_steps
    env = make_policy_env(reference.manifest, None, None)
    same = steps = 0
    actions, carried = set(), 0
    try:
        obs, _ = env.reset(seed=3)
        while steps < 120:
            raw = raw_clip(obs, m.obs_mean, m.obs_std, m.obs_clip)  # the manifest's clip
            logits = _imported_logits(net, raw, T, reset=True)
            np.testing.assert_allclose(logits, reference.readout(obs), atol=1e-5)
            action = policy.predict(obs)
            same += int(np.argmax(logits)) == action
            actions.add(action)
            again = _imported_logits(net, raw, T, reset=False)  # the state carried over
            carried += not np.allclose(again, logits, atol=1e-5)
            obs, _, terminated, truncated, _ = env.step(action)
            steps += 1
            if terminated or truncated:
                obs, _ = env.reset(seed=3 + steps)
    finally:
        env.close()
    assert len(actions) >= 2 and same == steps, (same, steps)
    assert carried > 0  # without the reset, the importer's neurons remember the last call
