"""Training's progress where no terminal shows a bar (a log file, nohup, a cluster job): a plain
line every few iterations, and at the first and the last."""

from __future__ import annotations

import io

from rich.console import Console

from snnkart.cli.console import LOG_EVERY, ConsoleReporter


def _record(iteration: int, batch: int = 100) -> dict[str, object]:
    return {"iteration": iteration, "global_step": iteration * batch, "charts/SPS": 1234.5,
            "charts/episodic_return": 1.5, "charts/cumulative_finishes": 2 * iteration}  # fmt: skip


def test_a_log_file_gets_plain_lines_every_few_iterations() -> None:
    out = io.StringIO()
    reporter = ConsoleReporter(console=Console(file=out, width=200))
    iterations = 2 * LOG_EVERY + 3
    with reporter.training(iterations * 100, 0) as update:
        for i in range(1, iterations + 1):
            update(_record(i))
    lines = out.getvalue().splitlines()
    steps = [int(line.split()[1].split("/")[0].replace(",", "")) for line in lines]
    assert steps == [100, LOG_EVERY * 100, 2 * LOG_EVERY * 100, iterations * 100]
    assert lines[0].startswith(f"step 100/{iterations * 100:,}  return 1.50  laps 2  1,234 steps/s")
    assert "\x1b" not in out.getvalue()  # no bar, no escape codes


def test_a_terminal_gets_the_bar_not_the_lines() -> None:
    out = io.StringIO()
    reporter = ConsoleReporter(console=Console(file=out, width=80, force_terminal=True))
    with reporter.training(1000, 0) as update:
        update(_record(1))
    assert "step 100/1,000" not in out.getvalue()
