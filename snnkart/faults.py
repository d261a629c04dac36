"""Ctrl-C and SIGTERM as one interrupt taken at safe points, and the test-only fault points.

**Interrupts.** snnkart handles SIGTERM exactly like Ctrl-C (SIGINT). Long-running loops
(PPO iterations, episodes, the exchanges with the Lava worker) run inside :func:`caught`, where
either signal only sets a flag; the loop calls :func:`check` at its safe points (between env
steps, between Lava exchanges), which raises :class:`Interrupted`. Raising asynchronously in
the middle of arbitrary code is not safe here:

- pymunk calls the env's collision handlers from C through cffi, and cffi *prints and drops*
  an exception raised inside them ("Exception ignored from cffi callback"): a Ctrl-C landing in
  one was lost and the command ran on (about 1 in 100 interrupts of a stepping env);
- an exchange with the Lava worker cut in half leaves half a message in the pipe.

A second signal while the first is pending raises at once (the impatient user's way out);
whatever Lava processes are still running are then stopped at exit.

**Fault points** (tests only). ``fault_point(phase)`` marks a named moment; when the
environment variable ``SNNKART_FAULT`` names it, the process sends a signal to the command's
process group, as a terminal's Ctrl-C does::

    SNNKART_FAULT="window@3:SIGINT"      # at the 3rd mid-window moment
    SNNKART_FAULT="step@40+0.004:SIGTERM"  # 4 ms after the 40th env step began
    SNNKART_FAULT="checkpoint:SIGSTOP"   # stop while a checkpoint is written (test remounts)

The group is ``SNNKART_FAULT_PGID`` (set for the Lava worker: its parent's group) or this
process's own. Each firing is appended to the file ``SNNKART_FAULT_LOG`` if set, so a test
knows the phase was reached. Without ``SNNKART_FAULT`` a fault point costs one dict lookup.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

INTERRUPT_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM; ``exit_code`` is the shell's 128 + signal number."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


@dataclass
class _Pending:
    signum: int | None = None
    at: float = 0.0
    depth: int = 0


_pending = _Pending()
last_signal: int | None = None
"""The last interrupt signal this process received (for the exit status)."""


def _raise_now(signum: int, frame: object) -> None:
    global last_signal
    last_signal = signum
    raise Interrupted(signum)


def _set_flag(signum: int, frame: object) -> None:
    global last_signal
    last_signal = signum
    if _pending.signum is not None:
        raise Interrupted(signum)  # a second signal: do not wait for the safe point
    _pending.signum, _pending.at = signum, time.monotonic()


def install() -> None:
    """For a command's process: SIGTERM interrupts like Ctrl-C (an ignored SIGINT stays so)."""
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, _raise_now)
    signal.signal(signal.SIGTERM, _raise_now)


@contextlib.contextmanager
def caught() -> Iterator[None]:
    """Within: SIGINT and SIGTERM set a flag that :func:`check` turns into :class:`Interrupted`.

    An interrupt still pending when the outermost ``caught`` ends is raised there, unless the
    code inside took it with :func:`consume`. Nested uses share the outer one. Outside the
    main thread this does nothing (signals are delivered to the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _pending.depth:
        _pending.depth += 1
        try:
            yield
        finally:
            _pending.depth -= 1
        return
    previous = {s: signal.getsignal(s) for s in INTERRUPT_SIGNALS}
    for s in INTERRUPT_SIGNALS:
        if previous[s] is not signal.SIG_IGN:
            signal.signal(s, _set_flag)
    _pending.depth = 1
    try:
        yield
    finally:
        _pending.depth = 0
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)
        signum, _pending.signum = _pending.signum, None
    if signum is not None:
        raise Interrupted(signum)


def pending() -> int | None:
    """The interrupt signal received inside :func:`caught` and not yet acted on, if any."""
    return _pending.signum


def pending_for() -> float:
    """Seconds since the pending interrupt arrived (0 if none)."""
    return 0.0 if _pending.signum is None else time.monotonic() - _pending.at


def consume() -> int | None:
    """Take the pending interrupt (the caller acts on it); return its signal number."""
    signum, _pending.signum = _pending.signum, None
    return signum


def check() -> None:
    """Raise :class:`Interrupted` if an interrupt is pending (a safe point)."""
    if _pending.signum is not None:
        raise Interrupted(_pending.signum)


# -- fault points (tests only) ----------------------------------------------------------------


@dataclass(frozen=True)
class FaultSpec:
    phase: str
    occurrence: int
    delay_s: float
    signum: int

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """``phase[@n][+delay_s]:SIGNAL``."""
        where, _, sig = text.partition(":")
        if not sig:
            raise ValueError(f"SNNKART_FAULT={text!r}: expected phase[@n][+delay]:SIGNAL")
        where, _, delay = where.partition("+")
        phase, _, n = where.partition("@")
        return cls(phase, int(n or 1), float(delay or 0.0), int(signal.Signals[sig.upper()]))


_spec: FaultSpec | None = None
_spec_read = False
_counts: dict[str, int] = {}


def _fault_spec() -> FaultSpec | None:
    global _spec, _spec_read
    if not _spec_read:
        text = os.environ.get("SNNKART_FAULT")
        _spec = FaultSpec.parse(text) if text else None
        _spec_read = True
    return _spec


def fault_point(phase: str) -> None:
    """Send the configured signal to the command's process group if this is the moment."""
    spec = _fault_spec()
    if spec is None or spec.phase != phase:
        return
    _counts[phase] = n = _counts.get(phase, 0) + 1
    if n != spec.occurrence:
        return
    target = int(os.environ.get("SNNKART_FAULT_PGID") or os.getpgrp())
    log = os.environ.get("SNNKART_FAULT_LOG")

    def fire() -> None:
        if log:  # before the signal: SIGSTOP would hold the line back
            with open(log, "a") as f:
                f.write(
                    f"{phase}@{n}+{spec.delay_s}:{signal.Signals(spec.signum).name} "
                    f"pid {os.getpid()} t={time.monotonic()}\n"
                )
        with contextlib.suppress(ProcessLookupError):
            os.killpg(target, spec.signum)

    if spec.delay_s > 0:
        timer = threading.Timer(spec.delay_s, fire)
        timer.daemon = True
        timer.start()
    else:
        fire()


__all__ = [
    "INTERRUPT_SIGNALS",
    "Interrupted",
    "caught",
    "check",
    "consume",
    "fault_point",
    "install",
    "pending",
]
