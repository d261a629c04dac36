"""Open-loop runs of a NIR chain on given input: the engine of ``snnkart nir run``.

The input is ``[N, n_in]`` (currents, or spikes as 0/1) for N time steps; the network starts
from zero state and runs N steps without a reset, as one window of the backends' pipeline
(:mod:`snnkart.backends.reference`): the host computes the first layer's current ``W1 x[t] + b1``
in the backend's arithmetic, the spiking layers run on the numpy reference or as Lava's own
processes, and every Dense delays by one step, which the logical raster undoes. The readout of
each step is the last Affine/Linear applied to the last layer's spikes of that step, or, with
an LI node after it, the LI's membrane at that step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.backends.base import Arithmetic, split_window
from snnkart.backends.host import first_current
from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import FixedPointNetwork, quantize
from snnkart.backends.reference import ChainSimulator
from snnkart.contract.encoding import leaky_readout
from snnkart.errors import DeployError


@dataclass(frozen=True)
class OpenLoopResult:
    backend: str
    arithmetic: Arithmetic
    logical: np.ndarray  # [N, sum(sizes)] bool: every layer's spikes at its logical steps
    raster: np.ndarray  # the rows the backend ran ([N + L, sum(sizes)] on the Lava pipeline)
    sizes: tuple[int, ...]
    names: tuple[str, ...]  # the neuron nodes, in order
    readout: np.ndarray | None  # [N, n_out] float64, or None without a readout node

    def layer(self, i: int) -> np.ndarray:
        offsets = np.cumsum((0, *self.sizes))
        return self.logical[:, offsets[i] : offsets[i + 1]]

    def arrays(self) -> dict[str, np.ndarray]:
        """What ``--out`` writes: one raster per layer (by node name), the readout, the input
        current's arithmetic."""
        out = {f"spikes_{name}": self.layer(i) for i, name in enumerate(self.names)}
        if self.readout is not None:
            out["readout"] = self.readout
        out["raw_raster"] = self.raster
        return out


def check_inputs(inputs: Any, n_in: int, steps: int | None) -> np.ndarray:
    """The input as float64 ``[N, n_in]``, or a clear error naming what is wrong with it."""
    arr = np.asarray(inputs)
    if arr.dtype.kind not in "biuf":
        raise DeployError(
            f"the input has dtype {arr.dtype}; give numbers (currents, or spikes as 0/1)"
        )
    if arr.ndim == 1 and n_in == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != n_in:
        raise DeployError(
            f"the input has shape {list(arr.shape)}; the graph takes [N, {n_in}] (N time steps "
            f"of its {n_in} inputs)"
        )
    if steps is not None:
        if steps < 1 or steps > arr.shape[0]:
            raise DeployError(f"--steps {steps}: the input has {arr.shape[0]} steps (1 or more)")
        arr = arr[:steps]
    if not np.isfinite(arr.astype(np.float64)).all():
        raise DeployError("the input contains NaN or infinite values")
    return arr.astype(np.float64)


def run_open_loop(
    chain: ChainNetwork,
    inputs: np.ndarray,
    backend: str,
    arithmetic: Arithmetic,
    fixed: FixedPointNetwork | None = None,
) -> OpenLoopResult:
    """Run ``inputs`` ``[N, n_in]`` through ``chain`` on ``backend`` ("nir-ref" or "lava-sim")."""
    n = inputs.shape[0]
    if arithmetic == "fixed" and fixed is None:
        fixed = quantize(chain)
    x = inputs.astype(np.float32) if arithmetic == "float32" else inputs
    if chain.input_scale is not None:
        x = x * chain.input_scale.astype(x.dtype)
    current = np.ascontiguousarray(first_current(chain, x, arithmetic, fixed))
    if backend == "nir-ref":
        raster = ChainSimulator(chain, n, arithmetic, fixed).window(current)
    elif backend == "lava-sim":
        if arithmetic == "float32":
            raise DeployError("lava-sim runs float (float64) or fixed, not float32")
        raster = _lava_window(chain, n, arithmetic, fixed, current)
    else:
        raise DeployError(f"unknown backend {backend!r}; choose nir-ref or lava-sim")
    window = split_window(raster, chain.sizes, n)
    last = window.logical[:, -chain.sizes[-1] :].astype(np.float64)
    readout = None
    li = chain.readout_li
    if chain.readout_weight is not None and chain.readout_bias is not None:
        if li is not None:  # an LI node: its membrane at every step
            trace = leaky_readout(
                last, chain.readout_weight, chain.readout_bias, li.decay, li.gain, li.leak
            )
            readout = trace.astype(np.float64)
        else:
            w = chain.readout_weight.astype(np.float64)
            readout = last @ w.T + chain.readout_bias.astype(np.float64)
    names = tuple(layer.neuron for layer in chain.layers)
    return OpenLoopResult(backend, arithmetic, window.logical, raster, chain.sizes, names, readout)


def _lava_window(
    chain: ChainNetwork,
    n: int,
    arithmetic: Arithmetic,
    fixed: FixedPointNetwork | None,
    current: np.ndarray,
) -> np.ndarray:
    from snnkart.backends.lava_params import lava_spec
    from snnkart.backends.lava_sim import LavaWorker

    worker = LavaWorker(lava_spec(chain, n, arithmetic, fixed))
    try:
        return worker.window(current)
    finally:
        worker.close()


def compare(a: OpenLoopResult, b: OpenLoopResult) -> dict[str, Any]:
    """Bit-exactness of two runs of the same chain and input, and the spikes that differ
    (flips) per layer."""
    flips = [int(np.sum(a.layer(i) != b.layer(i))) for i in range(len(a.sizes))]
    return {
        "a": f"{a.backend} {a.arithmetic}",
        "b": f"{b.backend} {b.arithmetic}",
        "bit_exact": sum(flips) == 0,
        "flips": dict(zip(a.names, flips, strict=True)),
        "spikes_a": int(a.logical.sum()),
        "spikes_b": int(b.logical.sum()),
    }
