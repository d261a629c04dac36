"""The host side of a deployed policy: observation -> input current, spike counts -> action.

Every backend (the numpy reference in each arithmetic, Lava float and Lava fixed) shares this
code, so the host never causes a difference between them; only the spiking layers differ.

- Normalisation: ``z = clip((obs - mean) / std, +-clip)`` in float64, cast to float32, with
  the statistics frozen in the manifest (as the torch policy at evaluation).
- Encoding: ``current``: the first layer's input current ``c = W1 z + b1``, computed once per
  env step and held for the T SNN steps. ``rate``: Bernoulli input spikes
  ``x[t] = u[t] < p`` with ``p = clip((obs - low) / (high - low), 0, 1)`` (float32) and
  ``u = rng.random((T, n_in))`` from ``numpy.random.Generator(PCG64(seed))``, seeded once per
  predictor with its seed and drawn once per env step; then ``c[t] = W1 x[t] + b1``.
  The arithmetic of ``c`` follows the backend: float32 (torch order), float64 (Lava float) or
  the quantised integer current (Lava fixed point).
- Readout: ``out = W_r (n / T) + b_r`` in float32 from the last layer's spike counts ``n``;
  discrete actions take the argmax, continuous ones are clipped to [-1, 1].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import FixedPointNetwork
from snnkart.export.manifest import Manifest

RATE_RNG = (
    "rng = numpy.random.Generator(numpy.random.PCG64(seed)), seed = the predictor's seed "
    "(eval/deploy --seed), created once; per env step u = rng.random((T, n_in)) and "
    "x[t] = u[t] < clip((obs - obs_low) / (obs_high - obs_low), 0, 1) in float32"
)


def rate_probabilities(obs: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Spike probabilities of the rate encoding (float32, as the torch policy computes them)."""
    raw = np.asarray(obs, dtype=np.float32)
    p = (raw - low.astype(np.float32)) / (high.astype(np.float32) - low.astype(np.float32))
    return np.clip(p, 0.0, 1.0)


def rate_spikes(rng: np.random.Generator, p: np.ndarray, num_steps: int) -> np.ndarray:
    """Input spike trains ``[T, n_in]`` (float32 0/1) for probabilities ``p``."""
    return (rng.random((num_steps, p.shape[-1])) < p).astype(np.float32)


class HostCodec:
    """Encodes observations and decodes spike counts for one chain, manifest and arithmetic."""

    def __init__(
        self,
        chain: ChainNetwork,
        manifest: Manifest,
        arithmetic: str,
        fixed: FixedPointNetwork | None = None,
        seed: int = 0,
    ) -> None:
        if arithmetic not in ("float32", "float64", "fixed"):
            raise ValueError(f"unknown arithmetic {arithmetic!r}")
        if arithmetic == "fixed" and fixed is None:
            raise ValueError("fixed arithmetic needs the quantised network")
        self.chain = chain
        self.manifest = manifest
        self.arithmetic = arithmetic
        self.fixed = fixed
        self.T = manifest.num_steps
        self.mean = np.asarray(manifest.obs_mean)
        self.std = np.asarray(manifest.obs_std)
        self.low = np.asarray(manifest.obs_low)
        self.high = np.asarray(manifest.obs_high)
        first = chain.layers[0]
        self.w32, self.b32 = first.weight, first.bias
        self.w64, self.b64 = first.weight.astype(np.float64), first.bias.astype(np.float64)
        self.readout_w = chain.readout_weight
        self.readout_b = chain.readout_bias
        self.rng = np.random.Generator(np.random.PCG64(seed))
        self.last_input_spikes: np.ndarray | None = None

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        z = (np.asarray(obs, dtype=np.float64) - self.mean) / self.std
        return np.clip(z, -self.manifest.obs_clip, self.manifest.obs_clip).astype(np.float32)

    def _input(self, obs: np.ndarray) -> np.ndarray:
        """The first layer's input: ``[n_in]`` (current encoding) or ``[T, n_in]`` spikes."""
        if self.manifest.encoding == "rate":
            spikes = rate_spikes(self.rng, rate_probabilities(obs, self.low, self.high), self.T)
            self.last_input_spikes = spikes
            return spikes
        z = self.normalise(obs)
        if self.chain.input_scale is not None:
            z = (z * self.chain.input_scale).astype(np.float32)
        return z

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """The first layer's input current for the T SNN steps, ``[T, n1]``, in this arithmetic."""
        x = self._input(obs)
        if self.arithmetic == "float32":
            current = x @ self.w32.T + self.b32 if x.ndim == 2 else self.w32 @ x + self.b32
        else:
            x64 = x.astype(np.float64)
            current = x64 @ self.w64.T + self.b64 if x.ndim == 2 else self.w64 @ x64 + self.b64
            if self.arithmetic == "fixed":
                assert self.fixed is not None
                current = self.fixed.host_current(current)
        if current.ndim == 1:
            current = np.broadcast_to(current, (self.T, current.shape[0]))
        return np.ascontiguousarray(current)

    def readout(self, last_counts: np.ndarray) -> np.ndarray:
        """The readout vector (logits or action means) from the last layer's spike counts."""
        rates = np.asarray(last_counts, dtype=np.float32) / np.float32(self.T)
        if self.readout_w is None or self.readout_b is None:
            return rates
        return self.readout_w @ rates + self.readout_b

    def decode(self, out: np.ndarray) -> Any:
        if self.manifest.action_mode == "discrete":
            return int(np.argmax(out))
        return np.clip(out, -1.0, 1.0).astype(np.float32)
