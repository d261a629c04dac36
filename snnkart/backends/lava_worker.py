"""The Lava side of ``lava-sim``: a separate Python process that builds the spiking layers as
Lava library processes, runs them on ``Loihi2SimCfg`` and serves one window per request.

Run as ``python -m snnkart.backends.lava_worker`` by :mod:`snnkart.backends.lava_sim`, never
imported by the rest of snnkart: importing lava sets the multiprocessing start method to fork,
which must not happen in a process that trains or uses torch's multiprocessing.

Protocol (length-prefixed pickles): stdin receives a :class:`~snnkart.backends.lava_params.LavaSpec`, then ``("window", current)``
per env step and finally ``("close",)``; the protocol stream answers ``("ready", info)``,
``("raster", array)`` per window, ``("closed", info)`` or ``("error", message)``. Anything
Lava prints goes to stderr. On end of input (the parent died) the run is closed the same way.

Network (L = layers - 1 Dense synapses, window W = T + L):

    HostBridge.a_out -> LIFReset_0 -> Dense_1 -> LIFReset_1 -> ... -> LIFReset_{L}
    every LIFReset_i.s_out -> HostBridge.s_in{i}      (the spike raster, read back per window)

with ``LIFReset(reset_interval=W, reset_offset=(i + 1) % W)``, or for a stateful policy
(``LavaSpec.persist``) plain ``LIF`` processes (the same bit-accurate arithmetic, never reset):
the state carries from window to window. Lava stays running for the whole session in one
non-blocking ``RunSteps``; the bridge blocks on the host at the start of each window, so the
host paces it, and a close request makes the bridge ask the runtime to stop. A ``("reset",)``
request (a stateful policy's episode start) stops the runtime and builds the network again, from
zero state, and answers ``("ready", info)``: what a host does on a chip by writing zeros to the
neuron and synapse state between episodes.
"""

from __future__ import annotations

import os
import pickle
import signal
import struct
import sys
import time
import traceback
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from snnkart.backends import lava_compat

if TYPE_CHECKING:
    from snnkart.backends.lava_params import LavaSpec

RECV_TIMEOUT = 60.0
"""Seconds one window may take before the worker declares Lava hung."""
HEADER = struct.Struct("<Q")


def write_msg(stream: IO[bytes], obj: Any, phase: str | None = None) -> None:
    """Write one length-prefixed message; ``phase`` names a fault point between the header and
    the payload (tests interrupt there: "while the worker writes its reply")."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    if phase is None:
        stream.write(HEADER.pack(len(data)) + data)
    else:
        from snnkart.faults import fault_point

        stream.write(HEADER.pack(len(data)))
        stream.flush()
        fault_point(phase)
        stream.write(data)
    stream.flush()


def read_msg(stream: IO[bytes]) -> Any:
    head = stream.read(HEADER.size)
    if len(head) < HEADER.size:
        raise EOFError
    (n,) = HEADER.unpack(head)
    data = stream.read(n)
    if len(data) < n:
        raise EOFError
    return pickle.loads(data)


class LavaNetwork:
    """The compiled Lava network and its running runtime."""

    def __init__(self, spec: LavaSpec) -> None:
        from lava.magma.core.run_conditions import RunSteps
        from lava.magma.core.run_configs import Loihi2SimCfg
        from lava.proc.dense.process import Dense
        from lava.proc.lif.process import LIF, LIFReset

        from snnkart.backends.lava_procs.bridge import HostBridge
        from snnkart.faults import fault_point

        self.fixed = spec.arithmetic == "fixed"
        self.T = int(spec.num_steps)
        self.sizes = tuple(int(n) for n in spec.sizes)
        K = len(self.sizes)
        self.W = self.T + K - 1
        self.bridge = HostBridge(sizes=self.sizes, num_steps=self.T, name="host_bridge")
        self.lifs = []
        for i, layer in enumerate(spec.layers):
            common = dict(shape=(self.sizes[i],), du=layer.du, dv=layer.dv, vth=layer.vth,
                          bias_mant=layer.bias_mant, bias_exp=layer.bias_exp, name=f"lif{i}")  # fmt: skip
            lif = (
                LIF(**common)
                if spec.persist
                else LIFReset(**common, reset_interval=self.W, reset_offset=(i + 1) % self.W)
            )
            self.lifs.append(lif)
            lif.s_out.connect(getattr(self.bridge, f"s_in{i}"))
        self.bridge.a_out.connect(self.lifs[0].a_in)
        self.dense = []
        for i in range(1, K):
            layer = spec.layers[i]
            kwargs: dict[str, Any] = {}
            if self.fixed:
                kwargs = {"num_weight_bits": 8, "weight_exp": 0}
            dense = Dense(weights=layer.weight, name=f"dense{i}", **kwargs)
            self.lifs[i - 1].s_out.connect(dense.s_in)
            dense.a_out.connect(self.lifs[i].a_in)
            self.dense.append(dense)
        tag = "fixed_pt" if self.fixed else "floating_pt"
        self.run_cfg = Loihi2SimCfg(select_tag=tag)
        self.dtype = np.int32 if self.fixed else np.float64
        t0 = time.perf_counter()
        # SIGINT is ignored while the runtime forks its processes, so they inherit "ignore":
        # the parent owns Ctrl-C and ends the run through the close request.
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            fault_point("lava-startup")  # (a delay lands the signal while the runtime forks)
            self.bridge.create_runtime(run_cfg=self.run_cfg)
        finally:
            signal.signal(signal.SIGINT, previous)
        self.runtime = self.bridge.runtime
        self.startup_s = time.perf_counter() - t0
        self.host_send = self.bridge.host_in.external_pipe_csp_send_port
        self.host_recv = self.bridge.host_out.external_pipe_csp_recv_port
        self.bridge.run(condition=RunSteps(num_steps=2**62, blocking=False), run_cfg=self.run_cfg)
        self.windows = 0
        self.closed = False

    def _recv(self, timeout: float = RECV_TIMEOUT) -> np.ndarray:
        """Receive from the bridge, failing fast when a Lava process died or nothing comes."""
        return lava_compat.receive(self.host_recv, self.runtime, timeout)

    def window(self, current: np.ndarray) -> np.ndarray:
        msg = np.zeros(self.T * self.sizes[0] + 1, dtype=self.dtype)
        msg[:-1] = np.asarray(current).reshape(-1)
        self.host_send.send(msg)
        raster = self._recv()
        self.windows += 1
        return raster.reshape(self.W, sum(self.sizes)) != 0

    def close(self) -> None:
        """End the run through the bridge's stop request, then stop the runtime."""
        if self.closed:
            return
        self.closed = True
        msg = np.zeros(self.T * self.sizes[0] + 1, dtype=self.dtype)
        msg[-1] = 1
        self.host_send.send(msg)
        self.runtime.wait()  # receives REQ_STOP and stops the runtime
        if lava_compat.is_started(self.runtime):
            self.runtime.stop()


def abort(net: LavaNetwork | None) -> None:
    """Last resort after a failure: terminate this runtime's processes and shared memory."""
    if net is not None:
        lava_compat.terminate(net.runtime)


def main() -> int:
    # The parent ends us with a close request, or with SIGTERM to this session (default action:
    # Lava's processes die, and Python's resource tracker frees their shared memory).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    proto_out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # Lava's prints go to stderr
    proto_in = sys.stdin.buffer
    net: LavaNetwork | None = None
    try:
        spec = read_msg(proto_in)
        try:
            import lava.magma.core.run_configs  # noqa: F401
        except Exception as exc:
            write_msg(
                proto_out,
                ("error", f"Lava (lava-nc 0.10) cannot be imported in Python "
                          f"{sys.version.split()[0]} ({type(exc).__name__}: {exc}); it needs "
                          "Python 3.10 and numpy < 2: run `bash scripts/setup.sh` to create a "
                          "Python 3.10 environment"),
            )  # fmt: skip
            return 3
        net = LavaNetwork(spec)
        write_msg(proto_out, ("ready", {"startup_s": net.startup_s, "pid": os.getpid()}))
        while True:
            try:
                msg = read_msg(proto_in)
            except EOFError:
                msg = ("close",)
            if msg[0] == "window":
                write_msg(proto_out, ("raster", net.window(msg[1])), phase="reply")
            elif msg[0] == "reset":
                windows = net.windows
                net.close()
                net = LavaNetwork(spec)
                net.windows = windows
                write_msg(proto_out, ("ready", {"startup_s": net.startup_s, "pid": os.getpid()}))
            elif msg[0] == "close":
                net.close()
                try:
                    write_msg(proto_out, ("closed", {"windows": net.windows}))
                except BrokenPipeError:
                    pass
                return 0
            else:
                raise ValueError(f"unknown request {msg[0]!r}")
    except Exception as exc:
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        try:
            write_msg(proto_out, ("error", detail))
        except BrokenPipeError:
            pass
        traceback.print_exc(file=sys.stderr)
        abort(net)
        sys.stderr.flush()
        # Not a normal exit: the runtime's __del__ would call stop(), which waits forever for
        # processes that abort() has just terminated.
        os._exit(1)


if __name__ == "__main__":
    sys.exit(main())
