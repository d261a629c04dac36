"""The launcher and ``snnkart sweep`` on a real local Ray instance (the ``ray`` extra): the same
list of runs as the local pool, and an Optuna search in which ASHA stops trials early. Each test
starts and stops its own Ray and leaves no Ray process behind."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_launch import BATCH, TINY, _specs

ray = pytest.importorskip("ray", reason="optional: the ray extra is not installed "
                          "(pip install -e '.[ray]')")  # fmt: skip
ROOT = Path(__file__).resolve().parents[1]


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

    assert not _ray_processes(), "a Ray instance is already running"
    results = run_on_ray(_specs(2), tmp_path, cpus=2)
    assert [(r.name, r.status, r.global_step) for r in results] == [
        ("ann-s1", "done", 2 * BATCH), ("snn-s2", "done", 2 * BATCH)]  # fmt: skip
    record = json.loads((tmp_path / "launch.json").read_text())
    assert record["backend"] == "ray" and len(record["runs"]) == 2
    assert 'policy = "snn"' in (tmp_path / "snn-s2" / "config.toml").read_text()
    assert not _ray_processes(), "Ray processes outlived the launcher"
    # resumable: a finished list is reused without starting Ray's trials again
    again = run_on_ray(_specs(2), tmp_path, cpus=2)
    assert [r.status for r in again] == ["reused", "reused"]


@pytest.mark.timeout(400)
def test_sweep_stops_weak_trials_early(tmp_path: Path) -> None:
    sets = [arg for kv in TINY for arg in ("--set", kv)]
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "sweep", "--param",
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
    assert not _ray_processes(), "Ray processes outlived the sweep"
