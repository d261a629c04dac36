"""Post-training int8 quantisation of the ANN actor (Linear -> tanh or ReLU -> ... -> Linear), and the
integer forward pass that runs it: the int8 baseline of the energy report, measured on the
deployment's episodes (:mod:`snnkart.eval.ann_int8`) instead of assumed to drive as the float
policy does.

What is simulated, exactly (integers held in numpy int64 and kept inside the width named by
clipping or a bound checked when the network is made; the requantisation's product ``acc * M``
is a 64-bit intermediate; the float scales are fixed once, from calibration):

- **Scales, symmetric per tensor, zero point 0, int8 range ±127 (-128 unused).** Weights:
  ``s_w = max|W| / 127``. The input of each layer (the normalised observation, then each
  hidden layer's tanh output) and each hidden layer's pre-activation ``W x + b``: ``s = max|v|
  / 127`` over the calibration observations, ``v`` computed by the float network (float64).
- **Input (on the host, in float):** the frozen normalisation gives ``z`` (float32, as the
  torch policy sees it), sent as ``x0 = clip(rint(z / s_0), ±127)`` (int8).
- **Layer l:** ``W_q = clip(rint(W / s_w), ±127)`` (int8), ``b_q = rint(b / (s_l s_w))``
  (int32, the accumulator's scale), ``acc = W_q x_l + b_q`` accumulated in int32 (its bound
  ``127 * 127 * fan_in + max|b_q|`` is checked to fit when the network is made).
- **Requantisation (hidden layers):** ``a = clip((acc * M + 2**(k-1)) >> k, ±127)`` (int8),
  with ``M = rint(s_l s_w / s_a * 2**k)`` a 31-bit integer multiplier (``2**30 <= M < 2**31``)
  and ``k`` its shift: an integer multiply, an arithmetic right shift rounding half up, a
  saturation. No float arithmetic between layers.
- **tanh:** a 255-entry int8 table indexed by ``a``: ``x_{l+1} = clip(rint(tanh(a s_a) /
  s_{l+1}), ±127)`` (TFLite's int8 TANH is a table of the same kind).
- **ReLU (``ann.activation = "relu"``):** exact in integers, ``x_{l+1} = max(a, 0)`` with
  ``s_{l+1} = s_a``; ``s_a = max(relu(v)) / 127`` (negative pre-activations saturate at -127
  and become 0 either way, so the whole int8 range goes to the positive side).
- **Output:** discrete actions take the argmax of the int32 accumulator (its scale is positive,
  so it is the argmax of the logits; ties go to the first); continuous actions are the
  accumulator times ``s_L s_w`` in float on the host, clipped to [-1, 1] as the float policy's.

Not simulated: the observation normalisation and the input's rounding (float, on the host, as
the spiking deployment's host does); per-channel scales, zero points, int16 tables.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.contract.report_record import Int8LayerRecord
from snnkart.errors import CheckpointError

INT8_MAX = 127
"""Symmetric int8: values in [-127, 127] (zero point 0)."""
INT32_MAX = 2**31 - 1
MULTIPLIER_BITS = 31
"""The requantisation multiplier ``M`` is an integer in [2**30, 2**31)."""


@dataclass(frozen=True)
class Int8Layer:
    """One Linear layer in int8, with the requantisation and tanh table after it (hidden
    layers) or without (the output layer: ``table`` is None)."""

    weight: np.ndarray  # (out, in) int8
    bias: np.ndarray  # (out,) int32, scale in_scale * weight_scale
    in_scale: float  # s_l: float value of one unit of the layer's int8 input
    weight_scale: float  # s_w
    pre_scale: float | None  # s_a: one unit of the int8 pre-activation (hidden layers)
    multiplier: int  # M (0 for the output layer)
    shift: int  # k
    table: np.ndarray | None  # (255,) int8: tanh of pre-activation a at index a + 127
    activation: str = "tanh"  # hidden layers: "tanh" (by ``table``) or "relu" (max(a, 0))

    def accumulate(self, x: np.ndarray) -> np.ndarray:
        """``W_q x + b_q`` for int8 inputs ``x`` (batch, in): the int32 accumulator."""
        acc = np.asarray(x, np.int64) @ self.weight.astype(np.int64).T + self.bias.astype(np.int64)
        assert np.abs(acc).max(initial=0) <= INT32_MAX  # bounded when the layer was made
        return acc

    def requantise(self, acc: np.ndarray) -> np.ndarray:
        """The int8 pre-activation: ``clip((acc M + 2**(k-1)) >> k, ±127)``."""
        rounded = (acc * self.multiplier + (1 << (self.shift - 1))) >> self.shift
        return np.clip(rounded, -INT8_MAX, INT8_MAX)

    def activate(self, pre: np.ndarray) -> np.ndarray:
        """tanh by table, or ReLU exactly: the next layer's int8 input."""
        if self.activation == "relu":
            return np.maximum(pre, 0)
        assert self.table is not None
        return self.table[pre + INT8_MAX].astype(np.int64)


@dataclass(frozen=True)
class Int8Mlp:
    """An int8 MLP actor (see the module docstring for what it computes)."""

    layers: tuple[Int8Layer, ...]

    def quantise_input(self, z: np.ndarray) -> np.ndarray:
        """The host's int8 input for normalised observations ``z`` (batch, obs)."""
        scaled = np.rint(np.asarray(z, np.float64) / self.layers[0].in_scale)
        return np.clip(scaled, -INT8_MAX, INT8_MAX).astype(np.int64)

    def accumulator(self, z: np.ndarray) -> np.ndarray:
        """The output layer's int32 accumulator for normalised observations ``z``."""
        x = self.quantise_input(z)
        for layer in self.layers[:-1]:
            x = layer.activate(layer.requantise(layer.accumulate(x)))
        return self.layers[-1].accumulate(x)

    @property
    def out_scale(self) -> float:
        """The float value of one unit of the output accumulator."""
        last = self.layers[-1]
        return last.in_scale * last.weight_scale

    def act(self, z: np.ndarray, discrete: bool) -> np.ndarray:
        """Deterministic actions: argmax (discrete) or clipped means (continuous)."""
        acc = self.accumulator(z)
        if discrete:
            return acc.argmax(-1)
        return np.clip(acc * self.out_scale, -1.0, 1.0).astype(np.float32)

    def describe(self) -> list[Int8LayerRecord]:
        """The scales and integer widths per layer, for the report."""
        return [
            {
                "layer": i,
                "shape": list(q.weight.shape),
                "in_scale": q.in_scale,
                "weight_scale": q.weight_scale,
                "pre_scale": q.pre_scale,
                "multiplier": q.multiplier,
                "shift": q.shift,
                "max_abs_bias": int(np.abs(q.bias).max(initial=0)),
            }
            for i, q in enumerate(self.layers)
        ]


def symmetric_scale(values: np.ndarray) -> float:
    """``max|v| / 127`` (1.0 for an all-zero tensor, which any scale represents exactly)."""
    top = float(np.abs(np.asarray(values, np.float64)).max(initial=0.0))
    return top / INT8_MAX if top > 0 else 1.0


def to_int8(values: np.ndarray, scale: float) -> np.ndarray:
    """``clip(rint(v / scale), ±127)`` as int8."""
    q = np.clip(np.rint(np.asarray(values, np.float64) / scale), -INT8_MAX, INT8_MAX)
    return q.astype(np.int8)


def fixed_multiplier(ratio: float) -> tuple[int, int]:
    """``(M, k)`` with ``M / 2**k`` the closest to ``ratio`` and ``2**30 <= M < 2**31``."""
    if not 0 < ratio < 2 ** (MULTIPLIER_BITS - 2):
        raise ValueError(f"requantisation ratio {ratio!r} is outside (0, 2**29)")
    shift = MULTIPLIER_BITS - 1 - int(np.floor(np.log2(ratio)))
    m = int(np.rint(ratio * 2.0**shift))
    if m >= 2**MULTIPLIER_BITS:  # rounding reached the next power of two
        m, shift = m // 2, shift - 1
    return m, shift


def tanh_table(pre_scale: float, out_scale: float) -> np.ndarray:
    """The int8 tanh table: entry ``a + 127`` is ``clip(rint(tanh(a s_a) / s_out), ±127)``."""
    a = np.arange(-INT8_MAX, INT8_MAX + 1, dtype=np.float64)
    return to_int8(np.tanh(a * pre_scale), out_scale)


def quantise_mlp(
    params: list[tuple[np.ndarray, np.ndarray]], calibration: np.ndarray, activation: str = "tanh"
) -> Int8Mlp:
    """Quantise an MLP actor given as ``[(W, b), ...]`` (``activation``, tanh or relu, between
    layers) with activation scales calibrated on ``calibration``, normalised observations
    (n, obs) the float policy saw (see the module docstring for the rules)."""
    if activation not in ("tanh", "relu"):
        raise ValueError(f"activation {activation!r}: int8 quantisation takes tanh or relu")
    if len(calibration) == 0:
        raise ValueError("no calibration observations: record at least one episode")
    x = np.asarray(calibration, np.float64)
    in_scale = symmetric_scale(x)
    layers = []
    for i, (w, b) in enumerate(params):
        w, b = np.asarray(w, np.float64), np.asarray(b, np.float64)
        w_scale = symmetric_scale(w)
        w_q = to_int8(w, w_scale)
        b_q = np.rint(b / (in_scale * w_scale))
        bound = INT8_MAX * INT8_MAX * w.shape[1] + float(np.abs(b_q).max(initial=0.0))
        if bound > INT32_MAX:
            raise ValueError(f"layer {i}: the int32 accumulator could overflow ({bound:.3g})")
        pre = x @ w.T + b
        if i == len(params) - 1:
            layers.append(Int8Layer(w_q, b_q.astype(np.int32), in_scale, w_scale, None, 0, 0, None))
            break
        relu = activation == "relu"
        x = np.maximum(pre, 0.0) if relu else np.tanh(pre)
        pre_scale = symmetric_scale(x if relu else pre)
        out_scale = pre_scale if relu else symmetric_scale(x)
        m, k = fixed_multiplier(in_scale * w_scale / pre_scale)
        table = None if relu else tanh_table(pre_scale, out_scale)
        layers.append(
            Int8Layer(
                w_q, b_q.astype(np.int32), in_scale, w_scale, pre_scale, m, k, table, activation
            )
        )
        in_scale = out_scale
    return Int8Mlp(tuple(layers))


def actor_activation(actor: Any) -> str:
    """The hidden activation of an ANN actor, ``"tanh"`` or ``"relu"`` (of its second module;
    :func:`actor_params` checks that every hidden one is the same)."""
    import torch

    modules = list(actor)
    return "relu" if len(modules) > 1 and isinstance(modules[1], torch.nn.ReLU) else "tanh"


def actor_params(actor: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """The ``(W, b)`` of an ANN actor ``nn.Sequential(Linear, Tanh, ..., Linear)`` (or ReLU
    throughout), in float64; any other layout is refused, naming the module that does not fit."""
    import torch

    modules = list(actor)
    hidden = torch.nn.ReLU if actor_activation(actor) == "relu" else torch.nn.Tanh
    params = []
    for i, module in enumerate(modules):
        expected = torch.nn.Linear if i % 2 == 0 or i == len(modules) - 1 else hidden
        if not isinstance(module, expected):
            raise CheckpointError(
                f"the ANN actor's module {i} is {type(module).__name__}, expected "
                f"{expected.__name__}: int8 quantisation takes Linear -> Tanh (or ReLU) -> ... "
                "-> Linear"
            )
        if isinstance(module, torch.nn.Linear):
            w = module.weight.detach().double().numpy()
            b = (
                module.bias.detach().double().numpy()
                if module.bias is not None
                else np.zeros(w.shape[0])
            )
            params.append((w, b))
    return params
