"""Render the documentation's generated blocks from committed JSON.

    .venv/bin/python scripts/render_docs.py

``docs/energy.md``: the verdict and the table per pair of platforms, from
``docs/energy/report.json`` (the main job's report, copied in at a clean commit by
``python -m benchmarks.bench_main_job`` and ``cp runs/bench_main_job/report/report.json
docs/energy/``). ``tests/test_docs.py`` renders them again and fails if the page differs.
"""

from __future__ import annotations

import json
from pathlib import Path

from snnkart.report.docs_block import energy_block, replace_block

ROOT = Path(__file__).resolve().parents[1]
PAGES = {"docs/energy.md": "docs/energy/report.json"}


def rendered(page: str, source: str) -> str:
    """The page's text with its generated block rendered from ``source``."""
    report = json.loads((ROOT / source).read_text())
    return replace_block((ROOT / page).read_text(), energy_block(report, source))


def main() -> None:
    for page, source in PAGES.items():
        (ROOT / page).write_text(rendered(page, source))
        print(f"{page}: rendered from {source}")


if __name__ == "__main__":
    main()
