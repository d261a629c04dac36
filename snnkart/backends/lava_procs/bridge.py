"""``HostBridge``: the host's end of the closed loop, as one Lava process.

Per env step (a window of ``W`` Lava steps, ``T + L`` for a LIF chain) it receives one message
from the host, the first layer's input for the T SNN steps plus a command flag, drives the first
process's ``a_in`` with row r of it at window row r < T (zeros in the L drain rows; ``held``:
the one input row at every window row, as a sigma-delta chain's input Delta is fed), records
the output of every connected population at every step (spikes, or graded values), and sends
the whole window's raster back in one message at the window's last step. One message each way
per env step, no Var get/set.

Window rows are ``(time_step - 1) % W``: Lava's time starts at 1. A command flag of 1 (close)
makes the bridge request a stop of the run (``_req_stop``), so the host ends a non-blocking run
with ``wait()`` without any process blocked on a pipe.

The spiking layers themselves are Lava's library processes (``LIFReset``, ``Dense``); this
process does what a host does on a chip: encode, inject, read back.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from lava.magma.core.decorator import implements, requires, tag
from lava.magma.core.model.py.model import PyLoihiProcessModel
from lava.magma.core.model.py.ports import PyInPort, PyOutPort
from lava.magma.core.model.py.type import LavaPyType
from lava.magma.core.process.ports.ports import InPort, OutPort
from lava.magma.core.process.process import AbstractProcess
from lava.magma.core.resources import CPU
from lava.magma.core.sync.protocols.loihi_protocol import LoihiProtocol

MAX_LAYERS = 5


class HostBridge(AbstractProcess):
    """Bridge recording 1 to 5 populations of ``sizes`` neurons (a LIF chain's layers, or a
    sigma-delta chain's input Delta, SigmaDeltas and readout Sigma); ``window`` rows per env
    step (default ``num_steps + len(sizes) - 1``)."""

    def __init__(
        self,
        *,
        sizes: tuple[int, ...],
        num_steps: int,
        window: int | None = None,
        held: bool = False,
        buffer_size: int = 2,
        **kwargs: Any,
    ) -> None:
        if not 1 <= len(sizes) <= MAX_LAYERS:
            raise ValueError(f"the bridge serves 1 to {MAX_LAYERS} layers, got {len(sizes)}")
        window = num_steps + len(sizes) - 1 if window is None else window
        super().__init__(
            sizes=tuple(sizes), num_steps=num_steps, window=window, held=held, **kwargs
        )
        self.host_in = InPort(shape=(num_steps * sizes[0] + 1,))
        self.host_in.flag_external_pipe(buffer_size=buffer_size)
        self.host_out = OutPort(shape=(window * sum(sizes),))
        self.host_out.flag_external_pipe(buffer_size=buffer_size)
        self.a_out = OutPort(shape=(sizes[0],))
        # The models declare MAX_LAYERS spike ports; unused ones stay unconnected and unread.
        padded = (*sizes, *(1,) * (MAX_LAYERS - len(sizes)))
        self.s_in0 = InPort(shape=(padded[0],))
        self.s_in1 = InPort(shape=(padded[1],))
        self.s_in2 = InPort(shape=(padded[2],))
        self.s_in3 = InPort(shape=(padded[3],))
        self.s_in4 = InPort(shape=(padded[4],))


class _BridgeModel(PyLoihiProcessModel):
    host_in: PyInPort
    host_out: PyOutPort
    a_out: PyOutPort
    dtype: Any = float

    def __init__(self, proc_params: dict[str, Any]) -> None:
        super().__init__(proc_params)
        self.sizes = tuple(proc_params["sizes"])
        self.T = int(proc_params["num_steps"])
        self.W = int(proc_params["window"])
        self.held = bool(proc_params["held"])
        self.offsets = np.cumsum((0, *self.sizes))
        self.current = np.zeros((self.T, self.sizes[0]), dtype=self.dtype)
        self.zero = np.zeros(self.sizes[0], dtype=self.dtype)
        self.raster = np.zeros((self.W, int(self.offsets[-1])), dtype=self.dtype)
        self.closing = False

    def run_spk(self) -> None:
        row = (self.time_step - 1) % self.W
        if row == 0 and not self.closing:
            msg = self.host_in.recv()
            if msg[-1] != 0:
                self.closing = True
                self._req_stop = True
            self.current[:] = msg[:-1].reshape(self.T, self.sizes[0])
        if self.closing:
            self.a_out.send(self.zero)
        elif self.held:
            self.a_out.send(self.current[0])
        else:
            self.a_out.send(self.current[row] if row < self.T else self.zero)
        for k in range(len(self.sizes)):
            port = getattr(self, f"s_in{k}")
            self.raster[row, self.offsets[k] : self.offsets[k + 1]] = port.recv()
        if row == self.W - 1 and not self.closing:
            self.host_out.send(self.raster.reshape(-1))


@implements(proc=HostBridge, protocol=LoihiProtocol)
@requires(CPU)
@tag("floating_pt")
class PyHostBridgeFloat(_BridgeModel):
    host_in: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    host_out: PyOutPort = LavaPyType(PyOutPort.VEC_DENSE, float)
    a_out: PyOutPort = LavaPyType(PyOutPort.VEC_DENSE, float)
    s_in0: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    s_in1: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    s_in2: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    s_in3: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    s_in4: PyInPort = LavaPyType(PyInPort.VEC_DENSE, float)
    dtype = float


@implements(proc=HostBridge, protocol=LoihiProtocol)
@requires(CPU)
@tag("bit_accurate_loihi", "fixed_pt")
class PyHostBridgeFixed(_BridgeModel):
    host_in: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    host_out: PyOutPort = LavaPyType(PyOutPort.VEC_DENSE, np.int32, precision=24)
    a_out: PyOutPort = LavaPyType(PyOutPort.VEC_DENSE, np.int32, precision=24)
    s_in0: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    s_in1: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    s_in2: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    s_in3: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    s_in4: PyInPort = LavaPyType(PyInPort.VEC_DENSE, np.int32, precision=24)
    dtype = np.int64
