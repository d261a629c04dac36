"""A study's document: ``study.md``, its tables beside the original's, naming the figures that
:mod:`snnkart.report.study_plots` draws from the same record."""

from __future__ import annotations

from pathlib import Path

from snnkart.report.held_out import held_out_lines
from snnkart.report.study_plots import CAPTION, KEYS, cell_label, plot_names, record_commit
from snnkart.report.study_record import CellSummary, DeployedRun, Spread, StudyRecord

ANN, SNN = "ann", "snn"
"""The pair the learning table sets side by side with the original thesis's own numbers."""


def _k(steps: float | None) -> str:
    return ">cap" if steps is None else f"{steps / 1000:.0f}k"


def spread_steps(s: Spread) -> str:
    if s.of == 1 or s.reached == 0:
        text = _k(s.median)
    else:
        text = f"{_k(s.median)} ({_k(s.min)}–{_k(s.max)})"
    return text if s.reached == s.of else f"{text}, {s.reached}/{s.of} seeds"


def spread_pct(s: Spread) -> str:
    def p(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.0f} %"

    return f"{p(s.median)} ({p(s.min)}–{p(s.max)})" if s.of > 1 else p(s.median)


def spread_count(s: Spread | None) -> str:
    if s is None or s.median is None:
        return "-"
    if s.of == 1:
        return f"{s.median:.0f}"
    return f"{s.median:.0f} ({s.min:.0f}–{s.max:.0f})"


def _vs(ours: float | None, theirs: float | None, lower_is_better: bool = True) -> str:
    if theirs is None:
        return ""
    if ours is None:
        return " ✗" if lower_is_better else ""
    better = ours < theirs if lower_is_better else ours > theirs
    return " ✓" if better else " ✗"


def markdown(record: StudyRecord, original: dict[str, dict[str, float]]) -> str:
    study = record.study
    n = study.finishes
    lines = [
        f"# Study: {study.name}",
        "",
        f"{len(study.seeds)} seeds per cell, at most {study.steps:,} env steps per run. "
        "Medians over seeds with (min–max); `>cap`: not reached within the cap; "
        '"k/n seeds": only k of the n seeds got there. '
        f'"{n} finishes": the step at which the run\'s cumulative laps (finished training '
        f"episodes that started at the spawn) reached {n}. Evaluation: "
        f"{study.eval_episodes} seeded episodes, ANNs in torch, SNNs exported to NIR on "
        "the numpy reference in fixed point. ✓/✗: better/worse than the original (one run "
        "per cell; shown for small_S at 300 finishes). Data: "
        f"{study.data or 'not declared'} (the results protocol, docs/results.md).",
        "",
    ]
    if any(r.eval_backend.startswith("torch (cuba") for r in record.runs):
        lines += [
            "Current-based LIF (cuba) SNNs with biases between their spiking layers are "
            "evaluated in torch: Lava's LIF cannot run those biases.",
            "",
        ]
    if record.only:
        lines += [f"A piece of the study: the cells matching `{' '.join(record.only)}`.", ""]
    for track in record.tracks():
        lines += [f"## {Path(track).stem}", "", *track_table(record, track, original), ""]
        lines += deployed_lines([d for d in record.deployed if d.track == track])
        lines += _figures(record, track)
    lines += held_out_lines(record)
    w = record.wall_clock
    lines += [
        f"Training {w.train_seconds / 60:.1f} min and evaluation "
        f"{w.eval_seconds / 60:.1f} min of wall-clock for {w.runs} runs "
        f"({w.runs_reused} reused); {record.env_steps:,} env steps in all. "
        f"Env revision {record.env_revision}, training code {record.code}.",
        "",
    ]
    if record.machine is not None:  # records before it have no machine
        m = record.machine
        lines += [f"Commit {m['commit']}, {m['cores']} cores of {m['cpu']}, {m['date']}.", ""]
    return "\n".join(lines)


def track_table(
    record: StudyRecord, track: str, original: dict[str, dict[str, float]]
) -> list[str]:
    """A track's table: per env (and variant) the ANN and SNN cells, beside the original's
    numbers where they compare (small_S at 300 finishes)."""
    study, n = record.study, record.study.finishes
    lines = [
        f"| env | ANN first finish | SNN first finish | ANN {n} finishes | "
        f"SNN {n} finishes | SNN % of ANN | ANN eval | SNN eval | SNN spikes/step |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for env in study.envs:
        # the original's numbers: its track and its mark of 300 finishes only
        comparable = Path(track).stem == "small_S" and n == 300
        orig = original.get(env) if comparable else None
        shown = False
        for variant in study.variant_names:
            by = {
                c.policy: c
                for c in record.cells
                if (c.track, c.env, c.variant) == (track, env, variant)
            }
            if by:
                lines += _rows(cell_label(env, variant), by, orig)
                shown = True
        if orig and shown:  # the original's row once per env, under all its variants
            lines.append(
                f"| *original* | {_k(orig['ann_first'])} | {_k(orig['snn_first'])} | "
                f"{_k(orig['ann_300'])} | {_k(orig['snn_300'])} | "
                f"{orig['snn_pct_of_ann']:.1f} % | | | |"
            )
    return lines


def _figures(record: StudyRecord, track: str) -> list[str]:
    """The track's figures: their files, the record and commit they are drawn from (the
    table's), what they show and why a median band ends early; the first one shown."""
    stem, pngs = Path(track).stem, [n for n in plot_names(track) if n.endswith(".png")]
    files = ", ".join(f"`plots/{n}`" for n in pngs)
    return [
        f"Figures: {files} (SVG beside them), drawn from this record (commit "
        f"{record_commit(record)}), the runs of the table above: one panel per cell, the "
        f"ANN blue, the SNN red. {CAPTION}",
        "",
        f"![{stem}: {KEYS['finishes']}](plots/{pngs[0]})",
        "",
    ]


def deployed_lines(entries: list[DeployedRun]) -> list[str]:
    """The median-seed SNNs on lava-sim beside their reference evaluation."""
    if not entries:
        return []
    lines = [
        "Deployed: each env's median-seed SNN (by steps to the finishes mark) on lava-sim in "
        "fixed point, checked step by step against the numpy reference of the same "
        "arithmetic.",
        "",
        "| env | run | lava-sim fixed | bit-exact with the reference | reference |",
        "|---|---|---|---|---|",
    ]
    for d in entries:
        exact = f"{'yes' if d.bit_exact else '**no**'} ({d.env_steps:,} env steps)"
        env = f"{d.env} · {d.variant}" if d.variant else d.env
        lines.append(
            f"| {env} | {d.run} | {100 * d.success_rate:.0f} % "
            f"({d.episodes} episodes) | {exact} | "
            f"{100 * d.reference_success_rate:.0f} % ({d.reference_episodes} "
            "episodes) |"
        )
    return [*lines, ""]


def _rows(env: str, by: dict[str, CellSummary], orig: dict[str, float] | None) -> list[str]:
    def cell(policy: str, key: str, orig_key: str) -> str:
        c = by.get(policy)
        if c is None:
            return "-"
        s: Spread = getattr(c, key)
        mark = _vs(s.median, orig[orig_key]) if orig else ""
        return spread_steps(s) + mark

    snn = by.get(SNN)
    pct = snn.snn_pct_of_ann if snn else None
    pct_text = "-" if pct is None else f"{pct:.1f} %"
    if orig and pct is not None:
        pct_text += _vs(pct, orig["snn_pct_of_ann"], lower_is_better=False)
    row = [
        env,
        cell(ANN, "first_finish_step", "ann_first"),
        cell(SNN, "first_finish_step", "snn_first"),
        cell(ANN, "steps_to_finishes", "ann_300"),
        cell(SNN, "steps_to_finishes", "snn_300"),
        pct_text,
        spread_pct(by[ANN].eval_success_rate) if ANN in by else "-",
        spread_pct(by[SNN].eval_success_rate) if SNN in by else "-",
        spread_count(snn.eval_spikes_per_step if snn else None),
    ]
    lines = ["| " + " | ".join(row) + " |"]
    return lines
