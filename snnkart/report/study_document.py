"""A study's document and figures: ``study.md`` beside the original's table, and the plots of
cumulative finishes and returns against training steps (median line, min-max band per policy
kind; PNG and SVG)."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.report.held_out import held_out_lines
from snnkart.report.plots import _figure
from snnkart.report.study_record import (
    CellSummary,
    DeployedRun,
    RunRecord,
    Spread,
    StudyRecord,
    StudySettings,
)

COLOURS = {"ann": "#1f77b4", "snn": "#d62728"}


def _k(steps: float | None) -> str:
    return ">cap" if steps is None else f"{steps / 1000:.0f}k"


def _steps(s: Spread) -> str:
    if s.of == 1 or s.reached == 0:
        text = _k(s.median)
    else:
        text = f"{_k(s.median)} ({_k(s.min)}–{_k(s.max)})"
    return text if s.reached == s.of else f"{text}, {s.reached}/{s.of} seeds"


def _pct(s: Spread) -> str:
    def p(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.0f} %"

    return f"{p(s.median)} ({p(s.min)}–{p(s.max)})" if s.of > 1 else p(s.median)


def _count(s: Spread | None) -> str:
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
    lines = [f"# Study: {study.name}", "",
             f"{len(study.seeds)} seeds per cell, at most {study.steps:,} env steps per run. "
             "Medians over seeds with (min–max); `>cap`: not reached within the cap; "
             "\"k/n seeds\": only k of the n seeds got there. "
             f"\"{n} finishes\": the step at which the run's cumulative laps (finished training "
             f"episodes that started at the spawn) reached {n}. Evaluation: "
             f"{study.eval_episodes} seeded episodes, ANNs in torch, SNNs exported to NIR on "
             "the numpy reference in fixed point. ✓/✗: better/worse than the original (one run "
             "per cell; shown for small_S at 300 finishes). Data: "
             f"{study.data or 'not declared'} (the results protocol, docs/results.md).",
             ""]  # fmt: skip
    if any(r.eval_backend.startswith("torch (cuba") for r in record.runs):
        lines += ["Current-based LIF (cuba) SNNs with biases between their spiking layers are "
                  "evaluated in torch: Lava's LIF cannot run those biases.", ""]  # fmt: skip
    if record.only:
        lines += [f"A piece of the study: the cells matching `{' '.join(record.only)}`.", ""]
    for track in record.tracks():
        lines += [f"## {Path(track).stem}", "", *track_table(record, track, original), ""]
        lines += _deployed([d for d in record.deployed if d.track == track])
    lines += held_out_lines(record)
    w = record.wall_clock
    lines += [f"Training {w.train_seconds / 60:.1f} min and evaluation "
              f"{w.eval_seconds / 60:.1f} min of wall-clock for {w.runs} runs "
              f"({w.runs_reused} reused); {record.env_steps:,} env steps in all. "
              f"Env revision {record.env_revision}, training code {record.code}.", ""]  # fmt: skip
    if record.machine is not None:  # records before it have no machine
        m = record.machine
        lines += [f"Commit {m['commit']}, {m['cores']} cores of {m['cpu']}, {m['date']}.", ""]
    return "\n".join(lines)


def track_table(record: StudyRecord, track: str,
                original: dict[str, dict[str, float]]) -> list[str]:  # fmt: skip
    """A track's table: per env (and variant) the ANN and SNN cells, beside the original's
    numbers where they compare (small_S at 300 finishes)."""
    study, n = record.study, record.study.finishes
    lines = [f"| env | ANN first finish | SNN first finish | ANN {n} finishes | "
             f"SNN {n} finishes | SNN % of ANN | ANN eval | SNN eval | SNN spikes/step |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for env in study.envs:
        # the original's numbers: its track and its mark of 300 finishes only
        comparable = Path(track).stem == "small_S" and n == 300
        orig = original.get(env) if comparable else None
        shown = False
        for variant in study.variant_names:
            by = {c.policy: c for c in record.cells
                  if (c.track, c.env, c.variant) == (track, env, variant)}  # fmt: skip
            if by:
                label = f"{env} · {variant}" if variant else env
                lines += _rows(label, by, orig)
                shown = True
        if orig and shown:  # the original's row once per env, under all its variants
            lines.append(f"| *original* | {_k(orig['ann_first'])} | {_k(orig['snn_first'])} | "
                         f"{_k(orig['ann_300'])} | {_k(orig['snn_300'])} | "
                         f"{orig['snn_pct_of_ann']:.1f} % | | | |")  # fmt: skip
    return lines


def _deployed(entries: list[DeployedRun]) -> list[str]:
    """The median-seed SNNs on lava-sim beside their reference evaluation."""
    if not entries:
        return []
    lines = ["Deployed: each env's median-seed SNN (by steps to the finishes mark) on lava-sim in "
             "fixed point, checked step by step against the numpy reference of the same "
             "arithmetic.", "",
             "| env | run | lava-sim fixed | bit-exact with the reference | reference |",
             "|---|---|---|---|---|"]  # fmt: skip
    for d in entries:
        exact = f"{'yes' if d.bit_exact else '**no**'} ({d.env_steps:,} env steps)"
        env = f"{d.env} · {d.variant}" if d.variant else d.env
        lines.append(f"| {env} | {d.run} | {100 * d.success_rate:.0f} % "
                     f"({d.episodes} episodes) | {exact} | "
                     f"{100 * d.reference_success_rate:.0f} % ({d.reference_episodes} "
                     "episodes) |")  # fmt: skip
    return [*lines, ""]


def _rows(env: str, by: dict[str, CellSummary], orig: dict[str, float] | None) -> list[str]:
    def cell(policy: str, key: str, orig_key: str) -> str:
        c = by.get(policy)
        if c is None:
            return "-"
        s: Spread = getattr(c, key)
        mark = _vs(s.median, orig[orig_key]) if orig else ""
        return _steps(s) + mark

    snn = by.get("snn")
    pct = snn.snn_pct_of_ann if snn else None
    pct_text = "-" if pct is None else f"{pct:.1f} %"
    if orig and pct is not None:
        pct_text += _vs(pct, orig["snn_pct_of_ann"], lower_is_better=False)
    row = [env, cell("ann", "first_finish_step", "ann_first"),
           cell("snn", "first_finish_step", "snn_first"),
           cell("ann", "steps_to_finishes", "ann_300"), cell("snn", "steps_to_finishes", "snn_300"),
           pct_text, _pct(by["ann"].eval_success_rate) if "ann" in by else "-",
           _pct(by["snn"].eval_success_rate) if "snn" in by else "-",
           _count(snn.eval_spikes_per_step if snn else None)]  # fmt: skip
    lines = ["| " + " | ".join(row) + " |"]
    return lines


def _band(ax: Any, runs: list[RunRecord], key: str, colour: str, label: str) -> None:
    """Every seed as a thin line, and the median and min-max band over seeds while every seed
    is still training. A run stopped early (the study's ``stop`` rule: it had learned) ends in
    a dot; after the first such stop the median of the seeds left would be a median of the
    slow ones (a cumulative count would seem to fall), so it is not drawn."""
    field = "returns" if key == "return" else key  # the curve's JSON key is "return"
    curves = [(np.asarray(r.curve.steps, dtype=float),
               np.asarray([np.nan if v is None else v for v in getattr(r.curve, field)],
                          dtype=float))
              for r in runs]  # fmt: skip
    full = min(len(x) for x, _ in curves)
    steps = curves[0][0][:full]
    ys = np.stack([y[:full] for _, y in curves])
    with warnings.catch_warnings():  # iterations in which no seed ended an episode: a gap
        warnings.simplefilter("ignore", RuntimeWarning)
        median, low, high = (np.nanmedian(ys, axis=0), np.nanmin(ys, axis=0),
                             np.nanmax(ys, axis=0))  # fmt: skip
    ax.plot(steps, median, color=colour, lw=2, label=f"{label} (median of {len(runs)})")
    ax.fill_between(steps, low, high, color=colour, alpha=0.15)
    for r, (x, y) in zip(runs, curves, strict=True):
        ax.plot(x, y, color=colour, lw=0.6, alpha=0.45)
        if r.stopped_early:
            ax.plot(x[-1:], y[-1:], "o", color=colour, ms=3.5)
    ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:.0f}k")


def _groups(study: StudySettings) -> list[tuple[str, str]]:
    """(policy, variant) of every band in a panel; an ablation colours them by variant."""
    return [(p, v) for p in study.policies for v in study.variant_names]


def write_plots(record: StudyRecord, out: Path) -> list[Path]:
    """Per track: cumulative finishes and mean episodic return against steps, one panel per
    env; PNG and SVG. Returns the files written."""
    import matplotlib.pyplot as plt

    study, runs, written = record.study, record.runs, []
    for track in record.tracks():
        for key, ylabel in (("finishes", "cumulative laps finished"),
                            ("return", "mean episodic return")):  # fmt: skip
            envs = [e for e in study.envs if any(r.cell[:2] == (track, e) for r in runs)]
            fig, axes = _figure(4.2 * len(envs), 3.4, ncols=len(envs))
            for ax, env in zip(axes[0], envs, strict=True):
                for k, (policy, variant) in enumerate(_groups(study)):
                    cell = (track, env, policy, variant)
                    rs = [r for r in runs if r.cell == cell]
                    if rs:
                        colour = COLOURS[policy] if not variant else f"C{k % 10}"
                        _band(ax, rs, key, colour, f"{policy.upper()} {variant}".strip())
                if key == "finishes":
                    ax.axhline(study.finishes, color="grey", lw=0.8, ls=":")
                    ax.plot([], [], "o", color="grey", ms=3.5, label="stopped: learned")
                ax.set_title(f"{env} / {Path(track).stem}")
                ax.set_xlabel("training env steps")
                ax.set_ylabel(ylabel)
                ax.legend(loc="upper left", fontsize=8)
            fig.tight_layout()
            for suffix in ("png", "svg"):
                path = out / f"{Path(track).stem}-{key}.{suffix}"
                fig.savefig(path, format=suffix)
                written.append(path)
            plt.close(fig)
    return written
