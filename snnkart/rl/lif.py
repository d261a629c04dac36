"""A fused leaky integrate-and-fire layer for training: snntorch's ``Leaky`` maths, less overhead.

For ``reset_mechanism="zero"``, ``reset_delay=False`` and a positive threshold, snntorch's
``Leaky.forward`` computes, per step (its ``reset`` term is always 0 there, because a reset
membrane is 0 < threshold)::

    U = clamp(beta, 0, 1) * U + I
    S = FastSigmoid(U - threshold)          # Heaviside forward, 1/(1+k|x|)^2 backward
    U = U - S * U                           # reset to zero; the gradient flows through S

:class:`FusedLIF` runs those steps over a whole ``[T, B, N]`` window in one compiled loop
(numba, float32, the same operations in the same order, no FMA contraction) and
back-propagates through time by hand with the same chain rule. Spikes are identical and
gradients equal to float32 rounding (``tests/test_lif.py``). Export and deployment always use
the snntorch modules.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from numba import njit


@njit(cache=True, nogil=True)
def _forward(
    current: np.ndarray, beta: np.float32, threshold: np.float32,
    mem_pre: np.ndarray, spikes: np.ndarray,
) -> None:  # fmt: skip
    T, n = current.shape
    u = np.zeros(n, dtype=np.float32)
    zero = np.float32(0.0)
    for t in range(T):
        for i in range(n):
            m = beta * u[i] + current[t, i]
            mem_pre[t, i] = m
            if m - threshold > zero:
                spikes[t, i] = 1.0
                u[i] = m - m  # = m - S*m with S = 1
            else:
                spikes[t, i] = 0.0
                u[i] = m


@njit(cache=True, nogil=True)
def _backward(
    grad_spikes: np.ndarray, mem_pre: np.ndarray, spikes: np.ndarray,
    beta: np.float32, threshold: np.float32, slope: np.float32, grad_current: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    T, n = mem_pre.shape
    grad_u = np.zeros(n, dtype=np.float32)  # dL/dU_t (post-reset), from step t+1
    one = np.float32(1.0)
    grad_beta = 0.0
    grad_thr = 0.0
    for t in range(T - 1, -1, -1):
        for i in range(n):
            m = mem_pre[t, i]
            s = spikes[t, i]
            surrogate = one / (slope * abs(m - threshold) + one) ** 2
            grad_x = (grad_spikes[t, i] - grad_u[i] * m) * surrogate
            grad_m = grad_u[i] * (one - s) + grad_x
            grad_current[t, i] = grad_m
            grad_thr -= grad_x
            if t > 0:
                grad_beta += grad_m * (mem_pre[t - 1, i] * (one - spikes[t - 1, i]))
            grad_u[i] = beta * grad_m
    return grad_beta, grad_thr


class FusedLIF(torch.autograd.Function):
    """Spikes of a reset-to-zero LIF layer over ``T`` steps, starting from U = 0."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any, current: torch.Tensor, beta: torch.Tensor, threshold: torch.Tensor, slope: float
    ) -> torch.Tensor:
        shape = current.shape
        cur = current.detach().reshape(shape[0], -1).contiguous().numpy()
        mem_pre = np.empty_like(cur)
        spikes = np.empty_like(cur)
        b, thr = np.float32(beta.item()), np.float32(threshold.item())
        _forward(cur, b, thr, mem_pre, spikes)
        ctx.save_for_backward(torch.from_numpy(mem_pre), torch.from_numpy(spikes))
        ctx.params = (b, thr, np.float32(slope), shape, beta.shape, threshold.shape)
        return torch.from_numpy(spikes).reshape(shape)

    @staticmethod
    def backward(ctx: Any, grad_spikes: torch.Tensor) -> tuple[Any, ...]:  # type: ignore[override]
        mem_pre, spikes = ctx.saved_tensors
        b, thr, slope, shape, beta_shape, thr_shape = ctx.params
        grad = grad_spikes.reshape(shape[0], -1).contiguous().numpy()
        grad_current = np.empty_like(grad)
        g_beta, g_thr = _backward(
            grad, mem_pre.numpy(), spikes.numpy(), b, thr, slope, grad_current
        )
        return (
            torch.from_numpy(grad_current).reshape(shape),
            torch.tensor(g_beta, dtype=torch.float32).reshape(beta_shape),
            torch.tensor(g_thr, dtype=torch.float32).reshape(thr_shape),
            None,
        )


def fused_lif_layer(
    current: torch.Tensor, beta: torch.Tensor, threshold: torch.Tensor, slope: float
) -> torch.Tensor:
    """Spikes ``[T, B, N]`` of a LIF layer driven by ``current`` ``[T, B, N]``, from U = 0.

    ``beta`` and ``threshold`` are scalars (0-d tensors), one per layer; beta is clamped to
    [0, 1] as snntorch does, with the clamp's gradient.
    """
    return FusedLIF.apply(current, beta.clamp(0, 1), threshold, slope)


# -- current-based (synaptic) LIF: snntorch ``Synaptic`` -------------------------------------
#
# For reset_mechanism="zero", reset_delay=False and a positive threshold, ``Synaptic.forward``
# computes per step (its delayed reset is always 0 there, as for ``Leaky``)::
#
#     I = clamp(alpha, 0, 1) * I + x          (synaptic current; never reset)
#     U = clamp(beta, 0, 1) * U + I
#     S = FastSigmoid(U - threshold)
#     U = U - S * U
#
# which is Lava's CUBA LIF (u: current, du = 1 - alpha; v: voltage, dv = 1 - beta).


@njit(cache=True, nogil=True)
def _cuba_forward(
    current: np.ndarray, alpha: np.float32, beta: np.float32, threshold: np.float32,
    syn: np.ndarray, mem_pre: np.ndarray, spikes: np.ndarray,
) -> None:  # fmt: skip
    T, n = current.shape
    i_syn = np.zeros(n, dtype=np.float32)
    u = np.zeros(n, dtype=np.float32)
    zero = np.float32(0.0)
    for t in range(T):
        for i in range(n):
            i_syn[i] = alpha * i_syn[i] + current[t, i]
            syn[t, i] = i_syn[i]
            m = beta * u[i] + i_syn[i]
            mem_pre[t, i] = m
            if m - threshold > zero:
                spikes[t, i] = 1.0
                u[i] = m - m
            else:
                spikes[t, i] = 0.0
                u[i] = m


@njit(cache=True, nogil=True)
def _cuba_backward(
    grad_spikes: np.ndarray, syn: np.ndarray, mem_pre: np.ndarray, spikes: np.ndarray,
    alpha: np.float32, beta: np.float32, threshold: np.float32, slope: np.float32,
    grad_current: np.ndarray,
) -> tuple[float, float, float]:  # fmt: skip
    T, n = mem_pre.shape
    grad_u = np.zeros(n, dtype=np.float32)  # dL/dU_t (post-reset), from step t+1
    grad_i = np.zeros(n, dtype=np.float32)  # dL/dI_t through I_{t+1}, from step t+1
    one = np.float32(1.0)
    grad_alpha = 0.0
    grad_beta = 0.0
    grad_thr = 0.0
    for t in range(T - 1, -1, -1):
        for i in range(n):
            m = mem_pre[t, i]
            s = spikes[t, i]
            surrogate = one / (slope * abs(m - threshold) + one) ** 2
            grad_x = (grad_spikes[t, i] - grad_u[i] * m) * surrogate
            grad_m = grad_u[i] * (one - s) + grad_x
            g_syn = grad_m + grad_i[i]  # I_t feeds U_t and I_{t+1}
            grad_current[t, i] = g_syn
            grad_thr -= grad_x
            if t > 0:
                grad_beta += grad_m * (mem_pre[t - 1, i] * (one - spikes[t - 1, i]))
                grad_alpha += g_syn * syn[t - 1, i]
            grad_u[i] = beta * grad_m
            grad_i[i] = alpha * g_syn
    return grad_alpha, grad_beta, grad_thr


class FusedCubaLIF(torch.autograd.Function):
    """Spikes of a reset-to-zero current-based LIF layer over ``T`` steps, from I = U = 0."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any, current: torch.Tensor, alpha: torch.Tensor, beta: torch.Tensor,
        threshold: torch.Tensor, slope: float,
    ) -> torch.Tensor:  # fmt: skip
        shape = current.shape
        cur = current.detach().reshape(shape[0], -1).contiguous().numpy()
        syn, mem_pre, spikes = np.empty_like(cur), np.empty_like(cur), np.empty_like(cur)
        a, b = np.float32(alpha.item()), np.float32(beta.item())
        thr = np.float32(threshold.item())
        _cuba_forward(cur, a, b, thr, syn, mem_pre, spikes)
        ctx.save_for_backward(torch.from_numpy(syn), torch.from_numpy(mem_pre),
                              torch.from_numpy(spikes))  # fmt: skip
        ctx.params = (a, b, thr, np.float32(slope), shape, alpha.shape, beta.shape, threshold.shape)
        return torch.from_numpy(spikes).reshape(shape)

    @staticmethod
    def backward(ctx: Any, grad_spikes: torch.Tensor) -> tuple[Any, ...]:  # type: ignore[override]
        syn, mem_pre, spikes = ctx.saved_tensors
        a, b, thr, slope, shape, a_shape, b_shape, thr_shape = ctx.params
        grad = grad_spikes.reshape(shape[0], -1).contiguous().numpy()
        grad_current = np.empty_like(grad)
        g_a, g_b, g_thr = _cuba_backward(
            grad, syn.numpy(), mem_pre.numpy(), spikes.numpy(), a, b, thr, slope, grad_current
        )
        return (
            torch.from_numpy(grad_current).reshape(shape),
            torch.tensor(g_a, dtype=torch.float32).reshape(a_shape),
            torch.tensor(g_b, dtype=torch.float32).reshape(b_shape),
            torch.tensor(g_thr, dtype=torch.float32).reshape(thr_shape),
            None,
        )


def fused_cuba_layer(
    current: torch.Tensor, alpha: torch.Tensor, beta: torch.Tensor, threshold: torch.Tensor,
    slope: float,
) -> torch.Tensor:  # fmt: skip
    """Spikes ``[T, B, N]`` of a current-based LIF layer (snntorch ``Synaptic``, reset to zero,
    no reset delay) driven by ``current`` ``[T, B, N]``, from I = U = 0; ``alpha`` and ``beta``
    are clamped to [0, 1] as snntorch does, with the clamp's gradient."""
    return FusedCubaLIF.apply(current, alpha.clamp(0, 1), beta.clamp(0, 1), threshold, slope)
