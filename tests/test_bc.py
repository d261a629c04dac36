"""Behaviour cloning (``train --pretrain-bc``): the loss falls for every clonable policy kind,
the cloned policy drives, the run records it and a resume does not clone again."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from snnkart.envs.recording import Recording
from snnkart.envs.tracks import load_track
from snnkart.errors import ConfigError
from snnkart.eval.expert import record_driver
from snnkart.rl.bc import behaviour_clone
from snnkart.rl.config import load_config
from snnkart.rl.kinds import policy_for
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.ppo import Trainer
from snnkart.rl.stopping import seeded_episodes

TINY = {"ppo.num_envs": 2, "ppo.rollout_steps": 64, "ppo.num_minibatches": 2,
        "run.tensorboard": False, "run.trajectories": False}  # fmt: skip


@pytest.fixture(scope="module")
def grid_data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bc") / "grid-pursuit.npz"
    return record_driver("grid", "small_S", episodes=8, seed=0).save(path)


def _clone(data: Path, policy: str, epochs: int, env: str = "grid", **keys: object):  # type: ignore[no-untyped-def]
    cfg = load_config(None, {"env": env, "policy": policy, "bc.data": str(data), "bc.epochs": epochs, **keys})  # fmt: skip
    torch.manual_seed(1)
    net = policy_for(cfg, cfg.make_env().unwrapped)
    rms = RunningMeanStd.zeros(net.obs_dim)
    return cfg, net, rms


@pytest.fixture(scope="module")
def short_data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bc") / "grid-pursuit-2.npz"
    return record_driver("grid", "small_S", episodes=2, seed=0).save(path)


@pytest.mark.parametrize("policy", ["ann", "snn", "sdnn"])
def test_the_bc_loss_falls(short_data: Path, policy: str) -> None:
    cfg, net, rms = _clone(short_data, policy, 4, **{"bc.batch_size": 128})
    summary = behaviour_clone(net, rms, cfg, Recording.load(short_data))
    actor, value, accuracy = summary["actor_loss"], summary["value_loss"], summary["accuracy"]
    assert actor[-1] < 0.85 * actor[0], actor
    assert value[-1] < value[0], value
    assert accuracy[-1] > 0.5, accuracy  # 5 actions: chance is ~0.2
    assert summary["steps"] == len(Recording.load(short_data).obs)


@pytest.mark.parametrize("keys", [{}, {"snn.stateful": True, "snn.encoding": "current"}])
def test_every_batch_targets_the_recorded_action_of_its_own_rows(
    short_data: Path, keys: dict[str, object]
) -> None:
    """The loss is right only if row i's target is row i's action: a policy spy checks that
    every batch's raw observations and targets are the recording's, row for row. (Accuracy
    cannot tell: the pursuit driver's majority action is ~82 % of the steps, which a policy
    fitted to shuffled targets reaches too.)"""
    cfg, net, rms = _clone(short_data, "snn", 1, **{"bc.batch_size": 128, **keys})
    rec = Recording.load(short_data)
    rows_of = {tuple(o): i for i, o in enumerate(rec.obs.tolist())}
    seen = []
    real = net.forward

    def spy(obs, raw, action=None, **extra):  # type: ignore[no-untyped-def]
        rows = [rows_of[tuple(r)] for r in raw.tolist()]
        assert action is not None and action.tolist() == rec.actions[rows].tolist()
        seen.extend(rows)
        return real(obs, raw, action=action, **extra)

    net.forward = spy  # type: ignore[method-assign]
    behaviour_clone(net, rms, cfg, rec)
    assert len(set(seen)) >= 0.9 * len(rec.obs)


def test_continuous_actions_are_cloned_by_gaussian_likelihood(tmp_path: Path) -> None:
    data = record_driver("steer", "small_S", episodes=1, action_mode="continuous").save(
        tmp_path / "c.npz"
    )
    cfg, net, rms = _clone(data, "ann", 6, env="steer", action_mode="continuous")
    summary = behaviour_clone(net, rms, cfg, Recording.load(data))
    assert summary["actor_loss"][-1] < 0.85 * summary["actor_loss"][0], summary["actor_loss"]
    assert summary["accuracy"] == [None] * 6


@pytest.mark.slow  # ~25 s alone, ~100 s on a busy machine
def test_the_cloned_policy_drives(grid_data: Path) -> None:
    """BC only (no PPO): pursuit data, grid/small_S. Measured at this commit: success 0.0 and
    mean return -3.5 before cloning, 0.4 and +9.1 after 40 epochs (5 episodes, seeds 500+)."""
    cfg, net, rms = _clone(grid_data, "ann", 40)
    track = load_track("small_S")
    before = seeded_episodes(cfg, net, rms, track, 5, 500, lambda: False)
    behaviour_clone(net, rms, cfg, Recording.load(grid_data))
    after = seeded_episodes(cfg, net, rms, track, 5, 500, lambda: False)
    assert before is not None and after is not None
    assert after[0] > 0.0, (before, after)
    assert after[1] > before[1] + 5.0, (before, after)


def test_a_run_records_its_warm_start_and_a_resume_does_not_redo_it(
    grid_data: Path, tmp_path: Path
) -> None:
    cfg = load_config(None, {"env": "grid", "policy": "ann", "total_steps": 128, "bc.data": str(grid_data), "bc.epochs": 2, **TINY})  # fmt: skip
    run = tmp_path / "run"
    trainer = Trainer(cfg, run)
    trainer.train()
    trainer.close()
    bc = json.loads((run / "bc.json").read_text())
    assert bc["schema"] == "snnkart/bc/v1" and bc["epochs"] == 2 and bc["driver"] == "pursuit"
    assert 'data = "' in (run / "config.toml").read_text()
    assert not math.isclose(trainer.obs_rms.mean[0], 0.0)  # the normaliser saw the recording
    (run / "bc.json").unlink()
    resumed = Trainer(cfg, run, resume=True, total_steps=256)
    assert resumed.bc is None and resumed.cfg.bc == cfg.bc
    resumed.train()
    resumed.close()
    assert not (run / "bc.json").exists()


def test_a_recording_of_another_env_is_refused_before_training(
    grid_data: Path, tmp_path: Path
) -> None:
    cfg = load_config(None, {"env": "steer", "policy": "ann", "bc.data": str(grid_data), **TINY})
    with pytest.raises(ValueError, match=r"--pretrain-bc .* was recorded in another env \(env grid vs steer"):  # fmt: skip
        Trainer(cfg, tmp_path / "run")


def test_a_stateful_snn_is_cloned_on_windows(short_data: Path) -> None:
    keys = {"snn.stateful": True, "snn.encoding": "current", "bc.batch_size": 128}
    cfg, net, rms = _clone(short_data, "snn", 8, **keys)
    assert net.carries_state
    summary = behaviour_clone(net, rms, cfg, Recording.load(short_data))
    assert summary["actor_loss"][-1] < 0.9 * summary["actor_loss"][0], summary["actor_loss"]
    assert summary["accuracy"] == [None] * 8
    from snnkart.rl.bc import WINDOW, _batches

    rows, extra, kept = next(_batches(net, Recording.load(short_data), 128, torch.Generator()))
    steps = rows.reshape(WINDOW, -1)  # time-major: row s * E + e is step s of window e
    assert (steps.diff(dim=0) == 1).all() and steps.shape[1] == extra["state"].shape[0] == 2
    assert extra["starts"][0].tolist() == [1.0, 1.0] and not extra["starts"][1:].any()
    assert int(kept.sum()) == (WINDOW - 16) * 2


def test_windows_cover_every_step_of_long_enough_episodes() -> None:
    from snnkart.rl.bc import _windows

    w = _windows(np.array([0, 10, 13]), 20, 4)  # episodes of 10, 3 and 7 steps
    assert w.tolist() == [[0, 1, 2, 3], [4, 5, 6, 7], [6, 7, 8, 9], [13, 14, 15, 16], [16, 17, 18, 19]]  # fmt: skip


def test_train_pretrain_bc_on_the_command_line(grid_data: Path, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from snnkart.cli.main import app

    sets = [x for k, v in TINY.items() for x in ("--set", f"{k}={str(v).lower()}")]
    base = ["train", "--env", "steer", "--policy", "ann", "--steps", "128", *sets]
    result = CliRunner().invoke(app, [*base, "--bc-epochs", "3", "--out", str(tmp_path / "a")])
    assert result.exit_code == 2 and "--bc-epochs needs --pretrain-bc" in result.output
    refused = tmp_path / "refused"
    result = CliRunner().invoke(app, [*base, "--pretrain-bc", str(grid_data), "--out", str(refused)])  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "was recorded in another env (env grid vs steer" in result.output
    assert not (refused / "config.toml").exists()  # nothing to resume: the same command works
    run = tmp_path / "grid"
    args = ["--env", "grid", "--pretrain-bc", str(grid_data), "--bc-epochs", "1", "--out", str(run)]  # fmt: skip
    result = CliRunner().invoke(app, [*base, *args])
    assert result.exit_code == 0, result.output
    assert "behaviour cloning of" in result.output and "in 1 epochs" in result.output
    assert json.loads((run / "bc.json").read_text())["epochs"] == 1


def test_a_misspelled_bc_key_is_named_with_the_right_one() -> None:
    with pytest.raises(ConfigError, match=r"unknown key 'bc.epoch' .*did you mean 'bc.epochs'"):
        load_config(None, {"bc.data": "x.npz"}, ["bc.epoch=3"])
    with pytest.raises(ConfigError, match=r"bc.data: Field required"):
        load_config(None, {"bc.epochs": 3})
