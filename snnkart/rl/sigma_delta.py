"""The sigma-delta actor (``policy = "sdnn"``): a ReLU MLP whose forward pass is the integer
chain Lava runs (docs/sigma-delta.md), by fake quantisation with straight-through estimators.

With every message threshold at zero the chip's chain equals this network exactly, up to float
rounding of the readout (``tests/test_sdnn.py`` checks it against
:class:`snnkart.backends.sigma_delta.SigmaDeltaChain`)::

    q_0 = clip(round(z / s_0), +-(2**(input_bits-1) - 1))       z: the normalised observation
    W~_l = lava(round(W_l s_{l-1} / s_l))                          8-bit clip and truncation
    q_l = relu(W~_l q_{l-1} + round(b_l / s_l))                    l = 1..L, integers
    out = (W~_{L+1} q_L) s_{L+1} + b_{L+1}                         the host's readout

``lava`` is Lava's own weight preparation (:func:`snnkart.backends.sigma_delta.lava_fixed_weights`:
mixed-sign weights clip to ``-256..255`` and lose their least significant bit). Rounding passes
its gradient straight through, so ``W_l`` and ``b_l`` learn as in a float network.

**The units** ``s_l`` (real value per integer) are a function of the weights, never a trained
or stored value: ``s_0 = clip_obs / (2**(input_bits-1) - 1)`` (every observation the host can
send fits the input bits), ``s_l = s_{l-1} max|W_l| / 254`` (the largest weight becomes the
largest even 8-bit integer, so the weights use Lava's whole range). So training, evaluation,
a resumed run and the export all see the same integers from the same weights. The chain is
exact only with every exponent at 0 (docs/sigma-delta.md, "When it is exact": a right shift
floors each delta on its own), so no unit can be shifted back down: layer ``l``'s integers are
``h_l / s_l`` and grow by about ``254 / max|W_l|`` per layer. On a 64-64 grid run the hidden
layers' state needed 16 and 25 bits and the readout Sigma's 35 (docs/sigma-delta.md), past
Loihi 2's 24-bit state; Lava's Python models do not saturate, so the simulation stays exact, and
the export records the bits each layer needed on its calibration run (``state_bits``).

The policy (actor, critic, message penalty) is :class:`snnkart.rl.policies.SDNNPolicy`.
"""

from __future__ import annotations

import itertools
import math

import torch
from torch import nn

from snnkart.rl.sigma_delta_config import SDNNConfig

WEIGHT_TOP = 254
"""The largest weight magnitude the units give an integer weight: the largest even value of
Lava's 8-bit mixed-sign range (``-256..255``, least significant bit dropped)."""
LAVA_WEIGHT_MAX = 255
"""Lava's 8-bit clip of a one-signed weight matrix (``0..255`` or ``-255..0``)."""


def input_scale(clip_obs: float, input_bits: int) -> float:
    """``s_0``: the real value of one input integer, so that ``+-clip_obs`` fits the bits."""
    return float(clip_obs) / float(2 ** (input_bits - 1) - 1)


def layer_units(s0: float, weight_max: list[float]) -> list[float]:
    """Every layer's unit ``[s_0, s_1, ..., s_{L+1}]`` from ``s_0`` and each affine layer's
    ``max|W_l|`` (hidden layers, then the readout): ``s_l = s_{l-1} max|W_l| / 254``."""
    units = [float(s0)]
    for m in weight_max:
        units.append(units[-1] * max(float(m), 1e-12) / WEIGHT_TOP)
    return units


def lava_weights(q: torch.Tensor) -> torch.Tensor:
    """Lava's ``clip_weights`` and ``truncate_weights`` (8 bits, sign mode of the matrix) on
    an integer-valued tensor, as :func:`snnkart.backends.sigma_delta.lava_fixed_weights`."""
    if bool((q >= 0).all()):
        return q.clamp(0, LAVA_WEIGHT_MAX)
    if bool((q <= 0).all()):
        return q.clamp(-LAVA_WEIGHT_MAX, 0)
    return torch.floor(q.clamp(-(LAVA_WEIGHT_MAX + 1), LAVA_WEIGHT_MAX) / 2) * 2


def _straight_through(x: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """``q`` forward, the gradient of ``x`` backward."""
    return x + (q - x).detach()


class SigmaDeltaActor(nn.Module):
    """The fake-quantised ReLU MLP (module docstring): ``fc1 .. fcL`` and ``readout``.

    ``forward(z)`` takes normalised observations ``[B, n_in]`` and returns the readout
    ``[B, n_out]`` (float32) and the hidden integers ``[B, n_l]`` per layer (float64).
    """

    def __init__(self, n_in: int, n_out: int, cfg: SDNNConfig, clip_obs: float) -> None:
        super().__init__()
        self.cfg = cfg
        self.s0 = input_scale(clip_obs, cfg.input_bits)
        self.input_top = float(2 ** (cfg.input_bits - 1) - 1)
        sizes = (n_in, *cfg.hidden)
        for i, (a, b) in enumerate(itertools.pairwise(sizes), start=1):
            layer = nn.Linear(a, b)
            nn.init.orthogonal_(layer.weight, math.sqrt(2.0))
            nn.init.zeros_(layer.bias)
            setattr(self, f"fc{i}", layer)
        self.readout = nn.Linear(sizes[-1], n_out)
        nn.init.orthogonal_(self.readout.weight, 0.01)
        nn.init.zeros_(self.readout.bias)
        self.fcs: list[nn.Linear] = [getattr(self, f"fc{i}") for i in range(1, len(sizes))]

    def affine_layers(self) -> list[nn.Linear]:
        """The affine layers in order: hidden layers, then the readout."""
        return [*self.fcs, self.readout]

    def units(self) -> list[float]:
        """``[s_0, s_1, ..., s_{L+1}]`` from the current weights (:func:`layer_units`)."""
        maxima = [float(fc.weight.detach().abs().max()) for fc in self.affine_layers()]
        return layer_units(self.s0, maxima)

    def input_integers(self, z: torch.Tensor) -> torch.Tensor:
        """``q_0``: the observation as the host sends it (float64 integers)."""
        x = z.double() / self.s0
        return _straight_through(x, torch.round(x).clamp(-self.input_top, self.input_top))

    def integer_weights(self, i: int, units: list[float]) -> torch.Tensor:
        """Affine layer ``i``'s weights on the chip's integer grid (float64, straight through)."""
        w = self.affine_layers()[i].weight.double() * units[i] / units[i + 1]
        return _straight_through(w, lava_weights(torch.round(w)))

    def forward(self, z: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        units = self.units()
        q = self.input_integers(z)
        hidden: list[torch.Tensor] = []
        for i, fc in enumerate(self.fcs):
            b = fc.bias.double() / units[i + 1]
            q = torch.relu(q @ self.integer_weights(i, units).T + _straight_through(b, b.round()))
            hidden.append(q)
        sigma = q @ self.integer_weights(len(self.fcs), units).T
        out = sigma * units[-1] + self.readout.bias.double()
        return out.float(), hidden


def message_proxy(now: list[torch.Tensor], before: list[torch.Tensor]) -> torch.Tensor:
    """The penalty's proxy for the messages one env step sends: per hidden layer the mean
    ``|h_l(x_t) - h_l(x_{t-1})|`` over the batch and the neurons, divided by the mean
    ``|h_l(x_t)|``, summed over the layers.

    A neuron sends a message when its activation has changed by at least its threshold since
    its last message, and export calibrates each threshold as a multiple of its layer's mean
    activation (:mod:`snnkart.export.calibrate`); the L1 change relative to that mean is the
    smooth, scale-free stand-in for the count. Scale-free matters: a plain L1 would fall by
    shrinking one layer and growing the next one's weights, which changes no message."""
    terms = [
        (a - b).abs().mean() / (a.abs().mean() + 1e-6) for a, b in zip(now, before, strict=True)
    ]
    return torch.stack(terms).sum().float()


def changed_share(now: list[torch.Tensor], before: list[torch.Tensor]) -> torch.Tensor:
    """The measured message rate at zero thresholds: per layer the share of neurons whose
    integer changed since the previous env step (one message each under the held schedule)."""
    return torch.stack([(a != b).double().mean() for a, b in zip(now, before, strict=True)])
