"""The host side of a policy, written once for training, export and every backend.

- Normalisation: ``z = clip((obs - mean) / std, +-clip)`` in float64, cast to float32, with
  ``std = sqrt(var + 1e-8)`` (:func:`obs_std`); training normalises with its running
  statistics, a deployed policy with the ones frozen in its manifest.
- Rate encoding: Bernoulli input spikes ``x[t] = u[t] < p`` with
  ``p = clip((obs - low) / (high - low), 0, 1)`` (float32) and ``u = rng.random((T, n_in))``
  from ``numpy.random.Generator(PCG64(seed))``, seeded once per predictor and drawn once per
  env step (:data:`RATE_RNG`, recorded in the manifest).
- Population encoding: every observation value, scaled to [0, 1] as for the rate encoding,
  drives ``P`` neurons with Gaussian receptive fields centred at ``j / (P - 1)`` with width
  ``1 / (P - 1)``: ``a[i P + j] = exp(-((x01[i] - j / (P - 1)) (P - 1))^2 / 2)`` in float32
  (:func:`population`); ``a`` is the first layer's input, held for the T steps like the
  current encoding's ``z``.
- Readout: ``out = W_r (n / T) + b_r`` in float32 from the last layer's spike counts ``n``;
  discrete actions take the argmax, continuous ones are clipped to [-1, 1].
"""

from __future__ import annotations

from typing import Any

import numpy as np

OBS_EPS = 1e-8
"""Added to the variance before the square root of the observation normaliser."""

RATE_RNG = (
    "rng = numpy.random.Generator(numpy.random.PCG64(seed)), seed = the predictor's seed "
    "(eval/deploy --seed), created once; per env step u = rng.random((T, n_in)) and "
    "x[t] = u[t] < clip((obs - obs_low) / (obs_high - obs_low), 0, 1) in float32"
)


def obs_std(var: np.ndarray) -> np.ndarray:
    """The normaliser's divisor for observation variances ``var``."""
    return np.sqrt(np.asarray(var, dtype=np.float64) + OBS_EPS)


def normalise(obs: np.ndarray, mean: np.ndarray, std: np.ndarray, clip: float) -> np.ndarray:
    """``clip((obs - mean) / std, +-clip)`` in float64, as float32."""
    z = (np.asarray(obs, dtype=np.float64) - mean) / std
    return np.clip(z, -clip, clip).astype(np.float32)


def rate_generator(seed: int) -> np.random.Generator:
    """The rate encoding's generator of a predictor with this seed (:data:`RATE_RNG`)."""
    return np.random.Generator(np.random.PCG64(seed))


def rate_probabilities(obs: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Spike probabilities of the rate encoding (float32, as the torch policy computes them)."""
    raw = np.asarray(obs, dtype=np.float32)
    p = (raw - low.astype(np.float32)) / (high.astype(np.float32) - low.astype(np.float32))
    return np.clip(p, 0.0, 1.0)


def rate_spikes(rng: np.random.Generator, p: np.ndarray, num_steps: int) -> np.ndarray:
    """Input spike trains ``[T, n_in]`` (float32 0/1) for probabilities ``p``."""
    return (rng.random((num_steps, p.shape[-1])) < p).astype(np.float32)


def population_centres(size: int) -> np.ndarray:
    """The receptive fields' centres ``j / (size - 1)`` (float32), for every side."""
    return (np.arange(size, dtype=np.float32) / np.float32(size - 1)).astype(np.float32)


def population(obs: np.ndarray, low: np.ndarray, high: np.ndarray, size: int) -> np.ndarray:
    """The population encoding's input ``[..., n_obs * size]`` (float32; see the module).
    The torch policy computes the same operations in the same order; its ``exp`` may differ
    from numpy's in the last bit."""
    x = rate_probabilities(obs, low, high)
    d = (x[..., :, None] - population_centres(size)) * np.float32(size - 1)
    a = np.exp(np.float32(-0.5) * d * d)
    return a.reshape(*x.shape[:-1], -1).astype(np.float32)


def readout(
    last_counts: np.ndarray, num_steps: int, weight: np.ndarray | None, bias: np.ndarray | None
) -> np.ndarray:
    """The readout vector (logits or action means) from the last layer's spike counts; the
    mean rates themselves when the graph has no readout layer."""
    rates = np.asarray(last_counts, dtype=np.float32) / np.float32(num_steps)
    if weight is None or bias is None:
        return rates
    return weight @ rates + bias


def leaky_readout(
    last_spikes: np.ndarray,
    weight: np.ndarray,
    bias: np.ndarray,
    decay: np.ndarray,
    gain: np.ndarray,
    leak: np.ndarray,
) -> np.ndarray:
    """An LI readout's membrane at every step, ``[T, n_out]`` float32, from the last layer's
    spikes ``[T, n]``: ``v <- decay v + gain (W s[t] + b) + leak`` from ``v = 0``."""
    f32 = np.float32
    w, b = weight.astype(f32), bias.astype(f32)
    d, g, k = decay.astype(f32), gain.astype(f32), leak.astype(f32)
    v = np.zeros(w.shape[0], dtype=f32)
    out = np.zeros((last_spikes.shape[0], w.shape[0]), dtype=f32)
    for t, s in enumerate(np.asarray(last_spikes, dtype=f32)):
        v = d * v + g * (w @ s + b) + k
        out[t] = v
    return out


def decode(out: np.ndarray, action_mode: str) -> Any:
    """The env action: argmax (discrete) or the readout clipped to [-1, 1] (continuous)."""
    if action_mode == "discrete":
        return int(np.argmax(out))
    return np.clip(out, -1.0, 1.0).astype(np.float32)
