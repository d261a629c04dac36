"""A small numpy executor of the exported NIR policy: the oracle the other backends are checked
against. It reads only the ``.nir`` file and its manifest, never training code.

Sharp edges (what it does not do yet): only the graph snnkart exports (Input -> Affine -> LIF ->
Affine -> LIF -> Affine -> Output) with the ``current`` encoding runs; ``mode="float32"``
follows torch's order of operations (per SNN step ``U = beta * U + I``, spike if
``U - theta > 0``, reset to 0). The float64 Lava-order and the bit-accurate fixed-point modes
arrive with the Lava backend.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.export.manifest import Manifest, ManifestError, manifest_path

REFERENCE_MODES = ("float32",)


class NIRFileError(ValueError):
    """A NIR file is missing, unreadable or does not match its manifest."""


@dataclass
class SpikeCounts:
    """Per layer: spikes, synaptic operations (spikes x fan-out) and neuron updates."""

    spikes: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    synops: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    neuron_updates: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    env_steps: int = 0


def load_nir(path: str | Path) -> tuple[Any, Manifest]:
    """Read a NIR graph and its manifest, with clear errors for missing or broken files."""
    import nir

    path = Path(path)
    if not path.is_file():
        raise NIRFileError(f"no NIR file at {path}; create one with `snnkart export --nir RUN`")
    manifest = Manifest.read(manifest_path(path))
    try:
        graph = nir.read(path)
    except Exception as exc:  # h5py raises several types for truncated or foreign files
        raise NIRFileError(
            f"{path}: not a readable NIR file ({type(exc).__name__}: {exc})"
        ) from exc
    return graph, manifest


def _check_lif(source: Any, node: Any, layer: Any, size: int, dt: float) -> None:
    """The graph's LIF node must be the manifest's layer: uniform, reset to 0, same values."""
    tau = np.asarray(node.tau, dtype=np.float64)
    thr = np.asarray(node.v_threshold, dtype=np.float64)
    if tau.shape != (size,) or layer.size != size:
        raise NIRFileError(
            f"{source}: LIF node {layer.node} has {tau.shape} neurons, expected {size}"
        )
    if not np.all(np.asarray(node.v_reset) == 0):
        raise NIRFileError(f"{source}: LIF node {layer.node} does not reset to 0")
    beta = 1.0 - dt / tau
    if np.ptp(beta) > 1e-6 or np.ptp(thr) > 0:
        raise NIRFileError(f"{source}: LIF node {layer.node} has non-uniform decay or threshold")
    if abs(beta[0] - layer.beta) > 1e-6 or thr[0] != layer.threshold:
        raise NIRFileError(
            f"{source}: LIF node {layer.node} (beta {beta[0]:.6f}, threshold {thr[0]}) does not "
            f"match the manifest (beta {layer.beta:.6f}, threshold {layer.threshold})"
        )


class NIRReference:
    """Predictor running the NIR graph in numpy; counts spikes per layer per logical step."""

    def __init__(self, nir_path: str | Path, mode: str = "float32") -> None:
        if mode not in REFERENCE_MODES:
            raise ValueError(f"unknown mode {mode!r}; choose one of {', '.join(REFERENCE_MODES)}")
        graph, self.manifest = load_nir(nir_path)
        m = self.manifest
        if m.encoding != "current":
            raise ManifestError(f"{nir_path}: the reference runs the current encoding only")
        nodes = graph.nodes
        try:
            fc1, lif1, fc2, lif2, out = (nodes[k] for k in ("0", "1", "2", "3", "4"))
        except KeyError as exc:
            raise NIRFileError(
                f"{nir_path}: node {exc} missing; not an snnkart policy graph"
            ) from exc
        f32 = np.float32
        self.w = [np.asarray(n.weight, f32) for n in (fc1, fc2, out)]
        self.b = [np.asarray(n.bias, f32) for n in (fc1, fc2, out)]
        for arr in (*self.w, *self.b):
            if not np.isfinite(arr).all():
                raise NIRFileError(f"{nir_path}: NaN or infinite weights")
        if self.w[0].shape[1] != m.obs_dim:
            raise NIRFileError(
                f"{nir_path}: the graph takes {self.w[0].shape[1]} inputs but the manifest's "
                f"observation has {m.obs_dim}"
            )
        for lif, layer, fc in ((lif1, m.layers[0], fc1), (lif2, m.layers[1], fc2)):
            _check_lif(nir_path, lif, layer, fc.weight.shape[0], m.nir_dt)
        self.beta = [f32(layer.beta) for layer in m.layers]
        self.threshold = [f32(layer.threshold) for layer in m.layers]
        self.mean = np.asarray(m.obs_mean)
        self.std = np.asarray(m.obs_std)
        self.T = m.num_steps
        self.counts = SpikeCounts()

    def reset(self) -> None:
        pass

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / self.std
        return np.clip(z, -self.manifest.obs_clip, self.manifest.obs_clip).astype(np.float32)

    def readout(self, obs: np.ndarray) -> np.ndarray:
        """The readout vector (logits or action means) for one observation."""
        z = self.normalise(obs)
        current1 = self.w[0] @ z + self.b[0]
        u1 = np.zeros_like(current1)
        u2 = np.zeros(self.w[1].shape[0], dtype=np.float32)
        total2 = np.zeros_like(u2)
        c = self.counts
        for _ in range(self.T):
            u1 = self.beta[0] * u1 + current1
            s1 = u1 - self.threshold[0] > 0
            u1[s1] = 0.0
            u2 = self.beta[1] * u2 + (self.w[1] @ s1.astype(np.float32) + self.b[1])
            s2 = u2 - self.threshold[1] > 0
            u2[s2] = 0.0
            total2 += s2
            n1, n2 = int(s1.sum()), int(s2.sum())
            c.spikes += (n1, n2)
            c.synops += (n1 * self.w[1].shape[0], n2 * self.w[2].shape[0])
            c.neuron_updates += (u1.size, u2.size)
        c.env_steps += 1
        return self.w[2] @ (total2 / np.float32(self.T)) + self.b[2]

    def predict(self, obs: np.ndarray) -> Any:
        out = self.readout(obs)
        if self.manifest.action_mode == "discrete":
            return int(np.argmax(out))
        return np.clip(out, -1.0, 1.0).astype(np.float32)
