"""``lava-sim`` for a sigma-delta policy: the chain as Lava's own ``lava.proc.sdn`` (Delta,
SigmaDelta with ReLU, Sigma) and graded ``lava.proc.dense`` processes on ``Loihi2SimCfg``
(fixed_pt or floating_pt), closed loop, ``rows = L + 2`` Lava steps per env step with the
input held (:class:`snnkart.backends.lava_worker.SigmaDeltaNetwork`).

The worker process, its protocol, time-outs and every way out (Ctrl-C, a dead or hung worker,
the parent's death) are the LIF backend's (:class:`snnkart.backends.lava_sim.LavaWorker`);
Lava never enters this process. The host side is :class:`~snnkart.backends.sigma_delta_backend.
SigmaDeltaBackend`'s, shared with the numpy reference, which is the bit-exact oracle.

Sharp edges: the chain is built once and never reset (its state runs on across episodes, as
the reference's does); exponents are 0 (the manifest's block allows nothing else).
"""

from __future__ import annotations

import numpy as np

from snnkart.backends.base import Arithmetic
from snnkart.backends.lava_params import SigmaDeltaLavaSpec, sigma_delta_lava_spec
from snnkart.backends.lava_sim import LavaWorker
from snnkart.backends.sigma_delta_backend import SigmaDeltaBackend, SigmaDeltaEngine
from snnkart.backends.sigma_delta_policy import SigmaDeltaPolicy


class SigmaDeltaLavaWorker(LavaWorker):
    """The Lava worker running a sigma-delta chain: ``env_step(x)`` -> the raster of sent
    values (:mod:`snnkart.backends.sigma_delta_backend`)."""

    def __init__(self, spec: SigmaDeltaLavaSpec) -> None:
        super().__init__(spec)
        self.rows = spec.rows

    def env_step(self, x: np.ndarray) -> np.ndarray:
        return self.raster(x)


class SigmaDeltaLava(SigmaDeltaBackend):
    """The ``lava-sim`` backend of a sigma-delta policy (``arithmetic`` fixed or float64)."""

    name = "lava-sim"

    def __init__(
        self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic = "fixed", seed: int = 0
    ) -> None:
        super().__init__(policy, arithmetic, seed)
        self.startup_s = float(self.worker.info["startup_s"])

    def open_engine(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic) -> SigmaDeltaEngine:
        spec = sigma_delta_lava_spec(policy.spec(arithmetic), policy.block.rows)
        self.worker = SigmaDeltaLavaWorker(spec)
        return self.worker
