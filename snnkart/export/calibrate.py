"""Calibrating a sigma-delta policy's message thresholds on recorded observations.

1. **Record.** The zero-threshold fixed-point chain (:mod:`snnkart.backends.sigma_delta`, the
   network the chip runs, exactly the quantised ReLU network) drives ``episodes`` seeded
   episodes closed loop, each observation held for ``block.rows`` Lava steps (the ``held``
   schedule), one chain for all episodes in order (state persists, as on the chip). Kept: each
   step's input integers and action, each layer's mean activation and the largest value every
   layer's state reached (the bits it needs).
2. **Scale.** Thresholds are ``f`` times a per-layer statistic, the layer's mean activation in
   its integer units over the recorded steps (the input Delta: the mean ``|input integer|``),
   rounded to integers.
3. **Search.** ``f`` doubles from ``1/64`` while the chain with those thresholds, run open loop
   over the recorded episodes in order, still takes the recorded action on at least ``target``
   of the steps (discrete: the same argmax; continuous: every component within
   :data:`CONTINUOUS_TOLERANCE`); then bisection between the last ``f`` that passed and the
   first that failed. The share is not strictly monotone in ``f``: the result is the largest
   passing ``f`` this search found, and the smallest failing one is recorded beside it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from snnkart.backends.sigma_delta import (
    SigmaDeltaChain,
    input_integers,
    readout_value,
    spec_from_block,
)
from snnkart.contract.encoding import decode
from snnkart.contract.sigma_delta import SigmaDeltaBlock, SigmaDeltaLayer

CONTINUOUS_TOLERANCE = 0.05
"""Continuous actions: the largest change of any component (actions in ``[-1, 1]``) that still
counts as the same action."""
F_START, F_MAX, BISECTIONS = 1.0 / 64.0, 64.0, 6
"""The threshold factor search: first factor, largest factor tried, bisection steps."""


@dataclass
class Recording:
    """What the zero-threshold chain saw and did: per episode ``[steps, n_in]`` input integers
    and ``[steps, n_out]`` readouts, per layer (input, hidden...) the mean activation, per
    state (input, hidden..., readout) the largest magnitude."""

    inputs: list[np.ndarray] = field(default_factory=list)
    outputs: list[np.ndarray] = field(default_factory=list)
    activation_mean: list[float] = field(default_factory=list)
    state_max: list[int] = field(default_factory=list)

    @property
    def steps(self) -> int:
        return sum(len(x) for x in self.inputs)


@dataclass(frozen=True)
class AffineLayers:
    """A sigma-delta policy's affine layers as exported (float32, hidden then readout)."""

    weights: list[np.ndarray]
    biases: list[np.ndarray]


def thresholds(block: SigmaDeltaBlock, factor: float, means: list[float]) -> SigmaDeltaBlock:
    """``block`` with ``vth_in = round(f means[0])`` and ``vth_l = round(f means[l])``."""
    vth = [round(factor * m) for m in means]
    layers = tuple(replace(la, vth=v) for la, v in zip(block.layers, vth[1:], strict=True))
    return replace(block, layers=layers, vth_in=vth[0])


def _held(chain: SigmaDeltaChain, block: SigmaDeltaBlock, q: np.ndarray) -> np.ndarray:
    """The readout Sigma after holding ``q`` for ``block.rows`` Lava steps."""
    for _ in range(block.rows):
        sigma = chain.step(q)
    return sigma


def record(
    block: SigmaDeltaBlock,
    net: AffineLayers,
    env: Any,
    normalise: Callable[[np.ndarray], np.ndarray],
    action_mode: str,
    episodes: int,
    seed: int,
) -> Recording:
    """Step 1 (module docstring): ``normalise`` maps an env observation to ``z``."""
    zero = thresholds(block, 0.0, [0.0] * (len(block.layers) + 1))
    chain = SigmaDeltaChain(spec_from_block(zero, net.weights, net.biases, "fixed"))
    rec, sums, peaks = Recording(), np.zeros(len(block.layers) + 1), np.zeros(block.depth + 1)
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        ins, outs = [], []
        while True:
            q = input_integers(zero, normalise(obs))
            sigma = _held(chain, zero, q)
            out = readout_value(zero, sigma, net.biases[-1], "fixed")
            acts = [q, *(e.act for e in chain.enc[1:])]
            sums += [np.abs(a).mean() for a in acts]
            states = [
                np.abs(q).max(),
                *(np.abs(np.r_[e.sigma, e.act]).max() for e in chain.enc[1:]),
            ]
            peaks = np.maximum(peaks, [*states, np.abs(sigma).max()])
            ins.append(q)
            outs.append(out)
            obs, _, terminated, truncated, _ = env.step(decode(out, action_mode))
            if terminated or truncated:
                break
        rec.inputs.append(np.stack(ins))
        rec.outputs.append(np.stack(outs))
    rec.activation_mean = [float(s / rec.steps) for s in sums]
    rec.state_max = [int(p) for p in peaks]
    return rec


def same_actions(a: np.ndarray, b: np.ndarray, action_mode: str) -> np.ndarray:
    """Per row: ``a`` and ``b`` (readouts ``[N, n_out]``) give the same action."""
    if action_mode == "discrete":
        return np.argmax(a, axis=1) == np.argmax(b, axis=1)
    gap = np.abs(np.clip(a, -1.0, 1.0) - np.clip(b, -1.0, 1.0)).max(axis=1)
    return gap <= CONTINUOUS_TOLERANCE


def agreement(block: SigmaDeltaBlock, net: AffineLayers, rec: Recording, action_mode: str) -> float:
    """The share of recorded steps on which ``block``'s chain, run over the recorded episodes
    in order from zero state (state persisting), takes the recorded action."""
    chain = SigmaDeltaChain(spec_from_block(block, net.weights, net.biases, "fixed"))
    same = 0
    for ins, outs in zip(rec.inputs, rec.outputs, strict=True):
        sig = np.stack([_held(chain, block, q) for q in ins])
        got = np.stack([readout_value(block, s, net.biases[-1], "fixed") for s in sig])
        same += int(same_actions(got, outs, action_mode).sum())
    return same / rec.steps


def search(passes: Callable[[float], float], target: float) -> tuple[float, float, float | None]:
    """Step 3: ``(f, its share, the smallest failing f tried or None)`` for ``passes(f)``, the
    share of unchanged actions at factor ``f`` (``f = 0``: 1.0 by construction)."""
    lo, lo_share, hi = 0.0, 1.0, None
    f = F_START
    while f <= F_MAX:
        share = passes(f)
        if share < target:
            hi = f
            break
        lo, lo_share, f = f, share, f * 2
    if hi is None:
        return lo, lo_share, None
    for _ in range(BISECTIONS):
        mid = (lo + hi) / 2
        share = passes(mid)
        if share >= target:
            lo, lo_share = mid, share
        else:
            hi = mid
    return lo, lo_share, hi


def calibrate(
    block: SigmaDeltaBlock,
    net: AffineLayers,
    env: Any,
    normalise: Callable[[np.ndarray], np.ndarray],
    action_mode: str,
    target: float,
    episodes: int,
    seed: int,
) -> SigmaDeltaBlock:
    """``block`` with calibrated thresholds and its ``calibration`` record (module docstring)."""
    rec = record(block, net, env, normalise, action_mode, episodes, seed)
    means = rec.activation_mean

    def share(f: float) -> float:
        return agreement(thresholds(block, f, means), net, rec, action_mode)

    f, fraction, rejected = search(share, target)
    bits = [int(m).bit_length() + 1 for m in rec.state_max]  # + the sign bit
    calibration = {
        "target": target,
        "fraction": fraction,
        "steps": rec.steps,
        "episodes": episodes,
        "seed": seed,
        "tolerance": None if action_mode == "discrete" else CONTINUOUS_TOLERANCE,
        "f": f,
        "f_rejected": rejected,
        "statistic": "mean activation per layer (integer units) over the recorded steps",
        "activation_mean": means,
        "state_bits": bits,
        "state_bits_layers": ["input", *_names(block.layers), "readout"],
        "over_24_bits": max(bits) > 24,
    }
    return replace(thresholds(block, f, means), calibration=calibration)


def _names(layers: tuple[SigmaDeltaLayer, ...]) -> list[str]:
    return [la.node for la in layers]
