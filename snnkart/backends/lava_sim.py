"""``lava-sim``: the policy's spiking layers on Lava's CPU-simulated Loihi (``Loihi2SimCfg``).

The host (this process) normalises and encodes each observation, a worker process
(:mod:`snnkart.backends.lava_worker`) runs the LIF populations and Dense synapses as Lava's own
library processes and returns each window's spike raster, and the host reads the action out of
the last layer's spike counts. Host code is shared with the numpy reference
(:class:`~snnkart.backends.host.HostCodec`), so the two differ only in the spiking layers, and
:class:`~snnkart.backends.reference.ChainSimulator` in the same arithmetic is the bit-exact
oracle for them.

Lava never enters this process (importing it sets the multiprocessing start method). The worker
runs in its own session, so a terminal's Ctrl-C reaches only this process, which then closes
the worker cleanly; if this process dies, the worker sees its input end and closes itself.

Sharp edges: ``precision="fixed"`` runs the post-training quantisation of
:mod:`snnkart.backends.quantize`; 1 to 3 spiking layers; snntorch-style neurons only.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.backends.host import HostCodec
from snnkart.backends.lava_worker import HEADER, write_msg
from snnkart.backends.quantize import FixedPointNetwork, quantize
from snnkart.backends.reference import SpikeCounts, WindowResult, load_chain, split_window

PRECISIONS = ("float", "fixed")
STARTUP_TIMEOUT = 120.0
WINDOW_TIMEOUT = 90.0
CLOSE_TIMEOUT = 15.0


@contextlib.contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold Ctrl-C until one request/reply exchange with the worker is complete, so an
    interrupt never leaves half a message in the pipe (the close that follows would then read
    garbage and wait); the KeyboardInterrupt is raised right after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    hits: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: hits.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)
        if hits:
            raise KeyboardInterrupt


class LavaBackendError(RuntimeError):
    """Lava is unavailable, failed or hung; the message says which and what to do."""


def lava_spec(chain: Any, num_steps: int, precision: str, fixed: FixedPointNetwork | None) -> dict:
    """The worker's network description: Lava LIF/Dense parameters per layer."""
    layers = []
    for i, layer in enumerate(chain.layers):
        if precision == "float":
            layers.append({
                "du": 1.0,
                "dv": 1.0 - float(layer.beta[0]),
                "vth": float(layer.threshold[0]),
                "bias_mant": np.zeros(layer.size) if i == 0 else layer.bias.astype(np.float64),
                "bias_exp": 0,
                "weight": None if i == 0 else layer.weight.astype(np.float64),
            })  # fmt: skip
        else:
            assert fixed is not None
            q = fixed.layers[i]
            layers.append({
                "du": q.du,
                "dv": q.dv,
                "vth": q.vth,
                "bias_mant": q.bias_mant.astype(np.int32),
                "bias_exp": q.bias_exp,
                "weight": None if q.weight is None else q.weight.astype(np.int32),
            })  # fmt: skip
    return {
        "precision": precision,
        "num_steps": num_steps,
        "sizes": chain.sizes,
        "layers": layers,
    }


class LavaWorker:
    """A running worker process: one compiled network, one Lava runtime."""

    def __init__(self, spec: dict[str, Any]) -> None:
        self.stderr = tempfile.TemporaryFile()
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "snnkart.backends.lava_worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.stderr,
            start_new_session=True,
            env=env,
        )
        self.closed = False
        try:
            self._send(spec)
            kind, info = self._recv(STARTUP_TIMEOUT)
            if kind != "ready":
                raise LavaBackendError(f"Lava worker: unexpected reply {kind!r}")
            self.info = info
        except BaseException:
            self.kill()
            raise

    def _stderr_tail(self) -> str:
        self.stderr.seek(0)
        text = self.stderr.read().decode(errors="replace").strip()
        return "\n".join(text.splitlines()[-15:])

    def _send(self, obj: Any) -> None:
        assert self.proc.stdin is not None
        try:
            write_msg(self.proc.stdin, obj)
        except (BrokenPipeError, OSError) as exc:
            raise LavaBackendError(
                f"the Lava worker exited ({self.proc.poll()}): {self._stderr_tail()}"
            ) from exc

    def _read_exact(self, n: int, deadline: float) -> bytes:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        chunks, got = [], 0
        while got < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise LavaBackendError(
                    "the Lava worker did not answer in time (hung?); it was stopped. "
                    f"Its output:\n{self._stderr_tail()}"
                )
            ready, _, _ = select.select([fd], [], [], min(left, 1.0))
            if not ready:
                continue
            chunk = os.read(fd, n - got)
            if not chunk:
                code = self.proc.wait(timeout=5)
                raise LavaBackendError(
                    f"the Lava worker exited with code {code}. Its output:\n{self._stderr_tail()}"
                )
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def _recv(self, timeout: float) -> tuple[str, Any]:
        import pickle

        deadline = time.monotonic() + timeout
        (n,) = HEADER.unpack(self._read_exact(HEADER.size, deadline))
        kind, payload = pickle.loads(self._read_exact(n, deadline))
        if kind == "error":
            raise LavaBackendError(f"Lava failed: {payload}")
        return kind, payload

    def window(self, current: np.ndarray) -> np.ndarray:
        with _sigint_deferred():
            self._send(("window", current))
            kind, raster = self._recv(WINDOW_TIMEOUT)
        if kind != "raster":
            raise LavaBackendError(f"Lava worker: unexpected reply {kind!r}")
        return np.asarray(raster, dtype=bool)

    def close(self) -> None:
        """Ask the worker to stop its Lava runtime; kill its session if it does not."""
        if self.closed:
            return
        self.closed = True
        try:
            if self.proc.poll() is None:
                with _sigint_deferred():
                    self._send(("close",))
                    self._recv(CLOSE_TIMEOUT)
                    self.proc.wait(timeout=CLOSE_TIMEOUT)
        except (LavaBackendError, subprocess.TimeoutExpired):
            self.kill()
            raise
        finally:
            self.stderr.close()

    def kill(self) -> None:
        """Kill the worker and every Lava process it forked (they share its session)."""
        self.closed = True
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()


class LavaSimPredictor:
    """Predictor running the exported policy on Lava; ``step`` also returns the window."""

    def __init__(self, nir_path: str | Path, precision: str = "fixed", seed: int = 0) -> None:
        if precision not in PRECISIONS:
            raise ValueError(f"unknown precision {precision!r}; choose float or fixed")
        self.chain, self.manifest = load_chain(nir_path)
        self.precision = precision
        self.fixed = quantize(self.chain) if precision == "fixed" else None
        arithmetic = "fixed" if precision == "fixed" else "float64"
        self.codec = HostCodec(self.chain, self.manifest, arithmetic, self.fixed, seed)
        self.T = self.manifest.num_steps
        self.counts = SpikeCounts(len(self.chain.layers))
        if self.fixed is None:
            from snnkart.backends.quantize import check_lava_compatible

            check_lava_compatible(self.chain)
        spec = lava_spec(self.chain, self.T, precision, self.fixed)
        self.worker = LavaWorker(spec)
        self.startup_s = float(self.worker.info["startup_s"])

    def reset(self) -> None:
        """Nothing to forget: every layer is reset at the start of each window."""

    def step(self, obs: np.ndarray) -> tuple[WindowResult, np.ndarray]:
        raster = self.worker.window(self.codec.encode(obs))
        window = split_window(raster, self.chain.sizes, self.T)
        self.counts.add(window, self.chain.fan_out)
        return window, self.codec.readout(window.last_counts)

    def predict(self, obs: np.ndarray) -> Any:
        return self.codec.decode(self.step(obs)[1])

    def close(self) -> None:
        self.worker.close()

    def __enter__(self) -> LavaSimPredictor:
        return self

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self.close()
        else:
            try:
                self.close()
            except (LavaBackendError, subprocess.TimeoutExpired):
                pass  # the worker was killed; the original error matters more
