"""Where a result was made: the machine and the commit, for records that get committed."""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import os
import platform
import subprocess
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]  # the checkout snnkart runs from
PACKAGE = SOURCE / "snnkart"
TRAINING_CODE = ("rl", "envs")
"""The packages a run's training depends on (its study key)."""
EVALUATION_CODE = (
    "app",
    "backends",
    "backends/lava_procs",
    "contract",
    "energy",
    "envs",
    "eval",
    "export",
    "rl",
)
"""The packages an evaluation's numbers depend on (everything but the report, the command
line and ROS)."""


@functools.cache
def code_digest(packages: tuple[str, ...] = TRAINING_CODE) -> str:
    """The sha256 of every source file of these packages of :mod:`snnkart` (by file name: the
    study keys of runs trained before evaluations had keys stay the same)."""
    h = hashlib.sha256()
    for package in packages:
        for path in sorted((PACKAGE / package).glob("*.py")):
            h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def git_commit(cwd: Path = SOURCE) -> str:
    """The short commit of the checkout, ``-dirty`` if tracked files changed; ``unknown``
    outside a git checkout (an installed package)."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=cwd,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            cwd=cwd,
        ).stdout.strip()
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
