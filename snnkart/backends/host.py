"""The host side of a deployed policy on a backend: observation -> the first layer's input
current, spike counts -> action.

Every backend (the numpy reference in each arithmetic, Lava float and Lava fixed) shares this
code, so the host never causes a difference between them; only the spiking layers differ. The
normalisation, rate encoding, readout and decoding are the contract's
(:mod:`snnkart.contract.encoding`); what is added here is the first layer's input current
``c = W1 z + b1`` (current encoding: computed once per env step and held for the T SNN steps;
rate encoding: ``c[t] = W1 x[t] + b1``) in the backend's arithmetic: float32 (torch order),
float64 (Lava float) or the quantised integer current (Lava fixed point).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import FixedPointNetwork
from snnkart.contract import encoding
from snnkart.contract.manifest import Manifest


def first_current(
    chain: ChainNetwork, x: np.ndarray, arithmetic: str, fixed: FixedPointNetwork | None = None
) -> np.ndarray:
    """The first layer's input current ``W1 x + b1`` for ``x`` ``[n_in]`` or ``[N, n_in]`` in
    ``arithmetic``: float32 in torch's order, float64 (Lava float) or the quantised integer
    current (Lava fixed point)."""
    return _FirstLayer(chain).current(x, arithmetic, fixed)


class _FirstLayer:
    """The first synapse's weights in float32 and float64, converted once."""

    def __init__(self, chain: ChainNetwork) -> None:
        first = chain.layers[0]
        self.w32, self.b32 = first.weight, first.bias
        self.w64, self.b64 = first.weight.astype(np.float64), first.bias.astype(np.float64)

    def current(
        self, x: np.ndarray, arithmetic: str, fixed: FixedPointNetwork | None
    ) -> np.ndarray:
        if arithmetic == "float32":
            return x @ self.w32.T + self.b32 if x.ndim == 2 else self.w32 @ x + self.b32
        x64 = x.astype(np.float64)
        current = x64 @ self.w64.T + self.b64 if x.ndim == 2 else self.w64 @ x64 + self.b64
        if arithmetic == "fixed":
            if fixed is None:
                raise ValueError("fixed arithmetic needs the quantised network")
            current = fixed.host_current(current)
        return current


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
        self.first = _FirstLayer(chain)
        self.readout_w = chain.readout_weight
        self.readout_b = chain.readout_bias
        self.rng = encoding.rate_generator(seed)
        self.last_input_spikes: np.ndarray | None = None

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        return encoding.normalise(obs, self.mean, self.std, self.manifest.obs_clip)

    def _input(self, obs: np.ndarray) -> np.ndarray:
        """The first layer's input: ``[n_in]`` (current or population encoding) or
        ``[T, n_in]`` spikes (rate)."""
        if self.manifest.encoding == "population":
            assert self.manifest.population is not None
            return encoding.population(obs, self.low, self.high, self.manifest.population)
        if self.manifest.encoding == "rate":
            p = encoding.rate_probabilities(obs, self.low, self.high)
            spikes = encoding.rate_spikes(self.rng, p, self.T)
            self.last_input_spikes = spikes
            return spikes
        z = self.normalise(obs)
        if self.chain.input_scale is not None:
            z = (z * self.chain.input_scale).astype(np.float32)
        return z

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """The first layer's input current for the T SNN steps, ``[T, n1]``, in this arithmetic."""
        current = self.first.current(self._input(obs), self.arithmetic, self.fixed)
        if current.ndim == 1:
            current = np.broadcast_to(current, (self.T, current.shape[0]))
        return np.ascontiguousarray(current)

    def readout(self, last_counts: np.ndarray) -> np.ndarray:
        """The readout vector (logits or action means) from the last layer's spike counts."""
        return encoding.readout(last_counts, self.T, self.readout_w, self.readout_b)

    def readout_spikes(self, last_spikes: np.ndarray) -> np.ndarray:
        """The readout vector from the last layer's spikes of the window ``[T, n]``: the rate
        readout, or an LI readout's membrane at the last step."""
        li = self.chain.readout_li
        if li is None or self.readout_w is None or self.readout_b is None:
            return self.readout(np.asarray(last_spikes).sum(axis=0))
        trace = encoding.leaky_readout(
            last_spikes, self.readout_w, self.readout_b, li.decay, li.gain, li.leak
        )
        return trace[-1]

    def decode(self, out: np.ndarray) -> Any:
        return encoding.decode(out, self.manifest.action_mode)
