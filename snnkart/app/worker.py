"""One job of the process pool (:mod:`snnkart.app.pool`) in a process of its own:
``python -m snnkart.app.worker '<request JSON>'`` runs one app workflow, a training run
(:func:`snnkart.app.train.run_training`) or an evaluation (:mod:`snnkart.app.evaluate`).

The worker calls the app's functions, not the command line, so the layers hold across the
process boundary (cli -> app -> ...). It ends as the matching ``snnkart`` command would:

=====  ==============================================================================
0      done
2      a user error (``error: ...`` on stderr), or a failed write
4      a spiking backend left its reference (the record is written and says where)
130    Ctrl-C; 143: SIGTERM, taken like Ctrl-C (a training run saves its checkpoint first)
=====  ==============================================================================
"""

from __future__ import annotations

import json
import signal
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from snnkart import faults
from snnkart.app.reporter import Silent
from snnkart.envs.tracks import short_name
from snnkart.errors import ParityError, SnnkartError, UsageError


@dataclass(frozen=True)
class TrainJob:
    """Train the run in ``out`` from the config file ``config`` (``snnkart train --config
    CONFIG --out OUT``), continuing the run there with ``resume`` (``--resume``)."""

    config: str
    out: str
    resume: bool = False
    kind: str = "train"


@dataclass(frozen=True)
class EvalJob:
    """Evaluate the run in ``run_dir`` (``snnkart eval RUN_DIR --episodes --seed --backend
    --precision --out``): in torch, or exported to NIR on ``nir-ref`` or ``lava-sim``."""

    run_dir: str
    episodes: int
    seed: int
    out: str
    backend: str = "torch"
    precision: str = "fixed"
    """The ``--precision`` word on a NIR backend: ``fixed``, the default of both in the one
    table (:data:`snnkart.backends.defaults.DEFAULT_PRECISIONS`; tests/test_doors.py keeps
    them equal); torch ignores it. Written out, not None, so a study's request keys
    (:func:`snnkart.app.study_eval._eval_key`) stay what they were."""
    kind: str = "eval"
    sigma_delta: bool = False  # a ReLU ANN run converted to sigma-delta before it runs
    tracks: list[str] = field(default_factory=list)
    """Evaluate on each of these tracks instead of the run's own, into ``out/<stem>.json``
    (torch) or ``out/<stem>/`` (a NIR backend): one process for a run's held-out tracks."""


WorkerRequest = TrainJob | EvalJob
_KINDS: dict[str, type[TrainJob] | type[EvalJob]] = {"train": TrainJob, "eval": EvalJob}


def request_json(request: WorkerRequest) -> str:
    """The request as the worker's one command-line argument."""
    return json.dumps(asdict(request))


def parse_request(text: str) -> WorkerRequest:
    """A request from :func:`request_json`'s text; :class:`UsageError` if it is not one."""
    try:
        data = json.loads(text)
        return _KINDS[data["kind"]](**data)
    except (ValueError, KeyError, TypeError) as exc:
        raise UsageError(f"not a worker request ({exc}): {text[:200]}") from exc


class LineReporter(Silent):
    """The worker's reporter (its output goes to a log, not a terminal): messages as lines on
    stderr, no progress bars."""

    def message(self, text: str) -> None:
        print(text, file=sys.stderr, flush=True)


def run(request: WorkerRequest) -> int:
    """Run the request's workflow; its exit status (see the module docstring). Errors and
    interrupts propagate (:func:`main` turns them into statuses)."""
    reporter = LineReporter()
    if isinstance(request, TrainJob):
        from snnkart.app.train import run_training
        from snnkart.envs.tracks import load_track
        from snnkart.rl.config import load_config

        cfg = load_config(request.config)
        if not request.resume:
            load_track(cfg.track)
        # a launch list says how long each run is: resuming with a longer one extends it
        total = cfg.total_steps if request.resume else None
        return run_training(cfg, Path(request.out), reporter, request.resume, total)
    if request.episodes < 1:
        raise UsageError(f"episodes must be >= 1, got {request.episodes}")
    run_dir, out = Path(request.run_dir), Path(request.out)
    if not request.tracks:
        _evaluate(request, run_dir, out, None, reporter)
    for track in request.tracks:
        _evaluate(request, run_dir, track_out(out, track, request.backend), track, reporter)
    return 0


def track_out(out: Path, track: str, backend: str) -> Path:
    """Where a request with ``tracks`` writes ``track``'s evaluation: ``out/<name>.json`` in
    torch, the directory ``out/<name>/`` (holding ``deploy.json``) on a NIR backend."""
    name = short_name(track)
    return out / (f"{name}.json" if backend == "torch" else name)


def _evaluate(
    request: EvalJob, run_dir: Path, out: Path, track: str | None, reporter: LineReporter
) -> None:
    """One evaluation of the request's run, on ``track`` (None: its own), into ``out``, opened
    by the opener's rules (:func:`snnkart.app.opener.choose`)."""
    from snnkart.app.evaluate import run_eval, run_eval_exported
    from snnkart.app.opener import choose

    target = choose(run_dir, request.backend, request.precision, sigma_delta=request.sigma_delta)
    where, which = target.run_dir or target.path, target.checkpoint
    episodes, seed = request.episodes, request.seed
    if target.backend == "torch":
        run_eval(where, episodes, seed, which, False, None, out, reporter, track)
        return
    deploy = target.deploy_request(episodes, seed, track=track, out=out)
    run_eval_exported(where, which, deploy, reporter, sigma_delta=target.sigma_delta)


def main(argv: list[str] | None = None) -> int:
    """The worker process: SIGTERM interrupts like Ctrl-C; the request's exit status."""
    faults.install()
    args = sys.argv[1:] if argv is None else argv
    try:
        if len(args) != 1:
            raise UsageError("usage: python -m snnkart.app.worker '<request JSON>'")
        return run(parse_request(args[0]))
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, faults.Interrupted) else signal.SIGINT
        print(f"interrupted ({signal.Signals(signum).name})", file=sys.stderr, flush=True)
        return 128 + signum
    except ParityError as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 4
    except (SnnkartError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 2


if __name__ == "__main__":
    sys.exit(main())
