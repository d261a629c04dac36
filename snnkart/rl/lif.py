"""The one fused leaky integrate-and-fire kernel for training: snntorch's maths, less overhead.

Every LIF kind trains through it: the per-window actor (``snn``: T steps from zero membranes),
its current-based form (``snn.neuron = "cuba"``) and the stateful and recurrent actors' row
streams (:mod:`snnkart.rl.stateful_lif`: R rows from a stored membrane, zeroed where an
episode starts). For ``reset_mechanism="zero"``, ``reset_delay=False`` and a positive
threshold, snntorch's ``Leaky`` (and ``Synaptic``) compute per step (their ``reset`` term is
always 0 there, because a reset membrane is 0 < threshold)::

    I = clamp(alpha, 0, 1) * I + x          (Synaptic only: a synaptic current, never reset)
    U = clamp(beta, 0, 1) * U + I           (Leaky: I = x)
    S = FastSigmoid(U - threshold)          # Heaviside forward, 1/(1+k|x|)^2 backward
    U = U - S * U                           # reset to zero; the gradient flows through S

:class:`FusedLIF` runs those steps over a whole ``[R, B, N]`` block of rows in one compiled
loop (numba, float32, the same operations in the same order, no FMA contraction) and
back-propagates through time by hand with the same chain rule. Spikes are identical and
gradients equal to float32 rounding (``tests/test_lif.py``, ``tests/test_stateful.py``).
Export and deployment always use the snntorch modules.

A recurrent layer (``rsnn``) adds its own spikes of the row before through a matrix,
``I = x + R S[r - 1]``: :class:`FusedRecurrentLIF` runs the same membrane maths with that term
inside the loop (it needs the whole row before, so a row is not one neuron's scalar recursion)
and back-propagates into ``R``; its spikes equal the stepped modules', gradients to rounding
(``tests/test_kinds.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from numba import njit


@njit(cache=True, nogil=True)
def _forward(
    current: np.ndarray,
    u0: np.ndarray,
    zero_at: np.ndarray,
    alpha: np.float32,
    beta: np.float32,
    threshold: np.float32,
    cuba: bool,
    syn: np.ndarray,
    mem_pre: np.ndarray,
    spikes: np.ndarray,
) -> None:
    R, n = current.shape
    u = u0.copy()
    i_syn = np.zeros(n, dtype=np.float32)
    zero = np.float32(0.0)
    for t in range(R):
        for i in range(n):
            if zero_at[t, i]:  # an episode starts: no state carried in
                u[i] = zero
                i_syn[i] = zero
            if cuba:
                i_syn[i] = alpha * i_syn[i] + current[t, i]
                syn[t, i] = i_syn[i]
                m = beta * u[i] + i_syn[i]
            else:
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
    grad_spikes: np.ndarray,
    mem_pre: np.ndarray,
    spikes: np.ndarray,
    syn: np.ndarray,
    u0: np.ndarray,
    zero_at: np.ndarray,
    alpha: np.float32,
    beta: np.float32,
    threshold: np.float32,
    slope: np.float32,
    cuba: bool,
    grad_current: np.ndarray,
) -> tuple[float, float, float]:
    R, n = mem_pre.shape
    grad_u = np.zeros(n, dtype=np.float32)  # dL/dU_t (post-reset), from row t+1
    grad_i = np.zeros(n, dtype=np.float32)  # dL/dI_t through I_{t+1}, from row t+1
    one = np.float32(1.0)
    grad_alpha = 0.0
    grad_beta = 0.0
    grad_thr = 0.0
    for t in range(R - 1, -1, -1):
        for i in range(n):
            m = mem_pre[t, i]
            s = spikes[t, i]
            surrogate = one / (slope * abs(m - threshold) + one) ** 2
            grad_x = (grad_spikes[t, i] - grad_u[i] * m) * surrogate
            grad_m = grad_u[i] * (one - s) + grad_x
            g_in = grad_m + grad_i[i] if cuba else grad_m  # Synaptic: I_t feeds U_t and I_t+1
            grad_current[t, i] = g_in
            grad_thr -= grad_x
            if zero_at[t, i]:  # nothing before this row reaches it
                grad_u[i] = 0.0
                grad_i[i] = 0.0
                continue
            if t > 0:
                grad_beta += grad_m * (mem_pre[t - 1, i] * (one - spikes[t - 1, i]))
                if cuba:
                    grad_alpha += g_in * syn[t - 1, i]
            else:
                grad_beta += grad_m * u0[i]
            grad_u[i] = beta * grad_m
            grad_i[i] = alpha * g_in
    return grad_alpha, grad_beta, grad_thr


class FusedLIF(torch.autograd.Function):
    """Spikes ``[R, B, N]`` of a reset-to-zero (current-based, with ``cuba``) LIF layer driven
    by ``current`` ``[R, B, N]`` from the membrane ``u0`` ``[B, N]`` (a constant: zeros, or a
    stored state) and zero current, the state zeroed at the rows where ``zero_at`` ``[R, B]``."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any,
        current: torch.Tensor,
        u0: torch.Tensor,
        zero_at: torch.Tensor,
        alpha: torch.Tensor,
        beta: torch.Tensor,
        threshold: torch.Tensor,
        slope: float,
        cuba: bool,
    ) -> torch.Tensor:
        shape = current.shape
        cur = current.detach().reshape(shape[0], -1).contiguous().numpy()
        start = u0.detach().reshape(-1).contiguous().numpy()
        mask = zero_at.unsqueeze(-1).expand(shape).reshape(shape[0], -1).contiguous().numpy()
        syn = np.empty_like(cur) if cuba else np.empty((0, 0), dtype=np.float32)
        mem_pre, spikes = np.empty_like(cur), np.empty_like(cur)
        a, b = np.float32(alpha.item()), np.float32(beta.item())
        thr = np.float32(threshold.item())
        _forward(cur, start, mask, a, b, thr, cuba, syn, mem_pre, spikes)
        ctx.arrays = (mem_pre, spikes, syn, start, mask)
        ctx.params = (a, b, thr, np.float32(slope), cuba, shape)
        ctx.shapes = (alpha.shape, beta.shape, threshold.shape)
        return torch.from_numpy(spikes).reshape(shape)

    @staticmethod
    def backward(ctx: Any, grad_spikes: torch.Tensor) -> tuple[Any, ...]:  # type: ignore[override]
        mem_pre, spikes, syn, start, mask = ctx.arrays
        a, b, thr, slope, cuba, shape = ctx.params
        grad = grad_spikes.reshape(shape[0], -1).contiguous().numpy()
        grad_current = np.empty_like(grad)
        g_a, g_b, g_thr = _backward(
            grad, mem_pre, spikes, syn, start, mask, a, b, thr, slope, cuba, grad_current
        )
        a_shape, b_shape, thr_shape = ctx.shapes
        return (
            torch.from_numpy(grad_current).reshape(shape),
            None,
            None,
            torch.tensor(g_a, dtype=torch.float32).reshape(a_shape) if cuba else None,
            torch.tensor(g_b, dtype=torch.float32).reshape(b_shape),
            torch.tensor(g_thr, dtype=torch.float32).reshape(thr_shape),
            None,
            None,
        )


@njit(cache=True, nogil=True)
def _rec_forward(
    current: np.ndarray,
    u0: np.ndarray,
    s0: np.ndarray,
    zero_at: np.ndarray,
    weight: np.ndarray,
    beta: np.float32,
    threshold: np.float32,
    mem_pre: np.ndarray,
    spikes: np.ndarray,
    before: np.ndarray,
) -> None:
    R, E, N = current.shape
    zero = np.float32(0.0)
    for e in range(E):
        u = u0[e].copy()
        s = s0[e].copy()
        for t in range(R):
            if zero_at[t, e]:
                u[:] = zero
                s[:] = zero
            before[t, e] = s
            for n in range(N):
                rec = zero
                for j in range(N):
                    if s[j] != zero:
                        rec += weight[n, j]
                m = beta * u[n] + (current[t, e, n] + rec)
                mem_pre[t, e, n] = m
                if m - threshold > zero:
                    spikes[t, e, n] = 1.0
                    u[n] = m - m
                else:
                    spikes[t, e, n] = 0.0
                    u[n] = m
            s = spikes[t, e].copy()


@njit(cache=True, nogil=True)
def _rec_backward(
    grad_spikes: np.ndarray,
    mem_pre: np.ndarray,
    spikes: np.ndarray,
    before: np.ndarray,
    u0: np.ndarray,
    zero_at: np.ndarray,
    weight: np.ndarray,
    beta: np.float32,
    threshold: np.float32,
    slope: np.float32,
    grad_current: np.ndarray,
    grad_weight: np.ndarray,
) -> tuple[float, float]:
    R, E, N = mem_pre.shape
    one = np.float32(1.0)
    grad_beta = 0.0
    grad_thr = 0.0
    for e in range(E):
        grad_u = np.zeros(N, dtype=np.float32)
        grad_s = np.zeros(N, dtype=np.float32)  # dL/dS_t through row t+1's recurrence
        for t in range(R - 1, -1, -1):
            for n in range(N):
                m = mem_pre[t, e, n]
                s = spikes[t, e, n]
                surrogate = one / (slope * abs(m - threshold) + one) ** 2
                grad_x = (grad_spikes[t, e, n] + grad_s[n] - grad_u[n] * m) * surrogate
                grad_m = grad_u[n] * (one - s) + grad_x
                grad_current[t, e, n] = grad_m
                grad_thr -= grad_x
                if zero_at[t, e]:
                    grad_u[n] = 0.0
                else:
                    prior = (
                        u0[e, n] if t == 0 else mem_pre[t - 1, e, n] * (one - spikes[t - 1, e, n])
                    )
                    grad_beta += grad_m * prior
                    grad_u[n] = beta * grad_m
            grad_s[:] = 0.0
            for n in range(N):
                g = grad_current[t, e, n]
                if g != 0.0:
                    for j in range(N):
                        if before[t, e, j] != 0.0:
                            grad_weight[n, j] += g
                    if not zero_at[t, e]:
                        for j in range(N):
                            grad_s[j] += weight[n, j] * g
    return grad_beta, grad_thr


class FusedRecurrentLIF(torch.autograd.Function):
    """Spikes ``[R, E, N]`` of a reset-to-zero LIF layer whose input at row r is ``current[r]``
    plus ``weight @ S[r - 1]`` (its own spikes one row late), from the membrane ``u0`` and the
    spikes ``s0`` ``[E, N]`` (constants: the stored state), both zeroed where ``zero_at``
    ``[R, E]``."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any,
        current: torch.Tensor,
        u0: torch.Tensor,
        s0: torch.Tensor,
        zero_at: torch.Tensor,
        weight: torch.Tensor,
        beta: torch.Tensor,
        threshold: torch.Tensor,
        slope: float,
    ) -> torch.Tensor:
        cur = current.detach().contiguous().numpy()
        start, first = (t.detach().contiguous().numpy() for t in (u0, s0))
        mask = zero_at.contiguous().numpy()
        w = weight.detach().contiguous().numpy()
        mem_pre, spikes, before = np.empty_like(cur), np.empty_like(cur), np.empty_like(cur)
        b, thr = np.float32(beta.item()), np.float32(threshold.item())
        _rec_forward(cur, start, first, mask, w, b, thr, mem_pre, spikes, before)
        ctx.arrays = (mem_pre, spikes, before, start, mask, w)
        ctx.params = (b, thr, np.float32(slope), beta.shape, threshold.shape)
        return torch.from_numpy(spikes)

    @staticmethod
    def backward(ctx: Any, grad_spikes: torch.Tensor) -> tuple[Any, ...]:  # type: ignore[override]
        mem_pre, spikes, before, start, mask, w = ctx.arrays
        b, thr, slope, beta_shape, thr_shape = ctx.params
        grad = grad_spikes.contiguous().numpy()
        grad_current, grad_weight = np.empty_like(grad), np.zeros_like(w)
        g_beta, g_thr = _rec_backward(
            grad, mem_pre, spikes, before, start, mask, w, b, thr, slope, grad_current, grad_weight
        )
        return (
            torch.from_numpy(grad_current),
            None,
            None,
            None,
            torch.from_numpy(grad_weight),
            torch.tensor(g_beta, dtype=torch.float32).reshape(beta_shape),
            torch.tensor(g_thr, dtype=torch.float32).reshape(thr_shape),
            None,
        )


def lif_rows(
    current: torch.Tensor,
    beta: torch.Tensor,
    threshold: torch.Tensor,
    slope: float,
    u0: torch.Tensor | None = None,
    zero_at: torch.Tensor | None = None,
    alpha: torch.Tensor | None = None,
) -> torch.Tensor:
    """Spikes ``[R, B, N]`` of a LIF layer over R rows of ``current`` ``[R, B, N]`` (module
    docstring): from ``u0`` (default zeros), zeroed where ``zero_at`` ``[R, B]`` (default
    nowhere), current-based with ``alpha``. ``alpha`` and ``beta`` are scalars (0-d tensors),
    one per layer, clamped to [0, 1] by the caller as snntorch does."""
    R, B, N = current.shape
    start = current.new_zeros(B, N) if u0 is None else u0
    mask = torch.zeros(R, B, dtype=torch.bool) if zero_at is None else zero_at
    cuba = alpha is not None
    a = alpha if alpha is not None else torch.zeros(())
    return FusedLIF.apply(current, start, mask, a, beta, threshold, slope, cuba)


def fused_lif_layer(
    current: torch.Tensor, beta: torch.Tensor, threshold: torch.Tensor, slope: float
) -> torch.Tensor:
    """Spikes ``[T, B, N]`` of a LIF layer driven by ``current`` ``[T, B, N]``, from U = 0.

    ``beta`` and ``threshold`` are scalars (0-d tensors), one per layer; beta is clamped to
    [0, 1] as snntorch does, with the clamp's gradient.
    """
    return lif_rows(current, beta.clamp(0, 1), threshold, slope)


def fused_cuba_layer(
    current: torch.Tensor,
    alpha: torch.Tensor,
    beta: torch.Tensor,
    threshold: torch.Tensor,
    slope: float,
) -> torch.Tensor:
    """Spikes ``[T, B, N]`` of a current-based LIF layer (snntorch ``Synaptic``, reset to zero,
    no reset delay) driven by ``current`` ``[T, B, N]``, from I = U = 0; ``alpha`` and ``beta``
    are clamped to [0, 1] as snntorch does, with the clamp's gradient. Its current is Lava's
    CUBA LIF's ``u`` (du = 1 - alpha), its membrane ``v`` (dv = 1 - beta)."""
    return lif_rows(current, beta.clamp(0, 1), threshold, slope, alpha=alpha.clamp(0, 1))
