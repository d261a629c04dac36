"""``snnkart deploy``: a closed-loop run on a spiking backend, with progress and its summary."""

from __future__ import annotations

from pathlib import Path

from snnkart.app.reporter import Reporter
from snnkart.contract.deploy_record import DeployRecord
from snnkart.errors import DeployWriteError, ParityError


def run_deploy_reported(
    nir_file: Path,
    backend: str,
    precision: str,
    episodes: int,
    seed: int,
    env: str | None,
    track: str | None,
    out: Path | None,
    reporter: Reporter,
) -> DeployRecord:
    """:func:`snnkart.eval.deploy.run_deploy` with progress, then its summary. A parity
    mismatch or a failed write is reported with the summary, then raised."""
    from snnkart.eval.deploy import run_deploy

    try:
        with reporter.progress(f"{backend} episodes", episodes, steps="env steps") as task:
            record = run_deploy(
                nir_file, backend, precision, episodes, seed, env, track, out,
                on_episode=lambda r: task.advance(), on_step=lambda e: task.step(),
            )  # fmt: skip
    except ParityError as exc:
        report_summary(exc.record, out, reporter)
        raise
    except DeployWriteError as exc:
        report_summary(exc.record, None, reporter)
        raise
    report_summary(record, out, reporter)
    return record


def report_summary(record: DeployRecord, out: Path | None, reporter: Reporter) -> None:
    from snnkart.eval.deploy import summary_lines

    for line in summary_lines(record):
        reporter.message(line)
    if out is not None:
        reporter.message(f"results written to {out / 'deploy.json'}")
