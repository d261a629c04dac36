"""Finding the processes a test started, by a mark in their environment, and Lava's shared
memory: what must be gone when a command has ended.

Shared memory is attributed to the process tree under test (:class:`ShmWatch`), so another
Lava process running on the machine at the same time neither fails a test nor hides a leak."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterable
from pathlib import Path

SHM = "/dev/shm/"
SEGMENT_SCRIPT = """
import sys, time
from multiprocessing import resource_tracker
from multiprocessing.shared_memory import SharedMemory
shm = SharedMemory(create=True, size=4096)
if sys.argv[1] == "leak":  # nothing will unlink it, as after a SIGKILL of the whole tree
    resource_tracker.unregister(shm._name, "shared_memory")
print(shm.name.lstrip("/"), flush=True)
sys.stdin.read()  # held until the test closes its end
if sys.argv[1] == "hold":
    shm.close()
    time.sleep(float(sys.argv[2]) if len(sys.argv) > 2 else 0.0)  # unmapped, not yet unlinked
    shm.unlink()
"""
"""``python -c SEGMENT_SCRIPT leak|hold [delay]``: a process that makes a ``psm_*`` segment,
prints its name and holds it until its stdin closes; then ``hold`` unlinks it (``delay``
seconds after unmapping it) and ``leak`` leaves it."""


def marked_processes(mark: str) -> list[tuple[int, str]]:
    """Live processes whose environment has ``SNNKART_TEST_MARK=mark`` (children inherit it;
    a zombie's environment cannot be read, so zombies are not listed)."""
    needle = f"SNNKART_TEST_MARK={mark}".encode()
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            environ = Path(f"/proc/{entry}/environ").read_bytes().split(b"\0")
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            continue
        if needle in environ:
            found.append((int(entry), cmdline.decode(errors="replace")))
    return found


def shm_segments() -> set[str]:
    """Lava's shared-memory segments (Python's ``SharedMemory`` names them ``psm_*``)."""
    return {name for name in os.listdir("/dev/shm") if name.startswith("psm_")}


def _segment(path: str) -> str | None:
    """The ``psm_*`` name in a mapped or opened path (``/dev/shm/psm_ab12 (deleted)``)."""
    if not path.startswith(SHM + "psm_"):
        return None
    return path[len(SHM) :].split(" ", 1)[0]


def held_segments(pids: Iterable[int]) -> set[str]:
    """The ``psm_*`` segments the processes ``pids`` have mapped or open."""
    found: set[str] = set()
    for pid in pids:
        try:
            maps = Path(f"/proc/{pid}/maps").read_text()
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:  # ended, or a zombie
            continue
        paths = [line.split(maxsplit=5)[5] for line in maps.splitlines() if SHM in line]
        for fd in fds:
            try:
                paths.append(os.readlink(f"/proc/{pid}/fd/{fd}"))
            except OSError:
                continue
        found.update(name for name in map(_segment, paths) if name)
    return found


class ShmWatch:
    """The shared memory of the processes marked ``mark``: a thread looks, every ``every_s``
    while they run, at the ``psm_*`` segments they have mapped or open; :meth:`leaked` is
    those that still exist when they have ended.

    A segment is attributed to the tree under test by its having held it, so a segment of
    another process on the machine (another Lava run, even one that leaks) is never counted.
    The one gap: a segment the tree makes and abandons between two looks."""

    def __init__(self, mark: str, every_s: float = 0.02) -> None:
        self.mark = mark
        self.seen: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, args=(every_s,), daemon=True)

    def start(self) -> ShmWatch:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop watching, after a last look."""
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join()
            self.sample()

    def _watch(self, every_s: float) -> None:
        while not self._stop.wait(every_s):
            self.sample()

    def sample(self) -> None:
        self.seen |= held_segments(pid for pid, _ in marked_processes(self.mark))

    def leaked(self, grace_s: float = 1.0) -> set[str]:
        """The segments the marked processes held that still exist, after up to ``grace_s``
        for them to go (a process that has just ended may still be unlinking its own)."""
        deadline = time.monotonic() + grace_s
        while (left := self.seen & shm_segments()) and time.monotonic() < deadline:
            time.sleep(0.05)
        return left
