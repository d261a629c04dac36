"""The terminal side of the app's :class:`~snnkart.app.reporter.Reporter`: rich progress bars
and lines, written once for every command."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Mapping

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from snnkart.contract.report_record import lif_report, sd_report


def fmt(value: float | None, spec: str = ".2f") -> str:
    return "-" if value is None else format(value, spec)


LOG_EVERY = 10
"""Iterations between the plain progress lines of a training whose output is not a terminal
(a log file, nohup, a cluster job), as Stable-Baselines3 and CleanRL log."""


class ConsoleReporter:
    """Messages on stdout (stderr with ``stderr=True``); transient progress bars in a terminal,
    plain lines elsewhere."""

    def __init__(self, stderr: bool = False, console: Console | None = None) -> None:
        self.console = console or Console(stderr=stderr)

    def message(self, text: str) -> None:
        self.console.print(text, markup=False, highlight=False)

    @contextlib.contextmanager
    def progress(
        self, label: str, total: int | None = None, steps: str | None = None
    ) -> Iterator[_Task]:
        with Progress(console=self.console, transient=True) as bar:
            main = bar.add_task(label, total=total)
            sub = bar.add_task(steps, total=None) if steps else None
            yield _Task(bar, main, sub)

    @contextlib.contextmanager
    def training(
        self, total: int, completed: int
    ) -> Iterator[Callable[[Mapping[str, float | None]], None]]:
        if not self.console.is_terminal:
            yield self._log_lines(total)
            return
        columns = (
            TextColumn("[progress.description]{task.description}"),
            BarColumn(bar_width=20),
            TextColumn("{task.completed:,}/{task.total:,} steps"),
            TextColumn("{task.fields[sps]} steps/s"),
            TextColumn("return {task.fields[ret]}"),
            TextColumn("finishes {task.fields[fin]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
        )
        with Progress(*columns, console=self.console) as bar:
            task = bar.add_task("PPO", total=total, completed=completed, sps="-", ret="-", fin=0)

            def update(record: Mapping[str, float | None]) -> None:
                bar.update(
                    task,
                    completed=_count(record, "global_step"),
                    sps=f"{record['charts/SPS']:,.0f}",
                    ret=fmt(record["charts/episodic_return"]),
                    fin=_laps(record),
                )

            yield update

    def _log_lines(self, total: int) -> Callable[[Mapping[str, float | None]], None]:
        """A plain line every ``LOG_EVERY`` iterations (and at the first and the last): step,
        mean return, finished laps, steps per second, time since the start."""
        start = time.monotonic()

        def update(record: Mapping[str, float | None]) -> None:
            step, iteration = _count(record, "global_step"), _count(record, "iteration")
            if iteration % LOG_EVERY and iteration != 1 and step < total:
                return
            self.message(
                f"step {step:,}/{total:,}  return {fmt(record['charts/episodic_return'])}  "
                + (f"laps {_laps(record)}  " if _laps(record) != "-" else "")
                + f"{record['charts/SPS']:,.0f} steps/s  {time.monotonic() - start:,.0f} s"
            )

        return update


def _laps(record: Mapping[str, float | None]) -> str:
    """The run's finished laps so far ("-": an env without laps)."""
    laps = record.get("charts/cumulative_finishes")
    return "-" if laps is None else f"{laps:,}"


def _count(record: Mapping[str, float | None], key: str) -> int:
    """A counter of an iteration's metrics record (``global_step``, ``iteration``: never None)."""
    value = record[key]
    assert value is not None, key
    return int(value)


class _Task:
    """One progress bar's task (and its optional sub-step counter)."""

    def __init__(self, bar: Progress, main: TaskID, sub: TaskID | None) -> None:
        self.bar, self.main, self.sub = bar, main, sub

    def advance(self) -> None:
        self.bar.advance(self.main)

    def step(self) -> None:
        if self.sub is not None:
            self.bar.advance(self.sub)


def print_headline(report: Mapping[str, object], rows: list[dict[str, str]]) -> None:
    """The energy report's headline: a warning when the SNN does not drive, then the table of
    the primary ANN's comparisons (all of them are in report.md)."""
    from rich.table import Table

    console = Console()
    lif = lif_report(report)
    if not lif["drives"]:
        rate = lif["snn"]["task"]["success_rate"]
        console.print(
            f"[bold red]WARNING: the spiking policy does not drive (success {rate:.0%} < 80 %): "
            "its energy numbers are not a result.[/]"
        )
    primary = "run" if "run" in lif["ann"] else "same_width"
    ann = lif["ann"][primary]
    snn_task, ann_task = lif["snn"]["task"], ann["task"]
    ann_rate = f"{ann_task['success_rate']:.0%}" if ann_task else "not run"
    if ann_task and ann_task.get("int8"):
        ann_rate += f", int8 ANN {ann_task['int8']['success_rate']:.0%} (measured)"
    table = Table(
        title=f"energy per inference, SNN vs {ann['label']}",
        caption=f"success: SNN {snn_task['success_rate']:.0%}, ANN {ann_rate} "
        f"({snn_task['episodes']} episodes); report.html has every pair and figure",
    )
    keys = {
        "SNN on": "SNN on",
        "ANN on": "ANN on",
        "SNN nJ/inference": "SNN nJ",
        "ANN nJ/inference": "ANN nJ",
        "SNN/ANN": "SNN/ANN",
    }
    for title in keys.values():
        table.add_column(title, justify="right")
    for row in rows:
        if row["ANN"] == ann["label"]:
            table.add_row(*(row[k] for k in keys))
    console.print(table)


def print_sd_answer(report: Mapping[str, object], answer: str, rows: list[dict[str, str]]) -> None:
    """A sigma-delta report's headline: the warning when it does not drive, the goal's answer
    (``answer``, the report's first screen) and the energy per chip (``rows``)."""
    from rich.table import Table

    console = Console()
    sd = sd_report(report)
    if not sd["drives"]:
        rate = sd["task"]["success_rate"]
        console.print(
            f"[bold red]WARNING: the sigma-delta policy does not drive (success "
            f"{rate:.0%} < 80 %): its energy numbers are not a result.[/]"
        )
    console.print(answer)
    table = Table(
        title="energy per inference, sigma-delta vs the same-shape ANN",
        caption="report.html has every term, the counts per layer and the figures",
    )
    keys = [k for k in rows[0] if k != "updates rule"] if rows else []
    for title in keys:
        table.add_column(title, justify="right")
    for row in rows:
        table.add_row(*(row[k] for k in keys))
    console.print(table)
