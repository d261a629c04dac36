"""The sigma-delta backends' shared logic (host codec, counts, parity hooks) over an engine
that only steps the chain, and the numpy engine (``nir-ref``).

Per env step (the ``held`` schedule, docs/sigma-delta.md): the host normalises and clips the
observation (``z = clip((obs - mean) / std)``, the manifest's), in fixed point turns it into
message-unit integers (:func:`~snnkart.backends.sigma_delta.input_integers`; float64 sends
``z``), holds it for the block's ``rows = L + 2`` Lava steps, reads the readout Sigma after the
last of them (:func:`~snnkart.backends.sigma_delta.readout_value`) and decodes the action
(argmax, or clip to [-1, 1]). The chain's state persists across env steps AND episodes: it is
never reset (a chip deployment would not reset it either), so ``reset`` does nothing and two
runs agree only when they start from a freshly built chain.

An engine's ``env_step(x)`` returns the raster ``[rows, sum(sizes)]``: the values every
sending layer sent at every row (the input Delta, each SigmaDelta; 0 = no message) and, in the
last ``n_out`` columns, the readout Sigma's value at every row. The parity check compares it
bit for bit with the numpy reference's.

Sharp edges: ``float32`` is refused (Lava's floating-point models compute in float64); state
is never reset, so a mid-run parity comparison needs both engines to have seen the same
observations since they were built.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np

from snnkart.backends.backend import RunningPolicy
from snnkart.backends.base import Arithmetic
from snnkart.backends.loading import open_policy
from snnkart.backends.sigma_delta import SigmaDeltaChain, input_integers, readout_value
from snnkart.backends.sigma_delta_counts import SigmaDeltaCounter, SigmaDeltaStep, SigmaDeltaTotals
from snnkart.backends.sigma_delta_policy import SigmaDeltaPolicy
from snnkart.contract import encoding
from snnkart.errors import BackendError, DeployError


class SigmaDeltaEngine(Protocol):
    """Steps a sigma-delta chain one env step (``rows`` Lava steps, input held) per call."""

    arithmetic: Arithmetic
    is_reference: bool

    def env_step(self, x: np.ndarray) -> np.ndarray: ...
    def close(self) -> None: ...


@dataclass
class SigmaDeltaWindow:
    """One env step: the raster (module docstring; ``logical`` is the same array: every row is
    the policy's own), the readout Sigma after the last row, and the step's counts."""

    raster: np.ndarray
    logical: np.ndarray
    sigma: np.ndarray
    counts: SigmaDeltaStep


class NumpyEngine:
    """The numpy reference engine: :class:`~snnkart.backends.sigma_delta.SigmaDeltaChain`
    stepped ``rows`` times per env step on the held input."""

    is_reference = True

    def __init__(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic) -> None:
        self.arithmetic: Arithmetic = arithmetic
        self.chain = SigmaDeltaChain(policy.spec(arithmetic))
        self.rows = policy.block.rows

    def env_step(self, x: np.ndarray) -> np.ndarray:
        rows = []
        for _ in range(self.rows):
            out = self.chain.step(x)
            rows.append(np.concatenate([*self.chain.sent, out]))
        self.chain.messages.clear()  # kept per Lava step by the chain; counted here instead
        return np.stack(rows)

    def close(self) -> None:
        """Nothing to stop: the reference runs in this process."""


class SigmaDeltaCodec:
    """The host side: observation -> the input Delta's held input, readout -> action."""

    def __init__(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic) -> None:
        self.manifest, self.block, self.arithmetic = policy.manifest, policy.block, arithmetic
        self.mean = np.asarray(self.manifest.obs_mean)
        self.std = np.asarray(self.manifest.obs_std)
        self.bias = policy.readout_bias

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        return encoding.normalise(obs, self.mean, self.std, self.manifest.obs_clip)

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """The input Delta's input: message-unit integers (fixed) or ``z`` (float64)."""
        z = np.asarray(self.normalise(obs), np.float64)
        return input_integers(self.block, z) if self.arithmetic == "fixed" else z

    def readout(self, sigma: np.ndarray) -> np.ndarray:
        return readout_value(self.block, sigma, self.bias, self.arithmetic)

    def decode(self, out: np.ndarray) -> Any:
        return encoding.decode(out, self.manifest.action_mode)


class SigmaDeltaBackend(RunningPolicy):
    """The sigma-delta family's running policy: ``step(obs)`` encodes on the host, runs one env
    step (``rows`` Lava steps, input held) on the engine, counts it and returns the window and
    the readout. Subclasses open their engine in :meth:`open_engine`."""

    arithmetics: ClassVar[tuple[Arithmetic, ...]] = ("fixed", "float64")  # Lava's models
    float32_form: ClassVar[bool] = False  # no float32 reference (Lava's models are float64)
    records_inputs: ClassVar[bool] = False  # deploy.json alone
    fixed = None  # no LIF quantisation record: the block's units are the quantisation

    def __init__(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic, seed: int = 0) -> None:
        if arithmetic not in self.arithmetics:
            raise DeployError(
                f"a sigma-delta policy runs in fixed or float64 (Lava's models), not {arithmetic}"
            )
        self.policy, self.manifest, self.block = policy, policy.manifest, policy.block
        self.arithmetic: Arithmetic = arithmetic
        self.codec = SigmaDeltaCodec(policy, arithmetic)
        names = ("input", *(la.node for la in self.block.layers), self.block.readout_node)
        self.counts = SigmaDeltaTotals(names, self.block.rows, self.block.num_message_bits)
        chain_weights = SigmaDeltaChain(policy.spec(arithmetic)).weights
        self.counter = SigmaDeltaCounter(
            chain_weights, self.block.rows, self.block.num_message_bits
        )
        self.engine: SigmaDeltaEngine = self.open_engine(policy, arithmetic)

    @property
    def raster_sizes(self) -> tuple[int, ...]:
        return self.policy.sizes

    def open_engine(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic) -> SigmaDeltaEngine:
        raise NotImplementedError

    def reset(self) -> None:
        """An episode's start: nothing is reset, the chain's state carries on (module doc)."""

    def step(self, obs: np.ndarray) -> tuple[SigmaDeltaWindow, np.ndarray]:
        x = self.codec.encode(obs)
        raster = self.engine.env_step(x)
        expected = (self.block.rows, sum(self.raster_sizes))
        if raster.shape != expected:
            raise BackendError(
                f"the {self.name} engine returned a {raster.shape} raster, not {expected}"
            )
        sigma = raster[-1, -self.raster_sizes[-1] :]
        counts = self.counter.count(raster, x)
        self.counts.add(counts)
        return SigmaDeltaWindow(raster, raster, sigma, counts), self.codec.readout(sigma)

    def parity_references(self) -> tuple[Arithmetic | None, Arithmetic | None]:
        """The same-arithmetic numpy reference (None for the reference itself); no float32
        reference: a sigma-delta chain has no float32 form."""
        return (None if self.engine.is_reference else self.arithmetic), None


class SigmaDeltaReference(SigmaDeltaBackend):
    """``nir-ref`` for a sigma-delta policy: the numpy chain (fixed or float64)."""

    name = "nir-ref"

    def __init__(
        self, source: str | Path | SigmaDeltaPolicy, arithmetic: Arithmetic = "fixed", seed: int = 0
    ) -> None:
        if not isinstance(source, SigmaDeltaPolicy):
            opened = open_policy(source)
            if not isinstance(opened, SigmaDeltaPolicy):
                raise DeployError(f"{source} is not a sigma-delta policy")
            source = opened
        super().__init__(source, arithmetic, seed)

    def open_engine(self, policy: SigmaDeltaPolicy, arithmetic: Arithmetic) -> SigmaDeltaEngine:
        return NumpyEngine(policy, arithmetic)
