"""Published study tables in the documentation: a reporting study's ``study.json`` rendered
into a page's generated block (``scripts/render_docs.py``), never typed by hand. A tuning study
or one run at a commit with uncommitted changes is refused: published tables are reporting
data from a clean commit (docs/results.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from docs_blocks.main_job_block import bench_commit
from snnkart.envs.tracks import short_name
from snnkart.errors import ReportError
from snnkart.report.held_out import held_out_lines
from snnkart.report.study_document import (
    deployed_lines,
    spread_count,
    spread_pct,
    spread_steps,
    track_table,
)
from snnkart.report.study_record import CellSummary, StudyRecord


def check_publishable(record: StudyRecord, source: str) -> str:
    """The record's commit, if it may fill a published table; else a one-line refusal."""
    study = record.study
    if study.data != "reporting":
        raise ReportError(
            f"{source}: {study.data or 'undeclared'} data cannot fill a published table; run "
            'a study with data = "reporting" (docs/results.md)'
        )
    commit = str((record.machine or {}).get("commit") or "unknown")
    if commit.endswith("-dirty") or commit == "unknown" or record.only:
        raise ReportError(
            f"{source}: made at commit {commit}{' (a piece)' if record.only else ''}; run the "
            "whole study again at a clean commit"
        )
    return commit


def study_block(
    record: StudyRecord, source: str, begin: str, end: str, original: dict[str, dict[str, float]]
) -> str:
    """The block: what was run and where, each track's table, and the held-out table."""
    commit = check_publishable(record, source)
    study, w = record.study, record.wall_clock
    seeds = f"{study.seeds[0]}–{study.seeds[-1]}" if len(study.seeds) > 1 else str(study.seeds[0])
    lines = [
        begin.format(source=source),
        "",
        f"`{study.name}`: {len(study.seeds)} reporting seeds ({seeds}) per cell, at most "
        f"{study.steps:,} env steps per run; evaluation {study.eval_episodes} seeded episodes "
        "(ANNs in torch, SNNs on the numpy reference in fixed point). Medians over seeds with "
        f"(min–max). Commit {commit}; {w.runs} runs, {w.train_seconds / 60:.0f} min of "
        f"training and {w.eval_seconds / 60:.0f} min of evaluation on "
        f"{(record.machine or {}).get('cores', '?')} cores."
        + (
            " ✓/✗: better/worse than the original's single run of that cell (kart-simulator, "
            "small_S, 300 finishes)."
            if "small_S" in study.tracks and study.finishes == 300
            else ""
        ),
        "",
    ]
    for track in record.tracks():
        if len(study.tracks) > 1 or study.eval_tracks:
            lines += [f"Trained on {Path(track).stem}:", ""]
        lines += [*track_table(record, track, original), ""]
        lines += deployed_lines([d for d in record.deployed if d.track == track])
    held = held_out_lines(record)
    lines += held[2:]  # without its heading
    return "\n".join([*lines, end]).replace("\n\n\n", "\n\n")


def every_seed_block(records: list[tuple[StudyRecord, str]], begin: str, end: str) -> str:
    """One table from studies of one protocol (every-seed on small_S, held-out-reporting on
    zigzag and bends): per track a row, per env and policy kind a cell "seeds that reached a
    first finish / seeds · median first finish · median evaluation success"."""
    sources = ", ".join(f"`{source}`" for _, source in records)
    for record, source in records:
        if record.study.variants:
            raise ReportError(f"{source}: an ablation has a row per variant; use study_block")
    commits = sorted({check_publishable(record, source) for record, source in records})
    first = records[0][0].study
    envs = list(dict.fromkeys(e for record, _ in records for e in record.study.envs))
    kinds = list(dict.fromkeys(p for record, _ in records for p in record.study.policies))
    columns = [(env, kind) for env in envs for kind in kinds]
    lines = [
        begin.format(source=sources.replace("`", "")),
        "",
        f"Rendered from {sources} (commit {', '.join(commits)}): {len(first.seeds)} reporting "
        f"seeds per cell, at most {first.steps:,} env steps, a run stopping once it has "
        f"{first.finishes} finishes and evaluates >= 80 % at two checks 50k apart; a cell is "
        "seeds with a first finish / seeds · median first finish · median success over "
        f"{first.eval_episodes} evaluation episodes (> cap: the median seed never finished).",
        "",
        "| track | " + " | ".join(f"{e} {k.upper()}" for e, k in columns) + " |",
        "|---|" + "---|" * len(columns),
    ]
    for record, _ in records:
        for track in record.tracks():
            row = []
            for env, kind in columns:
                cell = next(
                    (c for c in record.cells if (c.track, c.env, c.policy) == (track, env, kind)),
                    None,
                )
                if cell is None:
                    row.append("-")
                    continue
                f, s = cell.first_finish_step, cell.eval_success_rate
                median = "> cap" if f.median is None else f"{f.median / 1000:.0f}k"
                success = "-" if s.median is None else f"{100 * s.median:.0f} %"
                row.append(f"{f.reached}/{f.of} · {median} · {success}")
            lines.append(f"| {Path(track).stem} | " + " | ".join(row) + " |")
    return "\n".join([*lines, "", end])


def cells_block(
    rows: list[tuple[StudyRecord, str, CellSummary]], begin: str, end: str, intro: str
) -> str:
    """Chosen cells of one or more reporting studies, a row each (an ablation's variants, or one
    env and policy kind across studies): first finish, steps to the study's finishes mark,
    evaluation success, spikes and synaptic operations per env step, medians (min–max)."""
    sources = list(dict.fromkeys(source for _, source, _ in rows))
    commits = {source: check_publishable(record, source) for record, source, _ in rows}
    marks = {record.study.finishes for record, _, _ in rows}
    mark = f"{marks.pop()} finishes" if len(marks) == 1 else "to the mark (finishes)"
    several = len(sources) > 1
    lines = [
        begin.format(source=", ".join(sources)),
        "",
        f"{intro} Rendered from "
        + ", ".join(f"`{s}` (commit {commits[s]})" for s in sources)
        + "; medians over seeds with (min–max).",
        "",
        ("| study " if several else "")
        + f"| cell | seeds | first finish | {mark} | eval | spikes/step | synops/step |",
        ("|---" if several else "") + "|---|---|---|---|---|---|---|",
    ]
    for record, _, c in rows:
        study = record.study
        lines.append(
            (f"| {study.name} " if several else "")
            + f"| {_cell_name(record, c)} | {len(c.seeds)} ({c.seeds[0]}–{c.seeds[-1]}) | "
            f"{spread_steps(c.first_finish_step)} | {spread_steps(c.steps_to_finishes)}"
            + ("" if len(marks) == 0 else f" ({study.finishes})" if several else "")
            + f" | {spread_pct(c.eval_success_rate)} | {spread_count(c.eval_spikes_per_step)} "
            f"| {spread_count(c.eval_synops_per_step)} |"
        )
    return "\n".join([*lines, "", end])


def _cell_name(record: StudyRecord, c: CellSummary) -> str:
    """track · env · POLICY · variant, with the variant's settings (``base``: none)."""
    sets = next(
        (v for k, v in record.study.variants.items() if k.rpartition(":")[2] == c.variant), []
    )
    name = " · ".join(x for x in (short_name(c.track), c.env, c.policy.upper(), c.variant) if x)
    return name + (f" (`{'`, `'.join(sets)}`)" if sets else "")


def regenerate_block(
    studies: list[tuple[StudyRecord, str, str]],
    main_job: tuple[dict[str, Any], str],
    begin: str,
    end: str,
    jobs: int = 2,
) -> str:
    """How each published result is made again and what it cost on the machine that made it:
    per study its config, command and runs, the wall-clock of training and evaluation as its
    record measured them, and its runs' own training time summed (a study started again reuses
    the runs it had finished, whose training its wall-clock does not hold); the main job's
    wall-clock; the total."""
    bench, bench_source = main_job
    sources = [source for _, source, _ in studies] + [bench_source]
    lines = [
        begin.format(source=", ".join(sources)),
        "",
        "| result | command | commit | runs | training | evaluation | runs' training, summed |",
        "|---|---|---|---|---|---|---|",
    ]
    total, reused_any = 0.0, False
    for record, source, config in studies:
        commit, w = check_publishable(record, source), record.wall_clock
        summed = sum(r.train_seconds for r in record.runs)
        total += w.train_seconds + w.eval_seconds
        reused_any = reused_any or w.runs_reused > 0
        runs = f"{w.runs} ({w.runs_reused} reused)" if w.runs_reused else str(w.runs)
        lines.append(
            f"| `{source}` | `snnkart study {config} --out runs/{Path(config).stem} --jobs "
            f"{jobs}` | {commit} | {runs} | {w.train_seconds / 60:.1f} min | "
            f"{w.eval_seconds / 60:.1f} min | {summed / 60:.0f} min |"
        )
    commit = bench_commit(bench, bench_source)
    wall = float(bench["wall_s"])
    total += wall
    cores = (studies[0][0].machine or {}).get("cores", "?")
    lines += [
        f"| `{bench_source}` | `python -m benchmarks.bench_main_job` | {commit} | 1 | "
        f"{wall / 60:.1f} min (training, deployment and report) | | |",
        "",
        f"The records' wall-clock adds up to {total / 3600:.1f} hours on {cores} cores, one "
        f"study at a time, {jobs} runs at once.",
    ]
    if reused_any:
        lines[-1] += (
            " A study started again reuses the runs it had finished, and may reuse runs of an "
            "earlier commit: only when a run's study key (the resolved config, the track, and "
            "the code of `snnkart/rl` and `snnkart/envs`) matches. A reused run's training is "
            "not in its record's wall-clock but is in the last column. Its evaluation is "
            "reused only when made from the same request, checkpoint and evaluation code, "
            "and made again otherwise (`snnkart/app/study_eval.py`)."
        )
    return "\n".join([*lines, "", end])
