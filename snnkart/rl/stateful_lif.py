"""The stateful actor's env sequences layer by layer, with a fused LIF kernel: the fast form of
:func:`snnkart.rl.stateful.stream_sequence` for the PPO update (``snn.fused``).

Layer i at row r depends only on layer i at row r - 1 and layer i - 1 at row r - 1, so a whole
sequence of S env steps (``S * W`` rows) runs one layer at a time: layer 0 on the held currents
and drain zeros, then each further layer on its Dense's input of the whole sequence (the layer
before's spikes shifted by one row) in one matrix multiply. Each layer is a reset-to-zero LIF
over ``S * W`` rows from the stored membrane, zeroed at the first row of every step that starts
an episode (where no spikes are in flight either). :class:`FusedStatefulLIF` runs that in numba
with the operations of :mod:`snnkart.rl.lif` (``U = beta U + I``, ``S = H(U - theta)``, ``U =
U - S U``) and back-propagates through time by hand; the spikes are those of the stepped
snntorch modules (``tests/test_stateful.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from numba import njit

from snnkart.rl.stateful import split_state


@njit(cache=True, nogil=True)
def _forward(
    current: np.ndarray, u0: np.ndarray, zero_at: np.ndarray, beta: np.float32,
    threshold: np.float32, mem_pre: np.ndarray, spikes: np.ndarray,
) -> np.ndarray:  # fmt: skip
    R, n = current.shape
    u = u0.copy()
    zero = np.float32(0.0)
    for t in range(R):
        for i in range(n):
            if zero_at[t, i]:
                u[i] = zero
            m = beta * u[i] + current[t, i]
            mem_pre[t, i] = m
            if m - threshold > zero:
                spikes[t, i] = 1.0
                u[i] = m - m
            else:
                spikes[t, i] = 0.0
                u[i] = m
    return u


@njit(cache=True, nogil=True)
def _backward(
    grad_spikes: np.ndarray, mem_pre: np.ndarray, spikes: np.ndarray, u0: np.ndarray,
    zero_at: np.ndarray, beta: np.float32, threshold: np.float32, slope: np.float32,
    grad_current: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    R, n = mem_pre.shape
    grad_u = np.zeros(n, dtype=np.float32)  # dL/dU_t (post-reset), from row t+1
    one = np.float32(1.0)
    grad_beta = 0.0
    grad_thr = 0.0
    for t in range(R - 1, -1, -1):
        for i in range(n):
            m = mem_pre[t, i]
            s = spikes[t, i]
            surrogate = one / (slope * abs(m - threshold) + one) ** 2
            grad_x = (grad_spikes[t, i] - grad_u[i] * m) * surrogate
            grad_m = grad_u[i] * (one - s) + grad_x
            grad_current[t, i] = grad_m
            grad_thr -= grad_x
            if zero_at[t, i]:
                grad_u[i] = 0.0
                continue
            before = u0[i] if t == 0 else mem_pre[t - 1, i] * (one - spikes[t - 1, i])
            grad_beta += grad_m * before
            grad_u[i] = beta * grad_m
    return grad_beta, grad_thr


class FusedStatefulLIF(torch.autograd.Function):
    """Spikes ``[R, B, N]`` of a reset-to-zero LIF layer over R rows from the membrane ``u0``
    ``[B, N]`` (a constant: the stored state), zeroed where ``zero_at`` ``[R, B]``."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any, current: torch.Tensor, u0: torch.Tensor, zero_at: torch.Tensor,
        beta: torch.Tensor, threshold: torch.Tensor, slope: float,
    ) -> torch.Tensor:  # fmt: skip
        shape = current.shape
        cur = current.detach().reshape(shape[0], -1).contiguous().numpy()
        start = u0.detach().reshape(-1).contiguous().numpy()
        mask = zero_at.unsqueeze(-1).expand(shape).reshape(shape[0], -1).contiguous().numpy()
        mem_pre, spikes = np.empty_like(cur), np.empty_like(cur)
        b, thr = np.float32(beta.item()), np.float32(threshold.item())
        _forward(cur, start, mask, b, thr, mem_pre, spikes)
        ctx.arrays = (mem_pre, spikes, start, mask)
        ctx.params = (b, thr, np.float32(slope), shape, beta.shape, threshold.shape)
        return torch.from_numpy(spikes).reshape(shape)

    @staticmethod
    def backward(ctx: Any, grad_spikes: torch.Tensor) -> tuple[Any, ...]:  # type: ignore[override]
        mem_pre, spikes, start, mask = ctx.arrays
        b, thr, slope, shape, beta_shape, thr_shape = ctx.params
        grad = grad_spikes.reshape(shape[0], -1).contiguous().numpy()
        grad_current = np.empty_like(grad)
        g_beta, g_thr = _backward(grad, mem_pre, spikes, start, mask, b, thr, slope, grad_current)
        return (
            torch.from_numpy(grad_current).reshape(shape),
            None,
            None,
            torch.tensor(g_beta, dtype=torch.float32).reshape(beta_shape),
            torch.tensor(g_thr, dtype=torch.float32).reshape(thr_shape),
            None,
        )


def fused_stream_sequence(
    actor: Any, x: torch.Tensor, state: torch.Tensor, starts: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, None]:
    """:func:`snnkart.rl.stateful.stream_sequence` layer by layer (module docstring): the
    readouts ``[S * E, n_out]`` and the mean firing rates ``[K]``; no final state (the update
    does not need it)."""
    S, E = starts.shape
    sizes = tuple(fc.out_features for fc in actor.fcs)
    T, L = actor.T, len(sizes) - 1
    W, R = T + L, S * (T + L)
    mems, prev = split_state(state.detach(), sizes)
    current = actor.fcs[0](x).reshape(S, 1, E, sizes[0]).expand(S, T, E, sizes[0])
    drain = current.new_zeros(S, L, E, sizes[0])
    inp = torch.cat([current, drain], dim=1).reshape(R, E, sizes[0])
    zero_at = torch.zeros(S, W, E, dtype=torch.bool)
    zero_at[:, 0] = starts.bool()
    zero_at = zero_at.reshape(R, E)
    in_flight = (~zero_at).unsqueeze(-1).float()  # no spikes in flight at an episode start
    slope = actor.cfg.surrogate_slope
    spikes: list[torch.Tensor] = []
    for i, lif in enumerate(actor.lifs):
        if i > 0:
            before = torch.cat([prev[i - 1].unsqueeze(0), spikes[-1][:-1]]) * in_flight
            inp = actor.fcs[i](before)
        beta = lif.beta.clamp(0, 1)
        spikes.append(FusedStatefulLIF.apply(inp, mems[i], zero_at, beta, lif.threshold, slope))
    last = spikes[-1].reshape(S, W, E, sizes[-1])[:, L:].mean(1)
    out = actor.readout(last).reshape(S * E, -1)
    return out, torch.stack([s.mean() for s in spikes]), None
