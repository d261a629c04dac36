"""``snnkart study``: the SNN-vs-ANN study the original is known for, seeds and all.

A study config (TOML, :class:`StudyConfig`) names tracks, envs, policy kinds, seeds, a step cap
and ``--set`` overrides for every run and per cell. Every run trains on the launcher (the local
pool by default, Ray Tune with ``ray=True``), one torch thread each, and is then evaluated on
seeded episodes: ANNs in torch, SNNs exported to NIR and run on the numpy reference in fixed
point (what the chip computes). :func:`run_study` gathers ``study.json``; the report layer
writes ``study.md`` and the plots.

Resumable: a run directory carries the key of what made it (:func:`study_key`: its resolved
config, the env revision, the track's geometry and the training code), so a finished run is
reused when nothing that determines it changed, also across unrelated commits; a run whose
key differs is set aside (renamed) and trained again.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import hashlib
import itertools
import json
import os
import sys
import time
from pathlib import Path

from pydantic import ValidationError

from snnkart.app.launch import LocalPool, RunResult, RunSpec
from snnkart.app.protocol import data_problem
from snnkart.app.provenance import code_digest, machine_info
from snnkart.app.reporter import Reporter
from snnkart.app.study_eval import (
    Evaluation,
    deploy_median_seeds,
    eval_backend,
    evaluate,
    evaluate_held_out,
)
from snnkart.app.study_types import (
    STUDY_SCHEMA,
    Run,
    StudyConfig,
    held_out_tracks,
)
from snnkart.envs.spec import ENV_REVISION
from snnkart.envs.tracks import load_track, short_name
from snnkart.errors import TrackError, UsageError
from snnkart.io import write_text
from snnkart.report.study_record import (
    STUDY,
    Curve,
    HeldOut,
    RunRecord,
    StudyRecord,
    StudySettings,
    WallClock,
    study_run_sets,
)
from snnkart.rl import kinds
from snnkart.rl.config import TrainConfig, load_config

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

RECORD_SCHEMA = STUDY.tag
KEY_FILE = "study_key.txt"


def load_study(path: Path) -> StudyConfig:
    """The study config in ``path``; errors name the file and the field."""
    try:
        data = tomllib.loads(Path(path).read_text())
    except OSError as exc:
        raise UsageError(f"cannot read the study config {path}: {exc.strerror or exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: not valid TOML: {exc}") from exc
    if "data" not in data:
        raise UsageError(
            f'{path}: no data key: add data = "tuning" (seeds 1-100; small_S, big_S, ring, '
            'hairpins) or data = "reporting" (seeds 101 and up; zigzag, bends), see docs/results.md'
        )
    try:
        study = StudyConfig.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(top level)"
        raise UsageError(f"{path}: {where}: {first['msg']}") from exc
    if study.schema_ != STUDY_SCHEMA:
        raise UsageError(f"{path}: schema {study.schema_!r}; this snnkart reads {STUDY_SCHEMA!r}")
    held_out = [track for _, track in held_out_tracks(study.eval_tracks)]
    for track in held_out:
        try:
            load_track(track)
        except TrackError as exc:
            raise UsageError(f"{path}: eval_tracks: {exc}") from exc
    problem = data_problem(study.data, study.seeds, [*study.tracks, *held_out])
    if problem:
        raise UsageError(f'{path}: data = "{study.data}", but {problem}')
    return study


TRAINED_AS = {c.name: c.trained_as for c in kinds.CONVERSIONS.values()}
"""Study policy kinds trained as another kind: ``ann-sd`` is a ReLU ANN run, converted to a
sigma-delta network (``snnkart export --nir RUN --sigma-delta``) when it is evaluated."""
KIND_SETS = {c.name: list(c.sets) for c in kinds.CONVERSIONS.values()}
"""Settings a study policy kind implies (before the study's own)."""


def plan(study: StudyConfig, only: list[str] | None = None) -> list[Run]:
    """Every run of the study, in a fixed order (cell by cell, seeds inside); with ``only``,
    the runs of the cells whose ``track/env-policy`` matches one of these glob patterns."""
    known = {f"{e}-{p}" for e in study.envs for p in study.policies}
    known |= {f"{short_name(t)}/{c}" for t in study.tracks for c in list(known)}
    for cell in study.cells:
        if cell not in known:
            raise UsageError(
                f"cells: {cell!r} is not a cell of this study ({', '.join(sorted(known))})"
            )
    variants = list(study.variants.items()) or [("", [])]
    runs = []
    for track, env, policy in itertools.product(study.tracks, study.envs, study.policies):
        for (variant, _), seed in itertools.product(_of(variants, policy), study.seeds):
            own = study_run_sets(
                study.sets, study.cells, study.variants, (track, env, policy, variant)
            )
            config = load_config(
                overrides={
                    "env": env,
                    "policy": TRAINED_AS.get(policy, policy),
                    "track": track,
                    "seed": seed,
                    "total_steps": study.steps,
                },
                sets=["run.tensorboard=false", *KIND_SETS.get(policy, []), *own],
            )
            name = "-".join(
                [short_name(track), env, policy, *([variant] if variant else []), f"s{seed}"]
            )
            problem = data_problem(study.data, [config.seed], [config.track])
            if problem:  # a setting may change a run's seed or track
                raise UsageError(f'{name}: the study\'s data is "{study.data}", but {problem}')
            if config.stop.finishes is not None and config.stop.finishes < study.finishes:
                raise UsageError(
                    f"{name}: stop.finishes={config.stop.finishes} would stop runs before the "
                    f"study's mark of {study.finishes} finishes; set it to at least that"
                )
            runs.append(Run(track, env, policy, seed, RunSpec(name, config), variant))
    return runs if only is None else _only(runs, only)


def _of(variants: list[tuple[str, list[str]]], policy: str) -> list[tuple[str, list[str]]]:
    """The variants a policy kind's cells run: those not restricted to another kind
    ('POLICY:NAME'), named without the prefix; none at all = the cell once, as it is."""
    mine = [
        (name.rpartition(":")[2], sets)
        for name, sets in variants
        if name.rpartition(":")[0] in ("", policy)
    ]
    return mine or [("", [])]


def _only(runs: list[Run], patterns: list[str]) -> list[Run]:
    def matches(r: Run, pattern: str) -> bool:  # a cell's pattern takes all its variants
        return any(fnmatch.fnmatchcase(label, pattern) for label in (r.label, r.cell_label))

    kept = [r for r in runs if any(matches(r, p) for p in patterns)]
    if not kept:
        cells = ", ".join(dict.fromkeys(r.label for r in runs))
        raise UsageError(f"--only {' '.join(patterns)} matches no cell of this study ({cells})")
    return kept


def study_key(config: TrainConfig, code: str) -> str:
    """What determines a run: its resolved config, the env revision, the track's geometry
    and the training code (not the commit)."""
    parts = {
        "config": config.model_dump(mode="json", by_alias=True),
        "env_revision": ENV_REVISION,
        "track": load_track(config.track).to_toml(),
        "code": code,
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:20]


def _set_aside_stale(runs_dir: Path, runs: list[Run]) -> int:
    """Rename run directories made by other configs or code; mark the rest. Returns how many
    were set aside."""
    code = code_digest()
    stale = 0
    for run in runs:
        run_dir = runs_dir / run.spec.name
        key = study_key(run.spec.config, code)
        marker = run_dir / KEY_FILE
        if run_dir.exists() and (not marker.is_file() or marker.read_text().strip() != key):
            old = marker.read_text().strip()[:8] if marker.is_file() else "unkeyed"
            run_dir.rename(run_dir.with_name(f"{run_dir.name}.stale-{old}-{int(time.time())}"))
            stale += 1
        run_dir.mkdir(parents=True, exist_ok=True)
        marker.write_text(key + "\n")
    return stale


def curve(run_dir: Path) -> Curve:
    """Per iteration: env steps, cumulative training finishes, mean episodic return."""
    rows = [
        json.loads(line)
        for line in (run_dir / "metrics.jsonl").read_text().splitlines()
        if line.strip()
    ]
    return Curve(
        steps=[r["global_step"] for r in rows],
        finishes=[r["charts/cumulative_finishes"] for r in rows],
        returns=[r["charts/episodic_return"] for r in rows],
        seconds=[
            (r["global_step"] - p) / r["charts/SPS"]
            for r, p in zip(rows, [0] + [r["global_step"] for r in rows[:-1]], strict=True)
        ],
    )


def steps_to(finishes: int, c: Curve) -> int | None:
    """The env step (iteration resolution) at which cumulative finishes first reach
    ``finishes``; None if they never did."""
    return next((s for s, f in zip(c.steps, c.finishes, strict=True) if f >= finishes), None)


def run_record(
    run: Run,
    result: RunResult,
    runs_dir: Path,
    study: StudyConfig,
    evaluation: Evaluation,
    held_out: list[HeldOut] | None,
) -> RunRecord:
    c = curve(runs_dir / run.spec.name)
    return RunRecord(
        name=run.spec.name,
        track=run.track,
        env=run.env,
        policy=run.policy,
        variant=run.variant,
        seed=run.seed,
        status=result.status,
        steps=result.global_step,
        stopped_early=result.stopped_early,
        first_finish_step=result.first_finish_step,
        steps_to_finishes=steps_to(study.finishes, c),
        training_finishes=result.finishes,
        training_episodes=result.episodes,
        train_seconds=sum(c.seconds),
        eval_backend=eval_backend(run),
        eval_success_rate=evaluation.summary.laps,
        eval_mean_return=evaluation.summary.mean_return,
        eval_crashes=evaluation.summary.crash_count,
        eval_mean_lap_time=evaluation.summary.mean_lap_time,
        eval_stood_still=evaluation.summary.stood_still,
        eval_spikes_per_step=evaluation.spikes_per_step,
        eval_counts_per_step=evaluation.counts_per_step,
        sigma_delta_counts=evaluation.sigma_delta_counts,
        held_out=held_out,
        curve=c,
    )


def _train(
    runs: list[Run], runs_dir: Path, reporter: Reporter, jobs: int | None, ray: bool
) -> list[RunResult]:
    """Train the runs on Ray Tune (``ray``) or the local pool; a UsageError if one failed."""
    specs = [r.spec for r in runs]
    if ray:
        from snnkart.app.launch_ray import run_on_ray

        results = run_on_ray(specs, runs_dir, cpus=jobs)
    else:
        results = LocalPool(runs_dir, jobs=jobs).run(specs, reporter)
    failed = [r for r in results if r.status not in ("done", "reused")]
    if failed:
        raise UsageError(
            f"{len(failed)} runs did not finish, e.g. {failed[0].name}: "
            f"{failed[0].status} ({failed[0].error})"
        )
    return results


def run_study(
    study: StudyConfig,
    out: Path,
    reporter: Reporter,
    jobs: int | None = None,
    ray: bool = False,
    only: list[str] | None = None,
) -> StudyRecord:
    """Train, evaluate and summarise the study into ``out`` (``out/runs/<name>`` per run,
    ``out/study.json``); returns the record. ``only``: see :func:`plan` (a piece of a study;
    the record then covers that piece)."""
    from snnkart.app.study_summary import summarise

    out = Path(out)
    runs_dir = out / "runs"
    runs = plan(study, only)
    stale = _set_aside_stale(runs_dir, runs)
    start = time.perf_counter()
    results = _train(runs, runs_dir, reporter, jobs, ray)
    train_wall = time.perf_counter() - start
    width = jobs or os.cpu_count() or 1
    evaluations = evaluate(runs, runs_dir, study, width, reporter)
    held_out = evaluate_held_out(runs, runs_dir, study, width, reporter)
    records = [
        run_record(
            run, res, runs_dir, study, evaluations[run.spec.name], held_out.get(run.spec.name)
        )
        for run, res in zip(runs, results, strict=True)
    ]
    record = StudyRecord(
        schema=RECORD_SCHEMA,
        study=StudySettings(**study.model_dump(mode="json", by_alias=True)),
        only=only,
        env_revision=ENV_REVISION,
        code=code_digest()[:20],
        machine=machine_info(),  # with the commit
        wall_clock=WallClock(
            train_seconds=train_wall,
            eval_seconds=time.perf_counter() - start - train_wall,
            runs=len(runs),
            runs_reused=sum(r.status == "reused" for r in results),
            runs_set_aside=stale,
        ),
        env_steps=sum(r.steps for r in records),
        cells=summarise(records, study),
        deployed=[],
        runs=records,
    )
    record.write(out / "study.json")  # the trainings and evaluations, kept whatever
    write_documents(record, out)  # happens to the deployments on Lava
    if study.deploy_episodes:
        deployed = deploy_median_seeds(records, runs_dir, study, reporter)
        record = dataclasses.replace(record, deployed=deployed)
        record.write(out / "study.json")
        write_documents(record, out)
    return record


def write_documents(record: StudyRecord, out: Path) -> None:
    """``study.md`` (the tables beside the original's) and ``plots/`` from a study record."""
    from snnkart.app.study_summary import ORIGINAL
    from snnkart.report.study_document import markdown
    from snnkart.report.study_plots import write_plots

    write_text(out / "study.md", markdown(record, ORIGINAL))
    (out / "plots").mkdir(parents=True, exist_ok=True)
    write_plots(record, out / "plots")
