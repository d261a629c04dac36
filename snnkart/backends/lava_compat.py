"""Every access to Lava 0.10's private internals, in one place.

Lava has no public API for these; each function names what it relies on, so a Lava upgrade
is checked here and nowhere else:

- the runtime's messaging infrastructure: its actor processes (to notice one that died, and to
  terminate them after a failure) and its shared-memory manager;
- a CSP receive port's ring buffer (``_queue``, ``_array``, ``_idx``, ``_size``, ``_ack``), read
  with a timeout, because the public ``recv()`` blocks forever when a Lava process has died;
- ``Runtime._is_started``, to stop a runtime only once.

Imported only by the Lava worker process (it does not import lava itself; it is handed Lava's
objects).
"""

from __future__ import annotations

import queue
import sys
import time
import traceback
from typing import Any

import numpy as np


def actors(runtime: Any) -> list[Any]:
    """The runtime's Lava processes (multiprocessing actors)."""
    return list(runtime._messaging_infrastructure.actors)


def check_actors(runtime: Any) -> None:
    """Raise if one of the runtime's Lava processes has died or reported an exception."""
    for actor in actors(runtime):
        if not actor.is_alive() or actor.exception:
            exc = actor.exception
            detail = exc[1] if exc else f"exit code {actor.exitcode}"
            raise RuntimeError(f"a Lava process failed: {detail}")


def receive(port: Any, runtime: Any, timeout: float) -> np.ndarray:
    """One message from a CSP receive port, failing fast when a Lava process died or nothing
    arrives within ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            port._queue.get(timeout=0.5)
            break
        except queue.Empty:
            check_actors(runtime)
            if time.monotonic() > deadline:
                raise RuntimeError(f"Lava produced no output for {timeout:.0f} s") from None
    result: np.ndarray = port._array[port._idx].copy()
    port._idx = (port._idx + 1) % port._size
    port._ack.release()
    return result


def is_started(runtime: Any) -> bool:
    return bool(runtime._is_started)


def terminate(runtime: Any) -> None:
    """Last resort after a failure: terminate the runtime's processes and shared memory."""
    try:
        infra = runtime._messaging_infrastructure
        for actor in infra.actors:
            if actor.is_alive():
                actor.terminate()
        for actor in infra.actors:
            actor.join(timeout=2)
        infra.smm.shutdown()
    except Exception:
        traceback.print_exc(file=sys.stderr)
