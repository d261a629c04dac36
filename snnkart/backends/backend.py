"""One backend over many engines: what every backend shares, around the small engine that only
steps the network.

An :class:`Engine` takes the first layer's input current of one window and returns the spike
raster of the window; it keeps its state from window to window (``reset`` is called only at the
start of an episode) and says how many rows a window has: its logical steps (T, or 1 for an
engine driven one step at a time) plus its pipeline depth (one row per Dense delay; 0 when the
layers run in the same step). The :class:`Backend` does the rest, the same for every engine:
the host codec (observation -> current, spike counts -> action), the split of each window into
the policy's steps and the pipeline's overhead, the counts, and the hooks the parity check
uses (which references shadow it, the window it compares).

A new engine is one new file: a class with this protocol and a :class:`Backend` subclass that
opens it (see :class:`snnkart.backends.reference.NIRReference`), named in
:mod:`snnkart.backends.registry`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from snnkart.backends.base import Arithmetic, SpikeCounts, WindowResult, split_window
from snnkart.backends.host import HostCodec
from snnkart.backends.loading import LoadedPolicy, as_policy
from snnkart.backends.quantize import FixedPointNetwork
from snnkart.contract.link import word_bits
from snnkart.errors import BackendError


class Engine(Protocol):
    """Steps a policy's spiking layers, one window per call.

    ``window(current)``: ``current`` ``[steps, n1]`` (the first layer's input current in the
    engine's arithmetic) -> raster ``[steps + depth, sum(sizes)]``, boolean (binary spikes)
    or integer (graded spikes, 0 = no message)."""

    arithmetic: Arithmetic
    steps: int  # logical SNN steps per window: T, or 1
    depth: int  # pipeline depth: rows of fill/drain per window
    payload_bits: int  # bits one output message carries (0 for a binary spike)
    is_reference: bool  # the numpy oracle itself (needs no same-arithmetic shadow)

    def window(self, current: np.ndarray) -> np.ndarray: ...
    def reset(self) -> None: ...
    def close(self) -> None: ...


class RunningPolicy:
    """What every backend of every family is: a policy running on an engine. ``step(obs)``
    encodes the observation on the host (the family's codec), runs one env step on the engine,
    counts it and returns the window and the readout; ``predict`` the decoded action;
    :meth:`parity_references` the references the parity check shadows it with. Closing stops
    the engine, also as a context manager: a close that fails while another error is on its
    way out gives way to that error.

    A family supplies the model (:class:`Backend` for LIF chains,
    :class:`~snnkart.backends.sigma_delta_backend.SigmaDeltaBackend`); a backend of it opens the
    engine; :data:`snnkart.backends.registry.ENGINES` names each (backend, family) pair."""

    name: ClassVar[str]
    arithmetics: ClassVar[tuple[Arithmetic, ...]] = ("float32", "float64", "fixed")
    float32_form: ClassVar[bool] = True  # the policy has a float32 (torch order) reference
    records_inputs: ClassVar[bool] = True  # a deploy writes inputs.npz (what entered the chip)
    engine: Any
    codec: Any
    manifest: Any
    arithmetic: Arithmetic
    fixed: FixedPointNetwork | None
    counts: Any

    def __init__(self, policy: Any, arithmetic: Arithmetic, seed: int = 0) -> None:
        raise NotImplementedError  # a family's class builds the codec, counts and engine

    @property
    def raster_sizes(self) -> tuple[int, ...]:
        """The raster's blocks of columns (each sending layer's neurons)."""
        raise NotImplementedError

    def step(self, obs: np.ndarray) -> tuple[Any, np.ndarray]:
        raise NotImplementedError

    def reset(self) -> None:
        """The start of an episode."""

    def parity_references(self) -> tuple[Arithmetic | None, Arithmetic | None]:
        """The arithmetic of the reference that must agree bit for bit (None for the reference
        itself) and of the float32 one that measures what the arithmetic changes (None when
        there is none)."""
        raise NotImplementedError

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self.codec.normalise(obs))

    def readout(self, obs: np.ndarray) -> np.ndarray:
        """The readout vector (logits or action means) for one observation."""
        return self.step(obs)[1]

    def predict(self, obs: np.ndarray) -> Any:
        return self.codec.decode(self.readout(obs))

    def close(self) -> None:
        self.engine.close()

    def __enter__(self: _Owner) -> _Owner:
        return self

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self.close()
        else:
            try:
                self.close()
            except BackendError:
                pass  # the engine was stopped; the original error matters more


_Owner = TypeVar("_Owner", bound=RunningPolicy)


class Backend(RunningPolicy):
    """The LIF family's running policy: ``step(obs)`` turns the observation into the first
    layer's current on the host, runs one window on the engine and returns the window and the
    readout.

    Subclasses open their engine in :meth:`open_engine`; everything else is here."""

    def __init__(
        self, source: str | Path | LoadedPolicy, arithmetic: Arithmetic, seed: int = 0
    ) -> None:
        self.policy = as_policy(source)
        self.chain, self.manifest = self.policy.chain, self.policy.manifest
        self.arithmetic: Arithmetic = arithmetic
        self.fixed: FixedPointNetwork | None = self.policy.fixed if arithmetic == "fixed" else None
        self.codec = HostCodec(self.chain, self.manifest, arithmetic, self.fixed, seed)
        self.T = self.manifest.num_steps
        self.counts = SpikeCounts(len(self.chain.layers))
        self.engine = self.open_engine(self.policy, arithmetic)

    @property
    def raster_sizes(self) -> tuple[int, ...]:
        """The raster's blocks of columns: each spiking layer's neurons."""
        return self.chain.sizes

    def open_engine(self, policy: LoadedPolicy, arithmetic: Arithmetic) -> Engine:
        """The engine running ``policy`` in ``arithmetic``, one window per env step."""
        raise NotImplementedError

    def reset(self) -> None:
        """The start of an episode: the engine's reset (its state otherwise runs on)."""
        self.engine.reset()

    def step(self, obs: np.ndarray) -> tuple[WindowResult, np.ndarray]:
        engine = self.engine
        current = self.codec.encode(obs)
        raster = engine.window(current)
        window = split_window(
            raster, self.chain.sizes, engine.steps, engine.depth, engine.payload_bits
        )
        last = window.logical[:, -self.chain.sizes[-1] :]
        # the link (snnkart.contract.link): the currents sent in, the last layer's spikes out
        window.host_to_chip_bits = current.size * word_bits(self.arithmetic)
        window.chip_to_host_bits = last.size * max(1, engine.payload_bits)
        self.counts.add(window, self.chain.fan_out)
        return window, self.codec.readout_spikes(last)

    def parity_references(self) -> tuple[Arithmetic | None, Arithmetic | None]:
        own = self.engine.is_reference
        exact = None if own else self.arithmetic
        float32: Arithmetic | None = None if own and self.arithmetic == "float32" else "float32"
        return exact, float32
