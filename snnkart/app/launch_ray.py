"""The launcher on Ray Tune, and ``snnkart sweep``: the only module that imports ray and optuna
(``pip install -e '.[ray]'``).

- :func:`run_on_ray` runs the same list of :class:`~snnkart.app.launch.RunSpec` as the local
  pool, as Tune trials of one CPU each, into ``out/<name>`` (resumable: a finished run is
  reused, an interrupted one resumes from its checkpoint), and gathers the same records.
- :func:`run_sweep` searches hyperparameters with Tune's Optuna searcher and ASHA early stopping
  (reduction factor 2: at each rung the weaker half stops) on the mean episodic return per
  training iteration; ``sweep.json`` lists every trial with
  its settings, how many iterations it ran and whether ASHA stopped it early.

Both start a local Ray instance (one CPU per core) and shut it down after, or join a cluster
with ``address`` (``ray start --head`` on the head node, ``ray start --address HEAD:6379`` on
the others, then ``snnkart sweep --address HEAD:6379``; every node needs snnkart installed and
``out`` on a shared file system).
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Final, TypedDict

from snnkart.app.launch import LaunchRecord, RunResult, RunSpec, complete, result_of
from snnkart.errors import UsageError
from snnkart.faults import Interrupted
from snnkart.io import write_json
from snnkart.rl.config import TrainConfig, validate_config

METRIC: Final = "episodic_return"


class _Trial(TypedDict):
    train: dict[str, object]  # the trial's training config, as JSON
    out: str


class TrialConfig(_Trial, total=False):
    """What Tune hands a trial: a launched run's ``name``, or a sweep's ``search`` settings
    (dotted keys) on top of ``train``."""

    name: str
    search: dict[str, object]


class TrialRecord(TypedDict):
    """One trial of a sweep, as ``sweep.json`` lists it."""

    settings: dict[str, object] | None
    iterations: int
    max_iterations: int
    stopped_early: bool | None  # None: interrupted, whether ASHA had is unknown
    episodic_return: float | None  # METRIC
    error: str | None
    run_dir: str | None


class SweepRecord(TypedDict):
    """``sweep.json``: the search, every trial, the best one."""

    metric: str
    mode: str
    grace_period: int
    samples: int
    interrupted: bool
    base: dict[str, object]
    trials: list[TrialRecord]
    best: TrialRecord | None


def _train_trial(config: TrialConfig) -> None:
    """A Tune trial: one ``snnkart train`` run in this worker, reporting every iteration."""
    from ray import tune

    from snnkart.rl.config import _set_dotted
    from snnkart.rl.ppo import train

    data = dict(config["train"])
    for key, value in config.get("search", {}).items():
        _set_dotted(data, key, value)
    cfg = validate_config(data, "sweep trial")
    run_dir = Path(config["out"]) / (config.get("name") or tune.get_context().get_trial_name())
    last = {"value": -math.inf}

    def report(record: Mapping[str, float | None]) -> None:
        ret = record.get("charts/episodic_return")
        if ret is not None:
            last["value"] = float(ret)
        tune.report(
            {
                METRIC: last["value"],
                "global_step": record["global_step"],
                "finishes": record["charts/cumulative_finishes"],
                "run_dir": str(run_dir),
            }
        )

    # Tune stops a trial (ASHA, Ctrl-C) while it waits in ``tune.report``, then ends the worker:
    # the checkpoint written just before each report is the run's last whole iteration.
    train(cfg, run_dir, report, threads=1, save_every_iteration=True)


class _Stop:
    """Ctrl-C or SIGTERM while Tune runs: ask Tune to stop gracefully (SIGUSR1, its own stop
    signal: it stops the trials and writes its state) and remember which signal it was
    (``signum``), so the caller can exit as interrupted. Tune's own SIGINT handler is kept
    off (it would end the run as if it had finished, and does not catch SIGTERM);
    :meth:`arm` again after ``ray.init``, which installs Ray's SIGTERM handler."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self.previous = {s: signal.getsignal(s) for s in (*self.SIGNALS, signal.SIGUSR1)}

    def _handler(self, signum: int, frame: object) -> None:
        if self.signum is None:
            self.signum = signum
        if signal.getsignal(signal.SIGUSR1) in (signal.SIG_DFL, signal.SIG_IGN, None):
            raise Interrupted(signum)  # Tune is not running yet (or any more)
        os.kill(os.getpid(), signal.SIGUSR1)

    def arm(self) -> None:
        for s in self.SIGNALS:
            if self.previous[s] is not signal.SIG_IGN:
                signal.signal(s, self._handler)

    def __enter__(self) -> _Stop:
        os.environ["TUNE_DISABLE_SIGINT_HANDLER"] = "1"
        self.arm()
        return self

    def __exit__(self, *exc: object) -> None:
        for s, h in self.previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextlib.contextmanager
def _ray(address: str | None, cpus: int | None) -> Iterator[_Stop]:
    """A local Ray instance for the duration (shut down after, also on Ctrl-C), or a cluster;
    Ctrl-C and SIGTERM meanwhile stop Tune gracefully (the :class:`_Stop` it yields says
    which signal came)."""
    import ray

    before = set(_ray_pids())
    with _Stop() as stop:
        ray.init(
            address=address,
            num_cpus=None if address else cpus,
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
        stop.arm()  # again: ray.init installs its own SIGTERM handler
        try:
            yield stop
        finally:
            ray.shutdown()
            if address is None:
                _reap_local_ray(before)


def _ray_pids() -> list[int]:
    """Processes of a local Ray instance (its GCS, raylet and workers), from /proc."""
    pids = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if state != "Z" and (
            b"raylet" in cmd
            or b"gcs_server" in cmd
            or cmd.startswith(b"ray::")
            or b"default_worker.py" in cmd
        ):
            pids.append(int(pid))
    return pids


def _reap_local_ray(before: set[int], grace: float = 15.0) -> None:
    """``ray.shutdown`` stops the local instance asynchronously: wait for the processes it
    started to exit, and kill any still there after ``grace`` seconds, so none outlives us."""
    deadline = time.monotonic() + grace
    while (left := [p for p in _ray_pids() if p not in before]) and time.monotonic() < deadline:
        time.sleep(0.2)
    for pid in left:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGKILL)


def run_on_ray(
    specs: list[RunSpec], out: Path, address: str | None = None, cpus: int | None = None
) -> list[RunResult]:
    """The local pool's list as Tune trials (one CPU each); the same records in
    ``out/launch.json``."""
    from ray import tune

    out = Path(out).resolve()
    todo = [s for s in specs if not complete(out / s.name, s)]
    signum = None
    if todo:
        space = {
            "spec": tune.grid_search(
                [
                    {
                        "name": s.name,
                        "train": s.config.model_dump(mode="json", by_alias=True, exclude_none=True),
                        "out": str(out),
                    }
                    for s in todo
                ]
            )
        }
        with _ray(address, cpus) as stop:
            tuner = tune.Tuner(
                tune.with_resources(lambda c: _train_trial(c["spec"]), {"cpu": 1}),
                param_space=space,
                run_config=tune.RunConfig(storage_path=str(out / "ray"), name="launch", verbose=0),
            )
            tuner.fit()
        signum = stop.signum
    results = [
        result_of(
            s,
            out / s.name,
            "reused" if s not in todo else _status(out / s.name, s, signum is not None),
            0.0,
            None,
        )
        for s in specs
    ]
    LaunchRecord(backend="ray", interrupted=signum is not None, runs=results).write(
        out / "launch.json"
    )
    if signum is not None:
        raise Interrupted(signum)
    return results


def _status(run_dir: Path, spec: RunSpec, stopped: bool) -> str:
    if complete(run_dir, spec):
        return "done"
    return "interrupted" if stopped else "failed"


def parse_param(text: str) -> tuple[str, Any]:
    """``KEY=uniform:LOW:HIGH``, ``KEY=loguniform:LOW:HIGH`` or ``KEY=choice:A,B,...``."""
    from ray import tune

    key, sep, dist = text.partition("=")
    kind, _, args = dist.partition(":")
    try:
        if sep and kind in ("uniform", "loguniform"):
            low, high = (float(x) for x in args.split(":"))
            return key, (tune.uniform if kind == "uniform" else tune.loguniform)(low, high)
        if sep and kind == "choice":
            values = [
                float(x) if x.replace(".", "", 1).replace("e-", "").isdigit() else x
                for x in args.split(",")
            ]
            return key, tune.choice(values)
    except ValueError:
        pass
    raise UsageError(
        f"--param {text!r}: write KEY=uniform:LOW:HIGH, KEY=loguniform:LOW:HIGH or "
        "KEY=choice:A,B (e.g. ppo.learning_rate=loguniform:1e-4:3e-3)"
    )


def run_sweep(
    base: TrainConfig,
    params: list[str],
    out: Path,
    samples: int,
    points: Sequence[Mapping[str, object]] | None = None,
    grace: int = 1,
    address: str | None = None,
    cpus: int | None = None,
) -> dict[str, object]:
    """Search ``params`` with Optuna, stop weak trials with ASHA; write ``out/sweep.json``."""
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler
    from ray.tune.search.optuna import OptunaSearch

    if samples < 1 or grace < 1:
        raise UsageError("--samples and --grace must be >= 1")
    space = dict(parse_param(p) for p in params)
    if not space:
        raise UsageError("give at least one --param to search")
    out = Path(out).resolve()
    iterations = max(1, base.total_steps // base.batch_size)
    with _ray(address, cpus) as stop:
        tuner = tune.Tuner(
            tune.with_resources(_train_trial, {"cpu": 1}),
            param_space={
                "train": base.model_dump(mode="json", by_alias=True, exclude_none=True),
                "out": str(out),
                "search": space,
            },
            tune_config=tune.TuneConfig(
                metric=METRIC,
                mode="max",
                num_samples=samples,
                search_alg=OptunaSearch(
                    seed=base.seed,
                    points_to_evaluate=[
                        {f"search/{k}": v for k, v in p.items()} for p in points or []
                    ],
                ),
                scheduler=ASHAScheduler(
                    time_attr="training_iteration",
                    grace_period=grace,
                    max_t=iterations,
                    reduction_factor=2,
                ),
            ),
            run_config=tune.RunConfig(storage_path=str(out / "ray"), name="sweep", verbose=0),
        )
        grid = tuner.fit()
    stopped = stop.signum is not None
    trials = [_trial_record(grid[i], iterations, stopped) for i in range(len(grid))]
    record = _sweep_record(base, grace, samples, stopped, trials)
    write_json(out / "sweep.json", record)
    if stop.signum is not None:
        raise Interrupted(stop.signum)
    return dict(record)  # a plain dict: the command line reads it as JSON


def _trial_record(result: Any, iterations: int, stopped: bool) -> TrialRecord:
    """One trial of Tune's results (a ``ray.tune.Result``) as ``sweep.json`` lists it."""
    ran = int(result.metrics.get("training_iteration", 0)) if result.metrics else 0
    return {
        "settings": (result.config or {}).get("search"),
        "iterations": ran,
        "max_iterations": iterations,
        # under Ctrl-C, Tune stops every running trial: whether ASHA had is then unknown
        "stopped_early": None if stopped else ran < iterations and result.error is None,
        METRIC: (result.metrics or {}).get(METRIC),
        "error": None if result.error is None else str(result.error),
        "run_dir": (result.metrics or {}).get("run_dir"),
    }


def _sweep_record(
    base: TrainConfig, grace: int, samples: int, stopped: bool, trials: list[TrialRecord]
) -> SweepRecord:
    """``sweep.json``'s record: the search's settings, every trial and the best scored one."""
    scored = [t for t in trials if isinstance(t[METRIC], float)]
    best = max(scored, key=lambda t: float(t[METRIC]), default=None)  # type: ignore[arg-type]
    return {
        "metric": METRIC,
        "mode": "max",
        "grace_period": grace,
        "samples": samples,
        "interrupted": bool(stopped),
        "base": base.model_dump(mode="json", by_alias=True, exclude_none=True),
        "trials": trials,
        "best": best,
    }
