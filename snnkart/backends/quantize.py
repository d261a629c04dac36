"""Post-training quantisation of a chain network to Lava's fixed-point (Loihi) LIF and Dense.

Lava's bit-accurate models (``lava/proc/lif/models.py: PyLifResetModelBitAcc``,
``lava/proc/dense/models.py: PyDenseModelBitAcc``) hold u and v in 24-bit integers, compare
``v > vth << 6``, add synaptic input as ``a_in << 6`` and decay by ``(4096 - d) / 4096`` with
truncation toward zero. The mapping, per spiking layer i with float parameters (W, b, beta, theta):

- Layer 0 is fed by the host (current encoding: ``c = W0 z + b0`` computed once per env step;
  rate encoding: once per SNN step). Its scale is ``S0 = VTH_HOST / theta0``; the host sends
  ``round(c * S0)`` clipped to +-(2**17 - 1), which is exact in spike terms because any
  current above ``theta`` fires every step and any negative current never fires.
- Layers i >= 1 are fed through a Dense of 8-bit mixed-sign weights; Lava drops the LSB of
  mixed-sign weights, so weights are rounded to even integers: ``S = 254 / max|W|``,
  ``w = 2 round(W S / 2)``. The threshold is ``vth = round(theta S)`` and the bias
  ``bias_mant * 2**bias_exp = round(b S 64)`` with the smallest ``bias_exp`` in 0..7 whose
  13-bit mantissa holds it.
- Decays: ``du = 4095`` (the current forgets everything each step, as snntorch's Leaky has no
  synaptic current) and ``dv = round((1 - beta) 4096)``; the effective beta is ``1 - dv/4096``.
  A CubaLIF (snntorch Synaptic) keeps its current: ``du = round((1 - alpha) 4096) - 1``, since
  Lava decays u by ``(4096 - du - 1) / 4096`` (its ``ds_offset`` of 1); the effective alpha is
  ``(4095 - du) / 4096``.
- A decaying current sums its inputs up to ``1 / (1 - alpha)`` times, so the largest input
  ``a_in`` is bounded by ``(2**17 - 1)(du + 1) / 4096`` to keep u inside 24 bits: the host
  clips its current there (and layer 0's threshold is at most half of it), and the weights of
  a Dense are scaled so that no neuron's summed input can pass it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.backends.network import ChainNetwork, SpikingLayer, UnsupportedGraphError

DECAY_UNITY = 4096
"""Lava/Loihi decays are 12-bit: the state is multiplied by (4096 - d) / 4096."""
ACT_SHIFT = 6
"""Synaptic input and the threshold are MSB-aligned by 6 bits in the 24-bit state."""
UV_MAX = 2**23
"""u and v are 24-bit: u wraps around at +-2**23, v saturates at +-(2**23 - 1)."""
VTH_MAX = 2**17 - 1
"""vth is a 17-bit unsigned integer."""
HOST_CURRENT_MAX = 2**17 - 1
"""|host current| limit so ``a_in << 6`` stays inside the 24-bit current."""
VTH_HOST = 4096
"""Integer threshold of the host-fed layer: the host current's resolution is theta / 4096."""
BIAS_MAX = 4095 * 2**7
"""Largest |bias_mant * 2**bias_exp| (13-bit signed mantissa, 3-bit exponent)."""
WEIGHT_MAX = 254
"""Largest even 8-bit mixed-sign weight (Lava truncates odd mixed-sign weights)."""


@dataclass(frozen=True)
class FixedLayer:
    """Integer parameters of one LIFReset population (and the Dense into it, if any)."""

    scale: float  # float value 1.0 of this layer's input current = `scale` integer units
    weight: np.ndarray | None  # (n, m) int64 even values in [-256, 254]; None for the host layer
    bias_mant: np.ndarray  # (n,) int64 13-bit
    bias_exp: int
    vth: int
    du: int
    dv: int
    input_max: int = HOST_CURRENT_MAX  # largest |a_in| that keeps u inside 24 bits
    recurrent: np.ndarray | None = None  # (n, n) int64 even: the recurrent Dense, same scale

    @property
    def effective_alpha(self) -> float:
        """The current's decay Lava computes: ``(4096 - du - 1) / 4096``."""
        return (DECAY_UNITY - self.du - 1) / DECAY_UNITY

    @property
    def effective_bias(self) -> np.ndarray:
        """The bias added to v each step, in v units (Lava's ``scale_bias``)."""
        return np.left_shift(self.bias_mant, self.bias_exp)


@dataclass(frozen=True)
class FixedPointNetwork:
    layers: tuple[FixedLayer, ...]

    def host_current(self, current: np.ndarray) -> np.ndarray:
        """Quantise the host's float current into layer 0's integer ``a_in``."""
        first = self.layers[0]
        scaled = np.rint(np.asarray(current, dtype=np.float64) * first.scale)
        return np.clip(scaled, -first.input_max, first.input_max).astype(np.int64)

    def describe(self) -> list[dict[str, Any]]:
        """A JSON-able summary of the quantisation, for the deploy report."""
        out = []
        for i, q in enumerate(self.layers):
            out.append(
                {
                    "layer": i,
                    "scale": q.scale,
                    "vth": q.vth,
                    "du": q.du,
                    "dv": q.dv,
                    "effective_beta": 1.0 - q.dv / DECAY_UNITY,
                    "bias_exp": q.bias_exp,
                    "weight_bits": None if q.weight is None else 8,
                    "max_abs_weight": None if q.weight is None else int(np.abs(q.weight).max()),
                }
            )
            if q.du != DECAY_UNITY - 1:  # a current that decays: a CubaLIF
                out[-1]["effective_alpha"] = q.effective_alpha
        return out


def uniform(values: np.ndarray, what: str, node: str) -> float:
    """The single value of a per-neuron vector that Lava needs to be uniform."""
    values = np.asarray(values)
    if values.size == 0 or np.ptp(values) > 0:
        raise UnsupportedGraphError(
            f"LIF node {node!r} has non-uniform {what}; Lava's LIF has one per population"
        )
    return float(values.reshape(-1)[0])


def lava_problems(chain: ChainNetwork) -> list[tuple[str, str]]:
    """Every (node, reason) that Lava's LIF and Dense cannot run; empty when all can."""
    problems = []
    if chain.input_scale is not None:
        problems.append(("Scale", "a Scale node after the input is not mapped to Lava yet"))
    for i, layer in enumerate(chain.layers):
        try:
            _check_layer(layer)
            if i > 0 and layer.cuba and np.any(layer.bias != 0):
                raise UnsupportedGraphError(
                    f"CubaLIF node {layer.neuron!r}: the bias of {layer.synapse!r} feeds its "
                    "decaying current (NIR), but Lava's LIF adds its bias to the voltage; it "
                    "would need an always-firing bias neuron (snnkart trains cuba policies "
                    "without these biases: snn.hidden_bias = false)"
                )
        except UnsupportedGraphError as exc:
            problems.append((layer.neuron, str(exc)))
    return problems


def _check_layer(layer: SpikingLayer) -> None:
    uniform(layer.beta, "decay (tau)", layer.neuron)
    theta = uniform(layer.threshold, "threshold", layer.neuron)
    if np.any(layer.v_reset != 0):
        raise UnsupportedGraphError(
            f"LIF node {layer.neuron!r} resets to v_reset != 0; Lava's LIF resets to zero "
            "(it would need a reset potential, which Lava's LIF does not have)"
        )
    if not layer.plain:
        raise UnsupportedGraphError(
            f"LIF node {layer.neuron!r} has r != tau/dt, v_leak != 0 or (CubaLIF) w_in != "
            "tau_syn/dt; the Lava mapping supports snntorch-style neurons (v = beta v + I): "
            "an input gain other than 1 or a leak potential would have to be folded into the "
            "weights and biases"
        )
    if layer.alpha is not None:
        alpha = uniform(layer.alpha, "current decay (tau_syn)", layer.neuron)
        if not 0.0 <= alpha < 1.0:
            raise UnsupportedGraphError(
                f"CubaLIF node {layer.neuron!r}: alpha {alpha} is outside [0, 1)"
            )
    if not 0.0 <= layer.beta[0] <= 1.0:  # 1: an IF neuron (Lava's LIF with dv = 0)
        raise UnsupportedGraphError(
            f"LIF node {layer.neuron!r}: beta {layer.beta[0]} is outside [0, 1]"
        )
    if theta <= 0:
        raise UnsupportedGraphError(f"LIF node {layer.neuron!r}: threshold must be > 0")


def check_lava_compatible(chain: ChainNetwork) -> None:
    """Refuse what Lava's LIF cannot run, naming the node and the reason."""
    problems = lava_problems(chain)
    if problems:
        raise UnsupportedGraphError(problems[0][1])


def current_decay(alpha: float | None) -> int:
    """Lava's ``du`` for a current decay ``alpha`` (None: no current state, ``du = 4095``)."""
    if alpha is None:
        return DECAY_UNITY - 1
    return int(np.clip(np.rint((1.0 - alpha) * DECAY_UNITY) - 1, 0, DECAY_UNITY - 1))


def quantize(chain: ChainNetwork) -> FixedPointNetwork:
    """Quantise ``chain`` (see the module docstring for the exact rules)."""
    check_lava_compatible(chain)
    layers = []
    for i, layer in enumerate(chain.layers):
        theta = float(layer.threshold[0])
        dv = int(np.clip(np.rint((1.0 - float(layer.beta[0])) * DECAY_UNITY), 0, DECAY_UNITY - 1))
        du = current_decay(None if layer.alpha is None else float(layer.alpha[0]))
        a_max = (HOST_CURRENT_MAX * (du + 1)) // DECAY_UNITY
        if i == 0:
            if layer.recurrent is not None:
                raise UnsupportedGraphError(
                    f"LIF node {layer.neuron!r} is fed by the host and has a recurrent synapse "
                    f"({layer.recurrent_node!r}); at the host current's scale (4096 / threshold) "
                    "its weights do not fit Lava's 8 bits: put recurrence on a later layer"
                )
            vth0 = min(VTH_HOST, a_max // 2)
            if vth0 < 1:
                raise UnsupportedGraphError(
                    f"CubaLIF node {layer.neuron!r}: its current decays too slowly (alpha "
                    f"{float(layer.alpha[0]) if layer.alpha is not None else 0:g}) for "
                    "Loihi's 24-bit current"
                )
            zeros = np.zeros(layer.size, np.int64)
            layers.append(FixedLayer(vth0 / theta, None, zeros, 0, vth0, du, dv, a_max))
            continue
        layers.append(_quantize_dense(layer, theta, du, dv, a_max))
    return FixedPointNetwork(tuple(layers))


def _quantize_dense(layer: SpikingLayer, theta: float, du: int, dv: int, a_max: int) -> FixedLayer:
    """A layer fed by a Dense: 8-bit weights, 17-bit threshold, 13-bit bias (module docstring).
    A recurrent synapse is quantised with the feed-forward one, at one scale: both Dense
    outputs add into the same current."""
    w = layer.weight.astype(np.float64)
    if layer.recurrent is not None:
        w = np.hstack([w, layer.recurrent.astype(np.float64)])
    wmax = float(np.abs(w).max())
    scale = WEIGHT_MAX / wmax if wmax > 0 else 1.0
    vth = int(np.rint(theta * scale))
    if vth > VTH_MAX:  # tiny weights against a large threshold: trade weight resolution
        scale = VTH_MAX / theta
    row_sum = float(np.abs(w).sum(axis=1).max())
    fan_in = w.shape[1]
    if row_sum * scale > a_max - fan_in:  # every input spiking must not overflow the current
        scale = (a_max - fan_in) / row_sum
    bmax = float(np.abs(layer.bias.astype(np.float64)).max(initial=0.0))
    if bmax * scale * 2**ACT_SHIFT > BIAS_MAX:  # a large bias: lower the scale to fit it
        scale = BIAS_MAX / (bmax * 2**ACT_SHIFT)
    vth = int(np.rint(theta * scale))
    if vth < 1:
        raise UnsupportedGraphError(
            f"LIF node {layer.neuron!r}: its bias ({bmax:g}) or summed weights are too large "
            f"against its threshold ({theta:g}) for Loihi's 13-bit bias, 17-bit threshold "
            "and 24-bit current"
        )
    weight = (2 * np.rint(w * scale / 2)).astype(np.int64)
    recurrent = None
    if layer.recurrent is not None:
        weight, recurrent = weight[:, : layer.weight.shape[1]], weight[:, layer.weight.shape[1] :]
    target = np.rint(layer.bias.astype(np.float64) * scale * 2**ACT_SHIFT)
    exp = 0
    while exp < 7 and np.abs(np.rint(target / 2**exp)).max(initial=0) > 4095:
        exp += 1
    mant = np.clip(np.rint(target / 2**exp), -4095, 4095).astype(np.int64)
    return FixedLayer(scale, weight, mant, exp, vth, du, dv, a_max, recurrent)
