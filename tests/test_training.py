"""PPO training end to end on tiny configs: run directories, checkpoints, resume, Ctrl-C,
error messages, evaluation and replay."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import json
import shutil
import signal
import subprocess
import sys
import time
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import nir
import numpy as np
import pytest
import tomli_w
import torch
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.cli import app
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.envs.spec import ENV_REVISION, env_spec, spec_hash
from snnkart.eval.episodes import EVAL_SCHEMA, EvalSummary, run_episodes
from snnkart.export.nir_export import export_nir
from snnkart.rl.checkpoint import (
    CHECKPOINT_SCHEMA,
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
from snnkart.rl.config import ConfigError, TrainConfig, load_config
from snnkart.rl.ppo import RunError, Trainer
from snnkart.rl.trained import TorchPredictor, load_run

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SNNKART = Path(sys.executable).with_name("snnkart")

TINY = [
    "ppo.num_envs=2",
    "ppo.rollout_steps=64",
    "ppo.update_epochs=2",
    "ppo.num_minibatches=2",
    "run.tensorboard=false",
]
BATCH = 2 * 64
STEPS = 2 * BATCH  # two iterations

EXPECTED_KEYS = {
    "iteration",
    "global_step",
    "charts/episodic_return",
    "charts/SPS",
    "charts/first_finish_step",
    "charts/cumulative_finishes",
    "losses/approx_kl",
    "losses/clipfrac",
    "losses/explained_variance",
    "losses/first_minibatch_max_ratio_deviation",
}
SNN_KEYS = {"snn/firing_rate_layer1", "snn/firing_rate_layer2"}


def tiny_config(
    env: str = "grid",
    policy: str = "ann",
    total_steps: int = STEPS,
    extra: list[str] | None = None,
) -> TrainConfig:
    return load_config(
        overrides={"env": env, "policy": policy, "total_steps": total_steps, "track": "small_S"},
        sets=[*TINY, *(extra or [])],
    )


def train(cfg: TrainConfig, run_dir: Path, resume: bool = False) -> Trainer:
    """Train ``cfg`` into ``run_dir``; a resume runs to ``cfg``'s length (given explicitly, as
    ``--steps`` does: a resume alone keeps the run's own)."""
    trainer = Trainer(cfg, run_dir, resume=resume, total_steps=cfg.total_steps if resume else None)
    try:
        trainer.train()
    finally:
        trainer.close()
    return trainer


def metrics(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Trainer]]:
    """A tiny ANN and a tiny SNN run on grid/small_S, shared by the tests below."""
    root = tmp_path_factory.mktemp("runs")
    runs = {}
    for policy in ("ann", "snn"):
        run_dir = root / f"grid-{policy}"
        runs[policy] = (run_dir, train(tiny_config("grid", policy), run_dir))
    return runs


# -- end to end ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("env", "policy", "extra"),
    [
        ("grid", "ann", []),
        ("grid", "snn", []),
        ("gazebo", "ann", []),
        ("gazebo", "snn", []),
        ("steer", "ann", []),
        ("steer", "snn", []),
        ("steer", "ann", ["action_mode=continuous"]),
        ("gazebo", "snn", ["action_mode=continuous"]),
        ("grid", "snn", ["snn.encoding=rate"]),
        ("steer", "snn", ["snn.neuron=cuba", "snn.learn_alpha=true"]),
    ],
)
def test_tiny_training_run(tmp_path: Path, env: str, policy: str, extra: list[str]) -> None:
    run_dir = tmp_path / "run"
    trainer = train(tiny_config(env, policy, extra=extra), run_dir)
    assert trainer.progress.global_step == STEPS
    assert trainer.progress.iteration == 2
    assert not trainer.interrupted

    saved = tomllib.loads((run_dir / "config.toml").read_text())
    assert saved["env"] == env and saved["policy"] == policy
    assert saved["total_steps"] == STEPS and saved["ppo"]["num_envs"] == 2
    if extra == ["action_mode=continuous"]:
        assert saved["action_mode"] == "continuous"
        assert not trainer.policy.discrete
    if "snn.encoding=rate" in extra:
        assert saved["snn"]["encoding"] == "rate"
    if "snn.neuron=cuba" in extra:  # snntorch Synaptic layers, trained through the fused kernel
        assert saved["snn"]["neuron"] == "cuba"
        assert all(type(lif).__name__ == "Synaptic" for lif in trainer.policy.snn.lifs)
        assert trainer.policy.snn.lif1.alpha.item() != 0.5  # learned: it moved
        # no biases between spiking layers (Lava adds a bias to the voltage, NIR to the current)
        assert saved["snn"]["hidden_bias"] is False and trainer.policy.snn.fc2.bias is None
        path, _ = export_nir(load_run(run_dir), tmp_path / "policy.nir")
        graph = nir.read(path)
        assert isinstance(graph.nodes["1"], nir.CubaLIF) and isinstance(
            graph.nodes["2"], nir.Linear
        )
        spec = Manifest.read(manifest_path(path)).layers[0]
        assert spec.alpha == pytest.approx(trainer.policy.snn.lif1.alpha.item(), abs=1e-6)

    for name in ("checkpoint.pt", "checkpoint.json", "checkpoints/iter_000002.pt"):
        assert (run_dir / name).is_file(), name
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    assert meta["global_step"] == STEPS and meta["policy"] == policy

    records = metrics(run_dir)
    assert [r["iteration"] for r in records] == [1, 2]
    assert [r["global_step"] for r in records] == [BATCH, 2 * BATCH]
    keys = EXPECTED_KEYS | (SNN_KEYS if policy == "snn" else set())
    for r in records:
        assert keys <= r.keys(), keys - r.keys()
        assert r["charts/SPS"] > 0
        assert 0.0 <= r["losses/clipfrac"] <= 1.0
        assert np.isfinite(r["losses/approx_kl"])
        if policy == "snn":
            for k in SNN_KEYS:
                assert 0.0 <= r[k] <= 1.0
        else:
            assert not SNN_KEYS & r.keys()

    trajectories = sorted((run_dir / "trajectories").glob("iter_*.npz"))
    assert [p.name for p in trajectories] == ["iter_000001.npz", "iter_000002.npz"]
    with np.load(trajectories[-1]) as data:
        assert data["positions"].shape == (64, 2, 2)
        assert data["episode_end"].shape == (64, 2)
        assert int(data["global_step"]) == STEPS
        assert np.isfinite(data["positions"]).all()


# -- checkpoints -------------------------------------------------------------------------------


def _observations(cfg: TrainConfig, n: int = 40) -> np.ndarray:
    env = cfg.make_env()
    rng = np.random.default_rng(5)
    env.action_space.seed(5)
    obs, _ = env.reset(seed=123)
    out = []
    for _ in range(n):
        out.append(obs)
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, _ = env.reset(seed=int(rng.integers(1000)))
    env.close()
    return np.asarray(out, dtype=np.float32)


@pytest.mark.parametrize("policy", ["ann", "snn"])
def test_checkpoint_roundtrip_gives_the_same_actions(
    trained: dict[str, tuple[Path, Trainer]], policy: str
) -> None:
    run_dir, trainer = trained[policy]
    run = load_run(run_dir)
    assert run.config == trainer.cfg
    assert not run.policy.training

    saved = trainer.policy.state_dict()
    loaded = run.policy.state_dict()
    assert saved.keys() == loaded.keys()
    assert all(torch.equal(saved[k], loaded[k]) for k in saved)
    np.testing.assert_array_equal(run.obs_rms.mean, trainer.obs_rms.mean)
    np.testing.assert_array_equal(run.obs_rms.var, trainer.obs_rms.var)

    predictor = TorchPredictor(run, seed=0)
    clip = trainer.cfg.ppo.clip_obs
    trainer.policy.eval()
    try:
        for raw in _observations(trainer.cfg):
            norm = trainer.obs_rms.normalize(raw[None].astype(np.float64), clip)
            expected = trainer.policy.act_deterministic(
                torch.from_numpy(norm), torch.from_numpy(raw[None])
            )
            assert predictor.predict(raw) == int(expected[0])
            # the actor's raw outputs agree exactly, not just their argmax
            out_trained = trainer.policy.actor_output(
                torch.from_numpy(norm), torch.from_numpy(raw[None]), None
            )[0]
            out_loaded = run.policy.actor_output(
                torch.from_numpy(run.obs_rms.normalize(raw[None], clip)),
                torch.from_numpy(raw[None]),
                None,
            )[0]
            assert torch.equal(out_trained, out_loaded)
    finally:
        trainer.policy.train()


def test_checkpoint_metadata_and_weights_only_load(
    trained: dict[str, tuple[Path, Trainer]],
) -> None:
    run_dir, trainer = trained["ann"]
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    assert meta["schema"] == CHECKPOINT_SCHEMA
    for pkg in ("python", "snnkart", "torch", "snntorch", "gymnasium", "numpy"):
        assert meta["versions"][pkg], pkg
    assert meta["versions"]["torch"] == importlib_metadata.version("torch")
    env = trainer.cfg.make_env()
    try:
        assert meta["env_spec_hash"] == spec_hash(env_spec(env.unwrapped))  # type: ignore[arg-type]
    finally:
        env.close()
    assert meta["env_spec"]["env"] == "grid" and meta["env_spec"]["track"] == "small_S"
    assert meta["config"]["policy"] == "ann"
    assert meta["global_step"] == STEPS and meta["iteration"] == 2

    state = torch.load(run_dir / "checkpoint.pt", map_location="cpu", weights_only=True)
    assert {"policy", "optimizer", "obs_rms", "progress"} <= state.keys()
    assert int(state["progress"]["global_step"]) == STEPS


# -- resume ------------------------------------------------------------------------------------


def test_resume_continues_from_the_checkpoint(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    train(tiny_config("steer", "snn", total_steps=STEPS), run_dir)
    assert [r["global_step"] for r in metrics(run_dir)] == [BATCH, 2 * BATCH]

    longer = tiny_config("steer", "snn", total_steps=2 * STEPS)
    trainer = Trainer(longer, run_dir, resume=True, total_steps=2 * STEPS)
    try:
        assert trainer.progress.global_step == STEPS  # not 0
        assert trainer.progress.iteration == 2
        assert trainer.cfg.total_steps == 2 * STEPS
        trainer.train()
    finally:
        trainer.close()
    assert trainer.progress.global_step == 2 * STEPS

    records = metrics(run_dir)
    assert [r["iteration"] for r in records] == [1, 2, 3, 4]
    assert [r["global_step"] for r in records] == [BATCH * k for k in (1, 2, 3, 4)]
    saved = tomllib.loads((run_dir / "config.toml").read_text())
    assert saved["total_steps"] == 2 * STEPS
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    assert meta["global_step"] == 2 * STEPS and meta["iteration"] == 4
    assert (run_dir / "trajectories" / "iter_000004.npz").is_file()


TIMING = {"charts/SPS", "charts/rollout_SPS", "charts/update_seconds"}


class _StoppedFromOutside(Exception):
    """What a launcher that ends a worker without a signal does (Ray Tune stopping a trial)."""


def test_saving_every_iteration_changes_nothing_and_a_stopped_run_resumes(
    tmp_path: Path,
) -> None:
    """A latest-only checkpoint after every iteration (Tune trials) leaves the run's results
    as they were, and a run stopped from outside resumes from its last whole iteration."""
    cfg = tiny_config("grid", "snn", total_steps=3 * BATCH, extra=["run.checkpoint_every=50"])

    def run(run_dir: Path, every: bool, stop_at: int | None = None) -> None:
        def stop(record: dict[str, Any]) -> None:
            if record["iteration"] == stop_at:
                raise _StoppedFromOutside

        trainer = Trainer(cfg, run_dir, resume=(run_dir / "config.toml").is_file())
        try:
            trainer.train(stop, save_every_iteration=every)
        finally:
            trainer.close()

    run(tmp_path / "plain", every=False)
    run(tmp_path / "every", every=True)
    strip = [{k: v for k, v in r.items() if k not in TIMING} for r in metrics(tmp_path / "plain")]
    assert [{k: v for k, v in r.items() if k not in TIMING}
            for r in metrics(tmp_path / "every")] == strip  # fmt: skip

    stopped = tmp_path / "stopped"
    with pytest.raises(_StoppedFromOutside):
        run(stopped, every=True, stop_at=2)
    meta = json.loads((stopped / "checkpoint.json").read_text())
    assert meta["global_step"] == 2 * BATCH  # the iteration it had just finished
    assert not list((stopped / "checkpoints").glob("*.pt"))  # latest only: no history copies
    run(stopped, every=True)
    assert [r["iteration"] for r in metrics(stopped)] == [1, 2, 3]
    assert json.loads((stopped / "checkpoint.json").read_text())["global_step"] == 3 * BATCH
    # without those saves a run stopped so has no checkpoint: it starts again, and the
    # records it logged before (iterations 1-2) are dropped instead of repeated
    unsaved = tmp_path / "unsaved"
    with pytest.raises(_StoppedFromOutside):
        run(unsaved, every=False, stop_at=2)
    assert not (unsaved / "checkpoint.pt").exists()
    with (unsaved / "metrics.jsonl").open("a") as f:
        f.write('{"iteration": 3, "glo')  # a record cut short by a kill
    run(unsaved, every=False)
    assert [r["iteration"] for r in metrics(unsaved)] == [1, 2, 3]
    assert metrics(unsaved)[0]["charts/episodic_return"] == strip[0]["charts/episodic_return"]


def _foreground_sigint() -> None:
    """In the child: Ctrl-C as in a terminal's foreground job, even when the suite itself runs
    with SIGINT ignored (started in the background by a non-interactive shell)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("policy", ["ann", "snn"])
def test_resume_restores_the_whole_training_state(tmp_path: Path, policy: str) -> None:
    """A run of 4 iterations interrupted after 2 (Ctrl-C, taken at the iteration boundary) and
    resumed: right after the restore, parameters, optimizer state (Adam moments and step),
    observation normaliser, torch's random generator, progress counters and the schedule
    position equal those of the interrupted trainer exactly. (The envs are reset with a fresh
    seed at each start, so the resumed run is not bit-identical to an uninterrupted one; this
    asserts the equality of everything the checkpoint carries instead.)"""
    import signal

    cfg = tiny_config(policy=policy, total_steps=4 * BATCH)
    run_dir = tmp_path / "run"
    first = Trainer(cfg, run_dir)

    def interrupt_after_two(record: dict) -> None:
        if record["iteration"] == 2:
            os.kill(os.getpid(), signal.SIGINT)  # taken as a flag inside train()

    # Ctrl-C as in a terminal, even when the suite runs with SIGINT ignored (started in the
    # background by a non-interactive shell, where faults.caught() leaves SIGINT ignored).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        first.train(interrupt_after_two)
    finally:
        signal.signal(signal.SIGINT, previous)
        first.close()
    assert first.interrupted and first.progress.iteration == 2
    rng_at_interrupt = torch.get_rng_state()  # before Trainer() seeds torch again
    resumed = Trainer(cfg, run_dir, resume=True)
    try:
        for (name, a), (_, b) in zip(
            first.policy.state_dict().items(), resumed.policy.state_dict().items(), strict=True
        ):
            assert torch.equal(a, b), name
        opt_a, opt_b = first.optimizer.state_dict(), resumed.optimizer.state_dict()
        assert opt_a["param_groups"] == opt_b["param_groups"]
        assert opt_a["state"].keys() == opt_b["state"].keys() and opt_a["state"]
        for key, state in opt_a["state"].items():
            for field, value in state.items():
                assert torch.equal(value, opt_b["state"][key][field]), (key, field)
        assert np.array_equal(first.obs_rms.mean, resumed.obs_rms.mean)
        assert np.array_equal(first.obs_rms.var, resumed.obs_rms.var)
        assert first.obs_rms.count == resumed.obs_rms.count
        assert first.progress == resumed.progress
        assert resumed.num_iterations == first.num_iterations == 4  # the schedule's length
        assert torch.equal(torch.get_rng_state(), rng_at_interrupt)
    finally:
        resumed.close()


def test_resume_without_a_run_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(RunError, match="nothing to resume"):
        Trainer(tiny_config(), tmp_path / "empty", resume=True)


def test_ctrl_c_saves_a_checkpoint_and_exits_130(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    cmd = [
        str(SNNKART), "train", "--env", "grid", "--track", "small_S", "--policy", "ann",
        "--steps", "100000000", "--out", str(run_dir),
        *[arg for s in TINY for arg in ("--set", s)],
    ]  # fmt: skip
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "COLUMNS": "200"}
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        preexec_fn=_foreground_sigint,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 90
        metrics_path = run_dir / "metrics.jsonl"
        while not (metrics_path.is_file() and metrics_path.read_text().count("\n") >= 1):
            assert proc.poll() is None, proc.communicate(timeout=10)
            assert time.monotonic() < deadline, "training wrote no metrics within 90 s"
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    output = stdout + stderr
    assert proc.returncode == 130, output
    assert (run_dir / "checkpoint.pt").is_file()
    assert "--resume" in output and "interrupted" in output, output
    assert "Traceback" not in output

    # the checkpoint holds exactly the completed iterations (a partial rollout is dropped)
    records = metrics(run_dir)
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    assert meta["iteration"] == records[-1]["iteration"] == len(records)
    assert meta["global_step"] == records[-1]["global_step"] == len(records) * BATCH

    # and it resumes from there
    done = len(records) * BATCH
    trainer = train(tiny_config(total_steps=done + BATCH), run_dir, resume=True)
    assert trainer.progress.global_step == done + BATCH
    assert [r["iteration"] for r in metrics(run_dir)] == list(range(1, len(records) + 2))


# -- bad inputs --------------------------------------------------------------------------------


def test_unknown_env_names_the_choices() -> None:
    with pytest.raises(ConfigError) as err:
        load_config(overrides={"env": "nope"})
    msg = str(err.value)
    assert "'nope'" in msg
    for name in ("grid", "gazebo", "steer"):
        assert name in msg


def test_missing_track_file_fails_cleanly_in_the_cli(tmp_path: Path) -> None:
    track = tmp_path / "no_such_track.toml"
    result = CliRunner().invoke(
        app,
        ["train", "--track", str(track), "--steps", "256", "--out", str(tmp_path / "run"),
         *[arg for s in TINY for arg in ("--set", s)]],
    )  # fmt: skip
    assert result.exit_code != 0
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "no_such_track" in result.output
    assert "error:" in result.output
    assert not (tmp_path / "run").exists()


def test_misspelled_config_key_in_a_file(tmp_path: Path) -> None:
    path = tmp_path / "train.toml"
    path.write_text('env = "grid"\n[ppo]\nlearnig_rate = 1e-3\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert "ppo.learnig_rate" in msg
    assert "misspelled" in msg
    assert str(path) in msg

    path.write_text('polcy = "snn"\n')
    with pytest.raises(ConfigError, match=r"'polcy'.*misspelled"):
        load_config(path)


def test_checkpoint_for_another_observation_size(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    run_dir, _ = trained["ann"]
    other = tmp_path / "other"
    shutil.copytree(run_dir, other)
    data = tomllib.loads((other / "config.toml").read_text())
    data["env_config"] = {"lidar": {"n_rays": 8}}
    (other / "config.toml").write_text(tomli_w.dumps(data))

    with pytest.raises(CheckpointError) as err:
        load_run(other)
    msg = str(err.value)
    assert "observation size" in msg
    assert "checkpoint.pt" in msg
    # the original still loads
    assert load_run(run_dir).config.env == "grid"


def test_checkpoint_from_an_older_env_revision_is_refused(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    """The observation layout alone does not show that its meaning changed: a checkpoint
    saved before the current env revision is refused, with what to do."""
    run_dir, _ = trained["ann"]
    other = tmp_path / "old"
    shutil.copytree(run_dir, other)
    state, meta = load_checkpoint(other / "checkpoint.pt")
    meta["env_spec"]["revision"] = ENV_REVISION - 1
    meta["env_spec_hash"] = spec_hash(meta["env_spec"])
    save_checkpoint(other / "checkpoint.pt", state, meta)
    with pytest.raises(CheckpointError, match=f"revision {ENV_REVISION - 1}.*retrain"):
        load_run(other)


def test_existing_run_dir_without_resume(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    run_dir, _ = trained["ann"]
    before = (run_dir / "metrics.jsonl").read_text()
    with pytest.raises(RunError, match="--resume"):
        Trainer(tiny_config(), run_dir)
    result = CliRunner().invoke(
        app, ["train", "--env", "grid", "--steps", "256", "--out", str(run_dir)]
    )
    assert result.exit_code != 0
    assert "already holds a run" in result.output and "--resume" in result.output
    assert (run_dir / "metrics.jsonl").read_text() == before  # untouched


def test_eval_and_replay_of_a_non_run_directory(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    runner = CliRunner()
    result = runner.invoke(app, ["eval", str(empty), "--episodes", "1"])
    assert result.exit_code == 2, result.output
    assert "not a run directory" in result.output
    assert not (empty / "eval.json").exists()
    result = runner.invoke(app, ["replay", str(empty), "--out", str(tmp_path / "x.gif")])
    assert result.exit_code == 2, result.output
    assert "not a run directory" in result.output
    assert not (tmp_path / "x.gif").exists()


# -- evaluation and replay ---------------------------------------------------------------------


@pytest.mark.parametrize("policy", ["ann", "snn"])
def test_run_episodes_summary_is_consistent(
    trained: dict[str, tuple[Path, Trainer]], policy: str
) -> None:
    run = load_run(trained[policy][0])
    env = run.config.make_env()
    try:
        results = run_episodes(env, TorchPredictor(run, seed=3), episodes=3, seed=100)
    finally:
        env.close()
    summary = EvalSummary.of(results)
    assert summary.episodes == len(results) == 3
    assert [r.seed for r in results] == [100, 101, 102]
    successes = round(summary.success_rate * summary.episodes)
    assert successes + summary.crashes + summary.stood_still + summary.timeouts == 3
    for r in results:
        outcomes = [r.finished, r.crashed, r.stood_still, r.timed_out]
        assert sum(outcomes) == 1, r
        assert r.length >= 1
        assert (r.lap_time is not None) == r.finished
    assert summary.mean_return == pytest.approx(np.mean([r.episode_return for r in results]))


def test_eval_cli_writes_json(tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]) -> None:
    run_dir, _ = trained["snn"]
    out = tmp_path / "eval.json"
    result = CliRunner().invoke(app, ["eval", str(run_dir), "--episodes", "2", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "2 episodes" in result.output and str(out) in result.output
    record = json.loads(out.read_text())
    assert record["schema"] == EVAL_SCHEMA == "snnkart/eval/v2"
    assert record["summary"]["episodes"] == 2
    assert len(record["episodes"]) == 2
    assert record["policy"] == "snn" and record["env"] == "grid"
    assert record["global_step"] == STEPS


def test_eval_cli_default_output_is_in_the_run_dir(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(trained["ann"][0], run_dir)
    result = CliRunner().invoke(app, ["eval", str(run_dir), "--episodes", "2"])
    assert result.exit_code == 0, result.output
    record = json.loads((run_dir / "eval.json").read_text())
    assert record["schema"] == "snnkart/eval/v2"
    assert record["summary"]["episodes"] == 2


def test_replay_writes_gif_and_mp4(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    run_dir, _ = trained["ann"]
    runner = CliRunner()
    gif = tmp_path / "x.gif"
    result = runner.invoke(app, ["replay", str(run_dir), "--mode", "batch", "--out", str(gif)])
    assert result.exit_code == 0, result.output
    assert gif.is_file() and gif.stat().st_size > 0
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")

    mp4 = tmp_path / "x.mp4"
    result = runner.invoke(
        app, ["replay", str(run_dir), "--mode", "all", "--out", str(mp4), "--every", "4"]
    )
    assert result.exit_code == 0, result.output
    assert mp4.is_file() and mp4.stat().st_size > 0
    assert b"ftyp" in mp4.read_bytes()[:64]


def test_replay_compare_races_the_trained_policies(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    """``replay --compare``: each run's deterministic episode on the first run's track, drawn
    together in the legend's colours; each outcome is what the policy does on its own."""
    import imageio.v2 as iio

    from snnkart.app.replay import run_compare
    from snnkart.app.reporter import Silent
    from snnkart.eval.episodes import run_episodes
    from snnkart.eval.ghosts import RACE_COLOURS

    dirs = [trained["ann"][0], trained["snn"][0]]
    gif = tmp_path / "cmp.gif"
    outcomes = run_compare(dirs, gif, 10_000, None, 4, Silent())
    for run_dir, got in zip(dirs, outcomes, strict=True):
        run = load_run(run_dir)
        (alone,) = run_episodes(run.config.make_env(track=run.track),
                                TorchPredictor(run, seed=10_000), 1, 10_000)  # fmt: skip
        ended = ("finished" if alone.finished else "crashed" if alone.crashed else
                 "stood still" if alone.stood_still else "time limit")  # fmt: skip
        assert got["outcome"].startswith(ended), (got, alone)
    last = np.asarray(list(iio.get_reader(gif))[-1])[..., :3].astype(int)
    panel = last[:, last.shape[1] * 3 // 4 :]
    for colour in RACE_COLOURS[:2]:  # the legend, in each kart's colour
        assert (np.abs(panel - np.array(colour)).sum(axis=-1) < 40).sum() > 20, colour
    runner = CliRunner()
    result = runner.invoke(app, ["replay", *map(str, dirs), "--out", str(tmp_path / "x.gif")])
    assert result.exit_code == 2 and "--compare" in result.output
    result = runner.invoke(app, ["replay", "--compare", *map(str, dirs * 3), "--out", str(gif)])
    assert result.exit_code == 2 and "1 to 4 runs" in result.output


def test_replay_unknown_mode_fails_cleanly(
    tmp_path: Path, trained: dict[str, tuple[Path, Trainer]]
) -> None:
    run_dir, _ = trained["ann"]
    out = tmp_path / "bad.gif"
    result = CliRunner().invoke(
        app, ["replay", str(run_dir), "--mode", "sideways", "--out", str(out)]
    )
    assert result.exit_code == 2, result.output
    assert "sideways" in result.output and "batch" in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert not out.exists()
    assert not list(tmp_path.glob(".bad.gif*"))  # no temp file left behind


# -- learning ----------------------------------------------------------------------------------


# What docs/results.md's earlier learning studies claim, at small scale and in the default run: a grid
# policy trained with the defaults drives a lap in at least 80 % of 20 seeded deterministic
# evaluation episodes. Seeds are fixed; if a change flips one, run 3 seeds before touching it.
# The runs stop once they have learned (two checks in a row, 25k steps apart, at >= 80 % on
# their own 20 episodes; issue 17's stop rule, which changes nothing the run computes) and are
# then evaluated on other seeds. Probes at seed 1 (stop; eval success here): ANN 127k, 85 %;
# SNN 76k, 90 %. Without the rule: ANN 300k 90 %; SNN 200k 90 %.
LEARNING = {"ann": 300_000, "snn": 200_000}  # the caps; about 45 s for both at once on 2 cores
STOP = ["stop.finishes=1", "stop.every=25000", "stop.checks=2"]


@pytest.fixture(scope="module")
def learned(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both learning runs, trained at the same time by ``snnkart train`` (one torch thread
    each, as the in-process trainer uses), so the pair costs the wall time of one."""
    base = tmp_path_factory.mktemp("learned")
    procs = {}
    for policy, steps in LEARNING.items():
        command = [
            sys.executable, "-m", "snnkart.cli", "train", "--env", "grid", "--track", "small_S",
            "--policy", policy, "--steps", str(steps), "--seed", "1", "--out", str(base / policy),
            "--set", "run.tensorboard=false", "--set", "run.trajectories=false",
            *(arg for kv in STOP for arg in ("--set", kv)),
        ]  # fmt: skip
        procs[policy] = subprocess.Popen(
            command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "SDL_VIDEODRIVER": "dummy"},
        )  # fmt: skip
    try:
        for policy, proc in procs.items():
            _, err = proc.communicate(timeout=540)
            assert proc.returncode == 0, f"training {policy} failed:\n{err[-3000:]}"
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
    return {policy: base / policy for policy in LEARNING}


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.xdist_group("learning")  # one worker trains the pair (it was built on both)
@pytest.mark.parametrize("policy", ["ann", "snn"])
def test_grid_policy_learns_to_drive(learned: dict[str, Path], policy: str) -> None:
    from snnkart.eval.episodes import EvalSummary, run_episodes
    from snnkart.rl.trained import TorchPredictor, load_run

    run = load_run(learned[policy])
    assert run.config.seed == 1 and run.meta["stopped_early"], run.meta  # it learned
    first_finish = run.meta["first_finish_step"]
    assert first_finish > 0, run.meta
    env = run.config.make_env(track=run.track)
    try:
        results = run_episodes(env, TorchPredictor(run, seed=10_000), 20, 10_000)
    finally:
        env.close()
    summary = EvalSummary.of(results)
    print(f"\n{policy} stopped at {run.meta['global_step']:,} steps: first finish at "
          f"{first_finish:,}, eval success {summary.success_rate:.0%}")  # fmt: skip
    assert summary.success_rate >= 0.8, summary


@pytest.mark.parametrize("anneal", [True, False])
def test_entropy_coefficient_anneals_with_the_learning_rate(tmp_path: Path, anneal: bool) -> None:
    """With ppo.anneal_ent the entropy coefficient of iteration i is ent_coef * (1 - (i-1)/N),
    exactly like the learning rate; without it, it stays at ent_coef."""
    cfg = tiny_config(
        total_steps=4 * BATCH,
        extra=["ppo.ent_coef=0.01", f"ppo.anneal_ent={str(anneal).lower()}"],
    )
    assert cfg.ppo.ent_coef == 0.01
    run_dir = tmp_path / "run"
    train(cfg, run_dir)
    rows = metrics(run_dir)
    assert len(rows) == 4
    for i, row in enumerate(rows):
        frac = 1.0 - i / 4
        assert row["charts/learning_rate"] == pytest.approx(frac * cfg.ppo.learning_rate)
        expected = frac * cfg.ppo.ent_coef if anneal else cfg.ppo.ent_coef
        assert row["charts/ent_coef"] == pytest.approx(expected)


@pytest.mark.parametrize(
    ("env", "policy", "ent_coef", "learning_rate", "rollout"),
    [
        ("grid", "ann", 0.005, 3e-4, (8, 256)), ("grid", "snn", 0.0, 1e-3, (8, 256)),
        ("gazebo", "ann", 0.02, 1e-3, (8, 256)), ("gazebo", "snn", 0.02, 1e-3, (16, 128)),
        ("steer", "ann", 0.02, 3e-4, (8, 256)), ("steer", "snn", 0.01, 1e-3, (8, 256)),
    ],
)  # fmt: skip
def test_defaults_per_env_and_policy_yield_to_the_user(
    env: str, policy: str, ent_coef: float, learning_rate: float, rollout: tuple[int, int]
) -> None:
    """The measured per-env defaults apply where the user set nothing, and only there."""
    cfg = load_config(overrides={"env": env, "policy": policy})
    assert cfg.ppo.ent_coef == ent_coef
    assert cfg.ppo.learning_rate == learning_rate
    assert (cfg.ppo.num_envs, cfg.ppo.rollout_steps) == rollout
    assert cfg.ann.hidden == ((64, 64) if policy == "ann" else (128, 128))
    mine = load_config(overrides={"env": env, "policy": policy}, sets=["ppo.ent_coef=0.005"])
    assert mine.ppo.ent_coef == 0.005
    assert mine.ppo.learning_rate == learning_rate
    assert mine.ppo.num_envs == cfg.ppo.num_envs
    theirs = load_config(overrides={"env": env, "policy": policy}, sets=["ppo.num_envs=4"])
    assert (theirs.ppo.num_envs, theirs.ppo.rollout_steps) == (4, cfg.ppo.rollout_steps)


def test_firing_rate_penalty_warmup_ramps_the_penalty(tmp_path: Path) -> None:
    """snn.rate_reg_warmup = 0.5 over 4 iterations: the penalty used at iterations 1..4 is
    0, half, full, full (of snn.rate_reg = 0.1), and it enters the update from iteration 2."""
    cfg = tiny_config(policy="snn", total_steps=4 * BATCH,
                      extra=["snn.rate_reg=0.1", "snn.rate_reg_warmup=0.5"])  # fmt: skip
    train(cfg, tmp_path / "warm")
    used = [m["charts/rate_reg"] for m in metrics(tmp_path / "warm")]
    assert used == pytest.approx([0.0, 0.05, 0.1, 0.1])
    none = tiny_config(policy="snn", total_steps=4 * BATCH)
    train(none, tmp_path / "none")
    warm, without = metrics(tmp_path / "warm"), metrics(tmp_path / "none")
    assert "charts/rate_reg" not in without[0]
    # iteration 1 trains without the penalty: the same update as no penalty at all;
    # from iteration 2 the penalty changes the update
    for key in ("losses/policy_loss", "losses/value_loss", "losses/approx_kl"):
        assert warm[0][key] == without[0][key], key
    assert warm[1]["losses/approx_kl"] != without[1]["losses/approx_kl"]


def test_a_run_made_before_a_default_changed_evaluates_and_resumes_in_its_own_env(
    tmp_path: Path,
) -> None:
    """gazebo's reward.stall became 0.01 by default; a run trained when it was off (here:
    set off, with the env config then dropped from its config.toml, as an older run's held
    only what was set and would not have it) still loads and resumes in the env it was
    trained in, not today's."""
    run = train_tiny(tmp_path / "old", "gazebo", "snn", total_steps=256,
                     extra_sets=["env_config.reward.stall=0"])  # fmt: skip
    config = run / "config.toml"
    data = tomllib.loads(config.read_text())
    assert data["env_config"]["reward"]["stall"] == 0.0  # today's runs write it out
    config.write_text(tomli_w.dumps({**data, "env_config": {}}))
    assert "stall" not in config.read_text()
    loaded = load_run(run)
    env = loaded.config.make_env(track=loaded.track)
    try:
        assert env.unwrapped.config.reward.stall == 0.0  # type: ignore[attr-defined]
    finally:
        env.close()
    resumed = Trainer(load_config(), run, resume=True, total_steps=512)
    try:
        assert resumed.karts[0].config.reward.stall == 0.0
        resumed.train()
    finally:
        resumed.close()
    assert json.loads((run / "checkpoint.json").read_text())["global_step"] == 512
