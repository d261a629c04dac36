"""Many training runs on one machine: a local process pool (the launcher's default).

Each run is one job of the process pool (:mod:`snnkart.app.pool`): a worker process that trains
it as ``snnkart train`` does, with one torch thread, as many at once as there are cores. The
pool is resumable: a run whose checkpoint already covers its steps is not trained again, one
that was interrupted is resumed from its checkpoint. Ctrl-C or SIGTERM reaches every running
run (as SIGTERM: each saves a checkpoint at its next iteration boundary, as ``snnkart train``
does); the pool waits for them to exit and leaves no worker process behind. Results are
gathered from each run's checkpoint metadata into one record per run.
"""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from snnkart.app.pool import Exit, Job, Pool
from snnkart.app.reporter import Reporter
from snnkart.app.worker import TrainJob
from snnkart.contract.records import OMIT_NONE, Record, RecordKind
from snnkart.errors import UsageError
from snnkart.rl.config import TrainConfig


@dataclass(frozen=True)
class RunSpec:
    """One run of the list: its name (the run directory's) and its resolved config."""

    name: str
    config: TrainConfig


@dataclass
class RunResult:
    name: str
    run_dir: str
    status: str  # "done", "reused", "interrupted" or "failed"
    global_step: int
    total_steps: int
    first_finish_step: int | None
    finishes: int
    episodes: int
    seconds: float
    error: str | None = None
    stopped_early: bool = False
    """The run's ``stop`` rule ended it before ``total_steps``."""


LAUNCH = RecordKind("launch", 1, rerun="snnkart study", untagged=1)
"""``launch.json``; v1 files carry no ``schema`` tag (they predate the tags): v2 will."""
SCHEMA_FILE = Path(__file__).with_name("launch.schema.json")


@dataclass(frozen=True, kw_only=True)
class LaunchRecord(Record):
    """``launch.json`` (``snnkart/launch/v1``): one result per run of a launcher's list, and
    whether the launch was interrupted; ``backend`` is ``ray`` for Ray Tune, absent for the
    local pool."""

    KIND = LAUNCH

    backend: str | None = field(default=None, metadata=OMIT_NONE)
    interrupted: bool
    runs: list[RunResult]


def complete(run_dir: Path, spec: RunSpec) -> bool:
    """The run in ``run_dir`` trained all its steps, or its ``stop`` rule ended it."""
    try:
        meta = json.loads((run_dir / "checkpoint.json").read_text())
        return bool(meta.get("stopped_early")) or meta["global_step"] >= spec.config.total_steps
    except (OSError, ValueError, KeyError, TypeError):
        return False


def result_of(
    spec: RunSpec, run_dir: Path, status: str, seconds: float, error: str | None
) -> RunResult:
    meta: dict[str, Any] = {}
    with contextlib.suppress(OSError, ValueError):
        meta = json.loads((run_dir / "checkpoint.json").read_text())
    first = meta.get("first_finish_step", -1)
    return RunResult(
        name=spec.name,
        run_dir=str(run_dir),
        status=status,
        global_step=int(meta.get("global_step", 0)),
        total_steps=spec.config.total_steps,
        first_finish_step=None if first is None or first < 0 else int(first),
        finishes=int(meta.get("finishes", 0)),
        episodes=int(meta.get("episodes", 0)),
        seconds=seconds,
        error=error,
        stopped_early=bool(meta.get("stopped_early", False)),
    )


class LocalPool:
    """Runs a list of :class:`RunSpec` under ``out`` (``out/<name>``), ``jobs`` at a time."""

    def __init__(self, out: Path, jobs: int | None = None) -> None:
        self.out = Path(out)
        self.jobs = jobs or os.cpu_count() or 1
        if self.jobs < 1:
            raise UsageError(f"jobs must be >= 1, got {self.jobs}")

    def run(self, specs: list[RunSpec], reporter: Reporter) -> list[RunResult]:
        """Train every run not yet complete; return one result per spec (in order) and write
        them to ``out/launch.json``. Ctrl-C/SIGTERM: the running runs save and stop, the
        results say which were interrupted, and :class:`~snnkart.faults.Interrupted` (a
        ``KeyboardInterrupt``) is raised after they are written."""
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise UsageError("every run needs its own name (they are directory names)")
        results: dict[str, RunResult] = {}
        pending = []
        for spec in specs:
            run_dir = self.out / spec.name
            if complete(run_dir, spec):
                results[spec.name] = result_of(spec, run_dir, "reused", 0.0, None)
            else:
                pending.append(spec)
        stopped = False
        with reporter.progress("runs", len(specs)) as task:
            for _ in results:
                task.advance()

            def ended(spec: RunSpec, end: Exit) -> None:
                results[spec.name] = self._result(spec, end)
                task.advance()

            try:
                Pool(self.jobs).run(pending, self._job, ended, stopped=ended)
            except KeyboardInterrupt:
                stopped = True
                for spec in pending:
                    if spec.name not in results:
                        results[spec.name] = result_of(
                            spec, self.out / spec.name, "interrupted", 0.0, None
                        )
                raise
            finally:
                self._write([results[s.name] for s in specs if s.name in results], stopped)
        return [results[s.name] for s in specs]

    def _job(self, spec: RunSpec) -> Job:
        """The run's job: its directory made and its config written, just before it starts."""
        run_dir = self.out / spec.name
        run_dir.mkdir(parents=True, exist_ok=True)
        config = self.out / f".{spec.name}.config.toml"
        config.write_text(spec.config.to_toml())
        resume = (run_dir / "config.toml").is_file()
        return Job(TrainJob(str(config), str(run_dir), resume), log=run_dir / "launch.log")

    def _result(self, spec: RunSpec, end: Exit) -> RunResult:
        run_dir = self.out / spec.name
        status = {0: "done", 130: "interrupted", 143: "interrupted"}.get(end.code, "failed")
        error = None if status != "failed" else f"exit {end.code}; see {run_dir / 'launch.log'}"
        return result_of(spec, run_dir, status, end.seconds, error)

    def _write(self, results: list[RunResult], interrupted: bool) -> None:
        LaunchRecord(interrupted=interrupted, runs=results).write(self.out / "launch.json")
