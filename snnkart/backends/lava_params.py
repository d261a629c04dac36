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
from snnkart.backends.sigma_delta import SigmaDeltaSpec


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
    recurrent: np.ndarray | None = None  # a Dense from the layer's spikes back to its input


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
                recurrent=None if layer.recurrent is None else layer.recurrent.astype(np.float64),
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
            recurrent=None if q.recurrent is None else q.recurrent.astype(np.int32),
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


@dataclass(frozen=True)
class SigmaDeltaLavaSpec:
    """What the Lava worker builds for a sigma-delta chain
    (:class:`~snnkart.backends.sigma_delta.SigmaDeltaSpec`): ``Delta(vth_in) -> Dense(weights[0])
    -> SigmaDelta(vth[0], biases[0], ReLU) -> ... -> Dense(weights[-1]) -> Sigma``, graded
    Dense messages, ``rows`` Lava steps per env step with the input held. Weights as the spec
    has them (Lava's fixed-point Dense clips and truncates them itself)."""

    arithmetic: Arithmetic
    rows: int
    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    vth: tuple[float | int, ...]
    vth_in: float | int
    num_message_bits: int

    @property
    def sizes(self) -> tuple[int, ...]:
        """Every recorded population: the input Delta, each SigmaDelta, the readout Sigma."""
        return (int(self.weights[0].shape[1]), *(int(w.shape[0]) for w in self.weights))


def sigma_delta_lava_spec(spec: SigmaDeltaSpec, rows: int) -> SigmaDeltaLavaSpec:
    """The Lava processes' parameters of ``spec`` (exponents 0 and no ``cum_error``, as a
    manifest's block has them)."""
    if (spec.weight_exp, spec.spike_exp, spec.state_exp, spec.cum_error) != (0, 0, 0, False):
        raise ValueError("the Lava sigma-delta worker runs exponents 0 without cum_error")
    fixed = spec.arithmetic == "fixed"
    dtype = np.int32 if fixed else np.float64
    cast = int if fixed else float
    return SigmaDeltaLavaSpec(
        arithmetic=spec.arithmetic,
        rows=rows,
        weights=tuple(np.asarray(w, dtype) for w in spec.weights),
        biases=tuple(np.asarray(b, dtype) for b in spec.biases),
        vth=tuple(cast(v) for v in spec.vth),
        vth_in=cast(spec.vth_in),
        num_message_bits=spec.num_message_bits,
    )
