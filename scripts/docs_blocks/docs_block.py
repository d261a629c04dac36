"""The energy page of the documentation (``docs/energy.md``): its verdict and table are
rendered from a committed ``report.json`` by this code, never typed by hand, and a test renders
them again and compares."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from snnkart.errors import ReportError
from snnkart.report.document import md_table
from snnkart.report.first_screen import pair_rows, sd_sentence, sentence
from snnkart.report.sigma_delta_document import chip_rows

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

READS = ("snnkart/report/v2", "snnkart/report/v3", "snnkart/report/v4")
"""The report.json versions this code reads: v3, and v2 (a LIF report, as v3 writes it)."""
BEGIN = "<!-- generated from {source} by scripts/render_docs.py: do not edit -->"
END = "<!-- end of generated block -->"
RESULTS_TAG = "results-1"
"""The tag the published results are made at (docs/results.md, "Making every result again")."""


def published_tags(root: Path) -> dict[str, str]:
    """``root``/docs/tags.toml: the tags results are published at, with their commits (a clone
    may lack the tags themselves)."""
    return {k: str(v) for k, v in tomllib.loads((root / "docs/tags.toml").read_text()).items()}


def check_version(report: dict[str, Any], source: str) -> None:
    """Refuse a report.json this code does not read, in one line naming the fix."""
    schema = report.get("schema")
    if schema in READS:
        return
    if isinstance(schema, str) and schema.startswith("snnkart/report/v"):
        raise ReportError(
            f"{source}: {schema} was written by an older snnkart; run `snnkart report "
            "DEPLOYMENT_DIR` again (it reads the deployment's deploy.json)"
        )
    raise ReportError(f"{source}: not a snnkart report.json (schema {schema!r})")


def energy_block(report: dict[str, Any], source: str) -> str:
    """The generated part of the page: where the numbers come from, the one-sentence verdict
    (the goal's answer first for a sigma-delta report) and the verdict per pair of platforms."""
    check_version(report, source)
    if report.get("kind") == "sigma-delta":
        return "\n\n".join(
            [
                BEGIN.format(source=source),
                sd_sentence(report),
                md_table(chip_rows(report)).rstrip(),
                END,
            ]
        )
    deploy = report["deploy"]
    where = (
        f"Deployment: `{deploy.get('backend', '?')}` ({deploy.get('precision', '?')}), "
        f"{deploy.get('episodes', '?')} episodes from seed {deploy.get('first_seed', '?')}; "
        f"report schema `{report['schema']}`."
    )
    return "\n\n".join(
        [
            BEGIN.format(source=source),
            where,
            sentence(report),
            md_table(pair_rows(report)).rstrip(),
            END,
        ]
    )


def replace_block(page: str, block: str, source: str | None = None) -> str:
    """``page`` with its generated block replaced by ``block``: the block generated from
    ``source`` when given (a page may hold one block per source), else the page's one block."""
    head = re.escape(BEGIN.format(source=source)) if source else r"<!-- generated from .*?"
    pattern = re.compile(head + r".*?" + re.escape(END), re.S)
    if not pattern.search(page):
        where = f" from {source}" if source else ""
        raise ValueError(f"the page has no generated block{where}; add the two marker lines")
    return pattern.sub(lambda _: block, page, count=1)
