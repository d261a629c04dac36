"""``snnkart study``: every cell for every seed on the local pool, evaluated (ANN in torch, SNN
on the numpy reference in fixed point), summarised against hand computations, reused when
nothing that determines a run changed and retrained when something did."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import matplotlib.image
import matplotlib.pyplot as plt
import pytest

from snnkart.app.study_eval import DEPLOY_DIR, median_seed
from snnkart.app.study_run import load_study, plan, steps_to
from snnkart.app.study_summary import pct_of_ann, spread, summarise
from snnkart.errors import UsageError
from snnkart.report.study_plots import _band
from snnkart.report.study_record import Curve, RunRecord, Spread, StudyRecord

ROOT = Path(__file__).resolve().parents[1]
TINY = ["ppo.num_envs=2", "ppo.rollout_steps=64", "ppo.update_epochs=1", "ppo.num_minibatches=2",
        "snn.num_steps=2"]  # fmt: skip
BATCH = 128


def _write_study(path: Path, cells: str = "", episodes: int = 2) -> Path:
    path.write_text(f"""
schema = "snnkart/study-config/v1"
data = "tuning"
name = "tiny"
envs = ["grid"]
policies = ["ann", "snn"]
seeds = [1, 2]
steps = {3 * BATCH}
finishes = 1
eval_episodes = {episodes}
deploy_episodes = 2
sets = {json.dumps(TINY)}
{cells}
""")
    return path


def _study(cfg: Path, out: Path, *args: str) -> dict:
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "study", str(cfg), "--out", str(out), "--jobs", "2",
         *args],
        cwd=ROOT, capture_output=True, text=True, timeout=400,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    assert "| env | ANN first finish" in result.stdout
    return json.loads((out / "study.json").read_text())


@pytest.mark.timeout(600)
def test_study_trains_evaluates_summarises_and_resumes(tmp_path: Path) -> None:
    out = tmp_path / "study"
    piece = _study(_write_study(tmp_path / "study.toml"), out, "--only", "*/grid-ann")
    assert [r["name"] for r in piece["runs"]] == ["small_S-grid-ann-s1", "small_S-grid-ann-s2"]
    assert "A piece of the study" in (out / "study.md").read_text()
    record = _study(_write_study(tmp_path / "study.toml"), out)  # gathers the piece's runs
    runs = record["runs"]
    assert [r["name"] for r in runs] == [
        "small_S-grid-ann-s1", "small_S-grid-ann-s2", "small_S-grid-snn-s1", "small_S-grid-snn-s2"]  # fmt: skip
    for r in runs:
        run_dir = out / "runs" / r["name"]
        rows = [json.loads(x) for x in (run_dir / "metrics.jsonl").read_text().splitlines()]
        assert r["steps"] == 3 * BATCH and [x["global_step"] for x in rows] == [128, 256, 384]
        reached = [x["global_step"] for x in rows if x["charts/cumulative_finishes"] >= 1]
        assert r["steps_to_finishes"] == (reached[0] if reached else None)
        if r["policy"] == "snn":  # the chip's arithmetic, not torch
            evaluation = json.loads((run_dir / "study-eval-nir-ref-fixed/deploy.json").read_text())
            assert evaluation["backend"] == "nir-ref" and evaluation["precision"] == "fixed"
        else:
            evaluation = json.loads((run_dir / "study-eval.json").read_text())
        assert evaluation["summary"]["episodes"] == 2
        assert r["eval_success_rate"] == evaluation["summary"]["success_rate"]
    (deployed,) = record["deployed"]  # the SNN cell's median seed on Lava, fixed point
    snns = [r for r in StudyRecord.read(out / "study.json").runs if r.policy == "snn"]
    assert deployed["run"] == median_seed(snns).name and deployed["episodes"] == 2
    result = json.loads((out / "runs" / deployed["run"] / DEPLOY_DIR / "deploy.json").read_text())
    assert (result["backend"], result["precision"]) == ("lava-sim", "fixed")
    assert result["parity"]["same_arithmetic_reference"] is not None
    assert deployed["bit_exact"] is True and deployed["env_steps"] > 0
    assert "| grid | small_S-grid-snn-s" in (out / "study.md").read_text()
    cells = {(c["env"], c["policy"]): c for c in record["cells"]}
    assert cells[("grid", "ann")]["env_steps"] == 2 * 3 * BATCH
    assert "snn_pct_of_ann" in cells[("grid", "snn")]
    text = (out / "study.md").read_text()
    assert "| grid |" in text and "*original*" not in text  # its numbers are for 300 finishes
    named = re.findall(r"`(plots/[^`]+)`", text)  # study.md names the figures written beside it
    assert named == ["plots/small_S-finishes.png", "plots/small_S-return.png"]
    assert all((out / name).is_file() for name in named)
    for key in ("finishes", "return"):
        image = matplotlib.image.imread(out / "plots" / f"small_S-{key}.png")
        assert image.shape[0] > 200 and image.std() > 0.01  # drawn, not blank
        assert (out / "plots" / f"small_S-{key}.svg").read_text().lstrip().startswith("<?xml")
    assert record["wall_clock"]["runs_reused"] == 2 and record["only"] is None
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                          capture_output=True).stdout.strip()  # fmt: skip
    machine = record["machine"]  # committed results say where they were made
    assert machine["commit"].removesuffix("-dirty") == (head or "unknown"), machine
    assert machine["cores"] == os.cpu_count() and f"Commit {machine['commit']}," in text

    # run again: everything is reused, nothing evaluated again
    stamp = (out / "runs/small_S-grid-ann-s1/study-eval.json").stat().st_mtime
    deploy_file = out / "runs" / deployed["run"] / DEPLOY_DIR / "deploy.json"
    deploy_stamp = deploy_file.stat().st_mtime
    again = _study(_write_study(tmp_path / "study.toml"), out)
    assert deploy_file.stat().st_mtime == deploy_stamp and again["deployed"] == [deployed]
    assert again["wall_clock"]["runs_reused"] == 4 and again["wall_clock"]["runs_set_aside"] == 0
    assert (out / "runs/small_S-grid-ann-s1/study-eval.json").stat().st_mtime == stamp
    assert [r["eval_success_rate"] for r in again["runs"]] == [r["eval_success_rate"] for r in runs]

    # a changed setting for one cell retrains that cell's runs only; the old ones are kept aside
    changed = _study(_write_study(tmp_path / "study.toml", 'cells = {"grid-snn" = ["snn.beta=0.8"]}'), out)  # fmt: skip
    assert (
        changed["wall_clock"]["runs_reused"] == 2 and changed["wall_clock"]["runs_set_aside"] == 2
    )
    assert len(list((out / "runs").glob("small_S-grid-snn-s1.stale-*"))) == 1
    cfg = (out / "runs/small_S-grid-snn-s1/config.toml").read_text()
    assert "beta = 0.8" in cfg

    # another evaluation setting evaluates every run again, the training reused (an evaluation
    # is keyed by its request, checkpoint and code, not by being newer than the checkpoint)
    more = _study(_write_study(tmp_path / "study.toml", 'cells = {"grid-snn" = ["snn.beta=0.8"]}',
                               episodes=3), out)  # fmt: skip
    assert more["wall_clock"]["runs_reused"] == 4
    for r in more["runs"]:
        run_dir = out / "runs" / r["name"]
        name = "study-eval-nir-ref-fixed/deploy.json" if r["policy"] == "snn" else "study-eval.json"
        assert json.loads((run_dir / name).read_text())["summary"]["episodes"] == 3, r["name"]


def test_spreads_and_the_snn_against_the_ann_by_hand() -> None:
    assert spread([100, None, 300]) == Spread(median=300.0, min=100, max=None, reached=2, of=3)
    assert spread([None, None, 300]).median is None  # the median run never got there
    assert spread([4, 1, 3, 2]).median == 2.5
    records = [
        _run(p, s, first=ff, steps_to=st, success=ev)
        for p, s, ff, st, ev in [("ann", 1, 10, 100, 1.0), ("ann", 2, 20, 200, 0.5),
                                 ("snn", 1, 30, 400, 0.9), ("snn", 2, None, None, 0.0)]
    ]  # fmt: skip
    cells = {c.policy: c for c in summarise(records, None)}
    assert cells["ann"].steps_to_finishes.median == 150.0
    assert cells["snn"].steps_to_finishes.median is None  # (400 + inf) / 2
    assert cells["snn"].snn_pct_of_ann is None
    assert cells["snn"].eval_success_rate.median == pytest.approx(0.45)
    ann = dataclasses.replace(cells["ann"], steps_to_finishes=spread([400_000, 420_000, 380_000]))
    snn = dataclasses.replace(cells["snn"], steps_to_finishes=spread([500_000, 400_000, None]))
    assert pct_of_ann(ann, snn) == pytest.approx(100 * 400_000 / 500_000)
    never = dataclasses.replace(snn, steps_to_finishes=spread([None, None, 1]))
    assert pct_of_ann(ann, never) is None
    assert steps_to(3, Curve([10, 20, 30], [0, 3, 5], [None] * 3)) == 20
    assert steps_to(9, Curve([10, 20, 30], [0, 3, 5], [None] * 3)) is None
    median = cells["ann"].train_seconds.median
    assert median is not None and not math.isnan(median)


def _run(policy: str = "snn", seed: int = 1, first: int | None = None,
         steps_to: int | None = None, success: float = 0.0, curve: Curve | None = None,
         stopped_early: bool = False) -> RunRecord:  # fmt: skip
    """A study's run record with what a test sets, the rest plain."""
    return RunRecord(
        name=f"s{seed}", track="t", env="grid", policy=policy, seed=seed, status="done",
        steps=10, stopped_early=stopped_early, first_finish_step=first,
        steps_to_finishes=steps_to, training_finishes=0, training_episodes=0,
        train_seconds=1.0, eval_success_rate=success, eval_mean_return=0.0, eval_crashes=0,
        curve=curve or Curve([], [], []),
    )  # fmt: skip


def test_the_median_seed_by_hand() -> None:
    def run(seed: int, steps: int | None) -> RunRecord:
        return _run(seed=seed, steps_to=steps)

    cell = [run(1, 300), run(2, None), run(3, 100), run(4, 200), run(5, None)]
    assert median_seed(cell).seed == 1  # 100, 200, [300], never, never
    assert median_seed(cell[:4]).seed == 4  # 100, [200], 300, never
    assert median_seed([run(2, 100), run(1, 100)]).seed == 1


def test_bad_study_configs_name_the_problem(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('schema = "snnkart/study-config/v1"\ndata = "tuning"\nseeds = []\n')
    with pytest.raises(UsageError, match=r"bad.toml: seeds"):
        load_study(bad)
    bad.write_text('schema = "snnkart/study-config/v1"\ndata = "tuning"\nepisodes = 3\n')
    with pytest.raises(UsageError, match=r"bad.toml: episodes: Extra inputs"):
        load_study(bad)
    bad.write_text(
        'schema = "snnkart/study-config/v1"\ndata = "tuning"\ncells = {"grid-lstm" = []}\n'
    )
    with pytest.raises(UsageError, match=r"'grid-lstm' is not a cell"):
        plan(load_study(bad))
    with pytest.raises(UsageError, match=r"--only ring/\* matches no cell .*small_S/steer-snn"):
        plan(load_study(ROOT / "studies" / "small_S.toml"), ["ring/*"])
    bad.write_text(
        'schema = "snnkart/study-config/v1"\ndata = "tuning"\nsets = ["stop.finishes=10"]\n'
    )
    with pytest.raises(UsageError, match=r"stop\.finishes=10 would stop runs before the study's"):
        plan(load_study(bad))
    with pytest.raises(UsageError, match="cannot read the study config"):
        load_study(tmp_path / "missing.toml")
    bad.write_text('schema = "snnkart/study-config/v1"\ndata = "tuning"\nenvs = ["CartPole-v1"]\n')
    with pytest.raises(UsageError, match=r"'CartPole-v1' is not a kart env.*a zoo study config"):
        load_study(bad)


def test_only_takes_a_cell_with_all_its_variants_or_one_variant() -> None:
    ablation = load_study(ROOT / "studies" / "ablation.toml")
    assert len(plan(ablation, ["small_S/steer-snn"])) == len(plan(ablation)) == 30
    t = plan(ablation, ["*:T*"])
    assert [r.spec.name for r in t][:2] == [
        "small_S-steer-snn-T4-s101",
        "small_S-steer-snn-T4-s102",
    ]
    assert {r.variant for r in t} == {"T4", "T16"}


@pytest.mark.parametrize("path", sorted((ROOT / "studies").glob("*.toml")), ids=lambda p: p.stem)
def test_the_committed_studies_plan(path: Path) -> None:
    runs = plan(load_study(path))
    assert runs and len({r.spec.name for r in runs}) == len(runs)
    for run in runs:
        assert (ROOT / run.track).is_file() or run.track in ("small_S", "big_S", "random")


def test_the_median_is_drawn_while_every_seed_trains_and_each_seed_to_its_end() -> None:
    runs = [
        _run(curve=Curve([1, 2, 3, 4], [0, 10, 20, 30], [None] * 4), stopped_early=False),
        _run(curve=Curve([1, 2], [2, 12], [None] * 2), stopped_early=True),
    ]
    fig, ax = plt.subplots()
    _band(ax, runs, "finishes", "blue", "ANN")
    median, seed_a, seed_b, stop = ax.get_lines()
    assert list(median.get_xdata()) == [1, 2] and list(median.get_ydata()) == [1, 11]
    assert list(seed_a.get_xdata()) == [1, 2, 3, 4] and list(seed_a.get_ydata()) == [0, 10, 20, 30]
    assert list(seed_b.get_ydata()) == [2, 12]
    assert list(stop.get_xdata()) == [2] and list(stop.get_ydata()) == [12]  # where it stopped
    plt.close(fig)


def test_the_median_band_is_the_median_of_three_seeds_not_their_mean() -> None:
    """Three seeds whose mean and median differ at every step: the thick line is the median,
    the band spans the lowest and the highest seed."""
    runs = [
        _run(seed=s, curve=Curve([1, 2, 3], finishes, [None] * 3))
        for s, finishes in ((1, [0, 1, 2]), (2, [1, 2, 4]), (3, [8, 12, 30]))
    ]
    fig, ax = plt.subplots()
    _band(ax, runs, "finishes", "blue", "ANN")
    median = ax.get_lines()[0]
    assert list(median.get_ydata()) == [1, 2, 4]  # the means would be 3, 5, 12
    assert median.get_label() == "ANN (median of 3)"
    (band,) = ax.collections
    (outline,) = band.get_paths()
    ys = sorted({float(y) for y in outline.vertices[:, 1]})
    assert ys == [0, 1, 2, 8, 12, 30]  # min and max per step, nothing else
    plt.close(fig)


@pytest.mark.timeout(600)
def test_an_ablation_trains_every_variant_and_reports_its_spikes(tmp_path: Path) -> None:
    cfg = _write_study(tmp_path / "ablation.toml",
                       'variants = { "T2" = [], "T4" = ["snn.num_steps=4"], '
                       '"cuba" = ["snn.neuron=cuba"] }')  # fmt: skip
    text = cfg.read_text().replace('policies = ["ann", "snn"]', 'policies = ["snn"]')
    cfg.write_text(text.replace("seeds = [1, 2]", "seeds = [1]").replace(
        "deploy_episodes = 2", "deploy_episodes = 0"))  # fmt: skip
    out = tmp_path / "ablation"
    record = _study(cfg, out)
    assert [r["name"] for r in record["runs"]] == [
        "small_S-grid-snn-T2-s1",
        "small_S-grid-snn-T4-s1",
        "small_S-grid-snn-cuba-s1",
    ]
    cuba = record["runs"][2]  # exported as CubaLIF, evaluated on the reference like the others
    assert cuba["eval_backend"] == "nir-ref fixed" and cuba["eval_spikes_per_step"] > 0
    assert "num_steps = 4" in (out / "runs/small_S-grid-snn-T4-s1/config.toml").read_text()
    spikes = {c["variant"]: c["eval_spikes_per_step"]["median"] for c in record["cells"]}
    for r in record["runs"]:  # spikes per inference, from the reference's counts
        counts = json.loads((out / "runs" / r["name"] / "study-eval-nir-ref-fixed/deploy.json")
                            .read_text())["counts"]  # fmt: skip
        assert spikes[r["variant"]] == sum(counts["spikes"]) / counts["env_steps"]
    text = (out / "study.md").read_text()
    assert "| grid · T2 |" in text and "| grid · cuba |" in text and record["deployed"] == []
    assert "evaluated in torch" not in text
    bad = tmp_path / "bad.toml"
    bad.write_text('schema = "snnkart/study-config/v1"\ndata = "tuning"\nvariants = {"T 4" = []}\n')
    with pytest.raises(UsageError, match="variant name 'T 4'"):
        load_study(bad)


@pytest.mark.timeout(120)
def test_a_failed_evaluation_stops_the_commands_still_running(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One of a study's commands fails while another still runs: the failure is reported and
    the running one is stopped (SIGTERM; a training run saves on its way out), not left
    behind."""
    from snnkart.app import pool, study_eval
    from snnkart.app.reporter import Silent
    from snnkart.app.worker import EvalJob, TrainJob
    from snnkart.rl.config import load_config

    started: list[subprocess.Popen[bytes]] = []
    real_popen = subprocess.Popen

    def recording_popen(*args: object, **kwargs: object) -> subprocess.Popen[bytes]:
        proc: subprocess.Popen[bytes] = real_popen(*args, **kwargs)  # type: ignore[call-overload]
        started.append(proc)
        return proc

    monkeypatch.setattr(pool.subprocess, "Popen", recording_popen)
    monkeypatch.setattr(pool, "STOP_GRACE_S", 30.0)
    config = tmp_path / "long.toml"
    config.write_text(load_config(overrides={"env": "grid", "policy": "ann",
                                             "total_steps": 100_000_000}).to_toml())  # fmt: skip
    long = TrainJob(str(config), str(tmp_path / "long"))
    bad = EvalJob(str(tmp_path / "no-such-run"), 2, 0, str(tmp_path / "bad.json"))
    try:
        with pytest.raises(UsageError, match="no-such-run"):
            study_eval._run_all([("long", long), ("bad", bad)], 2, Silent(), "evals")
        assert len(started) == 2
        assert all(proc.poll() is not None for proc in started), "a command outlived the study"
        assert started[0].returncode in (143, -15)
    finally:  # whatever failed, nothing is left running (the commands have their own sessions)
        for proc in started:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def test_a_policy_prefixed_variant_runs_only_in_that_policys_cells(tmp_path: Path) -> None:
    """'snn:t4' adds T = 4 runs to the SNN cells only; the ANN cell, with no variant of its own,
    runs once as it is; an unprefixed variant runs in every cell."""
    path = tmp_path / "s.toml"
    path.write_text(
        'schema = "snnkart/study-config/v1"\ndata = "tuning"\nenvs = ["grid"]\n'
        'policies = ["ann", "snn"]\nseeds = [1]\n[variants]\n"snn:t4" = ["snn.num_steps=4"]\n'
        '"snn:t2" = ["snn.num_steps=2"]\n'
    )
    names = [r.spec.name for r in plan(load_study(path))]
    assert names == ["small_S-grid-ann-s1", "small_S-grid-snn-t4-s1", "small_S-grid-snn-t2-s1"]
    t4 = next(r for r in plan(load_study(path)) if r.variant == "t4")
    assert t4.spec.config.snn.num_steps == 4
    path.write_text(path.read_text() + 'both = ["seed=1"]\n')
    names = [r.spec.name for r in plan(load_study(path))]
    assert names[:2] == ["small_S-grid-ann-both-s1", "small_S-grid-snn-t4-s1"]
