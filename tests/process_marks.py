"""Finding the processes a test started, by a mark in their environment, and Lava's shared
memory: what must be gone when a command has ended."""

from __future__ import annotations

import os
from pathlib import Path


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
