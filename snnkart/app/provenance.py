"""Where a result was made: the machine and the commit, for records that get committed."""

from __future__ import annotations

import datetime as dt
import os
import platform
import subprocess
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]  # the checkout snnkart runs from


def git_commit(cwd: Path = SOURCE) -> str:
    """The short commit of the checkout, ``-dirty`` if tracked files changed; ``unknown``
    outside a git checkout (an installed package)."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True, cwd=cwd).stdout.strip()  # fmt: skip
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, cwd=cwd).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def machine_info() -> dict[str, str | int | None]:
    """The date, commit, host, CPU model and core count, Python and platform."""
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "hostname": platform.node(),
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
