"""The energy page of the documentation (``docs/energy.md``): its verdict and table are
rendered from a committed ``report.json`` by this code, never typed by hand, and a test renders
them again and compares."""

from __future__ import annotations

import re
from typing import Any

from snnkart.report.document import md_table
from snnkart.report.first_screen import pair_rows, sentence

BEGIN = "<!-- generated from {source} by scripts/render_docs.py: do not edit -->"
END = "<!-- end of generated block -->"


def energy_block(report: dict[str, Any], source: str) -> str:
    """The generated part of the page: where the numbers come from, the one-sentence verdict
    and the verdict per pair of platforms."""
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


def replace_block(page: str, block: str) -> str:
    """``page`` with its generated block replaced by ``block`` (one block per page)."""
    pattern = re.compile(r"<!-- generated from .*?" + re.escape(END), re.S)
    if not pattern.search(page):
        raise ValueError("the page has no generated block; add the two marker lines")
    return pattern.sub(lambda _: block, page, count=1)
