"""Render the documentation's generated blocks from committed JSON.

    .venv/bin/python scripts/render_docs.py

``docs/energy.md``: the verdict and the table per pair of platforms, from
``docs/energy/report.json`` (the main job's report, copied in at a clean commit by
``python -m benchmarks.bench_main_job`` and ``cp runs/bench_main_job/report/report.json
docs/energy/``). ``docs/frontier.md``: the temporal-sparsity frontier per env and its verdicts,
priced from ``docs/frontier/study.json`` (``snnkart study studies/frontier.toml``'s record,
copied in), and its figure ``docs/frontier/frontier.png``. The published study tables
(:data:`STUDIES`: the behaviour-cloning studies in ``docs/training.md``, the generalisation
study in ``docs/tracks.md``) from their committed ``study.json``, each a reporting study run at
a clean commit (``snnkart study studies/<name>.toml``; the record copied in).
``tests/test_docs.py`` renders the pages again and fails if one differs.
"""

from __future__ import annotations

import json
from pathlib import Path

from snnkart.app.pipeline import DEMO_SEED
from snnkart.app.study_summary import ORIGINAL
from snnkart.report.docs_block import BEGIN, END, energy_block, replace_block
from snnkart.report.frontier import frontier, frontier_block, frontier_figure, verdicts_block
from snnkart.report.main_job_block import main_job_block
from snnkart.report.study_blocks import study_block
from snnkart.report.study_plots import figure as study_figure
from snnkart.report.study_record import StudyRecord

ROOT = Path(__file__).resolve().parents[1]
FRONTIER = "docs/frontier/study.json"
PAGES = {"docs/energy.md": "docs/energy/report.json", "docs/frontier.md": FRONTIER,
         "README.md": FRONTIER}  # fmt: skip
FIGURE = "docs/frontier/frontier.png"
STUDIES = {  # a page's block per study.json: (page, source)
    ("docs/training.md", "docs/bc/steer.json"),
    ("docs/training.md", "docs/bc/gazebo.json"),
    ("docs/tracks.md", "docs/generalisation/study.json"),
    ("docs/results.md", "docs/results/small_S.json"),
    ("README.md", "docs/results/small_S.json"),
    ("docs/results.md", "docs/results/big_S.json"),
}
MAIN_JOB = ("docs/deployment.md", "benchmarks/results/bench_main_job-8c4f9a5.json")
"""The page quoting the main job, and the record of ``python -m benchmarks.bench_main_job``."""
STUDY_FIGURES = {
    "docs/results/small_S-finishes.png": ("docs/results/small_S.json", "finishes"),
    "docs/results/big_S-finishes.png": ("docs/results/big_S.json", "finishes"),
}
"""Figures drawn from a published study's record: file -> (record, curve key)."""


def rendered(page: str, source: str) -> str:
    """The page's text with its generated block rendered from ``source``."""
    if (page, source) == MAIN_JOB:
        bench = json.loads((ROOT / source).read_text())
        block = main_job_block(bench, source, DEMO_SEED, BEGIN, END)
        return replace_block((ROOT / page).read_text(), block, source)
    if (page, source) in STUDIES:
        record = StudyRecord.read(ROOT / source)
        block = study_block(record, source, BEGIN, END, ORIGINAL)
        return replace_block((ROOT / page).read_text(), block, source)
    if source == FRONTIER:
        summary = frontier(StudyRecord.read(ROOT / source))
        render = verdicts_block if page == "README.md" else frontier_block
        block = render(summary, source, BEGIN, END)
    else:
        block = energy_block(json.loads((ROOT / source).read_text()), source)
    return replace_block((ROOT / page).read_text(), block, source)


def blocks() -> list[tuple[str, str]]:
    """Every (page, source) pair with a generated block."""
    return [*PAGES.items(), *sorted(STUDIES), MAIN_JOB]


def main() -> None:
    for page, source in blocks():
        (ROOT / page).write_text(rendered(page, source))
        print(f"{page}: rendered from {source}")
    summary = frontier(StudyRecord.read(ROOT / FRONTIER))
    (ROOT / FIGURE).write_bytes(frontier_figure(summary))
    print(f"{FIGURE}: drawn from {FRONTIER}")
    for path, (source, key) in STUDY_FIGURES.items():
        record = StudyRecord.read(ROOT / source)
        fig = study_figure(record, record.study.tracks[0], key)
        fig.savefig(ROOT / path)
        print(f"{path}: drawn from {source}")


if __name__ == "__main__":
    main()
