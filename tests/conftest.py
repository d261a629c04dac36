"""Suite-wide rules.

``SNNKART_REQUIRE_OPTIONAL=1`` (set by CI): a test that skips because an optional part is
missing (its skip reason starts with "optional:", e.g. a read-only mount needs root) fails
instead, and so does a test module that skips at collection for that reason (a module-level
``pytest.importorskip(..., reason="optional: ...")``, which no test-run hook sees): CI never
passes with part of the suite silently not run.
"""

from __future__ import annotations

import os
import sys

import pytest

REQUIRE_OPTIONAL = os.environ.get("SNNKART_REQUIRE_OPTIONAL") == "1"


def _missing_optional(report: pytest.TestReport | pytest.CollectReport) -> str | None:
    """The skip reason of a report that skipped for a missing optional part, else None."""
    if not (report.skipped and isinstance(report.longrepr, tuple)):
        return None
    reason = str(report.longrepr[2])
    return reason if reason.removeprefix("Skipped: ").startswith("optional:") else None


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:
    outcome = yield
    report = outcome.get_result()
    reason = _missing_optional(report) if REQUIRE_OPTIONAL else None
    if reason is not None:
        report.outcome = "failed"
        report.longrepr = f"SNNKART_REQUIRE_OPTIONAL=1 and a missing optional part: {reason}"


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> object:
    outcome = yield
    report = outcome.get_result()
    reason = _missing_optional(report) if REQUIRE_OPTIONAL else None
    if reason is not None:
        report.outcome = "failed"
        report.longrepr = (
            f"SNNKART_REQUIRE_OPTIONAL=1 and {collector.nodeid} skips at collection "
            f"for a missing optional part: {reason}"
        )


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    faults = sys.modules.get("test_faults")
    counts = getattr(faults, "PHASE_COUNTS", None)
    if counts:
        terminalreporter.write_sep("-", f"faults injected per phase (seed {faults.SEED})")
        slowest = getattr(faults, "SLOWEST", {})
        for phase, n in sorted(counts.items()):
            took = (
                f"  (slowest end {slowest[phase]:.2f} s after the fault)"
                if phase in slowest
                else ""
            )
            terminalreporter.write_line(f"{n:4d}  {phase}{took}")
        terminalreporter.write_line(f"{sum(counts.values()):4d}  in all")
