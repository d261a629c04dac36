"""A fused leaky integrate-and-fire layer for training: snntorch's ``Leaky`` maths, less overhead.

For ``reset_mechanism="zero"``, ``reset_delay=False`` and a positive threshold, snntorch's
``Leaky.forward`` computes, per step (``reset`` is always 0 there because a reset membrane is
0 < threshold)::

    U = clamp(beta, 0, 1) * U + I
    S = FastSigmoid(U - threshold)          # Heaviside forward, 1/(1+k|x|)^2 backward
    U = U - S * U                           # reset to zero; the gradient flows through S

This module runs the same operations in the same order on whole ``[T, B, N]`` tensors without
the per-call module bookkeeping, so spikes and gradients are identical (tested in
``tests/test_lif.py``). Export and deployment always use the snntorch modules.
"""

from __future__ import annotations

import torch
from snntorch.surrogate import FastSigmoid


def fused_lif_layer(
    current: torch.Tensor, beta: torch.Tensor, threshold: torch.Tensor, slope: float
) -> torch.Tensor:
    """Spikes ``[T, B, N]`` of a LIF layer driven by ``current`` ``[T, B, N]``, from U = 0."""
    b = beta.clamp(0, 1)
    mem = torch.zeros_like(current[0])
    spikes = []
    for t in range(current.shape[0]):
        mem = b * mem + current[t]
        spk = FastSigmoid.apply(mem - threshold, slope)
        mem = mem - spk * mem
        spikes.append(spk)
    return torch.stack(spikes)
