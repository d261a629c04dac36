"""The stateful spiking actor's row stream: what Lava computes per env step when the membranes
carry across env steps (``snn.stateful``; docs/stateful.md).

With K spiking layers and L = K - 1 Dense synapses (each delays by one Lava step), one env step
is ``W = T + L`` rows, run from the state the previous env step left::

    row r, layer 0:   I = W1 z + b1  (r < T; the host's current)   or 0  (r >= T: drain)
    row r, layer i>0: I = W_{i+1} S_{i-1}[r - 1] + b_{i+1}           (S of the row before)
    every layer:      U = beta U + I,  S = H(U - theta),  U = 0 where S      (snntorch Leaky)
    readout:          W_out mean(S_{K-1}[L .. L + T - 1]) + b_out

No reset between env steps: the fill and drain rows change the membranes (they decay, the
biases act), and ``S_{i-1}[r - 1]`` at row 0 is the last row of the previous env step. The state
is one tensor ``[B, D]``: every layer's membrane, then every layer but the last's spikes of the
last row (``D = sum(sizes) + sum(sizes[:-1])``); zeros at an episode's start. The neurons are
the actor's own snntorch modules (the same float32 operations and surrogate gradient as the
per-window actor); training back-propagates through every row of a whole env sequence.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch


def state_size(sizes: tuple[int, ...], recurrent: bool = False) -> int:
    """``D``: every layer's membrane and every layer but the last's last-row spikes (every
    layer's, ``recurrent``: a recurrent layer's own spikes feed its next row)."""
    return sum(sizes) + sum(sizes if recurrent else sizes[:-1])


def split_state(
    state: torch.Tensor, sizes: tuple[int, ...], recurrent: bool = False
) -> tuple[list[Any], list[Any]]:
    """The membranes (per layer) and the last-row spikes (per layer but the last; per layer,
    ``recurrent``) in ``state``."""
    parts = list(torch.split(state, [*sizes, *(sizes if recurrent else sizes[:-1])], dim=-1))
    return parts[: len(sizes)], parts[len(sizes) :]


def stream_step(
    actor: Any, x: torch.Tensor, state: torch.Tensor, loops: Sequence[torch.nn.Linear] = ()
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """One env step of ``actor`` (a :class:`~snnkart.rl.spiking.SpikingActor`) on its input
    ``x`` ``[B, n_in]`` from ``state`` ``[B, D]``: (readout ``[B, n_out]``, mean firing rate per
    layer over all W rows ``[K]``, the new state ``[B, D]``). With ``loops``, layer i >= 1 also
    takes its own spikes of the row before through ``loops[i - 1]`` (the recurrent kind)."""
    sizes = tuple(fc.out_features for fc in actor.fcs)
    K, T = len(sizes), actor.T
    L = K - 1
    mems, prev = split_state(state, sizes, bool(loops))
    current = actor.fcs[0](x)
    drain = torch.zeros_like(current)
    read: list[torch.Tensor] = []
    totals: list[Any] = [0.0] * K
    for r in range(T + L):
        spikes = []
        for i, lif in enumerate(actor.lifs):
            if i == 0:
                inp = current if r < T else drain
            elif loops:  # both synapses arrive at the layer's input
                inp = actor.fcs[i](prev[i - 1]) + loops[i - 1](prev[i])
            else:
                inp = actor.fcs[i](prev[i - 1])
            s, mems[i] = lif(inp, mems[i])
            spikes.append(s)
            totals[i] = totals[i] + s.mean()
        prev = spikes if loops else spikes[:-1]
        if r >= L:
            read.append(spikes[-1])
    out = actor.readout(torch.stack(read).mean(0))
    rates = torch.stack(totals) / (T + L)
    return out, rates, torch.cat([*mems, *prev], dim=-1)


def stream_sequence(
    actor: Any,
    x: torch.Tensor,
    state: torch.Tensor,
    starts: torch.Tensor,
    loops: Sequence[torch.nn.Linear] = (),
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Env sequences: ``x`` ``[S * E, n_in]`` time-major (row ``s * E + e``), ``state`` the state
    before step 0 ``[E, D]``, ``starts`` ``[S, E]`` 1 where an episode begins at step ``s`` (the
    state is zeroed there). Returns the readouts ``[S * E, n_out]`` in the same order, the mean
    firing rates ``[K]`` and the state after the last step."""
    S, E = starts.shape
    xs = x.reshape(S, E, -1)
    outs, rates = [], []
    for s in range(S):
        state = state * (1.0 - starts[s]).unsqueeze(-1)
        out, rate, state = stream_step(actor, xs[s], state, loops)
        outs.append(out)
        rates.append(rate)
    return torch.cat(outs), torch.stack(rates).mean(0), state
