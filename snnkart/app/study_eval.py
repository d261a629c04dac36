"""A study's evaluations: every run (ANNs in torch, SNNs exported to NIR on the numpy
reference in fixed point), and each SNN cell's median seed deployed on Lava's simulated Loihi
in fixed point, checked step by step against the reference of the same arithmetic."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from snnkart.app.pool import Exit, Job, Pool
from snnkart.app.protocol import is_tuning_track
from snnkart.app.provenance import EVALUATION_CODE, code_digest
from snnkart.app.reporter import Reporter
from snnkart.app.study_types import held_out_tracks
from snnkart.app.worker import EvalJob, WorkerRequest, track_out
from snnkart.contract.deploy_record import DeployRecord, StepCounts
from snnkart.contract.eval_record import EvalRecord, EvalSummary
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.envs.tracks import short_name
from snnkart.errors import UsageError
from snnkart.io import write_text
from snnkart.report.study_record import DeployedRun, HeldOut, RunRecord
from snnkart.rl import kinds

if TYPE_CHECKING:
    from snnkart.app.study_types import Run, StudyConfig

DEPLOY_DIR = "study-deploy-lava-sim-fixed"


def exportable(run: Run) -> bool:
    """A policy the reference in fixed point (Lava's arithmetic) runs: LIF (stateful or not),
    current-based LIF trained without biases between its spiking layers (the default since
    they export), a trained sigma-delta network, or a ReLU ANN converted to one."""
    snn_cfg = run.spec.config.snn
    family = kinds.study_family(run.policy)
    if family.graded:
        return True
    return family.spiking and (snn_cfg.neuron == "lif" or not snn_cfg.hidden_bias)


def converted(run: Run) -> bool:
    """A run evaluated as the sigma-delta network converted from it (``--sigma-delta``)."""
    return run.policy in kinds.CONVERSIONS


def eval_backend(run: Run) -> str:
    if exportable(run):
        return "nir-ref fixed"
    if not kinds.study_family(run.policy).spiking:
        return "torch"
    return "torch (cuba with hidden biases: not on Lava)"


def _eval_job(run: Run, runs_dir: Path, study: StudyConfig) -> tuple[EvalJob, Path]:
    """A run's evaluation (as ``snnkart eval`` runs it), and the file holding its summary."""
    run_dir = runs_dir / run.spec.name
    episodes, seed = study.eval_episodes, study.eval_seed
    if exportable(run):
        out = run_dir / "study-eval-nir-ref-fixed"
        job = EvalJob(
            str(run_dir), episodes, seed, str(out), "nir-ref", "fixed", sigma_delta=converted(run)
        )
        return job, out / "deploy.json"
    out = run_dir / "study-eval.json"
    return EvalJob(str(run_dir), episodes, seed, str(out)), out


def _eval_key(job: EvalJob) -> str:
    """What an evaluation's numbers depend on: the request (but where it reads and writes),
    the checkpoint's bytes and the evaluation code."""
    request = {k: v for k, v in asdict(job).items() if k not in ("run_dir", "out")}
    checkpoint = hashlib.sha256((Path(job.run_dir) / "checkpoint.pt").read_bytes()).hexdigest()
    parts = {"request": request, "checkpoint": checkpoint, "code": code_digest(EVALUATION_CODE)}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def _key_file(job: EvalJob) -> Path:
    out = Path(job.out)
    return out.with_name(out.name + ".key")


def _stale(job: EvalJob, results: list[Path]) -> bool:
    """Whether ``job`` must run: a result is missing, or was made from another request,
    checkpoint or evaluation code (or before evaluations had keys)."""
    key = _key_file(job)
    return (
        not all(r.is_file() for r in results)
        or not key.is_file()
        or key.read_text() != _eval_key(job)
    )


PARITY_FAILED = 4
"""The worker's (and ``snnkart eval``/``deploy``'s) exit code when a backend left its reference
(the record is written and says where)."""


def _run_all(
    jobs: list[tuple[str, WorkerRequest]],
    width: int,
    reporter: Reporter,
    what: str,
    ok: tuple[int, ...] = (0,),
) -> None:
    """Run worker requests (name, request) on the process pool, ``width`` at a time; an exit
    status outside ``ok`` fails. Whatever ends the loop (a failure, Ctrl-C, SIGTERM) stops the
    jobs still running first, as the launcher stops its runs: none outlives the study."""
    with reporter.progress(what, len(jobs)) as task:

        def ended(item: tuple[str, WorkerRequest], end: Exit) -> None:
            if end.code not in ok:
                raise UsageError(f"{what}: {item[0]} failed (exit {end.code}): {end.tail}")
            if isinstance(item[1], EvalJob):
                write_text(_key_file(item[1]), _eval_key(item[1]))
            task.advance()

        Pool(width).run(jobs, lambda item: Job(item[1]), ended)


def evaluate(
    runs: list[Run], runs_dir: Path, study: StudyConfig, jobs: int, reporter: Reporter
) -> dict[str, Evaluation]:
    """Each run's evaluation summary, evaluating (``jobs`` at a time) where none was made from
    this request, checkpoint and evaluation code (:func:`_stale`)."""
    todo: list[tuple[str, WorkerRequest]] = []
    for run in runs:
        job, summary = _eval_job(run, runs_dir, study)
        if _stale(job, [summary]):
            todo.append((run.spec.name, job))
    _run_all(todo, jobs, reporter, "evaluations")
    return {run.spec.name: _summary(_eval_job(run, runs_dir, study)[1]) for run in runs}


HELD_OUT_DIR = "study-held-out"


def _held_out_job(
    run: Run, runs_dir: Path, study: StudyConfig, tracks: list[str]
) -> tuple[EvalJob, list[Path]]:
    """A run's evaluation on the held-out ``tracks`` (one worker), and its result files."""
    out = runs_dir / run.spec.name / HELD_OUT_DIR
    nir = exportable(run)
    job = EvalJob(
        str(out.parent),
        study.eval_track_episodes,
        study.eval_seed,
        str(out),
        "nir-ref" if nir else "torch",
        sigma_delta=converted(run),
        tracks=tracks,
    )
    files = [track_out(out, t, job.backend) / ("deploy.json" if nir else "") for t in tracks]
    return job, files


def evaluate_held_out(
    runs: list[Run], runs_dir: Path, study: StudyConfig, jobs: int, reporter: Reporter
) -> dict[str, list[HeldOut]]:
    """Each run on the study's held-out tracks (``eval_tracks``), ``eval_track_episodes``
    seeded episodes each on its evaluation backend, where no result of this request, checkpoint
    and code exists; by run name (empty when the study has no held-out tracks)."""
    pairs = held_out_tracks(study.eval_tracks)
    if not pairs:
        return {}
    tracks = [t for _, t in pairs]
    todo: list[tuple[str, WorkerRequest]] = []
    for run in runs:
        job, files = _held_out_job(run, runs_dir, study, tracks)
        if _stale(job, files):
            todo.append((run.spec.name, job))
    _run_all(todo, jobs, reporter, "held-out evaluations")
    out = {}
    for run in runs:
        files = _held_out_job(run, runs_dir, study, tracks)[1]
        out[run.spec.name] = [
            _held_out(short_name(t), group, _summary(f).summary)
            for (group, t), f in zip(pairs, files, strict=True)
        ]
    return out


def _held_out(track: str, group: str, s: EvalSummary) -> HeldOut:
    return HeldOut(
        track=track,
        group=group,
        tuning_track=is_tuning_track(track),
        episodes=s.episodes,
        success_rate=s.laps,
        mean_return=s.mean_return,
        crashes=s.crash_count,
    )


def median_seed(records: list[RunRecord]) -> RunRecord:
    """The run in the middle of a cell's seeds by steps to N finishes (never = last; ties by
    seed); of an even count, the earlier of the middle two."""
    order = sorted(
        records, key=lambda r: (r.steps_to_finishes is None, r.steps_to_finishes or 0, r.seed)
    )
    return order[(len(order) - 1) // 2]


def deploy_median_seeds(
    records: list[RunRecord], runs_dir: Path, study: StudyConfig, reporter: Reporter
) -> list[DeployedRun]:
    """Each SNN cell's median-seed run on lava-sim in fixed point for
    ``study.deploy_episodes`` episodes (the evaluation's first seeds), one at a time (Lava
    runs its own processes); what each deployment gave and whether it was bit-exact."""
    cells: dict[tuple[str, str, str, str], list[RunRecord]] = {}
    for r in records:
        if r.eval_backend == "nir-ref fixed":
            cells.setdefault((r.track, r.env, r.policy, r.variant), []).append(r)
    chosen = [median_seed(rs) for rs in cells.values()]
    policies = {r.name: r.policy for r in records}
    todo: list[tuple[str, WorkerRequest]] = []
    for r in chosen:
        run_dir = runs_dir / r.name
        job = EvalJob(
            str(run_dir),
            study.deploy_episodes,
            study.eval_seed,
            str(run_dir / DEPLOY_DIR),
            "lava-sim",
            "fixed",
            sigma_delta=policies[r.name] in kinds.CONVERSIONS,
        )
        if _stale(job, [run_dir / DEPLOY_DIR / "deploy.json"]):
            todo.append((r.name, job))
    # a deployment that left the reference still wrote its record: it shows as not bit-exact
    _run_all(todo, 1, reporter, "deployments on lava-sim", ok=(0, PARITY_FAILED))
    out = []
    for r in chosen:
        result = DeployRecord.read(runs_dir / r.name / DEPLOY_DIR / "deploy.json")
        out.append(
            DeployedRun(
                track=r.track,
                env=r.env,
                variant=r.variant,
                run=r.name,
                seed=r.seed,
                backend="lava-sim fixed",
                episodes=result.summary.episodes,
                success_rate=result.summary.laps,
                bit_exact=result.bit_exact,
                env_steps=result.parity.env_steps,
                reference_success_rate=r.eval_success_rate,
                reference_episodes=study.eval_episodes,
            )
        )
    return out


@dataclass(frozen=True)
class Evaluation:
    """A run's evaluation: its summary, and for an SNN on the reference its spikes per env step
    (one inference: T steps of every spiking layer, from the reference's counts)."""

    summary: EvalSummary
    spikes_per_step: float | None = None
    counts_per_step: StepCounts | None = None
    sigma_delta_counts: dict[str, object] | None = None
    """A sigma-delta network's counts per env step (:class:`SigmaDeltaCounts` as a dict)."""


def _summary(path: Path) -> Evaluation:
    """The evaluation in ``path``: a ``deploy.json`` (an SNN on the reference) or an
    ``eval.json`` (torch)."""
    if path.name != "deploy.json":
        return Evaluation(EvalRecord.read(path).summary)
    record = DeployRecord.read(path)
    steps = record.counts.env_steps
    if not steps:
        return Evaluation(record.summary)
    if record.counts.sigma_delta is not None:
        counts = asdict(SigmaDeltaCounts.of_deploy(record))
        return Evaluation(record.summary, sigma_delta_counts=counts)
    return Evaluation(record.summary, sum(record.counts.spikes) / steps, StepCounts.of(record))
