"""The stateful actor's env sequences layer by layer, with a fused LIF kernel: the fast form of
:func:`snnkart.rl.stateful.stream_sequence` for the PPO update (``snn.fused``).

Layer i at row r depends only on layer i at row r - 1 and layer i - 1 at row r - 1, so a whole
sequence of S env steps (``S * W`` rows) runs one layer at a time: layer 0 on the held currents
and drain zeros, then each further layer on its Dense's input of the whole sequence (the layer
before's spikes shifted by one row) in one matrix multiply. Each layer is a reset-to-zero LIF
over ``S * W`` rows from the stored membrane, zeroed at the first row of every step that starts
an episode (where no spikes are in flight either): :func:`snnkart.rl.lif.lif_rows`, the one LIF
kernel every LIF kind trains through; the spikes are those of the stepped snntorch modules
(``tests/test_stateful.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch

from snnkart.rl.lif import FusedRecurrentLIF, lif_rows
from snnkart.rl.stateful import split_state


def fused_stream_sequence(
    actor: Any,
    x: torch.Tensor,
    state: torch.Tensor,
    starts: torch.Tensor,
    loops: Sequence[torch.nn.Linear] = (),
) -> tuple[torch.Tensor, torch.Tensor, None]:
    """:func:`snnkart.rl.stateful.stream_sequence` layer by layer (module docstring): the
    readouts ``[S * E, n_out]`` and the mean firing rates ``[K]``; no final state (the update
    does not need it). With ``loops`` (a recurrent actor: layer i >= 1's recurrent synapse is
    ``loops[i - 1]``), ``state`` holds every layer's last-row spikes, and each recurrent layer
    runs in :class:`snnkart.rl.lif.FusedRecurrentLIF`."""
    S, E = starts.shape
    sizes = tuple(fc.out_features for fc in actor.fcs)
    T, L = actor.T, len(sizes) - 1
    W, R = T + L, S * (T + L)
    mems, prev = split_state(state.detach(), sizes, bool(loops))
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
        if i > 0 and loops:
            weight = loops[i - 1].weight
            spikes.append(
                FusedRecurrentLIF.apply(
                    inp, mems[i], prev[i], zero_at, weight, beta, lif.threshold, slope
                )
            )
            continue
        spikes.append(lif_rows(inp, beta, lif.threshold, slope, u0=mems[i], zero_at=zero_at))
    last = spikes[-1].reshape(S, W, E, sizes[-1])[:, L:].mean(1)
    out = actor.readout(last).reshape(S * E, -1)
    return out, torch.stack([s.mean() for s in spikes]), None
