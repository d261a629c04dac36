"""Generalised advantage estimation against hand-computed numbers, and the PPO ratio check.

The hand computation uses gamma = 0.9, lambda = 0.8 (gamma * lambda = 0.72) and
``delta_t = r_t + gamma * V_{t+1} * (1 - end_t) - V_t``,
``A_t = delta_t + gamma * lambda * (1 - end_t) * A_{t+1}``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer, compute_gae

GAMMA = 0.9
LAMBDA = 0.8


def test_compute_gae_by_hand() -> None:
    # env 0: terminates after step 1 (episode_end = 1, no bootstrap), then a new episode
    #        runs to the end of the rollout and is bootstrapped with last_value = 2.0.
    # env 1: truncated by the time limit after step 0. Raw reward 0.5, V(final_obs) = 4.0,
    #        so the stored reward already carries the bootstrap: 0.5 + 0.9 * 4.0 = 4.1
    #        (as Trainer does), and the episode is then cut (episode_end = 1).
    truncated_reward = 0.5 + GAMMA * 4.0  # = 4.1
    rewards = torch.tensor(
        [[1.0, truncated_reward], [2.0, -1.0], [3.0, 0.0], [0.5, 1.0]], dtype=torch.float64
    )
    values = torch.tensor([[0.5, 1.0], [1.0, 2.0], [1.5, -0.5], [2.0, 0.0]], dtype=torch.float64)
    episode_end = torch.tensor(
        [[0.0, 1.0], [1.0, 0.0], [0.0, 0.0], [0.0, 0.0]], dtype=torch.float64
    )
    last_value = torch.tensor([2.0, 1.0], dtype=torch.float64)

    advantages, returns = compute_gae(rewards, values, episode_end, last_value, GAMMA, LAMBDA)

    # env 0 (backwards):
    #   t=3: delta = 0.5 + 0.9*2.0 - 2.0 = 0.3;                 A3 = 0.3
    #   t=2: delta = 3.0 + 0.9*2.0 - 1.5 = 3.3;                 A2 = 3.3 + 0.72*0.3 = 3.516
    #   t=1: terminal: delta = 2.0 - 1.0 = 1.0;                 A1 = 1.0  (no bootstrap, chain cut)
    #   t=0: delta = 1.0 + 0.9*1.0 - 0.5 = 1.4;                 A0 = 1.4 + 0.72*1.0 = 2.12
    # env 1 (backwards):
    #   t=3: delta = 1.0 + 0.9*1.0 - 0.0 = 1.9;                 A3 = 1.9
    #   t=2: delta = 0.0 + 0.9*0.0 - (-0.5) = 0.5;              A2 = 0.5 + 0.72*1.9 = 1.868
    #   t=1: delta = -1.0 + 0.9*(-0.5) - 2.0 = -3.45;           A1 = -3.45 + 0.72*1.868 = -2.10504
    #   t=0: truncated: delta = 4.1 - 1.0 = 3.1;                A0 = 3.1  (bootstrap is in r_0)
    expected_adv = torch.tensor(
        [[2.12, 3.1], [1.0, -2.10504], [3.516, 1.868], [0.3, 1.9]], dtype=torch.float64
    )
    # returns = advantages + values:
    #   env 0: 2.12+0.5 = 2.62, 1.0+1.0 = 2.0, 3.516+1.5 = 5.016, 0.3+2.0 = 2.3
    #   env 1: 3.1+1.0 = 4.1, -2.10504+2.0 = -0.10504, 1.868-0.5 = 1.368, 1.9+0.0 = 1.9
    expected_ret = torch.tensor(
        [[2.62, 4.1], [2.0, -0.10504], [5.016, 1.368], [2.3, 1.9]], dtype=torch.float64
    )
    torch.testing.assert_close(advantages, expected_adv, rtol=0, atol=1e-12)
    torch.testing.assert_close(returns, expected_ret, rtol=0, atol=1e-12)
    torch.testing.assert_close(returns, advantages + values, rtol=0, atol=0)


def test_compute_gae_float32_and_lambda_one_is_discounted_return() -> None:
    # lambda = 1, no ends: A_t + V_t is the discounted return bootstrapped with last_value.
    #   G_2 = 1 + 0.9*10 = 10;  G_1 = 2 + 0.9*10 = 11;  G_0 = 3 + 0.9*11 = 12.9
    rewards = torch.tensor([[3.0], [2.0], [1.0]])
    values = torch.tensor([[5.0], [-1.0], [0.25]])
    ends = torch.zeros(3, 1)
    adv, ret = compute_gae(rewards, values, ends, torch.tensor([10.0]), GAMMA, 1.0)
    assert adv.dtype == torch.float32
    torch.testing.assert_close(ret, torch.tensor([[12.9], [11.0], [10.0]]))
    torch.testing.assert_close(adv, ret - values)


TINY = [
    "ppo.num_envs=2",
    "ppo.rollout_steps=64",
    "ppo.update_epochs=2",
    "ppo.num_minibatches=2",
    "run.tensorboard=false",
    "run.trajectories=false",
]


@pytest.mark.parametrize(
    ("env", "policy", "extra"),
    [
        ("grid", "ann", []),
        ("steer", "snn", ["snn.encoding=current"]),
        ("grid", "snn", ["snn.encoding=rate"]),
        ("gazebo", "snn", ["snn.encoding=rate", "action_mode=continuous"]),
        # short time limit: truncations (final_obs bootstrap) happen inside the rollout
        ("grid", "ann", ["env_config.max_episode_steps=20"]),
    ],
)
def test_first_minibatch_ratio_is_one(
    tmp_path: Path, env: str, policy: str, extra: list[str]
) -> None:
    """Rollout and update compute the same log-probs (incl. the stored rate-coded spikes)."""
    cfg = load_config(
        overrides={"env": env, "policy": policy, "total_steps": 384, "track": "small_S"},
        sets=[*TINY, *extra],
    )
    trainer = Trainer(cfg, tmp_path / "run")
    try:
        progress = trainer.train()
    finally:
        trainer.close()
    assert progress.global_step == 384
    records = [json.loads(line) for line in (tmp_path / "run" / "metrics.jsonl").open()]
    assert [r["iteration"] for r in records] == [1, 2, 3]
    for r in records:
        dev = r["losses/first_minibatch_max_ratio_deviation"]
        assert not math.isnan(dev)
        assert dev <= 1e-5, (r["iteration"], dev)
    if "env_config.max_episode_steps=20" in extra:
        # 384 steps over 2 envs with a 20-step limit: many episodes, none longer than 20
        assert progress.episodes >= 2 * (192 // 20)
        lengths = [r["charts/episodic_length"] for r in records if r["charts/episodic_length"]]
        assert lengths and max(lengths) <= 20


def test_trainer_bootstraps_time_limit_truncations(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The rewards GAE receives carry ``gamma * V(final_obs)`` at every time-limit truncation
    and nothing extra elsewhere. V is computed here from the rollout's own policy and
    normaliser (copied at each env step), not by the Trainer's code path."""
    from snnkart.rl.ppo import normalize_obs

    cfg = load_config(
        overrides={"env": "grid", "policy": "ann", "total_steps": 128, "track": "small_S"},
        sets=[*TINY, "env_config.max_episode_steps=20"],
    )
    trainer = Trainer(cfg, tmp_path / "run")
    expected: list[np.ndarray] = []
    truncations = 0
    real_step = trainer.envs.step

    def step(action: np.ndarray) -> tuple:
        nonlocal truncations
        obs, reward, terminated, truncated, info = real_step(action)
        want = reward.astype(np.float64).copy()
        for i in np.flatnonzero(truncated):
            final = np.asarray(info["final_obs"][i], dtype=np.float64)[None]
            norm = normalize_obs(trainer.obs_rms, cfg.ppo, final)
            with torch.no_grad():
                value = float(trainer.policy.value(torch.from_numpy(norm))[0])
            assert abs(value) > 1e-4  # a bootstrap that could be told from none
            want[i] += cfg.ppo.gamma * value
            truncations += 1
        expected.append(want.astype(np.float32))
        return obs, reward, terminated, truncated, info

    seen: list[torch.Tensor] = []
    real_gae = compute_gae

    def gae(rewards: torch.Tensor, *args: object, **kwargs: object) -> tuple:
        seen.append(rewards.clone())
        return real_gae(rewards, *args, **kwargs)

    monkeypatch.setattr(trainer.envs, "step", step)
    monkeypatch.setattr("snnkart.rl.ppo.compute_gae", gae)
    try:
        trainer.train()
    finally:
        trainer.close()
    assert truncations >= 4, "the test needs time-limit truncations inside the rollout"
    assert len(seen) == 1  # one iteration of 64 steps x 2 envs
    torch.testing.assert_close(seen[0], torch.from_numpy(np.stack(expected)), rtol=0, atol=1e-6)
