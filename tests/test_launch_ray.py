"""The launcher and ``snnkart sweep`` on a real local Ray instance (the ``ray`` extra): the same
list of runs as the local pool, and an Optuna search in which ASHA stops trials early. Each test
starts and stops its own Ray and leaves no Ray process behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_launch import BATCH, TINY, _specs

ray = pytest.importorskip("ray", reason="optional: the ray extra is not installed "
                          "(pip install -e '.[ray]')")  # fmt: skip
ROOT = Path(__file__).resolve().parents[1]
# one Ray instance at a time: under pytest-xdist these tests share one worker (--dist
# loadgroup), since a second instance started by the other worker would be taken for a leftover
pytestmark = pytest.mark.xdist_group("ray")


def _ray_left(wait: float = 30.0) -> list[str]:
    """The Ray processes still there after up to ``wait`` seconds: a stopped instance's
    processes take a moment to exit, longer on a loaded machine (another test's, or a
    launcher's reaper that waits 15 s before it kills)."""
    deadline = time.monotonic() + wait
    while (found := _ray_processes()) and time.monotonic() < deadline:
        time.sleep(0.5)
    return found


def _ray_processes() -> list[str]:
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if any(name in cmd for name in ("raylet", "gcs_server", "ray::", "default_worker.py")):
            found.append(cmd[:120])
    return found


@pytest.mark.timeout(300)
def test_the_pool_list_runs_as_tune_trials(tmp_path: Path) -> None:
    from snnkart.app.launch_ray import run_on_ray

    assert not _ray_left(), "a Ray instance is already running"
    results = run_on_ray(_specs(2), tmp_path, cpus=2)
    assert [(r.name, r.status, r.global_step) for r in results] == [
        ("ann-s1", "done", 2 * BATCH), ("snn-s2", "done", 2 * BATCH)]  # fmt: skip
    record = json.loads((tmp_path / "launch.json").read_text())
    assert record["backend"] == "ray" and len(record["runs"]) == 2
    assert 'policy = "snn"' in (tmp_path / "snn-s2" / "config.toml").read_text()
    assert not _ray_left(), "Ray processes outlived the launcher"
    # resumable: a finished list is reused without starting Ray's trials again
    again = run_on_ray(_specs(2), tmp_path, cpus=2)
    assert [r.status for r in again] == ["reused", "reused"]


@pytest.mark.timeout(400)
def test_sweep_stops_weak_trials_early(tmp_path: Path) -> None:
    """On a gymnasium env (CartPole-v1): trials scored by their mean episodic return."""
    sets = [arg for kv in TINY for arg in ("--set", kv)]
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "sweep", "--env", "CartPole-v1", "--param",
         "ppo.learning_rate=uniform:0:3e-3", "--point", "ppo.learning_rate=0", "--samples", "4",
         "--grace", "1", "--steps", str(6 * BATCH), "--cpus", "2", "--out", str(tmp_path), *sets],
        cwd=ROOT, capture_output=True, text=True, timeout=380,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((tmp_path / "sweep.json").read_text())
    trials = record["trials"]
    assert len(trials) == 4 and all(t["error"] is None for t in trials)
    assert {"ppo.learning_rate": 0.0} in [t["settings"] for t in trials]  # the hopeless trial
    assert sum(t["stopped_early"] for t in trials) >= 1, trials
    assert all(t["iterations"] >= 1 for t in trials) and record["grace_period"] == 1
    assert not _ray_left(), "Ray processes outlived the sweep"


@pytest.mark.timeout(400)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_of_a_sweep_saves_the_trials_and_leaves_no_ray_process(
    tmp_path: Path, signum: int
) -> None:
    """Ctrl-C (SIGINT to the terminal's whole process group) or SIGTERM (to the command): the
    sweep exits as interrupted, every trial's run directory holds a checkpoint of a whole
    iteration it recorded, and no Ray process is left."""
    assert not _ray_left(), "a Ray instance is already running"
    sets = [arg for kv in TINY for arg in ("--set", kv)]
    sweep = subprocess.Popen(
        [sys.executable, "-m", "snnkart.cli", "sweep", "--param",
         "ppo.learning_rate=loguniform:1e-4:1e-3", "--samples", "2", "--grace", "1000",
         "--steps", str(1000 * BATCH), "--cpus", "2", "--out", str(tmp_path), *sets],
        cwd=ROOT, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, preexec_fn=_foreground_sigint,
    )  # fmt: skip
    deadline = time.monotonic() + 240
    while len(_saved_steps(tmp_path)) < 2 or min(_saved_steps(tmp_path).values()) < 2 * BATCH:
        assert time.monotonic() < deadline and sweep.poll() is None, "trials did not start"
        time.sleep(0.5)
    if signum == signal.SIGINT:
        os.killpg(sweep.pid, signal.SIGINT)
    else:
        os.kill(sweep.pid, signal.SIGTERM)
    _, stderr = sweep.communicate(timeout=150)
    assert sweep.returncode == 128 + signum, stderr[-3000:]
    assert "interrupted" in stderr
    assert not _ray_left(), "Ray processes outlived the sweep"
    record = json.loads((tmp_path / "sweep.json").read_text())
    assert record["interrupted"] is True and len(record["trials"]) == 2
    for run_dir, step in _saved_steps(tmp_path).items():
        lines = (run_dir / "metrics.jsonl").read_text().splitlines()
        assert step % BATCH == 0 and step >= 2 * BATCH
        assert step >= (len(lines) - 1) * BATCH  # at most the iteration under way is lost


def _foreground_sigint() -> None:
    """In the child: Ctrl-C as in a terminal's foreground job, even when the suite itself runs
    with SIGINT ignored (started in the background by a non-interactive shell, as CI may)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _saved_steps(out: Path) -> dict[Path, int]:
    steps = {}
    for meta in out.glob("*/checkpoint.json"):
        try:
            steps[meta.parent] = int(json.loads(meta.read_text())["global_step"])
        except (OSError, ValueError, KeyError):
            continue
    return steps


@pytest.mark.timeout(400)
def test_a_study_runs_its_trainings_as_tune_trials(tmp_path: Path) -> None:
    """``snnkart study --ray``: the same runs, trained as Tune trials, then evaluated and
    summarised as on the local pool; no Ray process left."""
    assert not _ray_left(), "a Ray instance is already running"
    cfg = tmp_path / "study.toml"
    cfg.write_text(
        'schema = "snnkart/study-config/v1"\ndata = "tuning"\nenvs = ["grid"]\npolicies = ["ann", "snn"]\n'
        f"seeds = [1]\nsteps = {2 * BATCH}\neval_episodes = 1\ndeploy_episodes = 0\n"  # Lava: test_study
        f"sets = {json.dumps(TINY)}\n"
    )
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "study", str(cfg), "--out", str(tmp_path / "out"),
         "--ray", "--jobs", "2"],
        cwd=ROOT, capture_output=True, text=True, timeout=380,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    record = json.loads((tmp_path / "out" / "study.json").read_text())
    assert [(r["name"], r["steps"]) for r in record["runs"]] == [
        ("small_S-grid-ann-s1", 2 * BATCH), ("small_S-grid-snn-s1", 2 * BATCH)]  # fmt: skip
    launch = json.loads((tmp_path / "out" / "runs" / "launch.json").read_text())
    assert launch["backend"] == "ray"
    assert not _ray_left(), "Ray processes outlived the study"
