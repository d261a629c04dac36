"""A study's evaluations: every run (ANNs in torch, SNNs exported to NIR on the numpy
reference in fixed point), and each SNN cell's median seed deployed on Lava's simulated Loihi
in fixed point, checked step by step against the reference of the same arithmetic."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING

from snnkart.app.launch import stop_processes
from snnkart.app.reporter import Reporter
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord, EvalSummary
from snnkart.errors import UsageError
from snnkart.report.study_record import DeployedRun, RunRecord

if TYPE_CHECKING:
    from snnkart.app.study import Run, StudyConfig

DEPLOY_DIR = "study-deploy-lava-sim-fixed"


def exportable(run: Run) -> bool:
    """An SNN the reference in fixed point (Lava's arithmetic) runs: LIF, or current-based LIF
    trained without biases between its spiking layers (the default since they export)."""
    snn_cfg = run.spec.config.snn
    return run.policy == "snn" and (snn_cfg.neuron == "lif" or not snn_cfg.hidden_bias)


def eval_backend(run: Run) -> str:
    if exportable(run):
        return "nir-ref fixed"
    return "torch" if run.policy == "ann" else "torch (cuba with hidden biases: not on Lava)"


def _eval_target(run: Run, runs_dir: Path) -> tuple[list[str], Path]:
    """The ``snnkart eval`` arguments for a run, and the file holding its summary."""
    run_dir = runs_dir / run.spec.name
    if exportable(run):
        out = run_dir / "study-eval-nir-ref-fixed"
        args = ["--backend", "nir-ref", "--precision", "fixed", "--out", str(out)]
        return args, out / "deploy.json"
    out = run_dir / "study-eval.json"
    return ["--out", str(out)], out


def _stale(result: Path, checkpoint: Path) -> bool:
    return not result.is_file() or result.stat().st_mtime < checkpoint.stat().st_mtime


PARITY_FAILED = 4
"""``snnkart eval``/``deploy``'s exit code when a backend left its reference (the record is
written and says where)."""


def _run_all(cmds: list[tuple[str, list[str]]], jobs: int, reporter: Reporter, what: str,
             ok: tuple[int, ...] = (0,)) -> None:  # fmt: skip
    """Run ``snnkart`` commands (name, args), ``jobs`` at a time, one thread each; an exit
    code outside ``ok`` fails. Whatever ends the loop (a failure, Ctrl-C, SIGTERM) stops the
    commands still running first, as the launcher stops its runs: none outlives the study."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    todo = list(cmds)
    running: list[tuple[str, subprocess.Popen[bytes], IO[bytes]]] = []
    try:
        with reporter.progress(what, len(todo)) as task:
            while todo or running:
                while todo and len(running) < jobs:
                    name, args = todo.pop(0)
                    # stderr to a file, not a pipe, which a chatty command could fill and block on
                    err: IO[bytes] = tempfile.TemporaryFile()
                    try:
                        proc = subprocess.Popen([sys.executable, "-m", "snnkart.cli", *args],
                                                env=env, stdout=subprocess.DEVNULL, stderr=err,
                                                start_new_session=True)  # fmt: skip
                    except BaseException:
                        err.close()
                        raise
                    running.append((name, proc, err))
                for name, proc, err in list(running):
                    code = proc.poll()
                    if code is None:
                        continue
                    running.remove((name, proc, err))
                    with err:
                        if code not in ok:
                            err.seek(max(0, err.seek(0, os.SEEK_END) - 500))
                            text = err.read().decode(errors="replace")
                            raise UsageError(f"{what}: {name} failed (exit {code}): {text}")
                    task.advance()
                time.sleep(0.1)
    finally:
        stop_processes([proc for _, proc, _ in running])
        for _, _, err in running:
            err.close()


def evaluate(runs: list[Run], runs_dir: Path, study: StudyConfig, jobs: int,
             reporter: Reporter) -> dict[str, Evaluation]:  # fmt: skip
    """Each run's evaluation summary, evaluating (``jobs`` at a time) where none newer than
    its checkpoint exists."""
    cmds = []
    for run in runs:
        args, summary = _eval_target(run, runs_dir)
        if _stale(summary, runs_dir / run.spec.name / "checkpoint.pt"):
            cmds.append((run.spec.name, ["eval", str(runs_dir / run.spec.name),
                                         "--episodes", str(study.eval_episodes),
                                         "--seed", str(study.eval_seed), *args]))  # fmt: skip
    _run_all(cmds, jobs, reporter, "evaluations")
    return {run.spec.name: _summary(_eval_target(run, runs_dir)[1]) for run in runs}


def median_seed(records: list[RunRecord]) -> RunRecord:
    """The run in the middle of a cell's seeds by steps to N finishes (never = last; ties by
    seed); of an even count, the earlier of the middle two."""
    order = sorted(records, key=lambda r: (r.steps_to_finishes is None,
                                           r.steps_to_finishes or 0, r.seed))  # fmt: skip
    return order[(len(order) - 1) // 2]


def deploy_median_seeds(records: list[RunRecord], runs_dir: Path, study: StudyConfig,
                        reporter: Reporter) -> list[DeployedRun]:  # fmt: skip
    """Each SNN cell's median-seed run on lava-sim in fixed point for
    ``study.deploy_episodes`` episodes (the evaluation's first seeds), one at a time (Lava
    runs its own processes); what each deployment gave and whether it was bit-exact."""
    cells: dict[tuple[str, str, str], list[RunRecord]] = {}
    for r in records:
        if r.eval_backend == "nir-ref fixed":
            cells.setdefault((r.track, r.env, r.variant), []).append(r)
    chosen = [median_seed(rs) for rs in cells.values()]
    cmds = []
    for r in chosen:
        run_dir = runs_dir / r.name
        if _stale(run_dir / DEPLOY_DIR / "deploy.json", run_dir / "checkpoint.pt"):
            cmds.append((r.name, ["eval", str(run_dir), "--backend", "lava-sim",
                                  "--precision", "fixed", "--episodes",
                                  str(study.deploy_episodes), "--seed", str(study.eval_seed),
                                  "--out", str(run_dir / DEPLOY_DIR)]))  # fmt: skip
    # a deployment that left the reference still wrote its record: it shows as not bit-exact
    _run_all(cmds, 1, reporter, "deployments on lava-sim", ok=(0, PARITY_FAILED))
    out = []
    for r in chosen:
        result = DeployRecord.read(runs_dir / r.name / DEPLOY_DIR / "deploy.json")
        out.append(DeployedRun(
            track=r.track, env=r.env, variant=r.variant, run=r.name, seed=r.seed,
            backend="lava-sim fixed", episodes=result.summary.episodes,
            success_rate=result.summary.success_rate, bit_exact=result.bit_exact,
            env_steps=result.parity.env_steps, reference_success_rate=r.eval_success_rate,
            reference_episodes=study.eval_episodes,
        ))  # fmt: skip
    return out


@dataclass(frozen=True)
class Evaluation:
    """A run's evaluation: its summary, and for an SNN on the reference its spikes per env step
    (one inference: T steps of every spiking layer, from the reference's counts)."""

    summary: EvalSummary
    spikes_per_step: float | None = None


def _summary(path: Path) -> Evaluation:
    """The evaluation in ``path``: a ``deploy.json`` (an SNN on the reference) or an
    ``eval.json`` (torch)."""
    if path.name != "deploy.json":
        return Evaluation(EvalRecord.read(path).summary)
    record = DeployRecord.read(path)
    steps = record.counts.env_steps
    return Evaluation(record.summary, sum(record.counts.spikes) / steps if steps else None)
