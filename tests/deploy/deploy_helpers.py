"""What the deploy tests share: the tiny runs they train, how a run is made to spike more,
and how an export is copied."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import shutil
from pathlib import Path
from typing import Any

import nir
import numpy as np
import torch

from snnkart.contract.manifest import manifest_path
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.trained import LoadedRun

RUNS = {
    "steer": ("steer", "snn", "discrete"),
    "steer-continuous": ("steer", "snn", "continuous"),
    "steer-rate": ("steer", "snn", "discrete"),
    "steer-population": ("steer", "snn", "discrete"),
}
RUN_SETS = {
    "steer-rate": ["snn.encoding=rate"],  # input spikes drawn on the host (PCG64)
    "steer-population": ["snn.encoding=population"],  # Gaussian receptive fields on the host
}
TORCH_RUNS = ["steer", "steer-continuous"]
PARITY_STEPS = 300
TORCH_STEPS = 200
SUBPROCESS_ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "COLUMNS": "200", "NO_COLOR": "1"}


def excite(run: LoadedRun) -> LoadedRun:
    """Make layer 2 fire more and more variably, with a bias large enough to drive spikes in the
    Lava pipeline's fill rows, and the readout depend on it (parity must hold for any weights).
    The rate-encoded policy's layer-2 counts rise and fall together, so its readout rows are
    drawn at random (seeded) to turn their variation into different actions."""
    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    with torch.no_grad():
        policy.snn.fc2.bias.add_(0.5)
        policy.snn.fc2.weight.mul_(2.0)
        readout = policy.snn.readout.weight
        if policy.cfg.encoding == "rate":
            generator = torch.Generator().manual_seed(0)
            readout.copy_(0.5 * torch.randn(readout.shape, generator=generator))
        else:
            readout.mul_(30.0)
    return run


def copy_export(src: Path, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    shutil.copyfile(manifest_path(src), manifest_path(dst))
    return dst


DT = 1e-3


def snntorch_lif(n: int, tau: float, threshold: float) -> nir.LIF:
    """A LIF population as snntorch exports it: r = tau/dt (unit input gain), no leak, reset 0."""
    return nir.LIF(
        tau=np.full(n, tau),
        r=np.full(n, tau / DT),
        v_leak=np.zeros(n),
        v_threshold=np.full(n, threshold),
        v_reset=np.zeros(n),
    )


def nir_graph(nodes: dict[str, Any], edges: list[tuple[str, str]]) -> nir.NIRGraph:
    return nir.NIRGraph(nodes=nodes, edges=edges)


def plain_chain_graph(sizes: tuple[int, ...], n_in: int, seed: int) -> nir.NIRGraph:
    """A snntorch-style chain of ``len(sizes)`` LIF layers (one beta and threshold per layer)
    with a linear readout, built with the ``nir`` package as another library would."""
    rng = np.random.default_rng(seed)
    nodes: dict[str, Any] = {"in": nir.Input(input_type={"input": np.array([n_in])})}
    edges, prev, fan_in = [], "in", n_in
    for i, n in enumerate(sizes):
        gain = 1.0 if i == 0 else 2.5 / np.sqrt(fan_in)
        nodes[f"fc{i}"] = nir.Affine(
            weight=rng.normal(0.0, gain, (n, fan_in)).astype(np.float32),
            bias=(rng.normal(0.1, 0.2, n) if i else np.zeros(n)).astype(np.float32),
        )  # fmt: skip
        nodes[f"lif{i}"] = snntorch_lif(
            n, tau=[4e-3, 8e-3, 2.5e-3][i], threshold=[1.0, 0.6, 0.8][i]
        )
        edges += [(prev, f"fc{i}"), (f"fc{i}", f"lif{i}")]
        prev, fan_in = f"lif{i}", n
    nodes["ro"] = nir.Affine(
        weight=rng.normal(0.0, 1.0, (3, fan_in)).astype(np.float32), bias=np.zeros(3, np.float32)
    )
    nodes["out"] = nir.Output(output_type={"output": np.array([3])})
    edges += [(prev, "ro"), ("ro", "out")]
    return nir_graph(nodes, edges)
