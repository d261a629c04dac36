"""The one process pool: the launcher's training runs (:mod:`snnkart.app.launch`) and a
study's evaluations (:mod:`snnkart.app.study_eval`) are jobs run ``width`` at a time.

Each job is ``python -m snnkart.app.worker '<request>'`` (:mod:`snnkart.app.worker`, which
calls the app's own functions, never the command line) in a session of its own, with one
torch/OpenMP thread. Its output is appended to a log, or its stderr kept for the error message.

Whatever ends the pool stops the jobs still running first, so no worker outlives it:

- Ctrl-C or SIGTERM (taken between polls, :func:`snnkart.faults.caught`): SIGTERM to every
  running job, which each takes like Ctrl-C (a training run saves its checkpoint at its next
  iteration boundary); their exits are reported, then :class:`~snnkart.faults.Interrupted`
  (a ``KeyboardInterrupt``) is raised;
- anything else (a job the caller counts as failed, a run directory that cannot be made):
  the same SIGTERM, then the exception propagates.

A job still running :data:`STOP_GRACE_S` after its SIGTERM is killed (SIGKILL to its group).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Generic, TypeVar

from snnkart import faults
from snnkart.app.worker import WorkerRequest, request_json
from snnkart.errors import UsageError

STOP_GRACE_S = 120.0
"""How long the pool waits for stopped jobs to save and exit before killing them."""

TAIL_CHARS = 500
"""How much of a job's stderr :attr:`Exit.tail` keeps."""

T = TypeVar("T")


@dataclass(frozen=True)
class Job:
    """What one item of the pool runs: a worker request, and where its output goes."""

    request: WorkerRequest
    log: Path | None = None
    """A file the worker's stdout and stderr are appended to; None: stdout is dropped and
    stderr kept for :attr:`Exit.tail`."""


@dataclass(frozen=True)
class Exit:
    """How a job ended."""

    code: int
    """The worker's exit status (see :mod:`snnkart.app.worker`); negative: killed by that
    signal."""
    seconds: float
    tail: str = ""
    """The end of its stderr (empty when it went to a log)."""


@dataclass
class _Running(Generic[T]):
    item: T
    proc: subprocess.Popen[bytes]
    err: IO[bytes] | None
    start: float

    def exit(self, code: int) -> Exit:
        tail = ""
        if self.err is not None:
            self.err.seek(max(0, self.err.seek(0, os.SEEK_END) - TAIL_CHARS))
            tail = self.err.read().decode(errors="replace")
        return Exit(code, time.perf_counter() - self.start, tail)

    def close(self) -> None:
        if self.err is not None:
            self.err.close()


def spawn(job: Job) -> tuple[subprocess.Popen[bytes], IO[bytes] | None]:
    """Start ``job``'s worker in a session of its own; its process and the file holding its
    stderr (None when it goes to ``job.log``)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "snnkart.app.worker", request_json(job.request)]
    if job.log is not None:
        with job.log.open("ab") as log:
            proc = subprocess.Popen(
                cmd, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True
            )
        return proc, None
    # stderr to a file, not a pipe, which a chatty job could fill and block on
    err: IO[bytes] = tempfile.TemporaryFile()
    try:
        proc = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=err, env=env, start_new_session=True
        )
    except BaseException:
        err.close()
        raise
    return proc, err


def stop_processes(procs: Sequence[subprocess.Popen[bytes]]) -> None:
    """SIGTERM to each process's group (a worker takes it like Ctrl-C: a training run saves at
    its next iteration boundary, an evaluation stops its Lava runtime), also when started
    with SIGINT ignored, as under ``nohup``; SIGKILL to a group still there after
    :data:`STOP_GRACE_S`. The processes must have been started in sessions of their own."""
    for proc in procs:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
    deadline = time.monotonic() + STOP_GRACE_S
    for proc in procs:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


class Pool:
    """Runs items as worker jobs, ``width`` at a time (see the module docstring)."""

    def __init__(self, width: int) -> None:
        if width < 1:
            raise UsageError(f"jobs must be >= 1, got {width}")
        self.width = width

    def run(
        self,
        items: Sequence[T],
        job: Callable[[T], Job],
        ended: Callable[[T, Exit], None],
        stopped: Callable[[T, Exit], None] | None = None,
    ) -> None:
        """Start ``job(item)`` for each item in order (called just before it starts) and call
        ``ended(item, exit)`` as each job ends; after Ctrl-C/SIGTERM, ``stopped(item, exit)``
        for each job that was running. Whatever ``job`` or ``ended`` raises ends the pool as
        any other failure does."""
        todo = list(items)
        running: list[_Running[T]] = []
        try:
            with faults.caught():
                while todo or running:
                    while todo and len(running) < self.width:
                        item = todo.pop(0)
                        proc, err = spawn(job(item))
                        running.append(_Running(item, proc, err, time.perf_counter()))
                    self._reap(running, ended)
                    faults.check()
                    time.sleep(0.1)
        except KeyboardInterrupt:
            stop_processes([r.proc for r in running])
            done, running[:] = list(running), []
            for r in done:
                with contextlib.closing(r):
                    if stopped is not None:
                        stopped(r.item, r.exit(r.proc.wait()))
            raise
        finally:  # any other failure: no job outlives the pool either
            stop_processes([r.proc for r in running])
            for r in running:
                r.close()

    @staticmethod
    def _reap(running: list[_Running[T]], ended: Callable[[T, Exit], None]) -> None:
        for r in list(running):
            code = r.proc.poll()
            if code is None:
                continue
            running.remove(r)
            with contextlib.closing(r):
                ended(r.item, r.exit(code))
