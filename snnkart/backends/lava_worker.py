"""The Lava side of ``lava-sim``: a separate Python process that builds the spiking layers as
Lava library processes, runs them on ``Loihi2SimCfg`` and serves one window per request.

Run as ``python -m snnkart.backends.lava_worker`` by :mod:`snnkart.backends.lava_sim`, never
imported by the rest of snnkart: importing lava sets the multiprocessing start method to fork,
which must not happen in a process that trains or uses torch's multiprocessing.

Protocol (length-prefixed pickles): stdin receives a :class:`~snnkart.backends.lava_params.LavaSpec`
(or a :class:`~snnkart.backends.lava_params.SigmaDeltaLavaSpec`: :class:`SigmaDeltaNetwork`), then ``("window", current)``
per env step and finally ``("close",)``; the protocol stream answers ``("ready", info)``,
``("raster", array)`` per window, ``("closed", info)`` or ``("error", message)``. Anything
Lava prints goes to stderr. On end of input (the parent died) the run is closed the same way.

Network (L = layers - 1 Dense synapses, window W = T + L):

    HostBridge.a_out -> LIFReset_0 -> Dense_1 -> LIFReset_1 -> ... -> LIFReset_{L}
    every LIFReset_i.s_out -> HostBridge.s_in{i}      (the spike raster, read back per window)
    a recurrent layer: LIF_i.s_out -> Dense (its recurrent weights) -> LIF_i.a_in   (one step late)

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
    from snnkart.backends.lava_params import LavaSpec, SigmaDeltaLavaSpec

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


class BridgedNetwork:
    """A compiled Lava network behind a :class:`HostBridge`, running in one long non-blocking
    ``RunSteps``: one host message in and one raster out per env step (``W`` Lava steps)."""

    W: int
    sizes: tuple[int, ...]
    msg_size: int  # values per host message, the command flag included

    def _start(self, bridge: Any, fixed: bool) -> None:
        """Compile, create the runtime (its processes ignore SIGINT) and start the run."""
        from lava.magma.core.run_conditions import RunSteps
        from lava.magma.core.run_configs import Loihi2SimCfg

        from snnkart.faults import fault_point

        self.bridge = bridge
        self.fixed = fixed
        tag = "fixed_pt" if fixed else "floating_pt"
        self.run_cfg = Loihi2SimCfg(select_tag=tag)
        self.dtype = np.int32 if fixed else np.float64
        t0 = time.perf_counter()
        # SIGINT is ignored while the runtime forks its processes, so they inherit "ignore":
        # the parent owns Ctrl-C and ends the run through the close request.
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            fault_point("lava-startup")  # (a delay lands the signal while the runtime forks)
            bridge.create_runtime(run_cfg=self.run_cfg)
        finally:
            signal.signal(signal.SIGINT, previous)
        self.runtime = bridge.runtime
        self.startup_s = time.perf_counter() - t0
        self.host_send = bridge.host_in.external_pipe_csp_send_port
        self.host_recv = bridge.host_out.external_pipe_csp_recv_port
        bridge.run(condition=RunSteps(num_steps=2**62, blocking=False), run_cfg=self.run_cfg)
        self.windows = 0
        self.closed = False

    def _recv(self, timeout: float = RECV_TIMEOUT) -> np.ndarray:
        """Receive from the bridge, failing fast when a Lava process died or nothing comes."""
        return lava_compat.receive(self.host_recv, self.runtime, timeout)

    def exchange(self, values: np.ndarray) -> np.ndarray:
        """Send one env step's input to the bridge; the window's raster ``[W, sum(sizes)]``."""
        msg = np.zeros(self.msg_size, dtype=self.dtype)
        msg[:-1] = np.asarray(values).reshape(-1)
        self.host_send.send(msg)
        raster = self._recv()
        self.windows += 1
        return raster.reshape(self.W, sum(self.sizes))

    def window(self, values: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def close(self) -> None:
        """End the run through the bridge's stop request, then stop the runtime."""
        if self.closed:
            return
        self.closed = True
        msg = np.zeros(self.msg_size, dtype=self.dtype)
        msg[-1] = 1
        self.host_send.send(msg)
        self.runtime.wait()  # receives REQ_STOP and stops the runtime
        if lava_compat.is_started(self.runtime):
            self.runtime.stop()


class LavaNetwork(BridgedNetwork):
    """A LIF chain: ``LIFReset`` populations and ``Dense`` synapses (module docstring)."""

    def __init__(self, spec: LavaSpec) -> None:
        from lava.proc.dense.process import Dense
        from lava.proc.lif.process import LIF, LIFReset

        from snnkart.backends.lava_procs.bridge import HostBridge

        self.T = int(spec.num_steps)
        self.sizes = tuple(int(n) for n in spec.sizes)
        K = len(self.sizes)
        self.W = self.T + K - 1
        self.msg_size = self.T * self.sizes[0] + 1
        bridge = HostBridge(sizes=self.sizes, num_steps=self.T, name="host_bridge")
        self.lifs = []
        for i, layer in enumerate(spec.layers):
            common = dict(
                shape=(self.sizes[i],),
                du=layer.du,
                dv=layer.dv,
                vth=layer.vth,
                bias_mant=layer.bias_mant,
                bias_exp=layer.bias_exp,
                name=f"lif{i}",
            )
            lif = (
                LIF(**common)
                if spec.persist
                else LIFReset(**common, reset_interval=self.W, reset_offset=(i + 1) % self.W)
            )
            self.lifs.append(lif)
            lif.s_out.connect(getattr(bridge, f"s_in{i}"))
        bridge.a_out.connect(self.lifs[0].a_in)
        fixed = spec.arithmetic == "fixed"
        self.dense = []
        for i in range(1, K):
            layer = spec.layers[i]
            kwargs: dict[str, Any] = {"num_weight_bits": 8, "weight_exp": 0} if fixed else {}
            dense = Dense(weights=layer.weight, name=f"dense{i}", **kwargs)
            self.lifs[i - 1].s_out.connect(dense.s_in)
            dense.a_out.connect(self.lifs[i].a_in)
            self.dense.append(dense)
        for i, layer in enumerate(spec.layers):  # recurrent synapses: s_out -> Dense -> a_in
            if layer.recurrent is not None:
                kwargs = {"num_weight_bits": 8, "weight_exp": 0} if fixed else {}
                loop = Dense(weights=layer.recurrent, name=f"recurrent{i}", **kwargs)
                self.lifs[i].s_out.connect(loop.s_in)
                loop.a_out.connect(self.lifs[i].a_in)
                self.dense.append(loop)
        self._start(bridge, fixed)

    def window(self, current: np.ndarray) -> np.ndarray:
        return self.exchange(current) != 0


class SigmaDeltaNetwork(BridgedNetwork):
    """A sigma-delta chain (:class:`~snnkart.backends.lava_params.SigmaDeltaLavaSpec`):
    ``Delta -> Dense -> SigmaDelta(ReLU) -> ...`` of ``lava.proc.sdn`` and graded
    ``lava.proc.dense`` on Lava; the bridge holds the host's input for the window's ``rows``
    steps and records every population's sent values at every row.

    The readout (its Dense and Sigma) runs here, beside the bridge, in int64 (float64): its
    state needs more bits than Lava's fixed-point models hold (they compute in int32 and wrap;
    a 64-64 policy's readout needs about 35), so on Lava it would wrap where the chain does not.
    It is the reference's own arithmetic (:class:`~snnkart.backends.sigma_delta.SigmaDeltaChain`:
    the Dense one step late, the Sigma accumulating) applied to the last SigmaDelta's messages
    as Lava sent them, so the readout columns of the raster still check those messages."""

    def __init__(self, spec: SigmaDeltaLavaSpec) -> None:
        from lava.proc.dense.process import Dense
        from lava.proc.sdn.process import ActivationMode, Delta, SigmaDelta

        from snnkart.backends.lava_procs.bridge import HostBridge
        from snnkart.backends.sigma_delta import lava_fixed_weights

        fixed = spec.arithmetic == "fixed"
        self.sizes, self.W = spec.sizes[:-1], spec.rows  # what Lava runs and the bridge records
        self.msg_size = self.sizes[0] + 1
        readout = spec.weights[-1]
        self.readout_w = lava_fixed_weights(readout) if fixed else np.asarray(readout, float)
        self.acc_dtype = np.int64 if fixed else np.float64
        self.buf = np.zeros(readout.shape[0], self.acc_dtype)  # the readout Dense's buffer
        self.out = np.zeros(readout.shape[0], self.acc_dtype)  # the readout Sigma
        bridge = HostBridge(
            sizes=self.sizes, num_steps=1, window=self.W, held=True, name="host_bridge"
        )
        sender: Any = Delta(shape=(self.sizes[0],), vth=spec.vth_in)
        bridge.a_out.connect(sender.a_in)
        kwargs: dict[str, Any] = {"num_weight_bits": 8, "weight_exp": 0} if fixed else {}
        for i, w in enumerate(spec.weights[:-1]):
            dense = Dense(
                weights=w, num_message_bits=spec.num_message_bits, name=f"dense{i + 1}", **kwargs
            )
            sender.s_out.connect([dense.s_in, getattr(bridge, f"s_in{i}")])
            sender = SigmaDelta(
                shape=(w.shape[0],),
                vth=spec.vth[i],
                bias=spec.biases[i],
                act_mode=ActivationMode.RELU,
            )
            dense.a_out.connect(sender.a_in)
        sender.s_out.connect(getattr(bridge, f"s_in{len(spec.weights) - 1}"))
        self._start(bridge, fixed)

    def window(self, x: np.ndarray) -> np.ndarray:
        raster = self.exchange(x).astype(self.acc_dtype)
        last = raster[:, -self.sizes[-1] :]
        values = np.zeros((self.W, self.out.size), self.acc_dtype)
        for r in range(self.W):  # as SigmaDeltaChain.step: the Dense sends last row's buffer
            self.out = self.out + self.buf
            self.buf = self.readout_w @ last[r]
            values[r] = self.out
        return np.concatenate([raster, values], axis=1)


def build_network(spec: LavaSpec | SigmaDeltaLavaSpec) -> BridgedNetwork:
    """The network ``spec`` describes, compiled and running."""
    from snnkart.backends.lava_params import SigmaDeltaLavaSpec

    if isinstance(spec, SigmaDeltaLavaSpec):
        return SigmaDeltaNetwork(spec)
    return LavaNetwork(spec)


def abort(net: BridgedNetwork | None) -> None:
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
    net: BridgedNetwork | None = None
    try:
        spec = read_msg(proto_in)
        try:
            import lava.magma.core.run_configs  # noqa: F401
        except Exception as exc:
            write_msg(
                proto_out,
                (
                    "error",
                    f"Lava (lava-nc 0.10) cannot be imported in Python "
                    f"{sys.version.split()[0]} ({type(exc).__name__}: {exc}); it needs "
                    "Python 3.10 and numpy < 2: run `bash scripts/setup.sh` to create a "
                    "Python 3.10 environment",
                ),
            )
            return 3
        net = build_network(spec)
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
