"""``ann.activation``: a ReLU ANN trains, saves, loads and evaluates as it was in memory, really
computes ReLU, quantises to int8 with ReLU exact in integers; tanh stays the default."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from tiny_runs import TINY
from typer.testing import CliRunner

import snnkart
from snnkart.cli import app
from snnkart.errors import ConfigError
from snnkart.eval.ann_int8 import int8_task
from snnkart.eval.episodes import run_episodes
from snnkart.rl.checkpoint import load_checkpoint
from snnkart.rl.config import ANNConfig, load_config, read_run_config
from snnkart.rl.int8 import Int8Layer, Int8Mlp, actor_activation, actor_params, quantise_mlp
from snnkart.rl.policies import ANNPolicy
from snnkart.rl.ppo import Trainer
from snnkart.rl.trained import TorchPredictor, load_run

ROOT = Path(__file__).resolve().parents[1]
RELU = ["ann.activation=relu"]


@pytest.fixture(scope="module")
def relu_trainer(tmp_path_factory: pytest.TempPathFactory) -> Trainer:
    """A ReLU ANN trained two iterations on grid (kept in memory after saving)."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "ann", "total_steps": 512, "track": "small_S"},
        sets=[*TINY, *RELU],
    )
    trainer = Trainer(cfg, tmp_path_factory.mktemp("relu") / "run")
    try:
        trainer.train()
    finally:
        trainer.close()
    return trainer


class _Both:
    """The loaded run's predictor and the Python API's, checked on every step against the
    in-memory policy."""

    def __init__(self, trainer: Trainer) -> None:
        self.trainer = trainer
        self.loaded = TorchPredictor(load_run(trainer.run_dir), seed=0)
        self.api = snnkart.load_policy(trainer.run_dir)
        self.steps = 0

    def reset(self) -> None:
        self.loaded.reset()

    def predict(self, obs: np.ndarray) -> Any:
        raw = np.asarray(obs, np.float32)[None]
        norm = self.trainer.obs_rms.normalize(raw.astype(np.float64), self.trainer.cfg.ppo.clip_obs)
        expected = self.trainer.policy.act_deterministic(
            torch.from_numpy(norm), torch.from_numpy(raw)
        )
        action = self.loaded.predict(obs)
        assert self.api.predict(obs) == action
        assert action == int(expected[0]), f"step {self.steps}: loaded {action}, memory {expected}"
        self.steps += 1
        return action


def test_a_relu_run_saves_loads_and_evaluates_with_the_in_memory_actions(
    relu_trainer: Trainer,
) -> None:
    run_dir = relu_trainer.run_dir
    assert read_run_config(run_dir).ann.activation == "relu"  # config.toml
    _, meta = load_checkpoint(run_dir / "checkpoint.pt")
    assert meta["config"]["ann"]["activation"] == "relu"
    run = load_run(run_dir)
    assert actor_activation(run.policy.actor) == "relu"
    assert isinstance(run.policy.critic[1], torch.nn.ReLU)  # type: ignore[index]
    both = _Both(relu_trainer)
    relu_trainer.policy.eval()
    env = run.config.make_env(track=run.track)
    try:
        run_episodes(env, both, 2, 7)
    finally:
        env.close()
        relu_trainer.policy.train()
    assert both.steps >= 20  # two episodes, every step compared


def test_the_relu_actor_computes_relu() -> None:
    torch.manual_seed(0)
    policy = ANNPolicy(6, 3, True, ANNConfig(hidden=(16, 8), activation="relu"), -0.5)
    obs = torch.randn(64, 6)
    first, act, second, act2, out = policy.actor
    assert isinstance(act2, torch.nn.ReLU)
    pre = first(obs)
    assert (pre < 0).sum() > 100 and (pre > 0).sum() > 100
    hidden = act(pre)
    assert torch.equal(hidden[pre < 0], torch.zeros_like(hidden[pre < 0]))  # exactly 0
    assert torch.equal(hidden[pre >= 0], pre[pre >= 0])
    by_hand = out(torch.clamp(second(torch.clamp(pre, min=0.0)), min=0.0))
    assert torch.equal(policy.actor_output(obs, obs, None)[0], by_hand)


def test_tanh_stays_the_default_and_old_runs_load_as_tanh() -> None:
    assert load_config(overrides={"policy": "ann"}).ann.activation == "tanh"
    policy = ANNPolicy(6, 3, True, ANNConfig(), -0.5)
    assert isinstance(policy.actor[1], torch.nn.Tanh) and isinstance(
        policy.critic[1], torch.nn.Tanh
    )
    # the committed ANN run was saved before the option existed: its config.toml has no key
    fixture = ROOT / "tests/data/policies/grid-ann"
    assert "activation" not in (fixture / "config.toml").read_text()
    assert actor_activation(load_run(fixture).policy.actor) == "tanh"


def test_a_misspelled_activation_is_one_line_naming_both() -> None:
    with pytest.raises(ConfigError) as err:
        load_config(overrides={"policy": "ann"}, sets=["ann.activation=rellu"])
    message = str(err.value)
    assert "\n" not in message
    assert "ann.activation" in message and "'tanh'" in message and "'relu'" in message
    assert "'rellu'" in message


def test_the_cli_takes_and_documents_the_option(tmp_path: Path) -> None:
    runner = CliRunner()
    help_text = runner.invoke(app, ["train", "--help"], terminal_width=200).output
    assert "ann.activation=relu" in " ".join(help_text.split())
    out = tmp_path / "run"
    sets = [x for s in [*TINY, *RELU] for x in ("--set", s)]
    result = runner.invoke(
        app, ["train", "--env", "grid", "--policy", "ann", "--steps", "256", "--out", str(out),
              *sets],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert read_run_config(out).ann.activation == "relu"
    bad = runner.invoke(app, ["train", "--policy", "ann", "--set", "ann.activation=sigmoid"])
    assert bad.exit_code != 0 and "'relu'" in bad.output and "'sigmoid'" in bad.output


def _relu_tiny() -> Int8Mlp:
    """2 -> 2 (ReLU) -> 2 with integers chosen by hand."""
    hidden = Int8Layer(
        weight=np.array([[2, -1], [1, 3]], np.int8), bias=np.array([10, -5], np.int32),
        in_scale=0.1, weight_scale=0.01, pre_scale=0.002,
        multiplier=2**30, shift=31,  # M / 2**k = 0.5 = in_scale * weight_scale / pre_scale
        table=None, activation="relu",
    )  # fmt: skip
    out = Int8Layer(
        weight=np.array([[1, -2], [3, 1]], np.int8), bias=np.array([0, 7], np.int32),
        in_scale=0.002, weight_scale=0.01, pre_scale=None, multiplier=0, shift=0, table=None,
    )  # fmt: skip
    return Int8Mlp((hidden, out))


def test_int8_relu_forward_equals_a_hand_computation() -> None:
    net = _relu_tiny()
    z = np.array([[0.5, -0.3]])
    x0 = net.quantise_input(z)
    assert x0.tolist() == [[5, -3]]  # 0.5 / 0.1, -0.3 / 0.1
    acc = net.layers[0].accumulate(x0)
    assert acc.tolist() == [[23, -9]]  # 2*5 + 1*3 + 10, 5 - 9 - 5
    pre = net.layers[0].requantise(acc)
    assert pre.tolist() == [[12, -4]]  # 23 * 0.5 = 11.5 -> 12, -4.5 -> -4 (half up)
    x1 = net.layers[0].activate(pre)
    assert x1.tolist() == [[12, 0]]  # ReLU, exactly: the input's scale is the pre-activation's
    assert net.accumulator(z).tolist() == [[12, 43]]  # 12 - 0 + 0, 36 + 0 + 7
    assert net.act(z, discrete=True).tolist() == [1]
    assert net.act(z, discrete=False) == pytest.approx(np.array([[0.00024, 0.00086]]))


def test_int8_relu_agrees_with_the_float_actor() -> None:
    rng = np.random.default_rng(0)
    params = [(rng.normal(0, 0.5, (32, 8)), rng.normal(0, 0.1, 32)),
              (rng.normal(0, 0.3, (32, 32)), rng.normal(0, 0.1, 32)),
              (rng.normal(0, 0.3, (5, 32)), rng.normal(0, 0.1, 5))]  # fmt: skip
    z = np.clip(rng.normal(0, 1, (3000, 8)), -3, 3)
    x = z
    for i, (w, b) in enumerate(params):
        x = x @ w.T + b
        x = np.maximum(x, 0.0) if i < len(params) - 1 else x
    net = quantise_mlp(params, z[:1000], "relu")
    assert net.layers[0].table is None
    w1, b1 = params[0]
    top = np.maximum(z[:1000] @ w1.T + b1, 0.0).max()  # the positive side only: ReLU's range
    assert net.layers[0].pre_scale == pytest.approx(top / 127)
    assert net.layers[1].in_scale == net.layers[0].pre_scale  # ReLU keeps the scale
    held_out = z[1000:]
    agree = (net.act(held_out, discrete=True) == x[1000:].argmax(-1)).mean()
    assert agree >= 0.95, f"int8 ReLU agrees with float on only {agree:.1%}"
    error = np.abs(net.accumulator(held_out) * net.out_scale - x[1000:])
    assert error.mean() < 0.01 * np.abs(x).max()


def test_int8_task_on_a_relu_run(relu_trainer: Trainer) -> None:
    """What ``snnkart report --ann RUN`` runs for the ANN's int8 row, on the ReLU run."""
    run = load_run(relu_trainer.run_dir)
    params = actor_params(run.policy.actor)
    assert len(params) == 3
    task = int8_task(run, lambda: run.config.make_env(track=run.track), 500, 2, 1)
    assert "ReLU exact" in task["scheme"]
    assert task["action_agreement"] >= 0.9
