"""Shared helpers of the benchmarks: machine description and result file names."""

from __future__ import annotations

import argparse
import datetime as dt
import os
import platform
import subprocess
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def git_commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=RESULTS.parent,
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            cwd=RESULTS.parent,
        ).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def machine_info() -> dict[str, object]:
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


def results_path(name: str) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    return RESULTS / f"{name}-{git_commit()}.json"


def add_out_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out", type=Path, default=None,
        help="the results JSON (default: benchmarks/results/<benchmark>-<commit>.json)",
    )  # fmt: skip


def output_path(name: str, out: Path | None) -> Path:
    """``out`` if given (its folder made), else the committed results file of this commit."""
    if out is None:
        return results_path(name)
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def training_seconds(run_dir: Path) -> tuple[float, int] | None:
    """Seconds spent training and the iterations, from the run's per-iteration metrics (each
    iteration's steps / its steps per second, as ``snnkart study`` counts them); None without
    ``metrics.jsonl``."""
    from snnkart.app.study import curve

    if not (run_dir / "metrics.jsonl").is_file():
        return None
    c = curve(run_dir)
    return sum(c["seconds"]), len(c["steps"])
