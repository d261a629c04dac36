"""Network families: how a trained policy's network runs off the host, numpy only.

A policy kind (:mod:`snnkart.rl.kinds`) belongs to one family. The family, not the kind, decides
what export writes, which backends run the graph and how the energy model counts its activity;
the layers below training (backends, energy, report) know families, never kinds.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Family:
    """What a family is: its name, whether it runs as a spiking network on a chip (exports to
    NIR, deploys), whether its messages are graded (sigma-delta) rather than binary spikes, and
    a phrase for documents."""

    name: str
    spiking: bool
    graded: bool
    phrase: str


FAMILIES: dict[str, Family] = {
    f.name: f
    for f in (
        Family("ann", spiking=False, graded=False, phrase="an ordinary network (MLP)"),
        Family("lif", spiking=True, graded=False, phrase="leaky integrate-and-fire neurons"),
        Family("sigma_delta", spiking=True, graded=True, phrase="sigma-delta neurons (graded)"),
    )
}
