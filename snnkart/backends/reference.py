"""The numpy reference executor of an exported policy: the oracle every other backend is checked
against. It reads only the ``.nir`` file and its manifest, never training code.

Three arithmetics (:data:`snnkart.backends.base.Arithmetic`):

- ``float32``: torch's order of operations, one logical window of T SNN steps per env step
  starting from zero membranes (and currents): ``v = beta v + I`` (LIF; a CubaLIF first
  ``i = alpha i + I``, then ``v = beta v + i``), spike if ``v - theta > 0``, reset to 0.
  It differs from the torch policy only through matrix-multiply summation order (rare
  threshold flips).
- ``float64``: exactly what Lava's floating-point models compute (``PyLifResetModelFloat``,
  ``PyDenseModelFloat``): float64, the bias added separately, and the Lava pipeline below.
- ``fixed``: exactly what Lava's bit-accurate models compute (``PyLifResetModelBitAcc``,
  ``PyDenseModelBitAcc``) on the quantised network (:mod:`snnkart.backends.quantize`):
  24-bit state with wrap-around and saturation, decays truncated toward zero.

The Lava pipeline: the first layer is fed by the host (its current, see
:mod:`snnkart.backends.host`), each further layer through a Dense, and every Dense delays by
one step. With L = layers - 1 Dense synapses, each env step is a window of ``W = T + L`` Lava
steps; layer i is reset at window row i (``LIFReset(reset_interval=W, reset_offset=(i+1) % W)``,
Lava's time starting at 1) and computes the policy's logical steps 0..T-1 at rows i..i+T-1.
The other rows are the pipeline's fill and drain: their neuron updates and (bias-driven) spikes
are counted apart as overhead, so the policy's own counts equal the float32 window's.

A stateful policy (manifest ``state_persists``, docs/stateful.md) runs the same W rows per env
step with no reset: every arithmetic, float32 included (:class:`Float32Stream`, torch's order on
the row stream training simulated), carries the membranes and the Dense buffers from env step to
env step, and ``reset()`` (an episode's start) zeroes them.

Sharp edges: only feed-forward chains (:mod:`snnkart.backends.network`); the Lava arithmetics
need snntorch-style layers (uniform beta and threshold, reset to 0, no leak term).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snnkart.backends.backend import Backend, Engine
from snnkart.backends.base import ARITHMETICS, Arithmetic, check_arithmetic
from snnkart.backends.lava_params import lava_layers
from snnkart.backends.loading import LoadedPolicy
from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import (
    ACT_SHIFT,
    DECAY_UNITY,
    UV_MAX,
    FixedPointNetwork,
    check_lava_compatible,
    quantize,
)
from snnkart.contract.manifest import ManifestError
from snnkart.errors import NIRFileError


class _Simulator:
    """A chain's spiking layers in one arithmetic, an :class:`~snnkart.backends.backend.Engine`:
    ``window(current)`` takes the first layer's input current ``[T, n1]`` (from the host codec)
    and returns the window's raster, ``[T + depth, sum(sizes)]``."""

    arithmetic: Arithmetic
    depth = 0
    payload_bits = 0  # binary spikes
    is_reference = True

    def __init__(self, chain: ChainNetwork, num_steps: int) -> None:
        self.chain = chain
        self.T = num_steps
        self.steps = num_steps
        self.sizes = chain.sizes
        self.L = len(self.sizes) - 1
        self.offsets = np.cumsum((0, *self.sizes))

    def reset(self) -> None:
        """Nothing to forget at an episode's start: every layer is reset inside each window
        (a Lava pipeline's time and Dense buffers run on, as they do on Lava)."""

    def close(self) -> None:
        """Nothing to stop: the reference runs in this process."""

    def window(self, current: np.ndarray) -> np.ndarray:
        if current.shape != (self.T, self.sizes[0]):
            raise ValueError(f"current must be [T, n1] = {(self.T, self.sizes[0])}")
        return self._window(current)

    def _window(self, current: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class Float32Chain(_Simulator):
    """torch's order of operations: T logical steps from zero membranes, no pipeline."""

    arithmetic: Arithmetic = "float32"

    def __init__(self, chain: ChainNetwork, num_steps: int) -> None:
        super().__init__(chain, num_steps)
        f32 = np.float32
        self.weights = [layer.weight for layer in chain.layers]
        self.biases = [layer.bias for layer in chain.layers]
        self.beta = [layer.beta.astype(f32) for layer in chain.layers]
        self.gain = [layer.gain.astype(f32) for layer in chain.layers]
        self.leak = [layer.leak.astype(f32) for layer in chain.layers]
        self.theta = [layer.threshold.astype(f32) for layer in chain.layers]
        self.v_reset = [layer.v_reset.astype(f32) for layer in chain.layers]
        self.alpha = [None if a.alpha is None else a.alpha.astype(f32) for a in chain.layers]
        self.syn_gain = [
            None if a.syn_gain is None else a.syn_gain.astype(f32) for a in chain.layers
        ]

    membranes: np.ndarray | None = None  # [T, N] before reset, while trace() runs

    def trace(self, current: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The window's raster and every neuron's membrane before its reset, ``[T, N]``."""
        self.membranes = np.zeros((self.T, self.offsets[-1]), dtype=np.float32)
        try:
            raster = self.window(current)
            membranes = self.membranes
        finally:
            self.membranes = None
        return raster, membranes

    def _window(self, current: np.ndarray) -> np.ndarray:
        T, offsets = self.T, self.offsets
        raster = np.zeros((T, offsets[-1]), dtype=bool)
        v = [np.zeros(n, dtype=np.float32) for n in self.sizes]
        syn = [np.zeros(n, dtype=np.float32) for n in self.sizes]
        own = [np.zeros(n, dtype=bool) for n in self.sizes]  # each layer's spikes at t - 1
        for t in range(T):
            s_prev: np.ndarray | None = None
            for i in range(len(self.sizes)):
                if i == 0:
                    inp = current[t]
                else:
                    assert s_prev is not None
                    inp = self.weights[i] @ s_prev.astype(np.float32) + self.biases[i]
                rec = self.chain.layers[i].recurrent
                if rec is not None:  # its own spikes of the step before
                    inp = inp + rec @ own[i].astype(np.float32)
                alpha, syn_gain = self.alpha[i], self.syn_gain[i]
                if alpha is not None and syn_gain is not None:  # CubaLIF: a current first
                    syn[i] = alpha * syn[i] + (
                        inp if self.chain.layers[i].plain else syn_gain * inp
                    )
                    inp = syn[i]
                if self.chain.layers[i].plain:
                    v[i] = self.beta[i] * v[i] + inp
                else:
                    v[i] = self.beta[i] * v[i] + self.gain[i] * inp + self.leak[i]
                if self.membranes is not None:
                    self.membranes[t, offsets[i] : offsets[i + 1]] = v[i]
                s = v[i] - self.theta[i] > 0
                v[i][s] = self.v_reset[i][s]
                raster[t, offsets[i] : offsets[i + 1]] = s
                s_prev = own[i] = s
        return raster


class _LavaPipeline(_Simulator):
    """Lava's pipeline (module docstring): W = T + L rows per window, layer i reset at row i,
    each Dense one step late. The state carries across windows (Dense buffers, the Lava time
    step), as it does on Lava."""

    weights: list[np.ndarray]  # the Dense weights feeding layers 1.. (index i-1)
    buffers: list[np.ndarray]  # what each Dense sends next step
    u: list[np.ndarray]
    v: list[np.ndarray]

    recurrent: list[np.ndarray | None]  # each layer's recurrent Dense weights, or None
    loops: list[np.ndarray]  # what each recurrent Dense sends next step

    def __init__(self, chain: ChainNetwork, num_steps: int, persist: bool = False) -> None:
        super().__init__(chain, num_steps)
        check_lava_compatible(chain)
        self.depth = self.L
        self.W = num_steps + self.L
        self.t = 1  # Lava's first time step
        self.persist = persist

    def reset(self) -> None:
        """An episode's start: a persisting pipeline zeroes its state (a per-window one has
        nothing to forget)."""
        if self.persist:
            self._zero()

    def _zero(self) -> None:
        for x in (*self.u, *self.v, *self.buffers, *self.loops):
            x[...] = 0

    def _loop(self, i: int, spikes: np.ndarray) -> None:
        """Layer i's recurrent Dense integrates its own spikes of this row for the next."""
        weight = self.recurrent[i]
        assert weight is not None
        self.loops[i] = weight[:, spikes].sum(axis=1)

    def _reset_due(self, i: int) -> bool:
        return not self.persist and self.t % self.W == (i + 1) % self.W

    def _deliver(self, i: int, spikes: np.ndarray) -> None:
        """Dense i integrates layer i-1's spikes of this row into what it sends next row."""
        self.buffers[i - 1] = self.weights[i - 1][:, spikes].sum(axis=1)

    def _lif(self, i: int, a_in: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _window(self, current: np.ndarray) -> np.ndarray:
        if self.chain.recurrent and not self.persist and self.t > 1:
            raise ManifestError(
                "a recurrent graph runs more than one window on Lava's pipeline only with its "
                "state carried across env steps (manifest state_persists): the per-window "
                "reset of a LIF does not clear what its recurrent Dense holds"
            )
        K, T, offsets = len(self.sizes), self.T, self.offsets
        raster = np.zeros((self.W, offsets[-1]), dtype=bool)
        zero = np.zeros_like(current[0])
        for r in range(self.W):
            spikes = []
            for i in range(K):
                a_in = (current[r] if r < T else zero) if i == 0 else self.buffers[i - 1]
                if self.recurrent[i] is not None:  # both Dense outputs arrive at a_in
                    a_in = a_in + self.loops[i]
                s = self._lif(i, a_in)
                raster[r, offsets[i] : offsets[i + 1]] = s
                spikes.append(s)
            for i in range(1, K):  # each Dense sent its old buffer first, then integrates
                self._deliver(i, spikes[i - 1])
            for i in range(K):
                if self.recurrent[i] is not None:
                    self._loop(i, spikes[i])
            self.t += 1
        return raster


class Float32Stream(_LavaPipeline):
    """A stateful policy in torch's order on Lava's row stream (what training simulates,
    :mod:`snnkart.rl.stateful`): float32, ``v = beta v + I``, spike if ``v - theta > 0``, reset
    to 0; layer i > 0 gets ``W_i s_{i-1} + b_i`` of the row before, layer 0 the host's current
    on rows < T and 0 on the drain rows. Nothing is reset inside or between windows; ``reset()``
    zeroes the state (an episode's start)."""

    arithmetic: Arithmetic = "float32"

    def __init__(self, chain: ChainNetwork, num_steps: int) -> None:
        super().__init__(chain, num_steps, persist=True)
        if any(layer.alpha is not None for layer in chain.layers):
            raise ManifestError(
                "a stateful policy runs plain LIF layers; this graph has CubaLIF nodes"
            )
        f32 = np.float32
        self.w32 = [layer.weight for layer in chain.layers]
        self.b32 = [layer.bias for layer in chain.layers]
        self.beta = [layer.beta.astype(f32) for layer in chain.layers]
        self.theta = [layer.threshold.astype(f32) for layer in chain.layers]
        self.u: list[np.ndarray] = []
        self.v = [np.zeros(n, dtype=f32) for n in self.sizes]
        self.buffers = [np.zeros(n, dtype=f32) for n in self.sizes[1:]]
        self.recurrent = [layer.recurrent for layer in chain.layers]
        self.loops = [np.zeros(n, dtype=f32) for n in self.sizes]
        self._zero()  # layer i > 0 gets its bias b_i from the first row on

    def _zero(self) -> None:
        super()._zero()
        for i in range(1, len(self.sizes)):  # no spikes in flight: W_i 0 + b_i
            self.buffers[i - 1][...] = self.b32[i]

    def _deliver(self, i: int, spikes: np.ndarray) -> None:
        self.buffers[i - 1] = self.w32[i] @ spikes.astype(np.float32) + self.b32[i]

    def _loop(self, i: int, spikes: np.ndarray) -> None:
        weight = self.recurrent[i]
        assert weight is not None
        self.loops[i] = weight @ spikes.astype(np.float32)  # torch: fc(s_prev) + rec(s_own)

    def _lif(self, i: int, a_in: np.ndarray) -> np.ndarray:
        self.v[i] = self.beta[i] * self.v[i] + a_in.astype(np.float32, copy=False)
        s = self.v[i] - self.theta[i] > 0
        self.v[i][s] = 0
        return s


class LavaFloatChain(_LavaPipeline):
    """What Lava's floating-point models compute: float64, ``u = u (1 - du) + a_in`` (``du`` 1
    for LIF, ``1 - alpha`` for CubaLIF),
    ``v = v (1 - dv) + u + bias`` with the parameters Lava's processes get
    (:mod:`snnkart.backends.lava_params`)."""

    arithmetic: Arithmetic = "float64"

    def __init__(self, chain: ChainNetwork, num_steps: int, persist: bool = False) -> None:
        super().__init__(chain, num_steps, persist)
        params = lava_layers(chain, "float64")
        self.weights = [np.asarray(p.weight) for p in params[1:]]
        self.du = [float(p.du) for p in params]
        self.dv = [float(p.dv) for p in params]
        self.vth = [float(p.vth) for p in params]
        self.bias = [np.asarray(p.bias_mant, dtype=np.float64) for p in params]
        self.u = [np.zeros(n) for n in self.sizes]
        self.v = [np.zeros(n) for n in self.sizes]
        self.buffers = [np.zeros(n) for n in self.sizes[1:]]
        self.recurrent = [None if p.recurrent is None else np.asarray(p.recurrent) for p in params]
        self.loops = [np.zeros(n) for n in self.sizes]

    def _lif(self, i: int, a_in: np.ndarray) -> np.ndarray:
        if self._reset_due(i):
            self.u[i] *= 0
            self.v[i] *= 0
        self.u[i] = self.u[i] * (1 - self.du[i])
        self.u[i] += a_in
        self.v[i] = self.v[i] * (1 - self.dv[i]) + self.u[i] + self.bias[i]
        s = self.v[i] > self.vth[i]
        self.v[i][s] = 0
        return s


class LavaFixedChain(_LavaPipeline):
    """What Lava's bit-accurate models compute on the quantised network: 24-bit state with
    wrap-around and saturation, decays truncated toward zero."""

    arithmetic: Arithmetic = "fixed"

    def __init__(
        self,
        chain: ChainNetwork,
        num_steps: int,
        fixed: FixedPointNetwork | None = None,
        persist: bool = False,
    ) -> None:
        super().__init__(chain, num_steps, persist)
        self.fixed = fixed if fixed is not None else quantize(chain)
        q = self.fixed.layers
        self.weights = [np.asarray(layer.weight) for layer in q[1:]]
        self.eff_bias = [layer.effective_bias for layer in q]
        self.eff_vth = [layer.vth << ACT_SHIFT for layer in q]
        self.decay_u = [DECAY_UNITY - (layer.du + 1) for layer in q]
        self.decay_v = [DECAY_UNITY - layer.dv for layer in q]
        self.u = [np.zeros(n, dtype=np.int64) for n in self.sizes]
        self.v = [np.zeros(n, dtype=np.int64) for n in self.sizes]
        self.buffers = [np.zeros(n, dtype=np.int64) for n in self.sizes[1:]]
        self.recurrent = [
            None if layer.recurrent is None else np.asarray(layer.recurrent) for layer in q
        ]
        self.loops = [np.zeros(n, dtype=np.int64) for n in self.sizes]

    def _lif(self, i: int, a_in: np.ndarray) -> np.ndarray:
        if self._reset_due(i):
            self.u[i] *= 0
            self.v[i] *= 0
        du = self.u[i] * self.decay_u[i]
        u = np.sign(du) * np.right_shift(np.abs(du), 12) + np.left_shift(a_in, ACT_SHIFT)
        u = np.where(u > UV_MAX, u - 2 * UV_MAX, u)
        u = np.where(u <= -UV_MAX, u + 2 * UV_MAX, u)
        self.u[i] = u
        dv = self.v[i] * self.decay_v[i]
        v = np.sign(dv) * np.right_shift(np.abs(dv), 12) + u + self.eff_bias[i]
        v = np.clip(v, -UV_MAX + 1, UV_MAX - 1)
        s = v > self.eff_vth[i]
        v[s] = 0
        self.v[i] = v
        return s


def ChainSimulator(
    chain: ChainNetwork,
    num_steps: int,
    arithmetic: str,
    fixed: FixedPointNetwork | None = None,
    persist: bool = False,
) -> Float32Chain | Float32Stream | LavaFloatChain | LavaFixedChain:
    """The simulator of ``chain`` in ``arithmetic`` (one class per arithmetic); ``persist``:
    a stateful policy's (the state carries across windows)."""
    checked = check_arithmetic(arithmetic)
    if checked == "float32":
        return Float32Stream(chain, num_steps) if persist else Float32Chain(chain, num_steps)
    if checked == "float64":
        return LavaFloatChain(chain, num_steps, persist)
    return LavaFixedChain(chain, num_steps, fixed, persist)


def reference_engine(policy: LoadedPolicy, arithmetic: Arithmetic) -> Engine:
    """The numpy engine running ``policy`` in ``arithmetic``."""
    fixed = policy.fixed if arithmetic == "fixed" else None
    persist = policy.manifest.state_persists
    return ChainSimulator(policy.chain, policy.num_steps, arithmetic, fixed, persist)


class NIRReference(Backend):
    """The numpy reference backend: an exported policy in numpy, in any arithmetic; counts
    spikes per layer per logical step. ``step(obs)`` returns the window (raster, counts) and
    the readout; ``predict`` the action."""

    name = "nir-ref"

    def __init__(
        self, source: str | Path | LoadedPolicy, arithmetic: str = "float32", seed: int = 0
    ) -> None:
        super().__init__(source, check_arithmetic(arithmetic), seed)

    def open_engine(self, policy: LoadedPolicy, arithmetic: Arithmetic) -> Engine:
        return reference_engine(policy, arithmetic)


__all__ = [
    "ARITHMETICS",
    "ChainSimulator",
    "Float32Chain",
    "Float32Stream",
    "LavaFixedChain",
    "LavaFloatChain",
    "ManifestError",
    "NIRFileError",
    "NIRReference",
]
