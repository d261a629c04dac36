"""Where the spiking layers sit on a chip, and how far their spikes travel: what routing is
priced on.

The rule: each spiking layer on cores of its own (``ceil(n / neurons_per_core)`` of them, as
Lava places one process per core group), cores numbered in layer order, ``cores_per_tile`` cores
sharing a router tile, tiles numbered in a row. A spike is sent once to every core of the next
layer (one message per destination core) and crosses ``|tile(source) - tile(destination)|``
tile boundaries on the way; spikes within a tile cross none (their cost is the chip's ``spike``
price). Tiles in a row are the farthest a chip's 2-D mesh could place them, so the hops are an
upper bound for this rule. The last layer's spikes go to the host (the link, not a hop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Placement:
    """Cores used per layer, and per layer the tile hops one of its spikes makes to reach every
    core of the next layer (0 for the last layer)."""

    neurons_per_core: int
    cores_per_tile: int
    cores: tuple[int, ...]
    hops_per_spike: tuple[float, ...]

    @classmethod
    def of(cls, sizes: tuple[int, ...], neurons_per_core: int, cores_per_tile: int) -> Placement:
        if neurons_per_core < 1 or cores_per_tile < 1:
            raise ValueError("a placement needs neurons_per_core and cores_per_tile >= 1")
        cores = tuple(math.ceil(n / neurons_per_core) for n in sizes)
        first = [sum(cores[:i]) for i in range(len(cores))]  # each layer's first core

        def tile(core: int) -> int:
            return core // cores_per_tile

        hops = []
        for i, n in enumerate(sizes[:-1]):
            destinations = range(first[i + 1], first[i + 1] + cores[i + 1])
            total = 0.0
            for k in range(cores[i]):  # each source core, weighted by the neurons on it
                on_core = min(neurons_per_core, n - k * neurons_per_core)
                travel = sum(abs(tile(first[i] + k) - tile(d)) for d in destinations)
                total += on_core / n * travel
            hops.append(total)
        return cls(neurons_per_core, cores_per_tile, cores, (*hops, 0.0))

    @property
    def tiles(self) -> int:
        return math.ceil(sum(self.cores) / self.cores_per_tile)

    def as_dict(self) -> dict[str, object]:
        return {
            "neurons_per_core": self.neurons_per_core,
            "cores_per_tile": self.cores_per_tile,
            "cores": list(self.cores),
            "tiles": self.tiles,
            "hops_per_spike": list(self.hops_per_spike),
        }
