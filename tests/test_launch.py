"""The local launcher: a list of training runs in a process pool, resumable, and stopped
cleanly by Ctrl-C with every running run saved and no worker left behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from snnkart.app import pool as process_pool
from snnkart.app.launch import LocalPool, RunSpec
from snnkart.app.reporter import Silent
from snnkart.rl.config import load_config

ROOT = Path(__file__).resolve().parents[1]
TINY = ["ppo.num_envs=2", "ppo.rollout_steps=64", "ppo.update_epochs=1", "ppo.num_minibatches=2",
        "run.tensorboard=false"]  # fmt: skip
BATCH = 2 * 64


def _specs(iterations: int) -> list[RunSpec]:
    return [
        RunSpec(
            f"{policy}-s{seed}",
            load_config(
                overrides={
                    "env": "grid",
                    "policy": policy,
                    "track": "small_S",
                    "seed": seed,
                    "total_steps": iterations * BATCH,
                },
                sets=TINY,
            ),
        )
        for policy, seed in (("ann", 1), ("snn", 2))
    ]


@pytest.mark.timeout(180)
def test_pool_trains_a_list_and_reuses_finished_runs(tmp_path: Path) -> None:
    pool = LocalPool(tmp_path, jobs=2)
    results = pool.run(_specs(2), Silent())
    assert [r.status for r in results] == ["done", "done"]
    assert [r.global_step for r in results] == [2 * BATCH, 2 * BATCH]
    record = json.loads((tmp_path / "launch.json").read_text())
    assert [r["name"] for r in record["runs"]] == ["ann-s1", "snn-s2"]
    # the run is what `snnkart train` makes of that config, seed included
    config = (tmp_path / "snn-s2" / "config.toml").read_text()
    assert 'policy = "snn"' in config and "seed = 2" in config
    stamp = (tmp_path / "ann-s1" / "checkpoint.pt").stat().st_mtime
    again = pool.run(_specs(2), Silent())
    assert [r.status for r in again] == ["reused", "reused"]
    assert (tmp_path / "ann-s1" / "checkpoint.pt").stat().st_mtime == stamp


def _descendants_alive(pids: set[int]) -> list[int]:
    return [p for p in pids if Path(f"/proc/{p}").exists()
            and Path(f"/proc/{p}/stat").read_text().split(") ")[1][0] != "Z"]  # fmt: skip


POOL = """
import sys
from pathlib import Path
from snnkart import faults
from snnkart.app.launch import LocalPool
from snnkart.app.reporter import Silent
sys.path.insert(0, {tests!r})
from test_launch import _specs
import signal
signal.signal(signal.SIGINT, signal.default_int_handler)  # a terminal's Ctrl-C, even under CI
faults.install()
try:
    LocalPool(Path({out!r}), jobs=2).run(_specs({iterations}), Silent())
except KeyboardInterrupt as exc:
    sys.exit(getattr(exc, "exit_code", 130))
"""


@pytest.mark.timeout(300)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_saves_the_running_runs_and_leaves_no_worker(tmp_path: Path, signum: int) -> None:
    script = POOL.format(tests=str(ROOT / "tests"), out=str(tmp_path), iterations=400)
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    pool = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, env=env,
                            start_new_session=True)  # fmt: skip
    metrics = [tmp_path / name / "metrics.jsonl" for name in ("ann-s1", "snn-s2")]
    deadline = time.monotonic() + 120
    while not all(m.is_file() and m.read_text().strip() for m in metrics):
        assert time.monotonic() < deadline and pool.poll() is None, "runs did not start"
        time.sleep(0.2)
    workers = {int(p) for p in os.listdir("/proc") if p.isdigit()
               and str(tmp_path) in Path(f"/proc/{p}/cmdline").read_bytes().decode(errors="replace")
               and int(p) != pool.pid}  # fmt: skip
    assert len(workers) >= 2
    os.kill(pool.pid, signum)
    code = pool.wait(timeout=150)
    assert code == 128 + signum
    assert not _descendants_alive(workers), "a training process outlived the pool"
    record = json.loads((tmp_path / "launch.json").read_text())
    assert record["interrupted"] and [r["status"] for r in record["runs"]] == ["interrupted"] * 2
    for r in record["runs"]:
        meta = json.loads((Path(r["run_dir"]) / "checkpoint.json").read_text())
        assert 0 < meta["global_step"] < 400 * BATCH and meta["global_step"] % BATCH == 0
    # run again: both resume from their checkpoints (not from zero) and finish
    steps_before = {r["name"]: r["global_step"] for r in record["runs"]}
    results = LocalPool(tmp_path, jobs=2).run(
        [RunSpec(s.name, s.config.model_copy(update={"total_steps": max(
            steps_before[s.name] + BATCH, BATCH)})) for s in _specs(400)],
        Silent(),
    )  # fmt: skip
    assert [r.status for r in results] == ["done", "done"]
    for r in results:
        assert r.global_step == steps_before[r.name] + BATCH


@pytest.mark.timeout(120)
def test_a_pool_that_fails_stops_its_running_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Not only Ctrl-C: whatever else ends the pool (here the second run's directory cannot be
    made) stops the runs already started, which have sessions of their own."""
    long, second = _specs(100_000)
    (tmp_path / second.name).write_text("a file where the run directory should go")
    pool = LocalPool(tmp_path, jobs=2)
    started: list[subprocess.Popen[bytes]] = []
    real_popen = subprocess.Popen

    def recording_popen(*args: object, **kwargs: object) -> subprocess.Popen[bytes]:
        proc: subprocess.Popen[bytes] = real_popen(*args, **kwargs)  # type: ignore[call-overload]
        started.append(proc)
        return proc

    monkeypatch.setattr(process_pool.subprocess, "Popen", recording_popen)
    try:
        with pytest.raises(FileExistsError):
            pool.run([long, second], Silent())
        assert len(started) == 1
        assert started[0].poll() is not None, "a run outlived the failed pool"
    finally:
        for proc in started:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
