"""The spiking actor of an SNN policy (snntorch layers, one window of ``T`` steps per env
step from zero membranes); :class:`snnkart.rl.policies.SNNPolicy` wraps it with a critic."""

from __future__ import annotations

import itertools
import math

import snntorch as snn
import torch
from snntorch import surrogate
from torch import nn

from snnkart.rl.lif import fused_cuba_layer, fused_lif_layer
from snnkart.rl.sections import SNNConfig


def layer_init(layer: nn.Linear, std: float = math.sqrt(2.0), bias: float = 0.0) -> nn.Linear:
    """Orthogonal weights with gain ``std`` and constant bias (CleanRL's ``layer_init``)."""
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, bias)
    return layer


class SpikingActor(nn.Module):
    """Encoding -> Linear -> LIF -> Linear -> LIF -> mean spike count -> Linear readout.

    Each env step is one window of ``T`` SNN steps, starting from zero membranes:

        I1[t] = W1 x[t] + b1            (rate: x[t] ~ Bernoulli(obs01); current: x[t] = z)
        U1[t] = beta1 U1[t-1] (1 - S1[t-1]) + I1[t],   S1[t] = H(U1[t] - theta1)
        U2[t] = beta2 U2[t-1] (1 - S2[t-1]) + W2 S1[t] + b2,  S2[t] = H(U2[t] - theta2)
        out   = W3 mean_t(S2[t]) + b3

    ``obs01`` is the observation scaled to [0, 1] by the env's (true) bounds, ``z`` the
    observation normalised by the running mean and standard deviation (frozen in the
    checkpoint, applied on the host at deployment). The reset is
    reset-to-zero (snntorch ``reset_mechanism="zero"``), the surrogate gradient the fast
    sigmoid ``1 / (1 + k|U - theta|)^2``. Inputs ``[B, n_in]``, output ``[B, n_out]``.
    """

    def __init__(self, n_in: int, n_out: int, cfg: SNNConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.T = cfg.num_steps
        sizes = (n_in, *cfg.hidden)
        # Layers are attributes fc1, lif1, fc2, lif2, ... (the state-dict keys of every
        # checkpoint written so far); ``fcs`` and ``lifs`` list them in order.
        for i, (a, b) in enumerate(itertools.pairwise(sizes), start=1):
            setattr(self, f"fc{i}", nn.Linear(a, b, bias=i == 1 or cfg.hidden_bias))
        self.readout = layer_init(nn.Linear(sizes[-1], n_out), std=0.01)
        self.fcs: list[nn.Linear] = [getattr(self, f"fc{i}") for i in range(1, len(sizes))]
        with torch.no_grad():
            for fc in self.fcs:
                fc.weight.mul_(cfg.init_gain)
        for i in range(1, len(sizes)):
            setattr(self, f"lif{i}", _neuron(cfg))
        self.lifs: list[snn.Leaky] = [getattr(self, f"lif{i}") for i in range(1, len(sizes))]
        self.cuba = cfg.neuron == "cuba"

    def encode(self, obs01: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """Rate encoding: Bernoulli spike trains ``[B, T, n_in]`` with p = obs01."""
        p = obs01.clamp(0.0, 1.0).unsqueeze(1).expand(-1, self.T, -1)
        return torch.bernoulli(p, generator=generator)

    def forward(
        self, obs01: torch.Tensor, input_spikes: torch.Tensor | None = None, fused: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor]]:
        """Returns (readout output, mean firing rate per layer, spike records ``[T, B, n]``)."""
        B = obs01.shape[0]
        if self.cfg.encoding == "rate":
            if input_spikes is None:
                input_spikes = self.encode(obs01)
            current = self.fcs[0](input_spikes).transpose(0, 1)  # [T, B, h1]
        else:
            current = self.fcs[0](obs01).unsqueeze(0).expand(self.T, -1, -1)
        spikes: list[torch.Tensor] = []
        if fused:
            slope = self.cfg.surrogate_slope
            for i, lif in enumerate(self.lifs):
                if i > 0:
                    current = self.fcs[i](spikes[-1])
                spikes.append(
                    fused_cuba_layer(current, lif.alpha, lif.beta, lif.threshold, slope)
                    if self.cuba
                    else fused_lif_layer(current, lif.beta, lif.threshold, slope)
                )
        else:
            spikes = self._stepped(current, B)
        out = self.readout(spikes[-1].mean(0))
        rates = torch.stack([s.mean() for s in spikes])
        return out, rates, spikes

    def _stepped(self, current: torch.Tensor, B: int) -> list[torch.Tensor]:
        """snntorch's modules stepped T times from zero state: spikes ``[T, B, n]`` per layer."""
        mems = [torch.zeros(B, fc.out_features) for fc in self.fcs]
        syns = [torch.zeros(B, fc.out_features) for fc in self.fcs]
        steps: list[list[torch.Tensor]] = [[] for _ in self.lifs]
        for t in range(self.T):
            a = current[t]
            for i, lif in enumerate(self.lifs):
                x = a if i == 0 else self.fcs[i](a)
                if self.cuba:
                    a, syns[i], mems[i] = lif(x, syns[i], mems[i])
                else:
                    a, mems[i] = lif(x, mems[i])
                steps[i].append(a)
        return [torch.stack(s) for s in steps]


def _neuron(cfg: SNNConfig) -> snn.Leaky:
    """One spiking layer's neurons: reset to zero right after a spike (Lava's semantics)."""
    common = dict(
        beta=torch.tensor(cfg.beta),
        threshold=torch.tensor(cfg.threshold),
        spike_grad=surrogate.fast_sigmoid(slope=cfg.surrogate_slope),
        reset_mechanism="zero",
        reset_delay=False,
        learn_beta=cfg.learn_beta,
        learn_threshold=cfg.learn_threshold,
    )
    if cfg.neuron == "cuba":
        return snn.Synaptic(alpha=torch.tensor(cfg.alpha), learn_alpha=cfg.learn_alpha, **common)
    return snn.Leaky(**common)
