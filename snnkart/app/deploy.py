"""``snnkart deploy``: a closed-loop run on a spiking backend, with progress and its summary."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from snnkart.app.reporter import Reporter
from snnkart.contract.deploy_record import DeployRecord
from snnkart.errors import DeployWriteError, ParityError

if TYPE_CHECKING:
    from snnkart.eval.request import DeployRequest


def run_deploy_reported(request: DeployRequest, reporter: Reporter) -> DeployRecord:
    """:func:`snnkart.eval.closed_loop.run_deploy` with progress, then its summary. A parity
    mismatch or a failed write is reported with the summary, then raised."""
    from snnkart.eval.closed_loop import run_deploy

    label = f"{request.backend} episodes"
    try:
        with reporter.progress(label, request.episodes, steps="env steps") as task:
            record = run_deploy(
                request, on_episode=lambda r: task.advance(), on_step=lambda e: task.step()
            )
    except ParityError as exc:
        report_summary(exc.record, request.out, reporter)
        raise
    except DeployWriteError as exc:
        report_summary(exc.record, None, reporter)
        raise
    report_summary(record, request.out, reporter)
    return record


def report_summary(record: DeployRecord, out: Path | None, reporter: Reporter) -> None:
    from snnkart.eval.closed_loop import summary_lines

    for line in summary_lines(record):
        reporter.message(line)
    if out is not None:
        reporter.message(f"results written to {out / 'deploy.json'}")
