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
a clean commit (``snnkart study studies/<name>.toml``; the record copied in). The blocks' writers
are in ``scripts/docs_blocks/`` (not installed with snnkart).
``tests/test_docs.py`` renders the pages again and fails if one differs.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # docs_blocks/, beside this script

from docs_blocks.docs_block import (
    BEGIN,
    END,
    RESULTS_TAG,
    energy_block,
    published_tags,
    replace_block,
)
from docs_blocks.frontier_blocks import frontier_block, frontier_figure, verdicts_block
from docs_blocks.main_job_block import main_job_block
from docs_blocks.study_blocks import (
    cells_block,
    check_publishable,
    every_seed_block,
    regenerate_block,
    study_block,
)

from snnkart.app.pipeline import DEMO_SEED
from snnkart.app.study_summary import ORIGINAL
from snnkart.report.frontier import frontier
from snnkart.report.study_plots import figure as study_figure
from snnkart.report.study_record import CellSummary, StudyRecord

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
MAIN_JOB = (
    "docs/deployment.md",
    f"benchmarks/results/bench_main_job-{published_tags(ROOT)[RESULTS_TAG][:7]}.json",
)
"""The page quoting the main job, and the record ``python -m benchmarks.bench_main_job`` wrote
at the results tag."""
STUDY_FIGURES = {
    "docs/results/small_S-finishes.png": ("docs/results/small_S.json", "finishes"),
    "docs/results/big_S-finishes.png": ("docs/results/big_S.json", "finishes"),
    "docs/results/ablation-finishes.png": ("docs/results/ablation.json", "finishes"),
}
"""Figures drawn from a published study's record: file -> (record, curve key)."""
EVERY_SEED = (
    "docs/results.md",
    "docs/results/every-seed.json, docs/results/held-out-reporting.json",
)
"""The page whose "Does every seed learn?" table joins these records (a row per track)."""
GAZEBO_FIRST = ORIGINAL["gazebo"]["snn_first"]
GAZEBO_SOURCES = ", ".join(["docs/results/small_S.json", "docs/results/big_S.json",
                            "docs/results/every-seed.json", "docs/results/held-out-reporting.json",
                            "docs/bc/gazebo.json", "docs/frontier/study.json"])  # fmt: skip
CELL_BLOCKS: dict[tuple[str, str], tuple[str, Callable[[CellSummary], bool]]] = {
    ("docs/results.md", "docs/results/ablation.json"): (
        "Each variant changes one thing from the steer SNN's defaults (base: current "
        "encoding, T = 8, LIF, surrogate slope 25, no rate penalty).",
        lambda c: True,
    ),
    ("docs/results.md", GAZEBO_SOURCES): (
        "The gazebo SNN in every reporting study that trained one (the mark is 300 finishes "
        "or, in the every-seed protocol, 20); the original's single run first finished at "
        f"{GAZEBO_FIRST / 1000:.0f}k steps.",
        lambda c: c.env == "gazebo" and c.policy in ("snn", "sdnn"),
    ),
    ("docs/results.md", "docs/results/recurrent.json"): (
        "The recurrent LIF kind (`rsnn`) against the stateful LIF kind it extends, grid on "
        "small_S, the same widths (64-64), budget (300k env steps, the same stop rule) and "
        "reporting seeds on both sides.",
        lambda c: True,
    ),
}
"""Tables of chosen cells: (page, its records joined by ", ") -> (intro, which cells)."""
PUBLISHED = {
    "docs/results/small_S.json": "studies/small_S.toml",
    "docs/results/big_S.json": "studies/big_S.toml",
    "docs/results/every-seed.json": "studies/every-seed.toml",
    "docs/results/held-out-reporting.json": "studies/held-out-reporting.toml",
    "docs/results/ablation.json": "studies/ablation.toml",
    "docs/generalisation/study.json": "studies/generalisation.toml",
    "docs/bc/steer.json": "studies/bc-steer.toml",
    "docs/bc/gazebo.json": "studies/bc-gazebo.toml",
    "docs/frontier/study.json": "studies/frontier.toml",
    "docs/results/recurrent.json": "studies/recurrent.toml",
}
"""Every published study record and the config that makes it again (tests/test_docs.py checks
that they agree and that every reporting config is here)."""
REGENERATE = ("docs/results.md", ", ".join([*PUBLISHED, MAIN_JOB[1]]))
"""The page's table of how every published result is made again, and what it cost."""


ZOO_PAGE = "docs/zoo.md"
ZOO = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs/zoo").glob("*.json"))
"""The zoo studies' records (``snnkart study studies/zoo/<task>.toml``, copied in), a table each."""


def zoo_block(source: str) -> str:
    """A zoo study's table, from reporting data at a clean commit only."""
    from snnkart.errors import ReportError
    from snnkart.report.zoo_record import ZooStudyRecord
    from snnkart.report.zoo_table import zoo_markdown

    record = ZooStudyRecord.read(ROOT / source)
    commit = record.commit
    if record.data != "reporting" or commit.endswith("-dirty") or commit == "unknown":
        raise ReportError(
            f"{source}: {record.data} data at commit {commit} cannot fill a published table; "
            "run the zoo study again at a clean commit"
        )
    return "\n".join([BEGIN.format(source=source), "", zoo_markdown([record]).rstrip(), "", END])


def rendered(page: str, source: str) -> str:
    """The page's text with its generated block rendered from ``source``."""
    return replace_block((ROOT / page).read_text(), block(page, source), source)


def _records(source: str) -> list[tuple[StudyRecord, str]]:
    """The study records a block's source names, joined by ", "."""
    return [(StudyRecord.read(ROOT / s), s) for s in source.split(", ")]


def block(page: str, source: str) -> str:
    """The generated block of ``page`` whose source is ``source``."""
    if page == ZOO_PAGE:
        return zoo_block(source)
    if (page, source) == MAIN_JOB:
        return main_job_block(json.loads((ROOT / source).read_text()), source, DEMO_SEED,
                              BEGIN, END)  # fmt: skip
    if (page, source) == EVERY_SEED:
        return every_seed_block(_records(source), BEGIN, END)
    if (page, source) == REGENERATE:
        studies = [(StudyRecord.read(ROOT / s), s, c) for s, c in PUBLISHED.items()]
        bench = json.loads((ROOT / MAIN_JOB[1]).read_text())
        return regenerate_block(studies, (bench, MAIN_JOB[1]), BEGIN, END)
    if (page, source) in CELL_BLOCKS:
        intro, chosen = CELL_BLOCKS[page, source]
        rows = [(r, s, c) for r, s in _records(source) for c in r.cells if chosen(c)]
        return cells_block(rows, BEGIN, END, intro)
    if (page, source) in STUDIES:
        return study_block(StudyRecord.read(ROOT / source), source, BEGIN, END, ORIGINAL)
    if source == FRONTIER:
        record = StudyRecord.read(ROOT / source)
        commit = check_publishable(record, source)  # reporting data at a clean commit
        if page == "README.md":
            return verdicts_block(frontier(record), source, BEGIN, END)
        return frontier_block(frontier(record), source, BEGIN, END, commit)
    return energy_block(json.loads((ROOT / source).read_text()), source)


def blocks() -> list[tuple[str, str]]:
    """Every (page, source) pair with a generated block."""
    return [
        *PAGES.items(),
        *sorted(STUDIES),
        MAIN_JOB,
        EVERY_SEED,
        *sorted(CELL_BLOCKS),
        REGENERATE,
        *((ZOO_PAGE, source) for source in ZOO),
    ]


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
