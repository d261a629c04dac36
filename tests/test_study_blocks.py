"""Published study tables come from a reporting study's record at a clean commit, rendered by
code (``scripts/docs_blocks/study_blocks.py``); anything else is refused in one line."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest

from snnkart.app.study_summary import ORIGINAL
from snnkart.errors import ReportError
from snnkart.report.study_document import track_table
from snnkart.report.study_record import StudyRecord

# scripts/docs_blocks: the documents' writers, not installed with snnkart
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from docs_blocks.docs_block import BEGIN, END, replace_block
from docs_blocks.study_blocks import (
    cells_block,
    every_seed_block,
    regenerate_block,
    study_block,
)

RECORD = Path(__file__).parent / "data" / "records" / "study.json"


def _reporting(record: StudyRecord, commit: str = "abc1234") -> StudyRecord:
    study = dataclasses.replace(record.study, data="reporting")
    return dataclasses.replace(record, study=study, machine={**(record.machine or {}),
                                                              "commit": commit})  # fmt: skip


def test_a_tuning_dirty_or_partial_study_is_refused() -> None:
    record = StudyRecord.read(RECORD)  # tuning data, at a dirty commit
    with pytest.raises(ReportError, match=r"x.json: tuning data cannot fill a published table"):
        study_block(record, "x.json", BEGIN, END, ORIGINAL)
    with pytest.raises(ReportError, match=r"made at commit ab1\w+-dirty; run the whole study"):
        study_block(_reporting(record, "ab1092d-dirty"), "x.json", BEGIN, END, ORIGINAL)
    piece = dataclasses.replace(_reporting(record), only=["*/grid-ann"])
    with pytest.raises(ReportError, match=r"\(a piece\)"):
        study_block(piece, "x.json", BEGIN, END, ORIGINAL)


def test_the_block_holds_the_studys_own_table_and_replaces_only_its_own_block() -> None:
    record = _reporting(StudyRecord.read(RECORD))
    block = study_block(record, "a.json", BEGIN, END, ORIGINAL)
    assert block.startswith(BEGIN.format(source="a.json")) and block.endswith(END)
    assert "\n".join(track_table(record, "small_S", ORIGINAL)) in block
    assert "Commit abc1234;" in block and "reporting seeds" in block
    other = BEGIN.format(source="b.json") + "\nold b\n" + END
    page = f"# P\n\n{BEGIN.format(source='a.json')}\nold a\n{END}\n\ntext\n\n{other}\n"
    new = replace_block(page, block, "a.json")
    assert "old a" not in new and other in new and block in new
    with pytest.raises(ValueError, match=r"no generated block from c\.json"):
        replace_block(page, block, "c.json")


def test_a_published_ablation_shows_the_originals_row_once_per_env() -> None:
    """The BC study (two variants of one env) beside the original: one original row, under
    both variants, in the committed page's block."""
    record = StudyRecord.read(Path(__file__).parents[1] / "docs/bc/steer.json")
    block = study_block(record, "docs/bc/steer.json", BEGIN, END, ORIGINAL)
    rows = [line for line in block.splitlines() if line.startswith("| ")]
    assert [r.split(" | ")[0] for r in rows[1:]] == [
        "| env", "| steer · scratch", "| steer · bc", "| *original*"][1:]  # fmt: skip
    assert "better/worse than the original's single run" in block


def test_every_seed_cells_by_hand() -> None:
    """A cell is seeds with a first finish / seeds, the median first finish (None counts as
    never: "> cap" when the median seed never finished) and the median success, computed
    here from the runs of the BC study's scratch arm (steer ANN seed 104 never finished)."""
    import statistics

    record = StudyRecord.read(Path(__file__).parents[1] / "docs/bc/steer.json")
    with pytest.raises(ReportError, match="an ablation has a row per variant"):
        every_seed_block([(record, "s.json")], BEGIN, END)
    scratch = dataclasses.replace(
        record,
        study=dataclasses.replace(record.study, variants={}),
        cells=[c for c in record.cells if c.variant == "scratch"],
    )
    block = every_seed_block([(scratch, "s.json")], BEGIN, END)
    runs = [r for r in record.runs if r.variant == "scratch" and r.policy == "ann"]
    firsts = [r.first_finish_step for r in runs]
    reached = sum(f is not None for f in firsts)
    median = statistics.median([float("inf") if f is None else f for f in firsts])
    success = statistics.median([r.eval_success_rate for r in runs])
    expected = f"{reached}/5 · {median / 1000:.0f}k · {100 * success:.0f} %"
    assert reached == 4 and f"| small_S | {expected} | " in block, block


def test_chosen_cells_by_hand_and_their_settings() -> None:
    """A row per chosen cell with its variant's settings; its median first finish and steps to
    the mark computed here from the runs; a study column only when the rows span records; a
    tuning record refused."""
    import statistics

    path = Path(__file__).parents[1] / "docs/bc/steer.json"
    record = StudyRecord.read(path)
    rows = [(record, "s.json", c) for c in record.cells if c.policy == "snn"]
    block = cells_block(rows, BEGIN, END, "Intro.")
    runs = [r for r in record.runs if r.variant == "bc" and r.policy == "snn"]
    first = statistics.median(r.first_finish_step or 0 for r in runs)  # every seed finished
    mark = statistics.median(r.steps_to_finishes or 0 for r in runs)
    row = next(
        line for line in block.splitlines() if line.startswith("| small_S · steer · SNN · bc")
    )
    assert "(`bc.data=benchmarks/bc-data/steer-small_S-pursuit.npz`, `bc.epochs=20`)" in row
    cols = row.split(" | ")
    assert cols[2].startswith(f"{first / 1000:.0f}k (") and cols[3].startswith(
        f"{mark / 1000:.0f}k ("
    ), row
    assert "| cell | seeds | first finish | 300 finishes |" in block
    assert "| study |" not in block and sum(line.startswith("| small_S · steer") for line in
                                           block.splitlines()) == 2  # fmt: skip
    two = cells_block([*rows, (record, "t.json", rows[0][2])], BEGIN, END, "Intro.")
    assert "| study | cell |" in two and "`s.json` (commit" in two and "`t.json` (commit" in two
    with pytest.raises(ReportError, match="tuning data cannot fill a published table"):
        tuning = StudyRecord.read(RECORD)
        cells_block([(tuning, "x.json", tuning.cells[0])], BEGIN, END, "Intro.")


def test_the_regeneration_table_sums_every_wall_clock() -> None:
    """A row per study with its command and wall-clock, the main job's row, and a total that
    is their sum (computed here from the records)."""
    import json

    docs = Path(__file__).parents[1] / "docs"
    studies = [(StudyRecord.read(docs / f"bc/{e}.json"), f"docs/bc/{e}.json",
                f"studies/bc-{e}.toml") for e in ("steer", "gazebo")]  # fmt: skip
    bench_path = next((docs.parent / "benchmarks/results").glob("bench_main_job-*.json"))
    bench = json.loads(bench_path.read_text())
    block = regenerate_block(studies, (bench, bench_path.name), BEGIN, END)
    total = sum(r.wall_clock.train_seconds + r.wall_clock.eval_seconds for r, _, _ in studies)
    total += bench["wall_s"]
    assert f"adds up to {total / 3600:.1f} hours" in block, block
    row = next(line for line in block.splitlines() if line.startswith("| `docs/bc/steer.json`"))
    w, runs = studies[0][0].wall_clock, studies[0][0].runs
    summed = sum(r.train_seconds for r in runs) / 60
    assert "`snnkart study studies/bc-steer.toml --out runs/bc-steer --jobs 2`" in row
    assert row.endswith(
        f"| {w.runs} | {w.train_seconds / 60:.1f} min | {w.eval_seconds / 60:.1f} min | "
        f"{summed:.0f} min |"
    ), row
    assert f"| {bench['wall_s'] / 60:.1f} min (training" in block


def test_the_main_job_block_is_the_records_numbers() -> None:
    """Each number of the main-job paragraph is the record's; a dirty record is refused."""
    import json

    from docs_blocks.main_job_block import main_job_block

    path = Path(__file__).parents[1] / "tests/data/records/main-job.json"
    bench = json.loads(path.read_text())
    block = main_job_block(bench, "b.json", 101, BEGIN, END)
    for piece in ("commit 8c4f9a5", "seed 101", "301,056 steps", "first finish at 40,392 steps",
                  "torch 98 %, fixed point 98 %", "in 0 of 3,513 and 0 of 344 env steps",
                  "on 99.7 % of actions", "Lava 20/20 (fixed) and 2/2 (float)",
                  "34 spikes and 421 synaptic operations"):  # fmt: skip
        assert piece in block, piece
    bench["machine"]["commit"] += "-dirty"
    with pytest.raises(ReportError, match="run the benchmark at a clean commit"):
        main_job_block(bench, "b.json", 101, BEGIN, END)
