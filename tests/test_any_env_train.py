"""Training on any gymnasium env (issue 45): a registered id with Discrete actions, one with
Box actions, and an env the tests define by entry point with Dict observations; the kart-only
settings refused in words for them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from gymnasium import spaces as gym_spaces

from snnkart.rl.checkpoint import load_checkpoint
from snnkart.rl.config import TrainConfig
from snnkart.rl.ppo import train

TINY = {"total_steps": 512, "ppo": {"num_envs": 2, "rollout_steps": 128, "num_minibatches": 2}}


@pytest.mark.timeout(300)
@pytest.mark.parametrize(
    ("env", "policy"),
    [("CartPole-v1", "ann"), ("CartPole-v1", "snn"), ("Pendulum-v1", "sdnn"),
     ("my_envs:MyDictEnv-v0", "snn")],
)  # fmt: skip
def test_a_gymnasium_env_trains_and_records_its_spec(env: str, policy: str, tmp_path: Path) -> None:
    cfg = TrainConfig.model_validate({**TINY, "env": env, "policy": policy})
    result = train(cfg, tmp_path / "run")
    assert result["global_step"] == 512 and result["episodes"] > 0
    lines = (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()
    record = json.loads(lines[-1])
    assert record["charts/cumulative_finishes"] is None  # no laps outside the kart envs
    _, meta = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    spec = meta["env_spec"]
    assert spec["kind"] == "gymnasium" and spec["env"] == env and meta["track"] is None
    if env == "CartPole-v1":
        assert spec["reward_threshold"] == 475 and spec["max_episode_steps"] == 500
    if env == "Pendulum-v1":  # actions rescaled from [-1, 1] to the env's [-2, 2]
        assert "RescaleAction" in spec["wrappers"]
    if env.startswith("my_envs"):  # Dict observations flattened
        assert "FlattenObservation" in spec["wrappers"]


def test_multidiscrete_actions_are_one_categorical_over_the_joint_actions() -> None:
    """Joint action a is the components' C-order index over nvec, each offset by its start."""
    from snnkart.envs.resolve import resolve_env
    from snnkart.envs.task_env import MAX_JOINT_ACTIONS, make_gym_env
    from snnkart.errors import EnvError

    env = make_gym_env(resolve_env("my_envs:PickEnv"))
    assert env.action_space == gym_spaces.Discrete(6)
    assert [env.action(a).tolist() for a in range(6)] == [  # type: ignore[attr-defined]
        [1, 0], [1, 1], [1, 2], [2, 0], [2, 1], [2, 2]]  # fmt: skip
    with pytest.raises(EnvError, match=f"more than the {MAX_JOINT_ACTIONS}"):
        make_gym_env(resolve_env("my_envs:PickEnv"), {"nvec": [32, 32]})


@pytest.mark.timeout(300)
def test_a_policy_learns_a_multidiscrete_task(tmp_path: Path) -> None:
    """PickEnv pays 1 per component equal to the shown target's: a random policy earns
    10 x (1/2 + 1/3) = 8.3 an episode, the best 20."""
    from snnkart.app.evaluate import run_eval
    from snnkart.app.reporter import Silent

    cfg = TrainConfig.model_validate(
        {"total_steps": 8192, "env": "my_envs:PickEnv", "policy": "ann",
         "ppo": {"num_envs": 4, "rollout_steps": 128, "num_minibatches": 4}}
    )  # fmt: skip
    train(cfg, tmp_path / "run")
    record = run_eval(tmp_path / "run", 10, 3, None, False, None, None, Silent())
    assert record.summary.mean_return >= 17.0, record.summary.mean_return


@pytest.mark.parametrize(
    ("setting", "words"),
    [({"stop": {"finishes": 10}}, "stop.finishes needs a kart env"),
     ({"eval": {"every_steps": 1000}}, "eval.every_steps needs a kart env")],
)  # fmt: skip
def test_kart_only_settings_are_refused_for_a_gymnasium_env(setting: dict, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        TrainConfig.model_validate({"env": "CartPole-v1", **setting})


def test_an_unknown_env_names_the_close_ids() -> None:
    with pytest.raises(ValueError, match="CartPole-v1"):
        TrainConfig.model_validate({"env": "CartPole-v9"})


@pytest.mark.timeout(120)
@pytest.mark.parametrize("end", ["truncate", "terminate"])
def test_truncation_bootstraps_the_value_and_termination_does_not(end: str, monkeypatch) -> None:
    """A hand-made two-step episode (tests/my_envs.py TwoStepEnv): the reward GAE sees at its
    second step is 1 + gamma V([1, 0.5]) when a time limit cut it, and 1 when it ended."""
    import numpy as np
    import torch

    from snnkart.rl.ppo import Trainer

    cfg = TrainConfig.model_validate({
        "env": "my_envs:TwoStepEnv", "env_kwargs": {"end": end}, "policy": "ann",
        "total_steps": 8, "ppo": {"num_envs": 1, "rollout_steps": 8, "num_minibatches": 1,
                                  "norm_obs": False, "gamma": 0.9}})  # fmt: skip
    seen: list[tuple[torch.Tensor, float]] = []
    import snnkart.rl.ppo as ppo

    real_gae = ppo.compute_gae

    def gae(rewards: torch.Tensor, *args: object, **kwargs: object) -> tuple:
        with torch.no_grad():  # the policy the rollout ran (the update comes after)
            final = torch.tensor([[1.0, 0.5]])
            seen.append((rewards.clone(), float(trainer.policy.value(final)[0])))
        return real_gae(rewards, *args, **kwargs)

    monkeypatch.setattr(ppo, "compute_gae", gae)
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        trainer = Trainer(cfg, Path(tmp) / "run")
        try:
            trainer.train()
        finally:
            trainer.close()
    ((rewards, value),) = seen
    r = rewards[:, 0].numpy()
    assert abs(value) > 1e-4  # a bootstrap that could be told from none
    np.testing.assert_allclose(r[0::2], 1.0, atol=1e-6)  # first steps: the reward alone
    want = 1.0 + 0.9 * value if end == "truncate" else 1.0
    np.testing.assert_allclose(r[1::2], want, atol=1e-5)


@pytest.mark.timeout(120)
def test_reward_scaling_is_stable_baselines3s_vecnormalize() -> None:
    """ppo.norm_reward's scaling (rl/normalise.RewardScaling) against SB3's own VecNormalize
    (norm_obs off, gamma 0.97, clip 3) on three envs with random rewards and episode ends."""
    import gymnasium as gym
    import numpy as np

    vec_env = pytest.importorskip("stable_baselines3.common.vec_env",
                                  reason="optional: the zoo extra (stable-baselines3)")  # fmt: skip
    from snnkart.rl.normalise import RewardScaling

    class Noisy(gym.Env):
        observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
        action_space = gym.spaces.Discrete(2)

        def __init__(self, seed: int) -> None:
            self.rng = np.random.default_rng(seed)

        def reset(self, *, seed=None, options=None):
            return np.zeros(1, dtype=np.float32), {}

        def step(self, action):
            reward = float(self.rng.normal(2.0, 5.0))
            end = bool(self.rng.random() < 0.1)
            return np.zeros(1, dtype=np.float32), reward, end, False, {}

    venv = vec_env.DummyVecEnv([lambda i=i: Noisy(i) for i in range(3)])
    sb3 = vec_env.VecNormalize(venv, norm_obs=False, gamma=0.97, clip_reward=3.0)
    ours = RewardScaling.new(0.97, 3.0)
    sb3.reset()
    clipped = 0
    for _ in range(400):
        _, theirs, dones, _ = sb3.step(np.zeros(3, dtype=np.int64))
        mine = ours(sb3.get_original_reward().astype(np.float64), dones)
        np.testing.assert_allclose(mine, theirs, rtol=1e-5, atol=1e-6)
        clipped += int(np.sum(np.abs(mine) == 3.0))
    assert clipped > 0  # the clip was exercised


@pytest.mark.timeout(300)
def test_a_run_with_reward_scaling_resumes_with_its_return_statistics(tmp_path: Path) -> None:
    cfg = TrainConfig.model_validate({**TINY, "env": "CartPole-v1", "policy": "ann",
                                      "ppo": {**TINY["ppo"], "norm_reward": True}})  # fmt: skip
    train(cfg, tmp_path / "run")
    state, _ = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    first = state["reward_rms"]
    assert float(first["count"]) > 500 and float(first["var"]) > 1.0  # R grows
    longer = cfg.model_copy(update={"total_steps": 1024})
    train(longer, tmp_path / "run")  # resumes the run there
    state, _ = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    assert float(state["reward_rms"]["count"]) == pytest.approx(float(first["count"]) + 512)
