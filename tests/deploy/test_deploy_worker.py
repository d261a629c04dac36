"""The Lava worker's life: stopped once and leaving no open file, a missing Lava failing clearly,
Ctrl-C to the process group stopping everything; and the backend registry."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from deploy_helpers import (
    DT,
    SUBPROCESS_ENV,
    plain_chain_graph,
)
from process_marks import ShmWatch, marked_processes

from snnkart.backends.lava_params import lava_spec
from snnkart.backends.lava_sim import LavaWorker
from snnkart.backends.network import chain_from_graph


@pytest.mark.lava
@pytest.mark.timeout(120)
@pytest.mark.parametrize("how", ["close", "kill"])
def test_a_stopped_lava_worker_leaves_no_open_files_and_is_stopped_once(
    how: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After close() or kill(), the worker's pipes and its stderr file are closed (the tail of
    its output is kept for messages), and a second kill() signals nothing: the session's id
    may be another process's by then."""
    from snnkart.backends import lava_sim

    chain = chain_from_graph(plain_chain_graph((8,), n_in=3, seed=1), DT)
    worker = LavaWorker(lava_spec(chain, 4, "float64", None))
    worker.window(np.zeros((4, 8)))
    stops: list[int] = []
    real = lava_sim.stop_session
    monkeypatch.setattr(
        lava_sim, "stop_session", lambda sid, **kw: (stops.append(sid), real(sid, **kw))
    )
    getattr(worker, how)()
    assert worker.proc.poll() is not None
    assert worker.stderr.closed and worker.proc.stdin.closed and worker.proc.stdout.closed
    assert worker not in lava_sim._LIVE
    assert not lava_sim._session_members(worker.proc.pid)
    worker.kill()
    worker.close()
    assert stops == [worker.proc.pid], stops
    with pytest.raises(lava_sim.LavaBackendError, match="stopped"):
        worker.window(np.zeros((4, 8)))


# -- Lava missing ------------------------------------------------------------------------------


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_deploy_without_lava_fails_clearly(exported: Path, tmp_path: Path) -> None:
    block = tmp_path / "block"
    (block / "lava").mkdir(parents=True)
    (block / "lava" / "__init__.py").write_text('raise ImportError("blocked for the test")\n')
    env = dict(SUBPROCESS_ENV)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(block), env.get("PYTHONPATH")) if p)
    out = tmp_path / "out"
    args = ["deploy", str(exported), "--backend", "lava-sim", "--episodes", "1", "--out", str(out)]
    t0 = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=90,
    )
    elapsed = time.perf_counter() - t0
    assert result.returncode != 0, result.stdout
    err = " ".join(result.stderr.split())
    assert "Traceback" not in result.stderr, result.stderr
    assert "error:" in err and "Lava" in err and "Python 3.10" in err, result.stderr
    assert "blocked for the test" in err, result.stderr  # the cause is passed on
    assert not (out / "deploy.json").exists()
    assert elapsed < 60


# -- Ctrl-C to the process group mid-episode ---------------------------------------------------


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_sigint_to_the_process_group_stops_everything(exported: Path, tmp_path: Path) -> None:
    mark = uuid.uuid4().hex
    shm = ShmWatch(mark).start()  # the segments this deploy's processes hold, not another run's
    out = tmp_path / "out"
    args = [
        "deploy",
        str(exported),
        "--backend",
        "lava-sim",
        "--episodes",
        "500",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "snnkart.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**SUBPROCESS_ENV, "SNNKART_TEST_MARK": mark},
        start_new_session=True,
        # Ctrl-C as in a terminal's foreground job, even if the suite runs with SIGINT ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            procs = marked_processes(mark)
            if any("lava_worker" in cmd for _, cmd in procs) and len(procs) >= 4:
                break  # the worker and its Lava runtime processes are up
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        else:
            pytest.fail(f"the Lava worker did not start: {marked_processes(mark)}")
        time.sleep(3.0)  # ~250 env steps: well into the deploy, in the middle of an episode
        assert proc.poll() is None, "the deploy ended before it could be interrupted"
        shm.sample()
        assert shm.seen  # Lava's shared memory exists while it runs
        os.killpg(proc.pid, signal.SIGINT)
        t0 = time.monotonic()
        stdout, stderr = proc.communicate(timeout=10)
        stopped = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode != 0, (stdout, stderr)
    assert stopped < 10
    assert not (out / "deploy.json").exists()  # no partial record
    deadline = time.monotonic() + 3
    while time.monotonic() < deadline and marked_processes(mark):
        time.sleep(0.1)
    shm.stop()
    assert marked_processes(mark) == [], "processes of the deploy survived Ctrl-C"
    assert shm.leaked(grace_s=3.0) == set(), "Lava's shared memory was left in /dev/shm"
    print(f"\nSIGINT: exit code {proc.returncode} after {stopped:.2f} s; {stderr.decode()[-300:]}")


def test_backend_registry_names_one_arithmetic_per_precision(exported: Path) -> None:
    from snnkart.backends.registry import arithmetic_for, open_backend
    from snnkart.errors import DeployError

    assert arithmetic_for("lava-sim", "float") == "float64"
    assert arithmetic_for("lava-sim", "fixed") == "fixed"
    assert arithmetic_for("nir-ref", "float") == "float64"
    assert arithmetic_for("nir-ref", "float32") == "float32"
    with pytest.raises(DeployError, match="--precision for lava-sim is float or fixed"):
        arithmetic_for("lava-sim", "float32")
    with pytest.raises(DeployError, match="unknown backend 'loihi'"):
        arithmetic_for("loihi", "fixed")
    with open_backend(exported, "nir-ref", "float", seed=3) as backend:
        assert (backend.name, backend.arithmetic) == ("nir-ref", "float64")
        assert backend.fixed is None and backend.counts.env_steps == 0
