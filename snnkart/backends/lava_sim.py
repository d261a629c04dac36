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
the worker cleanly (see :class:`LavaWorker` for every way out); if this process dies, the
worker sees its input end and closes itself.

Sharp edges: the fixed arithmetic runs the post-training quantisation of
:mod:`snnkart.backends.quantize`; 1 to 3 spiking layers; snntorch-style neurons only.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
import weakref
from pathlib import Path
from typing import Any

import numpy as np

from snnkart import faults
from snnkart.backends.backend import Backend, Engine
from snnkart.backends.base import Arithmetic
from snnkart.backends.lava_params import LavaSpec, SigmaDeltaLavaSpec, lava_spec
from snnkart.backends.lava_worker import HEADER, write_msg
from snnkart.backends.loading import LoadedPolicy
from snnkart.backends.quantize import check_lava_compatible
from snnkart.errors import BackendError
from snnkart.faults import fault_point

STARTUP_TIMEOUT = 120.0
WINDOW_TIMEOUT = 90.0
CLOSE_TIMEOUT = 4.0
"""A normal stop takes 0.03-0.1 s (a cold one under load well under a second)."""
INTERRUPT_GRACE = 2.0
"""Seconds an exchange in flight may still take after Ctrl-C before the worker is killed."""


class LavaBackendError(BackendError):
    """The Lava worker failed, died or timed out; the message says what it reported."""


class LavaWorker:
    """A running worker process: one compiled network, one Lava runtime; the ``lava-sim``
    :class:`~snnkart.backends.backend.Engine` (its state, the runtime, runs on from window to
    window and from episode to episode: every layer is reset inside each window).

    Every way out stops the whole worker session (the worker and the Lava processes it forked):

    - a normal close, and a close after Ctrl-C/SIGTERM (:mod:`snnkart.faults`: the interrupt is
      taken between exchanges, never inside one), asks the worker to stop its runtime and waits
      at most ``CLOSE_TIMEOUT``;
    - an interrupt during start-up, an exchange cut short (a second Ctrl-C), a worker that died
      or failed, or a close that timed out: :meth:`kill`, which SIGTERMs the session so that
      Python's resource tracker (it ignores SIGTERM) frees Lava's shared memory, then SIGKILLs
      what is left;
    - a worker still running when this process exits (an interrupt between start-up and the
      caller's cleanup): the same, from an ``atexit`` hook.
    """

    payload_bits = 0  # binary spikes
    is_reference = False

    def __init__(self, spec: LavaSpec | SigmaDeltaLavaSpec) -> None:
        self.arithmetic: Arithmetic = spec.arithmetic
        self.persist = False  # a stateful LIF policy's network: rebuilt at an episode's start
        if isinstance(spec, LavaSpec):
            self.steps = spec.num_steps
            self.depth = len(spec.sizes) - 1  # one step per Dense
            self.persist = spec.persist
        self.dirty = False  # a persisting network has run a window since it was built
        self.stderr = tempfile.TemporaryFile()
        self._tail = ""  # the last lines of stderr, kept when the file is closed
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "SNNKART_FAULT_PGID": str(os.getpgrp())}
        self.closed = False
        self._stopped = False  # the session has been stopped: nothing left to kill
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "snnkart.backends.lava_worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.stderr,
            start_new_session=True,
            env=env,
        )
        _LIVE.add(self)
        try:
            fault_point("lava-spawn")
            self._send(spec)
            kind, info = self._recv(STARTUP_TIMEOUT, interruptible=True)
            if kind != "ready":
                raise LavaBackendError(f"Lava worker: unexpected reply {kind!r}")
            self.info = info
        except BaseException:
            self.kill()
            raise

    def _stderr_tail(self) -> str:
        """The worker's last 15 lines of output."""
        if self.stderr.closed:
            return self._tail
        self.stderr.seek(0, os.SEEK_END)
        self.stderr.seek(max(0, self.stderr.tell() - 16384))
        text = self.stderr.read().decode(errors="replace").strip()
        return "\n".join(text.splitlines()[-15:])

    def _died(self, code: int) -> LavaBackendError:
        how = (
            f"was killed by {signal.Signals(-code).name}"
            if code < 0
            else f"exited with code {code}"
        )
        self.kill()  # its Lava processes outlive it otherwise
        tail = self._stderr_tail()
        return LavaBackendError(
            f"the Lava backend died: its worker process {how}"
            + (f". Its output:\n{tail}" if tail else "")
        )

    def _send(self, obj: Any) -> None:
        assert self.proc.stdin is not None
        try:
            write_msg(self.proc.stdin, obj)
        except (BrokenPipeError, OSError) as exc:
            code = self.proc.poll()
            raise self._died(code if code is not None else 1) from exc

    def _read_exact(self, n: int, deadline: float, interruptible: bool) -> bytes:
        """Read ``n`` bytes of a reply. Checks ten times a second that the worker is alive (its
        forked Lava processes hold the pipe open, so its death is not an end of file), and
        gives up ``INTERRUPT_GRACE`` seconds after an interrupt (at once if ``interruptible``)."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        chunks, got = [], 0
        while got < n:
            if faults.pending() is not None and (
                interruptible or faults.pending_for() > INTERRUPT_GRACE
            ):
                self.kill()
                faults.check()
            if time.monotonic() > deadline:
                self.kill()
                raise LavaBackendError(
                    "the Lava worker did not answer in time (hung?); it was stopped. "
                    f"Its output:\n{self._stderr_tail()}"
                )
            ready, _, _ = select.select([fd], [], [], 0.1)
            if not ready:
                code = self.proc.poll()
                if code is not None:
                    raise self._died(code)
                continue
            chunk = os.read(fd, n - got)
            if not chunk:
                try:
                    code = self.proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    code = 1
                raise self._died(code)
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def _recv(self, timeout: float, interruptible: bool = False) -> tuple[str, Any]:
        import pickle

        deadline = time.monotonic() + timeout
        (n,) = HEADER.unpack(self._read_exact(HEADER.size, deadline, interruptible))
        kind, payload = pickle.loads(self._read_exact(n, deadline, interruptible))
        if kind == "error":
            self.kill()
            raise LavaBackendError(f"Lava failed: {payload}")
        return kind, payload

    def _exchange(self, request: tuple, phase: str, timeout: float) -> tuple[str, Any]:
        """One request and its reply; anything escaping half-way (a second Ctrl-C) kills the
        worker, since the pipe then holds half a message."""
        if self.closed:
            raise LavaBackendError("the Lava worker was stopped")
        try:
            with faults.caught():
                self._send(request)
                fault_point(phase)
                return self._recv(timeout)
        except BaseException:
            if not self.closed:
                self.kill()
            raise

    def raster(self, values: np.ndarray) -> np.ndarray:
        """One env step's input in, the window's raster out (as the worker's network gives it)."""
        self.dirty = True
        kind, raster = self._exchange(("window", values), "window", WINDOW_TIMEOUT)
        if kind != "raster":
            self.kill()
            raise LavaBackendError(f"Lava worker: unexpected reply {kind!r}")
        return np.asarray(raster)

    def window(self, current: np.ndarray) -> np.ndarray:
        return np.asarray(self.raster(current), dtype=bool)

    def reset(self) -> None:
        """An episode's start: nothing to forget when every layer is reset inside each window;
        a persisting network (a stateful policy) is built again from zero state, unless it has
        not run a window since it was built."""
        if self.persist and self.dirty:
            kind, _ = self._exchange(("reset",), "reset", STARTUP_TIMEOUT)
            if kind != "ready":
                self.kill()
                raise LavaBackendError(f"Lava worker: unexpected reply {kind!r}")
            self.dirty = False

    def close(self) -> None:
        """Ask the worker to stop its Lava runtime; kill its session if it does not."""
        if self.closed:
            return
        try:
            if self.proc.poll() is None:
                self._exchange(("close",), "close", CLOSE_TIMEOUT)
                self.proc.wait(timeout=CLOSE_TIMEOUT)
            self.closed = True
            stop_session(self.proc.pid, grace=CLOSE_TIMEOUT, first=None)  # the tracker's exit
        except subprocess.TimeoutExpired as exc:
            self.kill()
            raise LavaBackendError("the Lava worker did not stop in time; it was killed") from exc
        finally:
            if not self.closed:
                self.kill()
            self._finish()

    def kill(self) -> None:
        """Stop the worker and every Lava process it forked (they share its session); once:
        the session's id may belong to other processes after that."""
        self.closed = True
        if self._stopped:
            return
        stop_session(self.proc.pid)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=1)
        self._finish()

    def _finish(self) -> None:
        """The session is stopped: keep the output's tail, close the pipes and the file."""
        self._stopped = True
        _LIVE.discard(self)
        self._tail = self._stderr_tail()
        for stream in (self.stderr, self.proc.stdin, self.proc.stdout):
            with contextlib.suppress(OSError):
                if stream is not None:
                    stream.close()


def _session_members(sid: int) -> list[int]:
    """Live (not zombie) processes of session ``sid``, from /proc."""
    members = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z" and int(fields[3]) == sid:  # state, ppid, pgrp, session
            members.append(int(entry))
    return members


def stop_session(sid: int, grace: float = 3.0, first: int | None = signal.SIGTERM) -> None:
    """Send ``first`` to every process of the worker's session, wait up to ``grace`` seconds
    for them to end, SIGKILL what is left.

    SIGTERM first: Lava's processes die at once, while Python's resource tracker, which ignores
    SIGTERM, outlives them and unlinks the shared memory they registered (SIGKILL would leave
    it in /dev/shm); it exits by itself once the last of them is gone. After a normal close
    (``first=None``) only the tracker is left, for a moment."""
    if first is not None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(sid, first)
    deadline = time.monotonic() + grace
    while _session_members(sid) and time.monotonic() < deadline:
        time.sleep(0.02)
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(sid, signal.SIGKILL)


_LIVE: weakref.WeakSet[LavaWorker] = weakref.WeakSet()


@atexit.register
def _stop_live_workers() -> None:
    for worker in list(_LIVE):
        worker.kill()


class LavaSimPredictor(Backend):
    """The ``lava-sim`` backend: the policy's spiking layers in a Lava worker
    (``arithmetic``: float64, Lava's floating-point models, or fixed, its bit-accurate ones);
    ``step`` also returns the window."""

    name = "lava-sim"

    def __init__(
        self, source: str | Path | LoadedPolicy, arithmetic: Arithmetic = "fixed", seed: int = 0
    ) -> None:
        if arithmetic not in ("float64", "fixed"):
            raise ValueError(f"Lava runs float64 or fixed, not {arithmetic!r}")
        super().__init__(source, arithmetic, seed)
        self.startup_s = float(self.worker.info["startup_s"])

    def open_engine(self, policy: LoadedPolicy, arithmetic: Arithmetic) -> Engine:
        if self.fixed is None:
            check_lava_compatible(policy.chain)
        spec = lava_spec(
            policy.chain, policy.num_steps, arithmetic, self.fixed, policy.manifest.state_persists
        )
        self.worker = LavaWorker(spec)
        return self.worker
