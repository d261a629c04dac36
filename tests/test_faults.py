"""Fault injection: the real commands, as subprocesses, under CPU load (a busy process on each
core), interrupted at named phases and at seeded random moments, killed, and starved of disk.

Every case checks that the command ends within 10 s of the fault, says what happened, exits
with the right status (130 after Ctrl-C, 143 after SIGTERM, non-zero after a failure), and
leaves no process and no shared-memory segment behind; training cases also check that the run
resumes from a checkpoint that was saved.

Named phases are reached through the test-only fault points of :mod:`snnkart.faults`
(``SNNKART_FAULT``); each case checks from the fault log that its phase was reached. The random
draws are seeded: the seed is printed, and ``SNNKART_FAULT_SEED=<seed>`` replays a run.
Run the suite alone with ``pytest -m faults``; the counts per phase are printed at the end.
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import contextlib
import random
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from process_marks import SEGMENT_SCRIPT, ShmWatch, marked_processes, shm_segments
from tiny_runs import train_tiny

from snnkart.export.nir_export import export_nir
from snnkart.rl.checkpoint import load_checkpoint
from snnkart.rl.trained import load_run

pytestmark = pytest.mark.faults

SUBPROCESS_ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "COLUMNS": "200", "NO_COLOR": "1"}
FAULT_BOUND_S = 10.0
"""Every command must have ended this long after its fault."""
SEED = int(os.environ.get("SNNKART_FAULT_SEED") or random.SystemRandom().randrange(10**6))
RANDOM_DRAWS = int(os.environ.get("SNNKART_FAULT_DRAWS") or 4)
"""Random mid-episode interrupts per run (each run draws new ones from its printed seed; CI's
runs add up: ``SNNKART_FAULT_DRAWS=50`` for a long soak)."""
PHASE_COUNTS: Counter[str] = Counter()
"""Faults injected per phase in this run (printed in the terminal summary by conftest)."""
SLOWEST: dict[str, float] = {}
"""The longest time from a fault to the command's end, per phase."""

TRAIN_ARGS = [
    "train", "--env", "grid", "--policy", "ann", "--track", "small_S",
    "--set", "ppo.num_envs=2", "--set", "ppo.rollout_steps=64", "--set", "ppo.update_epochs=1",
    "--set", "ppo.num_minibatches=2", "--set", "run.tensorboard=false",
    "--set", "run.checkpoint_every=1",
]  # fmt: skip
BATCH = 2 * 64


# -- processes, shared memory, load ----------------------------------------------------------


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


@pytest.fixture(scope="module", autouse=True)
def cpu_load() -> Iterator[None]:
    """A busy process on each core for the whole suite."""
    busy = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"])
        for _ in range(os.cpu_count() or 2)
    ]
    try:
        yield
    finally:
        for p in busy:
            p.kill()
            p.wait()


@pytest.fixture(scope="module", autouse=True)
def announce_seed() -> None:
    print(f"\nfault suite seed {SEED} (replay: SNNKART_FAULT_SEED={SEED})")


# -- running a faulted command ---------------------------------------------------------------


@dataclass
class Outcome:
    args: list[str]
    fault: str | None
    returncode: int
    stdout: str
    stderr: str
    fired: list[str]
    took_s: float
    """From the fault (or the test's own signal) to the command's end."""

    def context(self) -> str:
        return (
            f"args {self.args}, fault {self.fault!r}, rc {self.returncode}, fired {self.fired}, "
            f"{self.took_s:.2f} s\nstdout: {self.stdout[-1500:]}\nstderr: {self.stderr[-2500:]}"
        )


def run_faulted(
    args: list[str],
    tmp: Path,
    fault: str | None = None,
    env: dict[str, str] | None = None,
    act: Callable[[subprocess.Popen, str, Path], float | None] | None = None,
    timeout: float = 120.0,
    fsize: int | None = None,
) -> Outcome:
    """Run ``snnkart ARGS`` in a session of its own (so a fault point's signal to its process
    group is a terminal's Ctrl-C) with ``SNNKART_FAULT=fault``; ``act(proc, mark, log)`` may
    act on it from outside and returns the time of its fault. Fails if the command does not
    end, or leaves processes or shared memory behind."""
    mark = uuid.uuid4().hex
    log = tmp / f"fault-{mark}.log"
    full_env = {**SUBPROCESS_ENV, **(env or {}), "SNNKART_TEST_MARK": mark}
    full_env["SNNKART_FAULT_LOG"] = str(log)
    if fault:
        full_env["SNNKART_FAULT"] = fault

    def child_setup() -> None:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # as in a terminal's foreground job
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    out_file, err_file = tmp / f"stdout-{mark}", tmp / f"stderr-{mark}"
    with open(out_file, "wb") as out, open(err_file, "wb") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "snnkart.cli", *args],
            stdout=out,
            stderr=err,
            env=full_env,
            start_new_session=True,
            preexec_fn=child_setup,
        )
    shm = ShmWatch(mark).start()
    fired_at = None
    try:
        if act is not None:
            fired_at = act(proc, mark, log)
        deadline = time.monotonic() + timeout
        while proc.poll() is None:
            if fired_at is None and log.exists() and fault and not fault.endswith("SIGCONT"):
                fired_at = _fired_at(log)
            late = fired_at is not None and time.monotonic() > fired_at + FAULT_BOUND_S + 5
            if late or time.monotonic() > deadline:
                raise TimeoutError("late" if late else "timeout")
            time.sleep(0.05)
    except BaseException as exc:
        for pid, _ in marked_processes(mark):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        proc.wait()
        shm.stop()
        when = (
            f"within {FAULT_BOUND_S + 5:.0f} s of its fault"
            if str(exc) == "late"
            else f"within {timeout:.0f} s"
        )
        pytest.fail(
            f"snnkart {args} (fault {fault!r}) did not end {when}; killed ({exc!r}).\n"
            f"stderr: {err_file.read_text(errors='replace')[-2500:]}",
            pytrace=False,
        )
    stdout = out_file.read_bytes()
    stderr = err_file.read_bytes()
    ended = time.monotonic()
    fired = log.read_text().splitlines() if log.exists() else []
    if fired_at is None:
        fired_at = _fired_at(log)
    outcome = Outcome(
        args, fault, proc.returncode, stdout.decode(), stderr.decode(), fired,
        ended - fired_at if fired_at is not None else float("nan"),
    )  # fmt: skip
    # The worker reaps its Lava session before the command exits; /proc may lag a moment.
    deadline = time.monotonic() + 1.0
    while marked_processes(mark) and time.monotonic() < deadline:
        time.sleep(0.05)
    shm.stop()
    left = marked_processes(mark)
    for pid, _ in left:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    assert left == [], f"processes left behind: {left}\n{outcome.context()}"
    leaked = shm.leaked()
    assert not leaked, f"shared memory left behind: {sorted(leaked)}\n{outcome.context()}"
    assert "Traceback" not in outcome.stderr, outcome.context()
    return outcome


def _fired_at(log: Path) -> float | None:
    """When the fault point fired (CLOCK_MONOTONIC is the same in every process); None while
    its line is not completely written yet."""
    text = log.read_text() if log.exists() else ""
    if "\n" not in text:
        return None
    return float(text.split("\n", 1)[0].rsplit("t=", 1)[1])


def assert_interrupted(o: Outcome, signum: int, phase: str) -> None:
    name = signal.Signals(signum).name
    assert o.fired, f"the fault point {phase!r} was never reached\n{o.context()}"
    assert o.returncode == 128 + signum, o.context()
    assert f"interrupted ({name})" in o.stderr, o.context()
    assert o.took_s <= FAULT_BOUND_S, o.context()
    count(f"{phase} {name}", o)


def count(phase: str, o: Outcome) -> None:
    PHASE_COUNTS[phase] += 1
    if o.took_s == o.took_s:  # not NaN
        SLOWEST[phase] = max(SLOWEST.get(phase, 0.0), o.took_s)


# -- deploy on lava-sim ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("fault-policy")
    run = train_tiny(base / "run", "steer", "snn")
    nir_path, _ = export_nir(load_run(run), base / "policy.nir")
    return nir_path


def deploy_args(policy: Path, out: Path, episodes: int = 1000) -> list[str]:
    return ["deploy", str(policy), "--backend", "lava-sim", "--episodes", str(episodes),
            "--out", str(out)]  # fmt: skip


# (phase, extra SNNKART_FAULT text, episodes, cold caches)
DEPLOY_PHASES = {
    "lava-spawn": ("", 1000, False),  # the worker just started, the parent waits for it
    "lava-startup": ("", 1000, False),  # in the worker, before the runtime forks
    "lava-startup-cold": ("", 1000, True),  # the same with nothing compiled or cached
    "lava-fork": ("+0.05", 1000, False),  # 50 ms into create_runtime: while it forks
    # in the env's wall-contact callback, which pymunk calls from C through cffi: cffi drops an
    # exception raised there, so a Ctrl-C taken as an exception was lost and the deploy ran on
    "physics-callback": ("", 1000, False),
    "window": ("@5", 1000, False),  # request sent, reply not yet read
    "reply": ("@5", 1000, False),  # the worker has written its reply's header only
    "close": ("", 1, False),  # the final close, after the last episode
}


def _phase_fault(phase: str, signum: int) -> tuple[str, int, dict[str, str]]:
    extra, episodes, cold = DEPLOY_PHASES[phase]
    point = {"lava-startup-cold": "lava-startup", "lava-fork": "lava-startup"}.get(phase, phase)
    env = {}
    if cold:
        cache = Path(tempfile.mkdtemp(prefix="snnkart-cold-"))
        env = {"NUMBA_CACHE_DIR": str(cache / "numba"), "PYTHONPYCACHEPREFIX": str(cache / "pyc")}
    return f"{point}{extra}:{signal.Signals(signum).name}", episodes, env


@pytest.mark.lava
@pytest.mark.timeout(200)
@pytest.mark.parametrize("phase", list(DEPLOY_PHASES))
def test_sigint_at_each_phase_of_a_lava_deploy(policy: Path, tmp_path: Path, phase: str) -> None:
    fault, episodes, env = _phase_fault(phase, signal.SIGINT)
    o = run_faulted(deploy_args(policy, tmp_path / "out", episodes), tmp_path, fault, env)
    assert_interrupted(o, signal.SIGINT, phase)
    assert "no Lava process is left running" in o.stderr, o.context()
    assert not (tmp_path / "out" / "deploy.json").exists(), "a partial record was written"


@pytest.mark.lava
@pytest.mark.timeout(200)
@pytest.mark.parametrize(
    "phase", ["lava-startup", "lava-fork", "physics-callback", "window", "reply", "close"]
)
def test_sigterm_is_handled_like_ctrl_c(policy: Path, tmp_path: Path, phase: str) -> None:
    fault, episodes, env = _phase_fault(phase, signal.SIGTERM)
    o = run_faulted(deploy_args(policy, tmp_path / "out", episodes), tmp_path, fault, env)
    assert_interrupted(o, signal.SIGTERM, phase)
    assert "no Lava process is left running" in o.stderr, o.context()
    assert not (tmp_path / "out" / "deploy.json").exists()


def random_draws(n: int, seed: int) -> list[tuple[int, float, int]]:
    """(env step, delay in s, signal) for ``n`` random moments mid-episode."""
    rng = random.Random(seed)
    return [
        (rng.randint(2, 60), round(rng.uniform(0.0, 0.012), 4),
         rng.choice([signal.SIGINT, signal.SIGTERM]))
        for _ in range(n)
    ]  # fmt: skip


@pytest.mark.lava
@pytest.mark.timeout(900)
def test_interrupts_at_random_moments_mid_episode(policy: Path, tmp_path: Path) -> None:
    """The signal is sent from a timer ``delay`` after env step ``n`` begins, so it lands
    anywhere in the step: the env's physics (pymunk callbacks), the Lava exchange, the
    references' arithmetic or the bookkeeping between them."""
    for k, (n, delay, signum) in enumerate(random_draws(RANDOM_DRAWS, SEED)):
        fault = f"step@{n}+{delay}:{signal.Signals(signum).name}"
        print(f"draw {k} (seed {SEED}): {fault}")
        out = tmp_path / f"out{k}"
        o = run_faulted(deploy_args(policy, out), tmp_path, fault)
        assert_interrupted(o, signum, "random mid-episode")
        assert not (out / "deploy.json").exists()


def _wait_for_steps(log: Path, proc: subprocess.Popen, timeout: float = 90.0) -> None:
    deadline = time.monotonic() + timeout
    while not log.exists() and time.monotonic() < deadline:
        assert proc.poll() is None, "the deploy ended before it could be hurt"
        time.sleep(0.05)
    assert log.exists(), "the deploy never reached its 20th env step"


def _kill_worker(proc: subprocess.Popen, mark: str, log: Path) -> float:
    _wait_for_steps(log, proc)
    (worker,) = _children(proc.pid)
    os.kill(worker, signal.SIGKILL)
    return time.monotonic()


def _kill_lava_process(proc: subprocess.Popen, mark: str, log: Path) -> float:
    _wait_for_steps(log, proc)
    (worker,) = _children(proc.pid)
    newest = max(_children(worker))  # a process model: forked after the runtime's services
    os.kill(newest, signal.SIGKILL)
    return time.monotonic()


@pytest.mark.lava
@pytest.mark.timeout(200)
@pytest.mark.parametrize(
    ("victim", "expected"),
    [(_kill_worker, "the Lava backend died"), (_kill_lava_process, "a Lava process failed")],
    ids=["worker", "lava-process"],
)
def test_a_killed_backend_is_reported_not_waited_for(
    policy: Path, tmp_path: Path, victim: Callable, expected: str
) -> None:
    # SIGCONT to the group is harmless: the fault point only marks the 20th env step
    o = run_faulted(deploy_args(policy, tmp_path / "out"), tmp_path, "step@20:SIGCONT", act=victim)
    assert o.returncode not in (0, 130, 143), o.context()
    assert "error:" in o.stderr and expected in o.stderr, o.context()
    assert o.took_s <= FAULT_BOUND_S, o.context()
    assert not (tmp_path / "out" / "deploy.json").exists()
    count(f"SIGKILL {'worker' if victim is _kill_worker else 'Lava process'}", o)


@pytest.mark.lava
@pytest.mark.timeout(200)
def test_shared_memory_of_another_process_is_not_counted(policy: Path, tmp_path: Path) -> None:
    """Another process (unmarked, as another user's Lava would be) creates and holds a segment
    while the deploy runs: the deploy is not blamed for it (a diff of all of /dev/shm was)."""
    other: list[subprocess.Popen] = []
    name: list[str] = []

    def start_other(proc: subprocess.Popen, mark: str, log: Path) -> None:
        _wait_for_steps(log, proc)
        other.append(subprocess.Popen([sys.executable, "-c", SEGMENT_SCRIPT, "hold"], text=True,
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE))  # fmt: skip
        assert other[0].stdout is not None
        name.append(other[0].stdout.readline().strip())

    before = shm_segments()
    try:
        o = run_faulted(deploy_args(policy, tmp_path / "out", episodes=1), tmp_path,
                        "step@20:SIGCONT", act=start_other)  # fmt: skip
        assert o.returncode == 0, o.context()
        assert name[0] in shm_segments() - before, "the other segment was not there at the check"
    finally:
        for p in other:
            p.communicate("")  # the holder unlinks its segment
    assert name[0] not in shm_segments()


def _kill_everything(proc: subprocess.Popen, mark: str, log: Path) -> float:
    """Stop every process of the deploy, then kill them all: nothing, not even Python's
    resource tracker, is left to unlink Lava's shared memory."""
    _wait_for_steps(log, proc)
    pids = [pid for pid, _ in marked_processes(mark)]
    for sig in (signal.SIGSTOP, signal.SIGKILL):
        for pid in pids:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
    return time.monotonic()


@pytest.mark.lava
@pytest.mark.timeout(200)
def test_shared_memory_left_by_the_tree_under_test_is_reported(
    policy: Path, tmp_path: Path
) -> None:
    with pytest.raises(AssertionError, match=r"shared memory left behind: \['psm_") as failed:
        run_faulted(deploy_args(policy, tmp_path / "out"), tmp_path, "step@20:SIGCONT",
                    act=_kill_everything)  # fmt: skip
    for name in re.findall(r"psm_\w+", str(failed.value).split("\n", 1)[0]):
        os.unlink(f"/dev/shm/{name}")  # what the killed deploy left, and only that


# -- deploy a sigma-delta policy on lava-sim (the same worker, another network) ---------------


@pytest.fixture(scope="module")
def sdnn_policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from sigma_delta_policy import write_sigma_delta_policy

    return write_sigma_delta_policy(tmp_path_factory.mktemp("fault-sdnn"), vth=4, vth_in=2)


@pytest.mark.lava
@pytest.mark.timeout(200)
@pytest.mark.parametrize("phase", ["lava-startup", "window", "reply", "close"])
def test_sigint_during_a_sigma_delta_lava_deploy(
    sdnn_policy: Path, tmp_path: Path, phase: str
) -> None:
    fault, episodes, env = _phase_fault(phase, signal.SIGINT)
    o = run_faulted(deploy_args(sdnn_policy, tmp_path / "out", episodes), tmp_path, fault, env)
    assert_interrupted(o, signal.SIGINT, phase)
    assert "no Lava process is left running" in o.stderr, o.context()
    assert not (tmp_path / "out" / "deploy.json").exists()


@pytest.mark.lava
@pytest.mark.timeout(200)
@pytest.mark.parametrize(
    ("victim", "expected"),
    [(_kill_worker, "the Lava backend died"), (_kill_lava_process, "a Lava process failed")],
    ids=["worker", "lava-process"],
)
def test_a_killed_sigma_delta_backend_is_reported_not_waited_for(
    sdnn_policy: Path, tmp_path: Path, victim: Callable, expected: str
) -> None:
    args = deploy_args(sdnn_policy, tmp_path / "out")
    o = run_faulted(args, tmp_path, "step@20:SIGCONT", act=victim)
    assert o.returncode not in (0, 130, 143), o.context()
    assert "error:" in o.stderr and expected in o.stderr, o.context()
    assert o.took_s <= FAULT_BOUND_S, o.context()
    assert not (tmp_path / "out" / "deploy.json").exists()


# -- train -----------------------------------------------------------------------------------


def _saved_step(run_dir: Path) -> int:
    _, meta = load_checkpoint(run_dir / "checkpoint.pt")
    return int(meta["global_step"])


def _check_resumes(run_dir: Path, tmp: Path) -> None:
    """``--resume`` continues from a whole saved iteration and finishes one more."""
    step = _saved_step(run_dir)
    state, meta = load_checkpoint(run_dir / "checkpoint.pt")
    assert int(state["progress"]["global_step"]) == step  # the .pt and its metadata agree
    assert step % BATCH == 0, f"step {step} is not a whole number of iterations"
    assert int(meta["iteration"]) * BATCH == step, "not the end of a whole iteration"
    o = run_faulted(["train", "--resume", "--out", str(run_dir), "--steps", str(step + BATCH)], tmp)
    assert o.returncode == 0, o.context()
    assert f"resuming at step {step:,}" in o.stderr, o.context()
    assert _saved_step(run_dir) == step + BATCH


def _interrupt_training_after(delay: float, signum: int) -> Callable:
    def act(proc: subprocess.Popen, mark: str, log: Path) -> float:
        deadline = time.monotonic() + 90
        while not log.exists():  # the first checkpoint has been written (see the fault)
            assert proc.poll() is None and time.monotonic() < deadline, "training did not start"
            time.sleep(0.02)
        time.sleep(delay)
        os.killpg(proc.pid, signum)
        return time.monotonic()

    return act


@pytest.mark.timeout(300)
def test_training_interrupted_at_random_moments_resumes(tmp_path: Path) -> None:
    rng = random.Random(SEED + 1)
    for k, signum in enumerate([signal.SIGINT, signal.SIGTERM]):
        delay = round(rng.uniform(0.0, 1.5), 3)
        print(f"train draw {k} (seed {SEED}): {signal.Signals(signum).name} {delay} s after "
              "the first checkpoint")  # fmt: skip
        run_dir = tmp_path / f"run{k}"
        args = [*TRAIN_ARGS, "--steps", "200000", "--out", str(run_dir)]
        o = run_faulted(
            args, tmp_path, "checkpoint:SIGCONT", act=_interrupt_training_after(delay, signum)
        )
        assert_interrupted(o, signum, "train random")
        assert f"checkpoint saved at step {_saved_step(run_dir):,}" in o.stderr, o.context()
        _check_resumes(run_dir, tmp_path)


@pytest.mark.timeout(300)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_training_interrupted_while_writing_a_checkpoint_resumes(
    tmp_path: Path, signum: int
) -> None:
    run_dir = tmp_path / "run"
    args = [*TRAIN_ARGS, "--steps", "200000", "--out", str(run_dir)]
    # checkpoint 3 is iteration 2's checkpoint.pt, written while iteration 1's is on disk
    o = run_faulted(args, tmp_path, f"checkpoint@3:{signal.Signals(signum).name}")
    assert_interrupted(o, signum, "train checkpoint-write")
    assert f"checkpoint saved at step {_saved_step(run_dir):,}" in o.stderr, o.context()
    _check_resumes(run_dir, tmp_path)


# -- disks that fail -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run of 2 iterations (256 steps), trained once and copied by each test."""
    run_dir = tmp_path_factory.mktemp("trained") / "run"
    o = run_faulted([*TRAIN_ARGS, "--steps", str(2 * BATCH), "--out", str(run_dir)],
                    run_dir.parent)  # fmt: skip
    assert o.returncode == 0, o.context()
    return run_dir


def _copy_run(src: Path, dst: Path) -> Path:
    subprocess.run(["cp", "-a", str(src), str(dst)], check=True)
    return dst


def _no_temp_files(run_dir: Path) -> None:
    left = [p.name for p in run_dir.rglob(".*") if p.is_file()]
    assert left == [], f"temporary files left behind: {left}"


def _assert_clean_write_failure(o: Outcome, run_dir: Path, step: int, reason: str) -> None:
    assert o.returncode == 2, o.context()
    assert "error:" in o.stderr and reason in o.stderr, o.context()
    assert f"last good checkpoint ({run_dir / 'checkpoint.pt'}, step {step:,}) is intact" in (
        " ".join(o.stderr.split())
    ), o.context()
    assert _saved_step(run_dir) == step  # loads, and is the one that was there


@pytest.mark.timeout(200)
def test_full_disk_while_writing_a_checkpoint(trained: Path, tmp_path: Path) -> None:
    """A file-size limit (RLIMIT_FSIZE) smaller than a checkpoint: the write fails with EFBIG
    as on a full disk (Python ignores SIGXFSZ)."""
    run_dir = _copy_run(trained, tmp_path / "run")
    step = _saved_step(run_dir)
    limit = (run_dir / "checkpoint.pt").stat().st_size // 2
    resume = ["train", "--resume", "--out", str(run_dir), "--steps", str(step + 4 * BATCH)]
    o = run_faulted(resume, tmp_path, fsize=limit)
    _assert_clean_write_failure(o, run_dir, step, "File too large")
    _no_temp_files(run_dir)
    count("full disk: checkpoint", o)


@contextlib.contextmanager
def read_only_later(tmp: Path) -> Iterator[tuple[Path, Callable[[], None]]]:
    """A bind mount of a fresh directory, and a function that makes it read-only (a real
    read-only file system: CI runs as root, so permissions alone never fail)."""
    if os.geteuid() != 0:
        pytest.skip("optional: mounting a read-only file system needs root")
    src, mnt = tmp / "src", tmp / "mnt"
    src.mkdir()
    mnt.mkdir()
    subprocess.run(["mount", "--bind", str(src), str(mnt)], check=True)
    try:
        yield mnt, lambda: subprocess.run(["mount", "-o", "remount,bind,ro", str(mnt)], check=True)
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def _freeze_then(action: Callable[[], None]) -> Callable:
    """For a ``phase:SIGSTOP`` fault: when the command has stopped itself, act, continue it."""

    def act(proc: subprocess.Popen, mark: str, log: Path) -> float:
        deadline = time.monotonic() + 120
        while True:
            state = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            if state == "T":
                break
            assert proc.poll() is None and time.monotonic() < deadline, "never reached the phase"
            time.sleep(0.02)
        action()
        os.killpg(proc.pid, signal.SIGCONT)
        return time.monotonic()

    return act


@pytest.mark.timeout(200)
def test_read_only_run_directory_while_writing_a_checkpoint(trained: Path, tmp_path: Path) -> None:
    with read_only_later(tmp_path) as (mnt, make_read_only):
        run_dir = _copy_run(trained, mnt / "run")
        step = _saved_step(run_dir)
        resume = ["train", "--resume", "--out", str(run_dir), "--steps", str(step + 4 * BATCH)]
        # stop while iteration 3's checkpoint is written (its .pt is in a temporary file)
        o = run_faulted(resume, tmp_path, "checkpoint:SIGSTOP", act=_freeze_then(make_read_only))
        _assert_clean_write_failure(o, run_dir, step, "Read-only file system")
        count("read-only: checkpoint", o)


@pytest.mark.lava
@pytest.mark.timeout(200)
def test_read_only_deploy_directory_while_writing_the_record(policy: Path, tmp_path: Path) -> None:
    with read_only_later(tmp_path) as (mnt, make_read_only):
        out = mnt / "out"
        o = run_faulted(
            deploy_args(policy, out, episodes=2), tmp_path, "deploy-write:SIGSTOP",
            act=_freeze_then(make_read_only),
        )  # fmt: skip
        assert o.returncode == 2, o.context()
        assert "deploy.json could not be written: Read-only file system" in o.stderr, o.context()
        assert "lava-sim (fixed) on steer/small_S, 2 episodes" in o.stdout, o.context()
        assert not (out / "deploy.json").exists()
        # and a directory that is read-only from the start fails before Lava starts
        o = run_faulted(deploy_args(policy, out, episodes=2), tmp_path)
        assert o.returncode == 2 and "cannot write results to" in o.stderr, o.context()
        assert "lava-sim (fixed)" not in o.stdout, o.context()
        count("read-only: deploy.json", o)


@pytest.mark.timeout(200)
def test_full_disk_while_writing_the_deploy_record(policy: Path, tmp_path: Path) -> None:
    """A one-page tmpfs (root) holds the pre-flight probe but not the record of 30 episodes."""
    if os.geteuid() != 0:
        pytest.skip("optional: mounting a small tmpfs needs root")
    mnt = tmp_path / "small"
    mnt.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4k", "tmpfs", str(mnt)], check=True)
    try:
        args = ["deploy", str(policy), "--backend", "nir-ref", "--episodes", "30",
                "--out", str(mnt / "out")]  # fmt: skip
        o = run_faulted(args, tmp_path)
        assert o.returncode == 2, o.context()
        assert "deploy.json could not be written: No space left on device" in o.stderr, o.context()
        assert "nir-ref (fixed) on steer/small_S, 30 episodes" in o.stdout, o.context()
        assert list((mnt / "out").iterdir()) == [], "a partial file was left"
        count("full disk: deploy.json", o)
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)
