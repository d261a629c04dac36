"""A study's figures (:mod:`snnkart.report.study_plots`): one panel per cell of the table, each
drawn, the legend and the caption outside every panel, the runs of each panel the runs of the
table's row; ``study.md`` names the files written and the record's commit."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from snnkart.app.study_summary import ORIGINAL
from snnkart.report.study_document import markdown, track_table
from snnkart.report.study_plots import CAPTION, figure, write_plots
from snnkart.report.study_record import Curve, StudyRecord

DATA = Path(__file__).parent / "data" / "records"
ENVS, VARIANTS = ("grid", "steer"), ("base", "T4")


@pytest.fixture(scope="module")
def ablation() -> StudyRecord:
    """The recorded tiny study made an ablation of 2 envs x 2 variants (4 cells, 2 policies,
    2 seeds each): finishes that grow with the seed (the SNN's faster), and one run per policy that stopped
    early (its curve shorter)."""
    base = StudyRecord.read(DATA / "study.json")
    steps = [128 * k for k in range(1, 7)]
    runs, cells = [], []
    for env in ENVS:
        for variant in VARIANTS:
            for r in base.runs:
                stop = r.seed == 2  # the faster seed stopped after 4 iterations
                n = 4 if stop else 6
                slope = 10 * r.seed + (5 if r.policy == "snn" else 0)
                curve = Curve(steps[:n], [slope * k for k in range(n)],
                              [float(r.seed + k) for k in range(n)])  # fmt: skip
                runs.append(dataclasses.replace(
                    r, env=env, variant=variant, name=f"small_S-{env}-{r.policy}-{variant}-s{r.seed}",
                    curve=curve, stopped_early=stop))  # fmt: skip
            cells += [dataclasses.replace(c, env=env, variant=variant) for c in base.cells]
    study = dataclasses.replace(base.study, envs=list(ENVS), variants={v: [] for v in VARIANTS})
    return dataclasses.replace(base, study=study, runs=runs, cells=cells, deployed=[])


def _table_rows(record: StudyRecord) -> list[str]:
    """The first column of the track's table: its cells' labels."""
    lines = track_table(record, "small_S", ORIGINAL)[2:]
    return [line.split(" | ")[0].removeprefix("| ") for line in lines]


@pytest.mark.parametrize("key", ["finishes", "return"])
def test_one_drawn_panel_per_cell_of_the_table(ablation: StudyRecord, key: str) -> None:
    """As many panels as the table has rows, in its order, each showing its curves (the
    coloured pixels inside a panel vary, a blank one's would not)."""
    fig = figure(ablation, "small_S", key)
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == _table_rows(ablation) == ["grid · base", "grid · T4", "steer · base",
                                               "steer · T4"]  # fmt: skip
    fig.canvas.draw()
    pixels = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float) / 255
    height = pixels.shape[0]
    for ax in fig.axes:
        box = ax.get_window_extent()
        inside = pixels[round(height - box.y1) + 3 : round(height - box.y0) - 3,
                        round(box.x0) + 3 : round(box.x1) - 3]  # fmt: skip
        colour = inside.max(axis=-1) - inside.min(axis=-1)  # grey frame and grid: 0
        assert colour.std() > 0.02, f"panel {ax.get_title()} is blank"
    plt.close(fig)


def test_the_legend_title_and_caption_cover_no_panel(ablation: StudyRecord) -> None:
    """The one legend, the title and the caption (why a median band ends) sit outside every
    panel, its title and tick labels included."""
    fig = figure(ablation, "small_S", "finishes")
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    outside = [legend, *fig.texts]
    assert any(CAPTION.split()[-6:] == t.get_text().split()[-6:] for t in fig.texts)
    for ax in fig.axes:
        assert ax.get_legend() is None
        panel = ax.get_tightbbox(renderer)
        for artist in outside:
            box = artist.get_window_extent(renderer)
            assert not box.overlaps(panel), f"{artist} covers the panel {ax.get_title()}"
    plt.close(fig)


def test_each_panel_shows_the_runs_of_its_table_row(ablation: StudyRecord) -> None:
    """A panel's seed lines are the runs of its cell, ANN and SNN, for the seeds its table
    row summarises; the SVG written names every run of the record once."""
    fig = figure(ablation, "small_S", "finishes")
    for ax, (env, variant) in zip(fig.axes, [(e, v) for e in ENVS for v in VARIANTS],
                                  strict=True):  # fmt: skip
        seeds = {c.policy: c.seeds for c in ablation.cells if (c.env, c.variant) == (env, variant)}
        drawn = {line.get_gid() for line in ax.get_lines()} - {None}
        assert drawn == {r.name for r in ablation.runs
                         if (r.env, r.variant) == (env, variant) and r.seed in seeds[r.policy]}  # fmt: skip
        assert len(drawn) == sum(len(s) for s in seeds.values()) == 4
    plt.close(fig)


def test_study_md_names_the_files_written_and_the_records_commit(
    ablation: StudyRecord, tmp_path: Path
) -> None:
    written = write_plots(ablation, tmp_path)
    svg = (tmp_path / "small_S-finishes.svg").read_text()
    ids = re.findall(r'id="(small_S-[a-z]+-[a-z]+-[A-Za-z0-9]+-s\d+)"', svg)
    assert sorted(ids) == sorted(r.name for r in ablation.runs)
    text = markdown(ablation, ORIGINAL)
    pngs = [p.name for p in written if p.suffix == ".png"]
    named = re.findall(r"`plots/([^`]+)`", text)
    assert named == pngs == ["small_S-finishes.png", "small_S-return.png"]
    assert f"(commit {ablation.machine['commit']})" in text and CAPTION in text  # type: ignore[index]
    assert "![small_S: cumulative laps finished](plots/small_S-finishes.png)" in text
