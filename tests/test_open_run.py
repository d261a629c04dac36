"""Opening a run: what resuming and loading both need, from one tiny SNN run of three
iterations, against the trainer that wrote it."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import torch
from tiny_runs import TINY

from snnkart.envs.spec import env_spec
from snnkart.rl.config import load_config
from snnkart.rl.open_run import open_run
from snnkart.rl.ppo import Trainer
from snnkart.rl.trained import load_run

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

BATCH = 2 * 128


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Trainer]:
    cfg = load_config(
        overrides={"env": "grid", "policy": "snn", "total_steps": 3 * BATCH, "track": "small_S"},
        sets=[*TINY, "run.checkpoint_every=2"],
    )
    run_dir = tmp_path_factory.mktemp("open") / "run"
    trainer = Trainer(cfg, run_dir)
    try:
        trainer.train()
    finally:
        trainer.close()
    return run_dir, trainer


def test_open_run_gives_what_resume_and_load_need(run: tuple[Path, Trainer]) -> None:
    run_dir, trainer = run
    opened = open_run(run_dir)
    assert opened.checkpoint == run_dir / "checkpoint.pt"
    assert opened.config == trainer.cfg and opened.track.name == trainer.track.name
    assert opened.env_spec == env_spec(trainer.karts[0]) == opened.meta["env_spec"]
    weights = trainer.policy.state_dict()
    for name, value in opened.policy.state_dict().items():
        assert torch.equal(value, weights[name]), name
    assert np.array_equal(opened.obs_rms.mean, trainer.obs_rms.mean)
    assert np.array_equal(opened.obs_rms.var, trainer.obs_rms.var)
    assert opened.obs_rms.count == trainer.obs_rms.count
    assert opened.progress == trainer.progress
    assert opened.state["optimizer"]["state"]  # Adam's moments, for the resume
    base_lr = trainer.cfg.ppo.learning_rate
    schedule = opened.schedule
    assert (schedule.total_steps, schedule.num_iterations) == (3 * BATCH, 3)
    assert (schedule.iteration, schedule.global_step) == (3, 3 * BATCH)
    assert schedule.learning_rate == pytest.approx(base_lr / 3)  # annealed: 1 - 2/3 left
    loaded = load_run(run_dir)  # the same run, for evaluation
    assert loaded.config == opened.config and not loaded.policy.training


def test_an_earlier_checkpoint_and_the_length_it_was_recorded_with(
    run: tuple[Path, Trainer], tmp_path: Path
) -> None:
    """The schedule is the checkpoint's: an earlier checkpoint stands earlier in it, and a
    config.toml rewritten since (a run extended, then stopped before it saved) does not move
    the length the checkpoint was training for."""
    run_dir, trainer = run
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    data = tomllib.loads((copy / "config.toml").read_text())
    data["total_steps"] = 10 * BATCH
    (copy / "config.toml").write_text(tomli_w.dumps(data))
    early = open_run(copy, copy / "checkpoints" / "iter_000002.pt")
    assert early.config.total_steps == 10 * BATCH  # what a resume would extend the run to
    schedule = early.schedule
    assert (schedule.total_steps, schedule.iteration, schedule.global_step) == (
        3 * BATCH,
        2,
        2 * BATCH,
    )
    assert schedule.learning_rate == pytest.approx(trainer.cfg.ppo.learning_rate * 2 / 3)
    assert early.progress.iteration == 2
