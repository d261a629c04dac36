"""Numpy reference of Lava 0.10's sigma-delta chain: the arithmetic of ``lava.proc.sdn``
(Delta, SigmaDelta, Sigma) and ``lava.proc.dense`` with graded messages, step for step.

Chain (L hidden layers, L + 1 Dense synapses, pipeline delay L + 1 steps)::

    obs -> Delta -> Dense_1 -> SigmaDelta_1(ReLU) -> ... -> Dense_{L+1} -> Sigma -> readout

Per Lava step, in the order Lava's process models compute it (docs/sigma-delta.md):

- Delta (input encoder): ``a = x << (spike_exp + state_exp)`` (fixed), ``d = a - act + residue``,
  ``s = d if |d| >= vth else 0``, ``residue = d - s``, ``act = a``, message ``s >> state_exp``.
- Dense: sends the buffer filled last step, then ``buf = (W @ s_in) << weight_exp`` (a negative
  exponent is an arithmetic right shift): every Dense delays by one step.
- SigmaDelta: ``sigma += a_in``; ``act_new = relu(sigma + bias)``; the same delta encoder as
  Delta on ``act_new``; message ``s >> state_exp``. ``vth`` and ``bias`` are given in message
  units and scaled by ``2 ** (spike_exp + state_exp)`` as the Lava process does at build time.
- Sigma (readout): ``sigma += a_in``.

A message is a non-zero graded value leaving a neuron; each carries ``num_message_bits``.

Sharp edges: only ReLU activation; weights in fixed point go through Lava's own clip and
truncation (8 bits, mixed sign drops the least significant bit), done once at construction;
Lava's Python models do not saturate ``sigma``/``act`` at their 24-bit precision and neither
does this reference; the right shift of a message (``state_exp > 0``) and of a Dense
(``weight_exp < 0``) floor every delta on its own, so the chain then no longer equals the
quantised ReLU network (it does exactly with both at zero and every threshold at zero).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from snnkart.backends.base import Arithmetic
from snnkart.contract.sigma_delta import SigmaDeltaBlock
from snnkart.errors import DeployError

WEIGHT_BITS = 8
"""Lava's Dense fixed-point weight width (``num_weight_bits`` default, ``clip_weights`` bits)."""


def lava_fixed_weights(weights: np.ndarray) -> np.ndarray:
    """The integer weights Lava's fixed-point Dense really uses: ``clip_weights`` then
    ``truncate_weights`` (lava/utils/weightutils.py) with 8 bits and the sign mode of the matrix."""
    w = np.asarray(weights).astype(np.int64)
    if np.min(w) >= 0:
        return np.clip(w, 0, 2**WEIGHT_BITS - 1)
    if np.max(w) <= 0:
        return -np.clip(-w, 0, 2**WEIGHT_BITS - 1)
    w = np.clip(w, -(2**WEIGHT_BITS), 2**WEIGHT_BITS - 1)
    return (w >> 1) << 1


def _shift(x: np.ndarray, exp: int) -> np.ndarray:
    """``x * 2**exp`` as Lava's fixed point does it: left shift, or arithmetic right shift."""
    return np.left_shift(x, exp) if exp > 0 else np.right_shift(x, -exp)


@dataclass(frozen=True)
class SigmaDeltaSpec:
    """A sigma-delta chain: ``weights[i]`` is Dense i ``[n_out, n_in]`` (the last one is the
    readout), ``biases[i]`` and ``vth[i]`` belong to SigmaDelta i (message units); ``vth_in`` is
    the input Delta's threshold. Fixed point wants integer weights, biases and thresholds."""

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    vth: tuple[float, ...]
    arithmetic: Arithmetic = "fixed"
    vth_in: float = 0
    weight_exp: int = 0
    spike_exp: int = 0
    state_exp: int = 0
    cum_error: bool = False
    num_message_bits: int = 8

    def __post_init__(self) -> None:
        if self.arithmetic == "float32":
            raise DeployError(
                "sigma-delta chain: Lava's floating_pt models compute in float64; use "
                "arithmetic 'float64' or 'fixed'"
            )
        if len(self.biases) != len(self.weights) - 1 or len(self.vth) != len(self.biases):
            raise DeployError(
                f"sigma-delta chain has {len(self.weights)} Dense layers, {len(self.biases)} "
                f"biases and {len(self.vth)} thresholds: give one bias and one threshold per "
                "hidden layer (Dense layers - 1)"
            )
        for i in range(1, len(self.weights)):
            if self.weights[i].shape[1] != self.weights[i - 1].shape[0]:
                raise DeployError(
                    f"Dense {i} takes {self.weights[i].shape[1]} inputs but layer {i - 1} has "
                    f"{self.weights[i - 1].shape[0]} neurons: fix the weight shapes"
                )

    @property
    def fixed(self) -> bool:
        return self.arithmetic == "fixed"

    @property
    def delay(self) -> int:
        """Lava steps from an observation to the readout that depends on it (one per Dense)."""
        return len(self.weights)


@dataclass
class _Encoder:
    """Delta-encoder state of one layer (Lava's ``act``, ``residue``, ``error``)."""

    act: np.ndarray
    residue: np.ndarray
    error: np.ndarray
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))


class SigmaDeltaChain:
    """Steps a :class:`SigmaDeltaSpec` one Lava step per call; state persists until ``reset``.

    ``step(x)`` returns the readout Sigma's value after this step (``[n_out]``), appends this
    step's per-layer message counts (input Delta first, then each SigmaDelta) to ``messages``
    and keeps the values sent in ``sent`` (one array per sending layer, zero = no message).
    """

    def __init__(self, spec: SigmaDeltaSpec) -> None:
        self.spec = spec
        self.dtype = np.int64 if spec.fixed else np.float64
        ws = spec.weights
        self.weights = [lava_fixed_weights(w) if spec.fixed else np.asarray(w, float) for w in ws]
        scale = 1 << (spec.spike_exp + spec.state_exp)
        self.vth = [self._cast(v * scale) for v in (spec.vth_in, *spec.vth)]
        self.bias = [np.asarray(b, self.dtype) * scale for b in spec.biases]
        self.messages: list[np.ndarray] = []
        self.sent: tuple[np.ndarray, ...] = ()
        self.reset()

    def _cast(self, v: float) -> int | float:
        return int(v) if self.spec.fixed else float(v)

    def reset(self) -> None:
        """Zero every state variable as a freshly built Lava network has it."""
        sizes = [self.weights[0].shape[1]] + [w.shape[0] for w in self.weights]
        self.enc = [_Encoder(*(np.zeros(n, self.dtype) for _ in range(4))) for n in sizes[:-1]]
        self.buf = [np.zeros(n, self.dtype) for n in sizes[1:]]
        self.out = np.zeros(sizes[-1], self.dtype)
        self.messages = []

    def _encode(self, i: int, act_new: np.ndarray) -> np.ndarray:
        """Lava's ``AbstractDeltaModel.delta_dynamics`` and the message shift: the message."""
        e, vth = self.enc[i], self.vth[i]
        delta = act_new - e.act + e.residue
        if self.spec.cum_error:
            e.error = e.error + delta
            s = np.where(np.abs(e.error) >= vth, delta, 0).astype(self.dtype)
            e.error = e.error * (1 - (np.abs(s) > 0))
        else:
            s = np.where(np.abs(delta) >= vth, delta, 0).astype(self.dtype)
        e.residue = delta - s
        e.act = act_new
        return np.right_shift(s, self.spec.state_exp) if self.spec.fixed else s

    def _dense(self, i: int, s_in: np.ndarray) -> np.ndarray:
        """Dense i: return last step's buffer, fill it from this step's messages."""
        out = self.buf[i]
        acc = self.weights[i] @ s_in
        self.buf[i] = _shift(acc, self.spec.weight_exp) if self.spec.fixed else acc
        return out

    def step(self, x: np.ndarray) -> np.ndarray:
        """One Lava step on observation ``x`` (fixed point: integers in message units)."""
        spec = self.spec
        a = np.asarray(x, self.dtype)
        if spec.fixed:
            a = np.left_shift(a, spec.spike_exp + spec.state_exp)
        sent = [self._encode(0, a)]
        for i in range(len(self.bias)):
            a_in = self._dense(i, sent[-1])
            e = self.enc[i + 1]
            e.sigma = e.sigma + a_in
            sent.append(self._encode(i + 1, np.maximum(e.sigma + self.bias[i], 0)))
        self.out = self.out + self._dense(len(self.bias), sent[-1])
        self.sent = tuple(sent)
        self.messages.append(np.array([np.count_nonzero(s) for s in sent], np.int64))
        return self.out.copy()

    def run(self, xs: np.ndarray) -> np.ndarray:
        """``[N, n_in]`` observations -> ``[N, n_out]`` readouts, continuing the state."""
        return np.stack([self.step(x) for x in xs])

    def message_counts(self) -> np.ndarray:
        """``[steps, layers + 1]`` messages sent per step (input Delta first)."""
        return np.stack(self.messages)

    def payload_bits(self) -> np.ndarray:
        """``[steps, layers + 1]`` payload bits sent (messages x ``num_message_bits``)."""
        return self.message_counts() * self.spec.num_message_bits

    def synaptic_events(self) -> np.ndarray:
        """``[steps, layers + 1]`` synaptic events: messages x fan-out of the Dense they enter."""
        fan_out = np.array([w.shape[0] for w in self.weights], np.int64)
        return self.message_counts() * fan_out


def relu_network(spec: SigmaDeltaSpec, xs: np.ndarray) -> np.ndarray:
    """The quantised ReLU network the chain computes with zero thresholds, without the delay:
    ``W_{L+1} m(relu(... relu(W_1 m(x) + b_1) ...))`` on the same (Lava-prepared) weights, where
    ``m(h) = h * 2**(spike_exp + state_exp) >> state_exp`` is an activation as its message
    carries it (fixed point; the identity in float)."""
    chain = SigmaDeltaChain(spec)
    h = np.asarray(xs, chain.dtype)
    if spec.fixed:
        h = np.right_shift(np.left_shift(h, spec.spike_exp + spec.state_exp), spec.state_exp)
    for w, b in zip(chain.weights[:-1], chain.bias, strict=True):
        h = np.maximum(_dense_all(spec, w, h) + b, 0)
        h = np.right_shift(h, spec.state_exp) if spec.fixed else h
    return _dense_all(spec, chain.weights[-1], h)


def _dense_all(spec: SigmaDeltaSpec, w: np.ndarray, h: np.ndarray) -> np.ndarray:
    acc = h @ w.T
    return _shift(acc, spec.weight_exp) if spec.fixed else acc


def spec_from_block(
    block: SigmaDeltaBlock,
    weights: list[np.ndarray],
    biases: list[np.ndarray],
    arithmetic: Arithmetic,
) -> SigmaDeltaSpec:
    """The chain a manifest's sigma-delta block makes of the graph's affine layers (``weights[i]``
    ``[n_out, n_in]`` and ``biases[i]``, hidden layers then the readout, as trained, float32).

    Fixed point: integer weights ``round(W_l * s_{l-1} / s_l)`` and biases ``round(b_l / s_l)``
    in each layer's unit (:mod:`snnkart.contract.sigma_delta`), thresholds as given. float64:
    the real weights and biases, thresholds ``vth * s_l``. The readout bias stays on the host.
    """
    if len(weights) != len(block.layers) + 1 or len(biases) != len(weights):
        raise DeployError(
            f"the graph has {len(weights)} affine layers but the sigma-delta block "
            f"{len(block.layers)} hidden layers + 1 readout: export the policy again"
        )
    units = [block.input_scale, *(la.act_scale for la in block.layers), block.out_scale]
    hidden = range(len(block.layers))
    if arithmetic == "fixed":
        ws = [
            np.rint(np.asarray(w, np.float64) * units[i] / units[i + 1]).astype(np.int64)
            for i, w in enumerate(weights)
        ]
        bs = [
            np.rint(np.asarray(biases[i], np.float64) / units[i + 1]).astype(np.int64)
            for i in hidden
        ]
        vth: list[float] = [float(la.vth) for la in block.layers]
        vth_in: float = block.vth_in
    else:
        ws = [np.asarray(w, np.float64) for w in weights]
        bs = [np.asarray(biases[i], np.float64) for i in hidden]
        vth = [la.vth * la.act_scale for la in block.layers]
        vth_in = block.vth_in * block.input_scale
    return SigmaDeltaSpec(
        weights=tuple(ws),
        biases=tuple(bs),
        vth=tuple(vth),
        arithmetic=arithmetic,
        vth_in=vth_in,
        num_message_bits=block.num_message_bits,
    )


def input_integers(block: SigmaDeltaBlock, z: np.ndarray) -> np.ndarray:
    """The host's message-unit input: ``round(z / input_scale)`` clipped to ``input_bits``
    signed bits (``z``: the normalised, clipped observation)."""
    top = 2 ** (block.input_bits - 1) - 1
    return np.clip(np.rint(np.asarray(z, np.float64) / block.input_scale), -top, top).astype(
        np.int64
    )


def readout_value(
    block: SigmaDeltaBlock, sigma: np.ndarray, bias: np.ndarray, arithmetic: Arithmetic
) -> np.ndarray:
    """The host's readout from the readout Sigma's value: ``sigma * out_scale + b`` in fixed
    point (``sigma`` in the readout's unit), ``sigma + b`` in float64."""
    scale = block.out_scale if arithmetic == "fixed" else 1.0
    return np.asarray(sigma, np.float64) * scale + np.asarray(bias, np.float64)
