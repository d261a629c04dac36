"""Shared helpers of the benchmarks: machine description and result file names."""

from __future__ import annotations

import argparse
from pathlib import Path

from snnkart.app.provenance import git_commit as git_commit
from snnkart.app.provenance import machine_info as machine_info

RESULTS = Path(__file__).resolve().parent / "results"


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
    from snnkart.app.study_run import curve

    if not (run_dir / "metrics.jsonl").is_file():
        return None
    c = curve(run_dir)
    return sum(c.seconds), len(c.steps)
