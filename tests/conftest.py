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


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """``--dist loadgroup`` as xdist documents it: the tests of one ``xdist_group`` on one
    worker. xdist 3.8 marks a test's group by assigning ``item._nodeid``, which pytest 9 no
    longer reads (a node's id lives in ``_id``), so every group was spread over the workers
    and a costly module fixture was built on each. Here the suffix is set where pytest 9 reads
    it, once, whichever version did it or not."""
    if not getattr(config.option, "loadgroup", False):
        return
    try:
        from _pytest.nodeid import coerce_node_id  # pytest >= 9
    except ImportError:  # older pytest: xdist's own hook has set the id
        return
    for item in items:
        groups = {m.args[0] if m.args else m.kwargs.get("name", "default")
                  for m in item.iter_markers("xdist_group")}  # fmt: skip
        suffix = "@" + "_".join(sorted(map(str, groups)))
        if groups and not item.nodeid.endswith(suffix):
            item._id = coerce_node_id(item.nodeid + suffix)  # type: ignore[attr-defined]
