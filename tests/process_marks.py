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


def _all_pids() -> list[int]:
    return [int(entry) for entry in os.listdir("/proc") if entry.isdigit()]


class ShmWatch:
    """The shared memory of the processes marked ``mark``, watched while they run.

    A thread records every ``psm_*`` segment a marked process maps or opens (every 20 ms).
    :meth:`leaked` is then, of the segments created since the watch began, those the marked
    processes held, and those no process holds at all (a segment made and abandoned between
    two looks); a segment another live process holds is that process's, not a leak."""

    def __init__(self, mark: str, every_s: float = 0.02) -> None:
        self.mark = mark
        self.before = shm_segments()
        self.seen: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, args=(every_s,), daemon=True)

    def start(self) -> ShmWatch:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop watching (after a last look); :meth:`leaked` may be asked after."""
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
        """Segments left behind by the marked processes, after up to ``grace_s`` for them
        to go (a process that has just ended may be unlinking its segments)."""
        deadline = time.monotonic() + grace_s
        while True:
            new = shm_segments() - self.before
            marked = {pid for pid, _ in marked_processes(self.mark)}
            others = held_segments(pid for pid in _all_pids() if pid not in marked)
            left = (new & self.seen) | (new - self.seen - others)
            if not left or time.monotonic() >= deadline:
                return left
            time.sleep(0.05)
