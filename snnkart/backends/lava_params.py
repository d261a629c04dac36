"""The one mapping from a chain to the parameters of Lava's LIF and Dense processes.

Float (Lava's floating-point models): ``du = 1`` (the current is the input of the step; for a
CubaLIF ``du = 1 - alpha``, the current decays),
``dv = 1 - beta``, ``vth = threshold``; the first layer's bias is 0, because the host adds it
to the current it sends (:mod:`snnkart.backends.host`); later layers carry their bias. Fixed
point: the quantised values of :mod:`snnkart.backends.quantize`. The numpy reference's float64
arithmetic reads the same values, and the Lava worker receives them as :class:`LavaSpec`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snnkart.backends.base import Arithmetic
from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import FixedPointNetwork


@dataclass(frozen=True)
class LavaLayer:
    """One LIF population and the Dense synapses feeding it (``weight``; None for the first
    layer, fed by the host)."""

    du: float | int
    dv: float | int
    vth: float | int
    bias_mant: np.ndarray
    bias_exp: int
    weight: np.ndarray | None


@dataclass(frozen=True)
class LavaSpec:
    """What the Lava worker builds: the layers, their sizes, T and the arithmetic, and whether
    the state persists across windows (plain ``LIF``, a stateful policy) or is reset in each
    (``LIFReset``)."""

    arithmetic: Arithmetic  # "float64" (floating-point models) or "fixed" (bit-accurate)
    num_steps: int
    sizes: tuple[int, ...]
    layers: tuple[LavaLayer, ...]
    persist: bool = False


def lava_layers(
    chain: ChainNetwork, arithmetic: Arithmetic, fixed: FixedPointNetwork | None = None
) -> tuple[LavaLayer, ...]:
    if arithmetic == "float64":
        return tuple(
            LavaLayer(
                du=1.0 if layer.alpha is None else 1.0 - float(layer.alpha[0]),
                dv=1.0 - float(layer.beta[0]),
                vth=float(layer.threshold[0]),
                bias_mant=np.zeros(layer.size) if i == 0 else layer.bias.astype(np.float64),
                bias_exp=0,
                weight=None if i == 0 else layer.weight.astype(np.float64),
            )
            for i, layer in enumerate(chain.layers)
        )
    if arithmetic != "fixed" or fixed is None:
        raise ValueError(
            f"Lava runs float64 or fixed (with its quantised network), not {arithmetic}"
        )
    return tuple(
        LavaLayer(
            du=q.du,
            dv=q.dv,
            vth=q.vth,
            bias_mant=q.bias_mant.astype(np.int32),
            bias_exp=q.bias_exp,
            weight=None if q.weight is None else q.weight.astype(np.int32),
        )
        for q in fixed.layers
    )


def lava_spec(
    chain: ChainNetwork,
    num_steps: int,
    arithmetic: Arithmetic,
    fixed: FixedPointNetwork | None,
    persist: bool = False,
) -> LavaSpec:
    return LavaSpec(
        arithmetic, num_steps, tuple(chain.sizes), lava_layers(chain, arithmetic, fixed), persist
    )
